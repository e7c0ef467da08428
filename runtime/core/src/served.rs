//! The requests a module served lately, per caller, so that a RETRY is answered without
//! executing the method twice.
//!
//! A caller sends a RETRY with the same (peer, sequence) as the EXEC it repeats, and never has
//! two requests with one sequence number outstanding to the same module. So the record keeps,
//! per caller and per sequence number, the method and the answer of the last EXEC served: a
//! RETRY that matches gets that answer again; one that does not (the EXEC never arrived, or it
//! was served by an earlier incarnation of this module) is executed. A new EXEC with the same
//! sequence number replaces the entry.
//!
//! Answers up to [`KEPT_ANSWER`] bytes are kept whole; a larger one is remembered by its size
//! only, and its RETRY gets a NAK "duplicate". The table of a caller is allocated the first time
//! it calls; after that, recording copies at most [`KEPT_ANSWER`] bytes and never allocates.

use modbot_ipc_schema::{Addr, FrameKind, Seq};

/// The largest answer payload kept for replay.
pub const KEPT_ANSWER: usize = 128;

#[derive(Clone, Copy)]
struct Entry {
    method: u8,
    kind: FrameKind,
    /// The answer's payload length; more than [`KEPT_ANSWER`] means it was not kept.
    len: usize,
    payload: [u8; KEPT_ANSWER],
}

type PeerTable = [Option<Entry>; Seq::COUNT];

/// What to answer a RETRY with.
#[derive(Debug, PartialEq, Eq)]
pub enum Replay<'a> {
    /// The kept answer.
    Answer { kind: FrameKind, payload: &'a [u8] },
    /// The answer was served but was too large to keep.
    NotKept { len: usize },
}

/// Per caller, the last request served under each sequence number.
pub struct ServedLog {
    peers: Vec<Option<Box<PeerTable>>>,
}

impl Default for ServedLog {
    fn default() -> Self {
        ServedLog {
            peers: (0..256).map(|_| None).collect(),
        }
    }
}

impl ServedLog {
    /// Records the answer to `peer`'s request `seq` for `method`.
    pub fn record(&mut self, peer: Addr, seq: Seq, method: u8, kind: FrameKind, payload: &[u8]) {
        let table = self.peers[usize::from(peer.0)].get_or_insert_with(|| Box::new([None; 32]));
        let mut entry = Entry {
            method,
            kind,
            len: payload.len(),
            payload: [0; KEPT_ANSWER],
        };
        if let Some(room) = entry.payload.get_mut(..payload.len()) {
            room.copy_from_slice(payload);
        }
        table[usize::from(seq.get())] = Some(entry);
    }

    /// The answer to give `peer`'s RETRY of request `seq` for `method`, if it was served.
    pub fn replay(&self, peer: Addr, seq: Seq, method: u8) -> Option<Replay<'_>> {
        let table = self.peers[usize::from(peer.0)].as_ref()?;
        let entry = table[usize::from(seq.get())]
            .as_ref()
            .filter(|e| e.method == method)?;
        Some(match entry.payload.get(..entry.len) {
            Some(payload) => Replay::Answer {
                kind: entry.kind,
                payload,
            },
            None => Replay::NotKept { len: entry.len },
        })
    }

    /// Forgets what was served to `peer` (it restarted: its sequence numbers start over).
    pub fn forget(&mut self, peer: Addr) {
        self.peers[usize::from(peer.0)] = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seq(n: u8) -> Seq {
        Seq::new(n).unwrap()
    }

    /// What a retry is answered with when a REPLY carrying `payload` was kept.
    fn replied(payload: &[u8]) -> Option<Replay<'_>> {
        Some(Replay::Answer {
            kind: FrameKind::Reply,
            payload,
        })
    }

    #[test]
    fn a_retry_of_a_served_request_gets_the_same_answer() {
        let mut sut = ServedLog::default();
        sut.record(Addr(3), seq(5), 2, FrameKind::Reply, b"\x2a");
        assert_eq!(sut.replay(Addr(3), seq(5), 2), replied(b"\x2a"));
    }

    #[test]
    fn a_retry_of_an_unseen_request_or_of_another_method_is_not_replayed() {
        let mut sut = ServedLog::default();
        sut.record(Addr(3), seq(5), 2, FrameKind::Ack, &[]);
        assert_eq!(sut.replay(Addr(3), seq(6), 2), None);
        assert_eq!(sut.replay(Addr(4), seq(5), 2), None);
        assert_eq!(sut.replay(Addr(3), seq(5), 1), None);
        sut.forget(Addr(3));
        assert_eq!(sut.replay(Addr(3), seq(5), 2), None);
    }

    #[test]
    fn a_new_request_with_a_reused_sequence_number_replaces_the_old_answer() {
        let mut sut = ServedLog::default();
        sut.record(Addr(3), seq(5), 2, FrameKind::Reply, b"old");
        sut.record(Addr(3), seq(5), 2, FrameKind::Reply, b"new");
        assert_eq!(sut.replay(Addr(3), seq(5), 2), replied(b"new"));
    }

    #[test]
    fn a_large_answer_is_remembered_by_its_size_only() {
        let mut sut = ServedLog::default();
        sut.record(Addr(3), seq(1), 0, FrameKind::Reply, &[7; KEPT_ANSWER + 1]);
        assert_eq!(
            sut.replay(Addr(3), seq(1), 0),
            Some(Replay::NotKept {
                len: KEPT_ANSWER + 1
            })
        );
    }
}
