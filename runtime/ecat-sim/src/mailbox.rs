//! The mailbox protocol on SM0 (master → slave) and SM1 (slave → master): the 6-byte header,
//! dispatch by type, the slave's own 1..=7 counter, and replies queued while the master has
//! not yet read the previous one.

use std::collections::VecDeque;

use crate::al::AlState;
use crate::coe::SdoServer;
use crate::dictionary::ObjectDictionary;

/// Bytes of the mailbox header.
pub const HEADER_LEN: usize = 6;
/// Mailbox type: error reply.
pub const TYPE_ERROR: u8 = 0x00;
/// Mailbox type: CoE.
pub const TYPE_COE: u8 = 0x03;

/// Mailbox error codes (ETG.1000.4 Table 30), sent in a reply of type 0.
pub mod error {
    /// Syntax of the 6-byte header is wrong.
    pub const SYNTAX: u16 = 0x0001;
    /// The protocol is not supported.
    pub const UNSUPPORTED_PROTOCOL: u16 = 0x0002;
    /// The length is too short for the protocol.
    pub const SIZE_TOO_SHORT: u16 = 0x0006;
}

/// A decoded mailbox header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxHeader {
    /// Bytes of payload after the header.
    pub length: u16,
    /// Station address of the source or destination (0 from the master).
    pub address: u16,
    /// Channel (6 bits) and priority (2 bits).
    pub channel_priority: u8,
    /// Type (low 4 bits).
    pub kind: u8,
    /// Counter 1..=7 (0: not used).
    pub counter: u8,
}

impl MailboxHeader {
    /// Decodes the first 6 bytes of a mailbox; `None` if there are fewer.
    pub fn decode(bytes: &[u8]) -> Option<Self> {
        let b = bytes.get(0..HEADER_LEN)?;
        Some(Self {
            length: u16::from_le_bytes([b[0], b[1]]),
            address: u16::from_le_bytes([b[2], b[3]]),
            channel_priority: b[4],
            kind: b[5] & 0x0F,
            counter: (b[5] >> 4) & 0x07,
        })
    }

    /// The 6 header bytes.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut out = [0u8; HEADER_LEN];
        out[0..2].copy_from_slice(&self.length.to_le_bytes());
        out[2..4].copy_from_slice(&self.address.to_le_bytes());
        out[4] = self.channel_priority;
        out[5] = (self.kind & 0x0F) | ((self.counter & 0x07) << 4);
        out
    }
}

/// The mailbox side of one slave's firmware.
#[derive(Debug, Clone, Default)]
pub struct MailboxServer {
    /// The slave's counter of its last reply (1..=7).
    counter: u8,
    /// Replies waiting for the master to empty SM1.
    pending: VecDeque<Vec<u8>>,
    /// The CoE SDO server.
    sdo: SdoServer,
}

impl MailboxServer {
    /// Forgets transfers in progress and queued replies (leaving PRE-OP).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    fn next_counter(&mut self) -> u8 {
        self.counter = if self.counter >= 7 {
            1
        } else {
            self.counter + 1
        };
        self.counter
    }

    fn wrap(&mut self, kind: u8, payload: &[u8]) -> Vec<u8> {
        let header = MailboxHeader {
            length: payload.len() as u16,
            address: 0,
            channel_priority: 0,
            kind,
            counter: self.next_counter(),
        };
        let mut out = header.encode().to_vec();
        out.extend_from_slice(payload);
        out
    }

    fn error_reply(&mut self, code: u16) -> Vec<u8> {
        let mut payload = 0x0001u16.to_le_bytes().to_vec();
        payload.extend_from_slice(&code.to_le_bytes());
        self.wrap(TYPE_ERROR, &payload)
    }

    /// Handles the contents of a full receive mailbox; the reply (if any) is queued.
    /// `send_size` is the size of the send mailbox.
    pub fn on_request(
        &mut self,
        mailbox: &[u8],
        od: &mut ObjectDictionary,
        state: AlState,
        send_size: usize,
    ) {
        let Some(header) = MailboxHeader::decode(mailbox) else {
            let reply = self.error_reply(error::SYNTAX);
            self.pending.push_back(reply);
            return;
        };
        let Some(payload) = mailbox.get(HEADER_LEN..HEADER_LEN + usize::from(header.length)) else {
            let reply = self.error_reply(error::SIZE_TOO_SHORT);
            self.pending.push_back(reply);
            return;
        };
        match header.kind {
            TYPE_COE => {
                let max_payload = send_size.saturating_sub(HEADER_LEN);
                if let Some(answer) = self.sdo.handle(payload, od, state, max_payload) {
                    let reply = self.wrap(TYPE_COE, &answer);
                    self.pending.push_back(reply);
                }
            }
            _ => {
                let reply = self.error_reply(error::UNSUPPORTED_PROTOCOL);
                self.pending.push_back(reply);
            }
        }
    }

    /// The next queued reply, if any, to put into the send mailbox.
    pub fn next_reply(&mut self) -> Option<Vec<u8>> {
        self.pending.pop_front()
    }

    /// Puts a reply back at the head of the queue (the send mailbox was still full).
    pub fn unsend(&mut self, reply: Vec<u8>) {
        self.pending.push_front(reply);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_matches_ethercrab_s_wire_capture() {
        // ethercrab's encode_header test vector: length 10, CoE, counter 3.
        let sut = MailboxHeader {
            length: 10,
            address: 0,
            channel_priority: 0,
            kind: TYPE_COE,
            counter: 3,
        };
        assert_eq!(sut.encode(), [0x0a, 0x00, 0x00, 0x00, 0x00, 0x33]);
        assert_eq!(MailboxHeader::decode(&sut.encode()), Some(sut));
    }

    #[test]
    fn the_reply_counter_cycles_from_1_to_7() {
        let mut sut = MailboxServer::default();
        let counters: Vec<u8> = (0..9).map(|_| sut.next_counter()).collect();
        assert_eq!(counters, [1, 2, 3, 4, 5, 6, 7, 1, 2]);
    }

    #[test]
    fn an_unsupported_protocol_gets_a_mailbox_error_reply() {
        let mut sut = MailboxServer::default();
        let mut od = ObjectDictionary::new();
        let request = MailboxHeader {
            length: 2,
            address: 0,
            channel_priority: 0,
            kind: 0x04,
            counter: 1,
        };
        let mut bytes = request.encode().to_vec();
        bytes.extend_from_slice(&[0, 0]);
        sut.on_request(&bytes, &mut od, AlState::PreOp, 128);
        let reply = sut.next_reply().unwrap();
        let header = MailboxHeader::decode(&reply).unwrap();
        assert_eq!(header.kind, TYPE_ERROR);
        assert_eq!(&reply[6..10], &[0x01, 0x00, 0x02, 0x00]);
    }

    #[test]
    fn a_length_beyond_the_mailbox_gets_a_size_error_reply() {
        let mut sut = MailboxServer::default();
        let mut od = ObjectDictionary::new();
        let request = MailboxHeader {
            length: 200,
            address: 0,
            channel_priority: 0,
            kind: TYPE_COE,
            counter: 1,
        };
        sut.on_request(&request.encode(), &mut od, AlState::PreOp, 128);
        let reply = sut.next_reply().unwrap();
        assert_eq!(&reply[6..10], &[0x01, 0x00, 0x06, 0x00]);
    }
}
