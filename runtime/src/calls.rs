//! The method queue: calls to other modules that wait for an answer.
//!
//! A call takes a sequence number that is free for its peer, and waits in the queue until the
//! peer's REPLY, ACK or NAK with that (peer, sequence) arrives, or its deadline passes. Many
//! calls can be outstanding at once (up to 32 per peer). A sequence number whose call timed
//! out stays reserved for one more timeout (at least a second), so a late answer cannot be taken for the answer to
//! a newer call. The table is allocated once; the hot path does not allocate.

use core::time::Duration;

use modbot_ipc_schema::{Addr, Seq};

use crate::error::CallError;

/// The most calls one module has outstanding at once.
pub const MAX_OUTSTANDING: usize = 256;

/// Options of one call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CallOptions {
    /// How long to wait for the answer.
    pub timeout: Duration,
    /// While the peer is down or its inbox is full, keep trying until the deadline instead of
    /// failing at once.
    pub wait_for_peer: bool,
}

impl Default for CallOptions {
    fn default() -> Self {
        CallOptions {
            timeout: Duration::from_secs(2),
            wait_for_peer: false,
        }
    }
}

impl CallOptions {
    pub fn timeout(timeout: Duration) -> CallOptions {
        CallOptions {
            timeout,
            ..Default::default()
        }
    }
}

/// A call waiting in the method queue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CallHandle(u64);

impl CallHandle {
    pub fn id(self) -> u64 {
        self.0
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SlotState {
    Waiting,
    /// Timed out; the sequence number is reserved until `until_ns`.
    Quarantined {
        until_ns: u64,
    },
}

#[derive(Debug, Clone, Copy)]
struct Slot {
    handle: CallHandle,
    peer: Addr,
    seq: Seq,
    deadline_ns: u64,
    /// The timeout the caller chose, for the error that reports it.
    timeout: Duration,
    state: SlotState,
    /// What the call is for (user call or a lookup the runtime makes).
    purpose: Purpose,
}

/// Why the runtime sent a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    /// The application's call.
    User,
    /// The runtime's `describe` of a peer, to learn its method table.
    Describe,
}

/// A call that ended without an answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Expired {
    pub handle: CallHandle,
    pub peer: Addr,
    pub purpose: Purpose,
    /// The timeout the caller chose.
    pub timeout: Duration,
}

/// The method queue.
#[derive(Debug)]
pub struct MethodQueue {
    slots: Vec<Option<Slot>>,
    /// Per peer, a bit per sequence number in use (waiting or quarantined).
    in_use: Vec<u32>,
    /// Per peer, where the round-robin search for a free sequence number starts.
    next_seq: Vec<u8>,
    next_handle: u64,
    /// Earliest deadline of any slot, so the expiry scan runs only when one is due.
    earliest_ns: u64,
    len: usize,
}

impl Default for MethodQueue {
    fn default() -> Self {
        MethodQueue {
            slots: vec![None; MAX_OUTSTANDING],
            in_use: vec![0; 256],
            next_seq: vec![0; 256],
            next_handle: 1,
            earliest_ns: u64::MAX,
            len: 0,
        }
    }
}

impl MethodQueue {
    /// Enters a call to `peer`; returns its handle and the sequence number to send.
    pub fn begin(
        &mut self,
        peer: Addr,
        now_ns: u64,
        timeout: Duration,
        purpose: Purpose,
    ) -> Result<(CallHandle, Seq), CallError> {
        let p = usize::from(peer.0);
        if self.in_use[p] == u32::MAX {
            return Err(CallError::TooManyOutstanding(peer));
        }
        let free_slot = self
            .slots
            .iter()
            .position(Option::is_none)
            .ok_or(CallError::QueueFull(self.len))?;
        let mut n = self.next_seq[p];
        while self.in_use[p] & (1 << n) != 0 {
            n = (n + 1) & Seq::MAX;
        }
        self.next_seq[p] = (n + 1) & Seq::MAX;
        self.in_use[p] |= 1 << n;
        let seq = Seq::new(n).expect("masked to 5 bits");
        let handle = CallHandle(self.next_handle);
        self.next_handle += 1;
        let deadline_ns = now_ns.saturating_add(timeout.as_nanos() as u64);
        self.slots[free_slot] = Some(Slot {
            handle,
            peer,
            seq,
            deadline_ns,
            timeout,
            state: SlotState::Waiting,
            purpose,
        });
        self.earliest_ns = self.earliest_ns.min(deadline_ns);
        self.len += 1;
        Ok((handle, seq))
    }

    /// Matches an answer from `peer` with sequence `seq` to its call.
    ///
    /// `None` means no call waits for it: a late answer to a call that timed out, or a stray.
    pub fn complete(&mut self, peer: Addr, seq: Seq) -> Option<(CallHandle, Purpose)> {
        let i = self.slots.iter().position(|s| {
            s.is_some_and(|s| s.peer == peer && s.seq == seq && s.state == SlotState::Waiting)
        })?;
        let slot = self.slots[i].take().expect("found above");
        self.release(slot);
        Some((slot.handle, slot.purpose))
    }

    /// Ends a call without an answer (its send failed, say).
    pub fn cancel(&mut self, handle: CallHandle) {
        if let Some(i) = self
            .slots
            .iter()
            .position(|s| s.is_some_and(|s| s.handle == handle))
        {
            let slot = self.slots[i].take().expect("found above");
            self.release(slot);
        }
    }

