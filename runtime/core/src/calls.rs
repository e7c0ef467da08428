//! The method queue: calls to other modules that wait for an answer.
//!
//! A call takes a sequence number that is free for its peer, and waits in the queue until the
//! peer's REPLY, ACK or NAK with that (peer, sequence) arrives, or its deadline passes. Many
//! calls can be outstanding at once (up to 32 per peer). A sequence number whose call timed
//! out stays reserved for one more timeout (at least a second), so a late answer cannot be taken
//! for the answer to a newer call.
//!
//! An unanswered call is retransmitted per its [`RetryPolicy`]: the timeout is split into
//! `retries + 1` equal intervals, and at the end of each but the last the queue hands the call
//! back to be sent again as a RETRY frame (same peer, same sequence number, same payload; the
//! receiver answers a RETRY of a request it already served from its record, without executing
//! twice). A call whose peer died and came back is sent again at once, if its caller chose to
//! wait for the peer. When the deadline passes the call fails with a timeout that says how
//! many times it was sent: nothing is silently lost.
//!
//! The table is allocated once; payloads kept for retransmission live in per-slot buffers that
//! are reused, so the hot path does not allocate once a buffer has grown to the payload size.
//! Finding a call costs the same whatever the number outstanding: a handle names its slot, an
//! answer finds its call through a (peer, sequence) index, and free slots wait on a stack.

use core::time::Duration;

use modbot_ipc_schema::{Addr, Args, OwnedValue, Seq, Value};

use crate::error::CallError;

/// The most calls one module has outstanding at once (a slot index fits a byte, and one
/// value of it means "none").
pub const MAX_OUTSTANDING: usize = 255;

/// Payload bytes a slot keeps without growing its buffer.
const KEPT_PAYLOAD: usize = 256;

/// How often an unanswered request is sent again before its deadline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RetryPolicy {
    /// Retransmissions after the first send, spread evenly over the timeout.
    pub retries: u8,
}

impl Default for RetryPolicy {
    fn default() -> Self {
        RetryPolicy { retries: 2 }
    }
}

impl RetryPolicy {
    /// Never retransmit: the payload is not kept, which saves a copy of large arguments.
    pub const NONE: RetryPolicy = RetryPolicy { retries: 0 };
}

/// Options of one call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CallOptions {
    /// How long to wait for the answer, all attempts included, from the request's first send
    /// (or from the call, for one that waits to be sent).
    pub timeout: Duration,
    /// While the peer is down or its inbox is full, keep trying until the deadline instead of
    /// failing at once; a call sent to a peer that then dies is sent again when it comes back.
    pub wait_for_peer: bool,
    /// Retransmission of a request whose answer is overdue.
    pub retry: RetryPolicy,
    /// How long a module in blocking mode looks for the answer of a blocking call
    /// ([`Module::call_blocking`](crate::module::Module::call_blocking)) before it sleeps:
    /// an answer that comes within it is taken without a wake-up, which costs tens of µs where
    /// idle cores halt (virtual machines); the caller's core is busy meanwhile. Zero sleeps at
    /// once. After a look that missed (the callee may share this core, or the machine is
    /// loaded), the module's next 16 blocking calls sleep at once; a thread under SCHED_FIFO or
    /// SCHED_RR never looks. A busy-mode module always looks without sleeping.
    pub spin: Duration,
}

/// [`CallOptions::spin`] by default: about one wake-up of a halted core on the machines
/// modbot is measured on, so that a quick method's answer does not wait for a second one.
pub const DEFAULT_CALL_SPIN: Duration = Duration::from_micros(50);

