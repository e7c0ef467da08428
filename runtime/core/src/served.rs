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

    /// The record as bytes, for the process that takes this module over: per entry, caller,
    /// sequence number, method, kind (0 ACK, 1 REPLY, 2 NAK), NAK code, answer length (u32 LE),
    /// then the kept answer.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for (peer, table) in self.peers.iter().enumerate() {
            let Some(table) = table else { continue };
            for (seq, entry) in table.iter().enumerate() {
                let Some(e) = entry else { continue };
                let (kind, code) = match e.kind {
                    FrameKind::Ack => (0, 0),
                    FrameKind::Nak { code } => (2, code.0),
                    _ => (1, 0),
                };
                out.extend_from_slice(&[peer as u8, seq as u8, e.method, kind, code]);
                out.extend_from_slice(&(e.len as u32).to_le_bytes());
                out.extend_from_slice(&e.payload[..e.len.min(KEPT_ANSWER)]);
            }
        }
        out
    }

    /// Reads a record [`ServedLog::encode`] wrote.
    pub fn decode(mut bytes: &[u8]) -> Result<ServedLog, ServedLogError> {
        let mut log = ServedLog::default();
        while !bytes.is_empty() {
            let at = bytes.len();
            let Some((head, rest)) = bytes.split_first_chunk::<9>() else {
                return Err(ServedLogError::Truncated { left: at });
            };
            let [peer, seq, method, kind, code, l0, l1, l2, l3] = *head;
            let len = u32::from_le_bytes([l0, l1, l2, l3]) as usize;
            let kept = len.min(KEPT_ANSWER);
            let Some(seq) = Seq::new(seq) else {
                return Err(ServedLogError::Sequence(seq));
            };
            let kind = match kind {
                0 => FrameKind::Ack,
                1 => FrameKind::Reply,
                2 => FrameKind::Nak {
                    code: modbot_ipc_schema::NakCode(code),
                },
                k => return Err(ServedLogError::Kind(k)),
            };
            if rest.len() < kept {
                return Err(ServedLogError::Truncated { left: at });
            }
            log.record(Addr(peer), seq, method, kind, &rest[..kept]);
            if len > KEPT_ANSWER {
                // Remembered by its size only, as when it was served.
                let table = log.peers[usize::from(peer)].as_mut().expect("recorded");
                if let Some(e) = table[usize::from(seq.get())].as_mut() {
                    e.len = len;
                }
            }
            bytes = &rest[kept..];
        }
        Ok(log)
    }
}

/// Why bytes are not a record of served requests.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ServedLogError {
    #[error("the record of served requests ends inside an entry ({left} bytes left)")]
    Truncated { left: usize },
    #[error("the record of served requests has sequence number {0} (0..=31)")]
    Sequence(u8),
    #[error("the record of served requests has answer kind {0} (0 ACK, 1 REPLY, 2 NAK)")]
    Kind(u8),
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
    fn a_record_read_back_from_its_bytes_replays_the_same_answers() {
        let mut sut = ServedLog::default();
        sut.record(Addr(3), seq(5), 2, FrameKind::Reply, b"\x2a");
        sut.record(Addr(9), seq(31), 0, FrameKind::Ack, &[]);
        let nak = FrameKind::Nak {
            code: modbot_ipc_schema::NakCode(4),
        };
        sut.record(Addr(9), seq(0), 1, nak, b"busy");
        sut.record(
            Addr(200),
            seq(1),
            0,
            FrameKind::Reply,
            &[7; KEPT_ANSWER + 5],
        );
        let bytes = sut.encode();
        let back = ServedLog::decode(&bytes).unwrap();
        assert_eq!(back.replay(Addr(3), seq(5), 2), replied(b"\x2a"));
        assert_eq!(
            back.replay(Addr(9), seq(31), 0),
            Some(Replay::Answer {
                kind: FrameKind::Ack,
                payload: &[]
            })
        );
        assert_eq!(
            back.replay(Addr(9), seq(0), 1),
            Some(Replay::Answer {
                kind: nak,
                payload: b"busy"
            })
        );
        assert_eq!(
            back.replay(Addr(200), seq(1), 0),
            Some(Replay::NotKept {
                len: KEPT_ANSWER + 5
            })
        );
        assert_eq!(back.encode(), bytes);
        assert_eq!(
            ServedLog::decode(&bytes[..bytes.len() - 1]).err(),
            Some(ServedLogError::Truncated {
                left: 9 + KEPT_ANSWER - 1
            })
        );
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