    fn release(&mut self, slot: Slot) {
        self.in_use[usize::from(slot.peer.0)] &= !(1 << slot.seq.get());
        self.len -= 1;
    }

    /// Moves calls past their deadline to quarantine and reports them through `on_expired`;
    /// frees quarantined sequence numbers whose time is up.
    pub fn expire(&mut self, now_ns: u64, mut on_expired: impl FnMut(Expired)) {
        if now_ns < self.earliest_ns {
            return;
        }
        let mut earliest = u64::MAX;
        for i in 0..self.slots.len() {
            let Some(mut slot) = self.slots[i] else {
                continue;
            };
            match slot.state {
                SlotState::Waiting if now_ns >= slot.deadline_ns => {
                    on_expired(Expired {
                        handle: slot.handle,
                        peer: slot.peer,
                        purpose: slot.purpose,
                        timeout: slot.timeout,
                    });
                    let quarantine = (slot.timeout.as_nanos() as u64).max(1_000_000_000);
                    slot.state = SlotState::Quarantined {
                        until_ns: now_ns + quarantine,
                    };
                    self.slots[i] = Some(slot);
                    earliest = earliest.min(now_ns + quarantine);
                }
                SlotState::Quarantined { until_ns } if now_ns >= until_ns => {
                    self.slots[i] = None;
                    self.release(slot);
                }
                SlotState::Waiting => earliest = earliest.min(slot.deadline_ns),
                SlotState::Quarantined { until_ns } => earliest = earliest.min(until_ns),
            }
        }
        self.earliest_ns = earliest;
    }

    /// Fails every waiting call to `peer` now (it died); reports them through `on_failed`.
    pub fn fail_peer(&mut self, peer: Addr, mut on_failed: impl FnMut(Expired)) {
        for i in 0..self.slots.len() {
            if let Some(slot) = self.slots[i].filter(|s| s.peer == peer) {
                self.slots[i] = None;
                self.release(slot);
                if slot.state == SlotState::Waiting {
                    on_failed(Expired {
                        handle: slot.handle,
                        peer,
                        purpose: slot.purpose,
                        timeout: slot.timeout,
                    });
                }
            }
        }
    }

    /// Calls waiting for an answer.
    pub fn waiting(&self) -> usize {
        self.slots
            .iter()
            .flatten()
            .filter(|s| s.state == SlotState::Waiting)
            .count()
    }

    /// Whether `handle` still waits.
    pub fn is_waiting(&self, handle: CallHandle) -> bool {
        self.slots
            .iter()
            .flatten()
            .any(|s| s.handle == handle && s.state == SlotState::Waiting)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEC: u64 = 1_000_000_000;

    #[test]
    fn answers_are_matched_by_peer_and_sequence() {
        let mut sut = MethodQueue::default();
        let (a, sa) = sut
            .begin(Addr(2), 0, Duration::from_secs(1), Purpose::User)
            .unwrap();
        let (b, sb) = sut
            .begin(Addr(2), 0, Duration::from_secs(1), Purpose::User)
            .unwrap();
        let (c, sc) = sut
            .begin(Addr(3), 0, Duration::from_secs(1), Purpose::User)
            .unwrap();
        assert_ne!(sa, sb);
        assert_eq!(sa, sc, "sequence numbers count per peer");
        assert_eq!(sut.complete(Addr(2), sb), Some((b, Purpose::User)));
        assert_eq!(
            sut.complete(Addr(2), sb),
            None,
            "an answer completes a call once"
        );
        assert_eq!(sut.complete(Addr(3), sc), Some((c, Purpose::User)));
        assert!(sut.is_waiting(a));
    }

    #[test]
    fn thirty_two_calls_can_wait_on_one_peer_and_the_thirty_third_is_refused() {
        let mut sut = MethodQueue::default();
        for _ in 0..32 {
            sut.begin(Addr(2), 0, Duration::from_secs(1), Purpose::User)
                .unwrap();
        }
        assert_eq!(
            sut.begin(Addr(2), 0, Duration::from_secs(1), Purpose::User),
            Err(CallError::TooManyOutstanding(Addr(2)))
        );
        assert!(sut
            .begin(Addr(3), 0, Duration::from_secs(1), Purpose::User)
            .is_ok());
    }

    #[test]
    fn a_timed_out_call_is_reported_and_its_late_answer_is_not_taken_for_a_new_call() {
        let mut sut = MethodQueue::default();
        let (a, seq) = sut
            .begin(Addr(2), 0, Duration::from_secs(1), Purpose::User)
            .unwrap();
        let mut expired = vec![];
        sut.expire(SEC / 2, |e| expired.push(e.handle));
        assert!(expired.is_empty());
        let mut timeouts = vec![];
        sut.expire(SEC, |e| {
            expired.push(e.handle);
            timeouts.push(e.timeout);
        });
        assert_eq!(expired, vec![a]);
        assert_eq!(
            timeouts,
            vec![Duration::from_secs(1)],
            "the expiry reports the caller's timeout"
        );
        for _ in 0..31 {
            let (_, s) = sut
                .begin(Addr(2), SEC, Duration::from_secs(1), Purpose::User)
                .unwrap();
            assert_ne!(s, seq, "a quarantined sequence number is not reused");
        }
        assert_eq!(
            sut.complete(Addr(2), seq),
            None,
            "the late answer matches nothing"
        );
        sut.expire(5 * SEC, |_| {});
        assert_eq!(sut.waiting(), 0);
    }
}