impl Default for CallOptions {
    fn default() -> Self {
        CallOptions {
            timeout: Duration::from_secs(2),
            wait_for_peer: false,
            retry: RetryPolicy::default(),
            spin: DEFAULT_CALL_SPIN,
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

    /// The same options, waiting for a peer that is down (see [`CallOptions::wait_for_peer`]).
    pub fn waiting_for_peer(mut self) -> CallOptions {
        self.wait_for_peer = true;
        self
    }

    /// The same options, looking for the answer `spin` long before sleeping (see
    /// [`CallOptions::spin`]).
    pub fn with_spin(mut self, spin: Duration) -> CallOptions {
        self.spin = spin;
        self
    }

    /// The same options with another retry policy.
    pub fn with_retry(mut self, retry: RetryPolicy) -> CallOptions {
        self.retry = retry;
        self
    }

    /// Whether the payload must be kept after the first send.
    pub fn keeps_payload(&self) -> bool {
        self.retry.retries > 0 || self.wait_for_peer
    }
}

/// A call waiting in the method queue.
///
/// Its low byte is the slot the call occupies, the rest counts calls: a handle is never
/// reused, and it finds its slot without a search.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CallHandle(u64);

impl CallHandle {
    pub fn id(self) -> u64 {
        self.0
    }

    fn slot(self) -> usize {
        (self.0 & 0xff) as usize
    }
}

/// No slot, in the (peer, sequence) index.
const NO_SLOT: u8 = u8::MAX;

/// The deadline of a call whose timeout has not started ([`MethodQueue::start`]).
const NOT_STARTED: u64 = u64::MAX;

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
    /// The method id, once the request was sent.
    method: Option<u8>,
    /// Time between two sends; 0 when the call is never retransmitted.
    retry_every_ns: u64,
    /// When the next retransmission is due.
    next_retry_ns: u64,
    /// Retransmissions left.
    retries_left: u8,
    /// How many times the request was sent.
    sends: u8,
    /// The caller waits for a peer that is down, and across its restart.
    wait_for_peer: bool,
    /// Whether the payload was kept for retransmission.
    kept: bool,
    /// When the request was first sent, for the call's latency.
    first_sent_ns: Option<u64>,
}

impl Slot {
    /// Starts the timeout at `now_ns` unless it has started; the deadline when it starts now.
    fn start(&mut self, now_ns: u64) -> Option<u64> {
        (self.deadline_ns == NOT_STARTED).then(|| {
            self.deadline_ns = now_ns.saturating_add(self.timeout.as_nanos() as u64);
            self.deadline_ns
        })
    }

    fn expired(&self) -> Expired {
        Expired {
            handle: self.handle,
            peer: self.peer,
            purpose: self.purpose,
            timeout: self.timeout,
            sends: self.sends,
        }
    }
}

/// How long a sequence number stays unused after a call that may still be answered (it timed
/// out, or it was sent more than once): the call's timeout, at least a second.
fn quarantine_ns(timeout: Duration) -> u64 {
    (timeout.as_nanos() as u64).max(1_000_000_000)
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
    /// How many times the request was sent.
    pub sends: u8,
}

/// A call that got its answer, as [`MethodQueue::answer`] hands it back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Answered {
    pub handle: CallHandle,
    pub purpose: Purpose,
    /// When the request was first sent (`None` if the answer came to a call never sent, which
    /// a well-behaved peer cannot cause).
    pub first_sent_ns: Option<u64>,
}

/// A request to send again, lent by [`MethodQueue::expire`] and [`MethodQueue::resend_to`].
#[derive(Debug)]
pub struct Resend<'a> {
    pub peer: Addr,
    pub seq: Seq,
    pub method: u8,
    pub payload: &'a [u8],
}

/// The method queue.
#[derive(Debug)]
pub struct MethodQueue {
    slots: Vec<Option<Slot>>,
    /// Per slot, the payload kept for retransmission.
    payloads: Vec<Vec<u8>>,
    /// Per peer, a bit per sequence number in use (waiting or quarantined).
    in_use: Vec<u32>,
    /// Per peer, where the round-robin search for a free sequence number starts.
    next_seq: Vec<u8>,
    /// Per peer and sequence number, the slot of the call that holds it ([`NO_SLOT`] if none).
    by_seq: Vec<[u8; 32]>,
    /// Slots free, taken from the end.
    free: Vec<u8>,
    /// Counts calls, for their handles.
    next_handle: u64,
    /// Earliest deadline of any slot, so the expiry scan runs only when one is due.
    earliest_ns: u64,
}

impl Default for MethodQueue {
    fn default() -> Self {
        MethodQueue {
            slots: vec![None; MAX_OUTSTANDING],
            payloads: (0..MAX_OUTSTANDING)
                .map(|_| Vec::with_capacity(KEPT_PAYLOAD))
                .collect(),
            in_use: vec![0; 256],
            next_seq: vec![0; 256],
            by_seq: vec![[NO_SLOT; 32]; 256],
            free: (0..MAX_OUTSTANDING as u8).rev().collect(),
            next_handle: 1,
            earliest_ns: u64::MAX,
        }
    }
}

impl MethodQueue {
    /// Enters a call to `peer`; returns its handle and the sequence number to send.
    ///
    /// Its timeout starts when it is first sent ([`MethodQueue::sent`]) or, for a call that
    /// waits to be sent, when it starts waiting ([`MethodQueue::start`]): the caller reads the
    /// clock after the request left, not on the way to sending it.
    pub fn begin(
        &mut self,
        peer: Addr,
        opts: CallOptions,
        purpose: Purpose,
    ) -> Result<(CallHandle, Seq), CallError> {
        let timeout = opts.timeout;
        let p = usize::from(peer.0);
        if self.in_use[p] == u32::MAX {
            return Err(CallError::TooManyOutstanding(peer));
        }
        let free_slot = usize::from(
            *self
                .free
                .last()
                .ok_or(CallError::QueueFull(MAX_OUTSTANDING))?,
        );
        let mut n = self.next_seq[p];
        while self.in_use[p] & (1 << n) != 0 {
            n = (n + 1) & Seq::MAX;
        }
        self.next_seq[p] = (n + 1) & Seq::MAX;
        self.in_use[p] |= 1 << n;
        let seq = Seq::new(n).expect("masked to 5 bits");
        self.free.pop();
        self.by_seq[p][usize::from(n)] = free_slot as u8;
        let handle = CallHandle((self.next_handle << 8) | free_slot as u64);
        self.next_handle += 1;
        let timeout_ns = timeout.as_nanos() as u64;
        let retry_every_ns = if opts.retry.retries > 0 {
            timeout_ns / (u64::from(opts.retry.retries) + 1)
        } else {
            0
        };
        self.slots[free_slot] = Some(Slot {
            handle,
            peer,
            seq,
            deadline_ns: NOT_STARTED,
            timeout,
            state: SlotState::Waiting,
            purpose,
            method: None,
            retry_every_ns,
            next_retry_ns: u64::MAX,
            retries_left: opts.retry.retries,
            sends: 0,
            wait_for_peer: opts.wait_for_peer,
            kept: false,
            first_sent_ns: None,
        });
        self.payloads[free_slot].clear();
        Ok((handle, seq))
    }

    /// Starts `handle`'s timeout at `now_ns`, unless it has started already.
    pub fn start(&mut self, handle: CallHandle, now_ns: u64) {
        if let Some(slot) = self.index(handle).and_then(|i| self.slots[i].as_mut()) {
            if let Some(deadline) = slot.start(now_ns) {
                self.earliest_ns = self.earliest_ns.min(deadline);
            }
        }
    }

    fn index(&self, handle: CallHandle) -> Option<usize> {
        let i = handle.slot();
        self.slots
            .get(i)?
            .is_some_and(|s| s.handle == handle)
            .then_some(i)
    }

    /// The buffer to keep `handle`'s payload in for retransmission (cleared, capacity kept).
    pub fn payload_buffer(&mut self, handle: CallHandle) -> Option<&mut Vec<u8>> {
        let i = self.index(handle)?;
        self.payloads[i].clear();
        Some(&mut self.payloads[i])
    }

    /// Records that `handle`'s request for `method` was sent now (which starts its timeout if
    /// it has not started); `kept` says whether its payload is in
    /// [`MethodQueue::payload_buffer`].
    pub fn sent(&mut self, handle: CallHandle, method: u8, now_ns: u64, kept: bool) {
        let Some(slot) = self.index(handle).and_then(|i| self.slots[i].as_mut()) else {
            return;
        };
        if let Some(deadline) = slot.start(now_ns) {
            self.earliest_ns = self.earliest_ns.min(deadline);
        }
        slot.method = Some(method);
        slot.sends = slot.sends.saturating_add(1);
        slot.first_sent_ns.get_or_insert(now_ns);
        slot.kept = kept;
        if kept && slot.retry_every_ns > 0 && slot.retries_left > 0 {
            slot.next_retry_ns = now_ns.saturating_add(slot.retry_every_ns);
            self.earliest_ns = self.earliest_ns.min(slot.next_retry_ns);
        }
    }

    /// Matches an answer from `peer` with sequence `seq` to its call.
    ///
    /// `None` means no call waits for it: a late answer to a call that timed out, or a stray.
    pub fn complete(&mut self, peer: Addr, seq: Seq, now_ns: u64) -> Option<(CallHandle, Purpose)> {
        self.answer(peer, seq, now_ns)
            .map(|a| (a.handle, a.purpose))
    }

    /// Like [`MethodQueue::complete`], with when the request was first sent.
    ///
    /// A request sent more than once may be answered more than once (a callee held up
    /// answers its retransmissions too): its sequence number stays in quarantine as a timed-out
    /// call's does, so that a late second answer is not taken for a newer call that reused it.
    pub fn answer(&mut self, peer: Addr, seq: Seq, now_ns: u64) -> Option<Answered> {
        let i = usize::from(self.by_seq[usize::from(peer.0)][usize::from(seq.get())]);
        // Read and changed in place: a slot is ~90 bytes, not moved out and back per answer.
        let slot = self
            .slots
            .get_mut(i)?
            .as_mut()
            .filter(|s| s.peer == peer && s.seq == seq && s.state == SlotState::Waiting)?;
        let answered = Answered {
            handle: slot.handle,
            purpose: slot.purpose,
            first_sent_ns: slot.first_sent_ns,
        };
        if slot.sends > 1 {
            let until_ns = now_ns + quarantine_ns(slot.timeout);
            slot.state = SlotState::Quarantined { until_ns };
            self.earliest_ns = self.earliest_ns.min(until_ns);
        } else {
            self.slots[i] = None;
            self.free_number(peer, seq);
            self.free.push(i as u8);
        }
        Some(answered)
    }

    /// Ends a call without an answer (its send failed, say).
    pub fn cancel(&mut self, handle: CallHandle) {
        if let Some(i) = self.index(handle) {
            let slot = self.slots[i].take().expect("found above");
            self.release(i, slot);
        }
    }

    /// Frees slot `i`, which held `slot` (already taken out of the table).
    fn release(&mut self, i: usize, slot: Slot) {
        self.free_number(slot.peer, slot.seq);
        self.free.push(i as u8);
    }

    /// Frees sequence number `seq` of `peer`.
    fn free_number(&mut self, peer: Addr, seq: Seq) {
        let p = usize::from(peer.0);
        self.in_use[p] &= !(1 << seq.get());
        self.by_seq[p][usize::from(seq.get())] = NO_SLOT;
    }

    /// Moves calls past their deadline to quarantine and reports them through `on_expired`;
    /// lends calls due for retransmission to `on_resend`; frees quarantined sequence numbers
    /// whose time is up.
    pub fn expire(
        &mut self,
        now_ns: u64,
        mut on_expired: impl FnMut(Expired),
        mut on_resend: impl FnMut(Resend<'_>),
    ) {
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
                    on_expired(slot.expired());
                    let quarantine = quarantine_ns(slot.timeout);
                    slot.state = SlotState::Quarantined {
                        until_ns: now_ns + quarantine,
                    };
                    self.slots[i] = Some(slot);
                    earliest = earliest.min(now_ns + quarantine);
                }
                SlotState::Waiting => {
                    if now_ns >= slot.next_retry_ns {
                        if let Some(method) = slot.method {
                            on_resend(Resend {
                                peer: slot.peer,
                                seq: slot.seq,
                                method,
                                payload: &self.payloads[i],
                            });
                        }
                        slot.sends = slot.sends.saturating_add(1);
                        slot.retries_left -= 1;
                        slot.next_retry_ns = if slot.retries_left > 0 {
                            now_ns + slot.retry_every_ns
                        } else {
                            u64::MAX
                        };
                        self.slots[i] = Some(slot);
                    }
                    earliest = earliest.min(slot.deadline_ns).min(slot.next_retry_ns);
                }
                SlotState::Quarantined { until_ns } if now_ns >= until_ns => {
                    self.slots[i] = None;
                    self.release(i, slot);
                }
                SlotState::Quarantined { until_ns } => earliest = earliest.min(until_ns),
            }
        }
        self.earliest_ns = earliest;
    }

    /// Sends again, through `on_resend`, every sent call to `peer` that waits for it across a
    /// restart (the peer came back: what it had received died with it).
    pub fn resend_to(&mut self, peer: Addr, mut on_resend: impl FnMut(Resend<'_>)) {
        for i in 0..self.slots.len() {
            let Some(slot) = self.slots[i].as_mut() else {
                continue;
            };
            if slot.peer != peer
                || slot.state != SlotState::Waiting
                || !slot.wait_for_peer
                || !slot.kept
            {
                continue;
            }
            if let Some(method) = slot.method {
                slot.sends = slot.sends.saturating_add(1);
                on_resend(Resend {
                    peer,
                    seq: slot.seq,
                    method,
                    payload: &self.payloads[i],
                });
            }
        }
    }

    /// Fails every waiting call to `peer` now (it died) and reports them through `on_failed`,
    /// except calls whose caller waits for the peer to come back: they keep their deadline.
    pub fn fail_peer(&mut self, peer: Addr, mut on_failed: impl FnMut(Expired)) {
        for i in 0..self.slots.len() {
            let Some(slot) = self.slots[i].filter(|s| s.peer == peer) else {
                continue;
            };
            match slot.state {
                SlotState::Waiting if slot.wait_for_peer => {}
                SlotState::Waiting => {
                    self.slots[i] = None;
                    self.release(i, slot);
                    on_failed(slot.expired());
                }
                SlotState::Quarantined { .. } => {
                    self.slots[i] = None;
                    self.release(i, slot);
                }
            }
        }
    }

    /// Calls waiting for an answer.
    /// When [`MethodQueue::expire`] has work next (a deadline or a retransmission), `u64::MAX`
    /// if never.
    pub fn next_due_ns(&self) -> u64 {
        self.earliest_ns
    }

    pub fn waiting(&self) -> usize {
        self.slots
            .iter()
            .flatten()
            .filter(|s| s.state == SlotState::Waiting)
            .count()
    }

    /// Whether `handle` still waits.
    pub fn is_waiting(&self, handle: CallHandle) -> bool {
        self.index(handle)
            .and_then(|i| self.slots[i])
            .is_some_and(|s| s.state == SlotState::Waiting)
    }
}

/// An answer as owned values (or its error), for the `call_owned` of modules and tools.
pub fn owned_answer(answer: Result<&Args<'_>, &CallError>) -> Result<Vec<OwnedValue>, CallError> {
    match answer {
        Ok(a) => Ok(a.as_slice().iter().map(Value::to_owned_value).collect()),
        Err(e) => Err(e.clone()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEC: u64 = 1_000_000_000;

    /// Enters a call whose timeout starts at `now` (as when it is sent or parked then).
    fn begin_at(
        sut: &mut MethodQueue,
        peer: Addr,
        now: u64,
        opts: CallOptions,
        purpose: Purpose,
    ) -> Result<(CallHandle, Seq), CallError> {
        let (handle, seq) = sut.begin(peer, opts, purpose)?;
        sut.start(handle, now);
        Ok((handle, seq))
    }

    /// One second, never retransmitted.
    fn one_second() -> CallOptions {
        CallOptions::timeout(Duration::from_secs(1)).with_retry(RetryPolicy::NONE)
    }

    #[test]
    fn answers_are_matched_by_peer_and_sequence() {
        let mut sut = MethodQueue::default();
        let (a, sa) = begin_at(&mut sut, Addr(2), 0, one_second(), Purpose::User).unwrap();
        let (b, sb) = begin_at(&mut sut, Addr(2), 0, one_second(), Purpose::User).unwrap();
        let (c, sc) = begin_at(&mut sut, Addr(3), 0, one_second(), Purpose::User).unwrap();
        assert_ne!(sa, sb);
        assert_eq!(sa, sc, "sequence numbers count per peer");
        assert_eq!(sut.complete(Addr(2), sb, 0), Some((b, Purpose::User)));
        assert_eq!(
            sut.complete(Addr(2), sb, 0),
            None,
            "an answer completes a call once"
        );
        assert_eq!(sut.complete(Addr(3), sc, 0), Some((c, Purpose::User)));
        assert!(sut.is_waiting(a));
    }

    #[test]
    fn thirty_two_calls_can_wait_on_one_peer_and_the_thirty_third_is_refused() {
        let mut sut = MethodQueue::default();
        for _ in 0..32 {
            begin_at(&mut sut, Addr(2), 0, one_second(), Purpose::User).unwrap();
        }
        assert_eq!(
            begin_at(&mut sut, Addr(2), 0, one_second(), Purpose::User),
            Err(CallError::TooManyOutstanding(Addr(2)))
        );
        assert!(begin_at(&mut sut, Addr(3), 0, one_second(), Purpose::User).is_ok());
    }

    #[test]
    fn a_second_answer_to_a_retransmitted_call_is_not_taken_for_a_newer_call() {
        let mut sut = MethodQueue::default();
        let opts = one_second().with_retry(RetryPolicy { retries: 3 });
        let (a, seq) = begin_at(&mut sut, Addr(2), 0, opts, Purpose::User).unwrap();
        sut.sent(a, 1, 0, true);
        let mut resent = 0;
        sut.expire(SEC / 2, |_| {}, |_| resent += 1);
        assert_eq!(resent, 1, "the request went out twice");
        assert_eq!(
            sut.complete(Addr(2), seq, SEC / 2),
            Some((a, Purpose::User))
        );
        assert!(!sut.is_waiting(a), "the call is answered");
        // Every other number in use, then one freed: the next call takes that one, not the
        // number of the call sent twice (which it would take next in turn).
        let others: Vec<Seq> = (0..31)
            .map(|_| {
                begin_at(&mut sut, Addr(2), SEC, one_second(), Purpose::User)
                    .unwrap()
                    .1
            })
            .collect();
        assert!(!others.contains(&seq));
        assert!(sut.complete(Addr(2), others[4], SEC).is_some());
        let (_, next) = begin_at(&mut sut, Addr(2), SEC, one_second(), Purpose::User).unwrap();
        assert_eq!(
            next, others[4],
            "the number of a call sent twice is not reused at once"
        );
        assert_eq!(
            sut.complete(Addr(2), seq, SEC),
            None,
            "the answer to the retransmission matches nothing"
        );
        sut.expire(5 * SEC, |_| {}, |_| {});
        assert_eq!(sut.waiting(), 0, "the quarantine ends");
    }

    #[test]
    fn an_answer_to_a_call_sent_once_frees_its_number_at_once() {
        let mut sut = MethodQueue::default();
        let (a, seq) = begin_at(&mut sut, Addr(2), 0, one_second(), Purpose::User).unwrap();
        sut.sent(a, 1, 0, false);
        assert_eq!(sut.complete(Addr(2), seq, 1), Some((a, Purpose::User)));
        assert_eq!(sut.waiting(), 0);
    }

    #[test]
    fn a_timed_out_call_is_reported_and_its_late_answer_is_not_taken_for_a_new_call() {
        let mut sut = MethodQueue::default();
        let (a, seq) = begin_at(&mut sut, Addr(2), 0, one_second(), Purpose::User).unwrap();
        let mut expired = vec![];
        sut.expire(SEC / 2, |e| expired.push(e.handle), |_| {});
        assert!(expired.is_empty());
        let mut timeouts = vec![];
        sut.expire(
            SEC,
            |e| {
                expired.push(e.handle);
                timeouts.push(e.timeout);
            },
            |_| {},
        );
        assert_eq!(expired, vec![a]);
        assert_eq!(
            timeouts,
            vec![Duration::from_secs(1)],
            "the expiry reports the caller's timeout"
        );
        for _ in 0..31 {
            let (_, s) = begin_at(&mut sut, Addr(2), SEC, one_second(), Purpose::User).unwrap();
            assert_ne!(s, seq, "a quarantined sequence number is not reused");
        }
        assert_eq!(
            sut.complete(Addr(2), seq, 0),
            None,
            "the late answer matches nothing"
        );
        sut.expire(5 * SEC, |_| {}, |_| {});
        assert_eq!(sut.waiting(), 0);
    }

    #[test]
    fn an_unanswered_call_is_sent_again_per_its_policy_and_then_fails_saying_how_often() {
        let mut sut = MethodQueue::default();
        let opts =
            CallOptions::timeout(Duration::from_secs(3)).with_retry(RetryPolicy { retries: 2 });
        let (handle, seq) = begin_at(&mut sut, Addr(4), 0, opts, Purpose::User).unwrap();
        sut.payload_buffer(handle)
            .unwrap()
            .extend_from_slice(b"args");
        sut.sent(handle, 9, 0, true);
        let mut resent = vec![];
        let mut expired = vec![];
        for t in [SEC / 2, SEC, 3 * SEC / 2, 2 * SEC, 5 * SEC / 2, 3 * SEC] {
            sut.expire(
                t,
                |e| expired.push((t, e.sends)),
                |r| resent.push((t, r.peer, r.seq, r.method, r.payload.to_vec())),
            );
        }
        assert_eq!(
            resent,
            vec![
                (SEC, Addr(4), seq, 9, b"args".to_vec()),
                (2 * SEC, Addr(4), seq, 9, b"args".to_vec())
            ],
            "sent again at each third of the timeout, same sequence and payload"
        );
        assert_eq!(
            expired,
            vec![(3 * SEC, 3)],
            "fails at the deadline after 3 sends"
        );
    }

    #[test]
    fn a_call_that_waits_for_its_peer_survives_the_peers_death_and_is_sent_again_when_it_returns() {
        let mut sut = MethodQueue::default();
        let waits = CallOptions::timeout(Duration::from_secs(5)).waiting_for_peer();
        let (patient, seq) = begin_at(&mut sut, Addr(4), 0, waits, Purpose::User).unwrap();
        sut.payload_buffer(patient).unwrap().push(7);
        sut.sent(patient, 1, 0, true);
        let (hasty, _) = begin_at(&mut sut, Addr(4), 0, one_second(), Purpose::User).unwrap();
        sut.sent(hasty, 1, 0, false);
        let mut failed = vec![];
        sut.fail_peer(Addr(4), |e| failed.push(e.handle));
        assert_eq!(
            failed,
            vec![hasty],
            "only the call that does not wait fails"
        );
        assert!(sut.is_waiting(patient));
        let mut resent = vec![];
        sut.resend_to(Addr(4), |r| resent.push((r.seq, r.payload.to_vec())));
        assert_eq!(resent, vec![(seq, vec![7])]);
        assert_eq!(
            sut.complete(Addr(4), seq, 0),
            Some((patient, Purpose::User))
        );
    }

    #[test]
    fn an_answer_tells_when_its_request_was_first_sent_even_after_retransmissions() {
        let mut sut = MethodQueue::default();
        let opts =
            CallOptions::timeout(Duration::from_secs(3)).with_retry(RetryPolicy { retries: 2 });
        let (handle, seq) = begin_at(&mut sut, Addr(4), 5, opts, Purpose::User).unwrap();
        sut.sent(handle, 1, 7, true);
        sut.expire(SEC + 7, |_| {}, |_| {});
        sut.sent(handle, 1, SEC + 8, true); // sent again from a pending queue, say
        assert_eq!(
            sut.answer(Addr(4), seq, 2 * SEC),
            Some(Answered {
                handle,
                purpose: Purpose::User,
                first_sent_ns: Some(7)
            })
        );
        let (never_sent, seq) = begin_at(&mut sut, Addr(4), 5, opts, Purpose::User).unwrap();
        assert_eq!(
            sut.answer(Addr(4), seq, 2 * SEC)
                .map(|a| (a.handle, a.first_sent_ns)),
            Some((never_sent, None))
        );
    }

    #[test]
    fn a_full_queue_refuses_a_call_and_a_freed_slot_takes_the_next_without_reviving_old_handles() {
        let mut sut = MethodQueue::default();
        let mut calls = vec![];
        for i in 0..MAX_OUTSTANDING {
            let peer = Addr(1 + (i / 32) as u8);
            calls.push((
                peer,
                begin_at(&mut sut, peer, 0, one_second(), Purpose::User).unwrap(),
            ));
        }
        assert_eq!(
            begin_at(&mut sut, Addr(100), 0, one_second(), Purpose::User),
            Err(CallError::QueueFull(MAX_OUTSTANDING))
        );
        let (peer, (old, seq)) = calls[200];
        assert_eq!(sut.complete(peer, seq, 0), Some((old, Purpose::User)));
        let (new, _) = begin_at(&mut sut, Addr(100), 0, one_second(), Purpose::User).unwrap();
        assert_ne!(new, old);
        assert!(sut.is_waiting(new));
        assert!(
            !sut.is_waiting(old),
            "a handle names one call, never a later one"
        );
        assert_eq!(sut.payload_buffer(old).map(|b| b.len()), None);
        for &(peer, (h, seq)) in calls.iter().filter(|c| c.1 .0 != old) {
            assert_eq!(sut.complete(peer, seq, 0), Some((h, Purpose::User)));
        }
        assert_eq!(sut.waiting(), 1);
    }

    #[test]
    fn a_calls_timeout_starts_when_it_is_first_sent_not_when_it_is_entered() {
        let mut sut = MethodQueue::default();
        let (handle, _) = sut.begin(Addr(4), one_second(), Purpose::User).unwrap();
        let mut expired = vec![];
        sut.expire(10 * SEC, |e| expired.push(e.handle), |_| {});
        assert!(
            expired.is_empty(),
            "not sent yet: its timeout has not started"
        );
        sut.sent(handle, 1, 10 * SEC, false);
        sut.sent(handle, 1, 10 * SEC + SEC / 2, false); // sent again: the timeout runs on
        sut.expire(10 * SEC + SEC / 2, |e| expired.push(e.handle), |_| {});
        assert!(expired.is_empty());
        assert_eq!(
            sut.next_due_ns(),
            11 * SEC,
            "due one timeout after the first send"
        );
        sut.expire(11 * SEC, |e| expired.push(e.handle), |_| {});
        assert_eq!(expired, vec![handle]);
    }

    #[test]
    fn a_call_without_retries_keeps_no_payload_and_is_never_resent() {
        let mut sut = MethodQueue::default();
        let (handle, _) = begin_at(&mut sut, Addr(4), 0, one_second(), Purpose::User).unwrap();
        sut.sent(handle, 1, 0, false);
        let mut resent = 0;
        for t in 1..=10 {
            sut.expire(t * SEC / 10, |_| {}, |_| resent += 1);
        }
        assert_eq!(resent, 0);
    }
}
