//! RVMF* frames: the messages modules send each other.
//!
//! The MRA paper's modified Robotic Vehicle Message Format packs the header so that an ACK costs
//! three bytes and executing a method without arguments five. modbot keeps those sizes:
//!
//! ```text
//! byte 0   dst   destination address (0xFF broadcast)
//! byte 1   src   source address
//! byte 2   ctl   kind (bits 7..5) | sequence number (bits 4..0)
//! -------- an ACK ends here: 3 bytes
//! byte 3   len   body length 0..=254, or 255: the length follows as u32 little-endian
//! [4..8]   ext   extended body length (>= 255), only when len == 255
//! body     EXEC, RETRY: method id (1 byte), then the arguments
//!          REPLY: the results
//!          NAK: error code (1 byte), then optionally a text detail
//!          REPORT: topic (1 byte), then the values
//! ```
//!
//! Values are MessagePack (see [`crate::value`]). Decoding reads the header in place: a
//! [`Frame`] borrows the buffer and copies nothing. [`Frame::decode`] and [`FrameSpec::encode`]
//! are the one entry point each way.

use core::fmt;

use thiserror::Error;
use zerocopy::byteorder::little_endian::U32;
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use crate::addr::Addr;
use crate::value::{self, Value, ValueError, Values};

/// Size of an ACK, the smallest frame.
pub const ACK_LEN: usize = 3;
/// Header size of every other frame with the short length form.
pub const SHORT_HEADER_LEN: usize = 4;
/// Header size with the extended length form.
pub const EXT_HEADER_LEN: usize = 8;
/// The largest body the short length form carries.
pub const SHORT_MAX_BODY: usize = 254;
/// The `len` byte that announces the extended form.
pub const EXT_MARKER: u8 = 255;

/// The first three bytes of every frame, read in place.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Header {
    pub dst: u8,
    pub src: u8,
    pub ctl: u8,
}

/// The extended body length.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct ExtLen {
    len: U32,
}

/// The kind of a frame (3 bits on the wire).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Kind {
    Ack = 0,
    Exec = 1,
    Reply = 2,
    Nak = 3,
    Report = 4,
    /// A retransmitted EXEC: same body, same (src, seq) as the original. A receiver that
    /// already served the original answers again without executing twice.
    Retry = 5,
}

impl Kind {
    fn from_bits(bits: u8) -> Option<Kind> {
        Some(match bits {
            0 => Kind::Ack,
            1 => Kind::Exec,
            2 => Kind::Reply,
            3 => Kind::Nak,
            4 => Kind::Report,
            5 => Kind::Retry,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            Kind::Ack => "ack",
            Kind::Exec => "exec",
            Kind::Reply => "reply",
            Kind::Nak => "nak",
            Kind::Report => "report",
            Kind::Retry => "retry",
        }
    }

    /// Whether the body starts with a one-byte operand (method, code or topic).
    fn has_op(self) -> bool {
        matches!(self, Kind::Exec | Kind::Nak | Kind::Report | Kind::Retry)
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A frame's sequence number: 5 bits, so it wraps after 31.
///
/// Requests are matched to answers by (peer, sequence); a sender keeps at most 32 requests
/// outstanding per peer and reuses a number only after its request was answered or expired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Seq(u8);

impl Seq {
    pub const MAX: u8 = 31;
    pub const COUNT: usize = 32;

    /// The sequence number `n`, if it fits in 5 bits.
    pub fn new(n: u8) -> Option<Seq> {
        (n <= Self::MAX).then_some(Seq(n))
    }

    pub fn get(self) -> u8 {
        self.0
    }

    /// The next number, wrapping from 31 to 0.
    pub fn next(self) -> Seq {
        Seq((self.0 + 1) & Self::MAX)
    }
}

impl fmt::Display for Seq {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// Why a request was refused, carried by a NAK.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NakCode(pub u8);

impl NakCode {
    pub const UNKNOWN_METHOD: NakCode = NakCode(1);
    pub const BAD_ARGUMENTS: NakCode = NakCode(2);
    pub const BUSY: NakCode = NakCode(3);
    pub const FAILED: NakCode = NakCode(4);
    pub const UNKNOWN_ITEM: NakCode = NakCode(5);
    pub const READ_ONLY: NakCode = NakCode(6);
    pub const TOO_LARGE: NakCode = NakCode(7);
    pub const NOT_READY: NakCode = NakCode(8);
    pub const DUPLICATE: NakCode = NakCode(9);
    /// The module is on another host and the link to it is down (a bridge's answer).
    pub const UNREACHABLE: NakCode = NakCode(10);

    pub fn name(self) -> &'static str {
        match self {
            Self::UNKNOWN_METHOD => "unknown method",
            Self::BAD_ARGUMENTS => "bad arguments",
            Self::BUSY => "busy",
            Self::FAILED => "method failed",
            Self::UNKNOWN_ITEM => "unknown blackboard item",
            Self::READ_ONLY => "blackboard item is read-only",
            Self::TOO_LARGE => "result too large",
            Self::NOT_READY => "not ready",
            Self::DUPLICATE => "duplicate request: already executed",
            Self::UNREACHABLE => "remote module unreachable",
            _ => "unknown error code",
        }
    }
}

impl fmt::Display for NakCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ({})", self.name(), self.0)
    }
}

/// What a frame is, with its one-byte operand where it has one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    Ack,
    Exec {
        method: u8,
    },
    Reply,
    Nak {
        code: NakCode,
    },
    Report {
        topic: u8,
    },
    /// A retransmitted EXEC.
    Retry {
        method: u8,
    },
}

impl FrameKind {
    /// The method a request asks for: `Some` for EXEC and RETRY.
    pub fn request_method(self) -> Option<u8> {
        match self {
            FrameKind::Exec { method } | FrameKind::Retry { method } => Some(method),
            _ => None,
        }
    }

    pub fn kind(self) -> Kind {
        match self {
            FrameKind::Ack => Kind::Ack,
            FrameKind::Exec { .. } => Kind::Exec,
            FrameKind::Reply => Kind::Reply,
            FrameKind::Nak { .. } => Kind::Nak,
            FrameKind::Report { .. } => Kind::Report,
            FrameKind::Retry { .. } => Kind::Retry,
        }
    }

    fn op(self) -> Option<u8> {
        match self {
            FrameKind::Exec { method } | FrameKind::Retry { method } => Some(method),
            FrameKind::Nak { code } => Some(code.0),
            FrameKind::Report { topic } => Some(topic),
            FrameKind::Ack | FrameKind::Reply => None,
        }
    }
}

/// Why bytes are not a valid frame, or a frame cannot be encoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FrameError {
    #[error("frame truncated: {needed} bytes needed, {got} present")]
    Truncated { needed: usize, got: usize },
    #[error("unknown frame kind {0} (known: 0 ack, 1 exec, 2 reply, 3 nak, 4 report, 5 retry)")]
    UnknownKind(u8),
    #[error("an ACK is exactly 3 bytes, this one has {0}")]
    AckWithBody(usize),
    #[error("{kind} frame has an empty body: its first byte (method, code or topic) is missing")]
    MissingOperand { kind: Kind },
    #[error("length field says {declared} body bytes, the frame has {actual}")]
    LengthMismatch { declared: usize, actual: usize },
    #[error("extended length {0} used for a body that fits the short form (< 255)")]
    NonCanonicalLength(usize),
    #[error("source address {0} is not a module address (1..=254)")]
    BadSource(u8),
    #[error("destination address 0 is reserved")]
    BadDestination,
    #[error("body of {0} bytes is too long (at most 4 GiB)")]
    TooLong(usize),
    #[error("output buffer too small: {needed} bytes needed, {available} available")]
    BufferTooSmall { needed: usize, available: usize },
    #[error("bad payload: {0}")]
    Payload(#[from] ValueError),
}

/// Everything needed to encode a frame except its payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameSpec {
    pub dst: Addr,
    pub src: Addr,
    pub seq: Seq,
    pub kind: FrameKind,
}

impl FrameSpec {
    /// The body length for a payload of `payload_len` bytes.
    fn body_len(&self, payload_len: usize) -> usize {
        payload_len + usize::from(self.kind.op().is_some())
    }

    /// The size of the header (and operand) in front of a payload of `payload_len` bytes.
    pub fn payload_offset(&self, payload_len: usize) -> usize {
        if self.kind == FrameKind::Ack {
            return ACK_LEN;
        }
        let header = if self.body_len(payload_len) <= SHORT_MAX_BODY {
            SHORT_HEADER_LEN
        } else {
            EXT_HEADER_LEN
        };
        header + usize::from(self.kind.op().is_some())
    }

    /// The whole frame's size with a payload of `payload_len` bytes.
    pub fn encoded_len(&self, payload_len: usize) -> usize {
        self.payload_offset(payload_len) + payload_len
    }

    /// Writes the header for a payload of `payload_len` bytes at the start of `out` and returns
    /// where the payload goes; the caller writes it there (into shared memory, say).
    pub fn encode_header(&self, payload_len: usize, out: &mut [u8]) -> Result<usize, FrameError> {
        if !self.src.is_module() {
            return Err(FrameError::BadSource(self.src.0));
        }
        if self.dst == Addr::NONE {
            return Err(FrameError::BadDestination);
        }
        if self.kind == FrameKind::Ack && payload_len > 0 {
            return Err(FrameError::AckWithBody(ACK_LEN + payload_len));
        }
        let needed = self.encoded_len(payload_len);
        if out.len() < needed {
            return Err(FrameError::BufferTooSmall {
                needed,
                available: out.len(),
            });
        }
        let header = Header {
            dst: self.dst.0,
            src: self.src.0,
            ctl: (self.kind.kind() as u8) << 5 | self.seq.get(),
        };
        out[..ACK_LEN].copy_from_slice(header.as_bytes());
        if self.kind == FrameKind::Ack {
            return Ok(ACK_LEN);
        }
        let body = self.body_len(payload_len);
        let mut at = if body <= SHORT_MAX_BODY {
            out[3] = body as u8;
            SHORT_HEADER_LEN
        } else {
            let len = u32::try_from(body).map_err(|_| FrameError::TooLong(body))?;
            out[3] = EXT_MARKER;
            out[4..8].copy_from_slice(ExtLen { len: U32::new(len) }.as_bytes());
            EXT_HEADER_LEN
        };
        if let Some(op) = self.kind.op() {
            out[at] = op;
            at += 1;
        }
        Ok(at)
    }

    /// Encodes the frame with an already encoded `payload` into `out`; returns its length.
    pub fn encode(&self, payload: &[u8], out: &mut [u8]) -> Result<usize, FrameError> {
        let at = self.encode_header(payload.len(), out)?;
        out[at..at + payload.len()].copy_from_slice(payload);
        Ok(at + payload.len())
    }

    /// Encodes the frame with `values` as payload into `out`; returns its length.
    pub fn encode_values(&self, values: &[Value<'_>], out: &mut [u8]) -> Result<usize, FrameError> {
        let payload_len = value::encoded_len(values);
        let at = self.encode_header(payload_len, out)?;
        value::encode_all(values, &mut out[at..at + payload_len])?;
        Ok(at + payload_len)
    }

    /// Encodes into a new vector (for tools and tests; the runtime encodes into shared memory).
    pub fn to_vec(&self, values: &[Value<'_>]) -> Result<Vec<u8>, FrameError> {
        let mut out = vec![0; self.encoded_len(value::encoded_len(values))];
        self.encode_values(values, &mut out)?;
        Ok(out)
    }
}

/// A decoded frame, borrowing the buffer it was read from.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    header: &'a Header,
    kind: FrameKind,
    payload: &'a [u8],
    payload_offset: usize,
    extended: bool,
}

impl<'a> Frame<'a> {
    /// Decodes `bytes` as one frame. Never panics; every malformed input is a [`FrameError`].
    ///
    /// The payload's values are checked lazily by [`Frame::values`]; use
    /// [`Frame::decode_strict`] to check them too.
    pub fn decode(bytes: &'a [u8]) -> Result<Frame<'a>, FrameError> {
        let (header, rest) = Header::ref_from_prefix(bytes).map_err(|_| FrameError::Truncated {
            needed: ACK_LEN,
            got: bytes.len(),
        })?;
        let raw_kind = header.ctl >> 5;
        let kind = Kind::from_bits(raw_kind).ok_or(FrameError::UnknownKind(raw_kind))?;
        if !Addr(header.src).is_module() {
            return Err(FrameError::BadSource(header.src));
        }
        if header.dst == Addr::NONE.0 {
            return Err(FrameError::BadDestination);
        }
        if kind == Kind::Ack {
            if !rest.is_empty() {
                return Err(FrameError::AckWithBody(bytes.len()));
            }
            return Ok(Frame {
                header,
                kind: FrameKind::Ack,
                payload: rest,
                payload_offset: ACK_LEN,
                extended: false,
            });
        }
        let (&len, rest) = rest.split_first().ok_or(FrameError::Truncated {
            needed: SHORT_HEADER_LEN,
            got: bytes.len(),
        })?;
        let (declared, body, body_offset, extended) = if len == EXT_MARKER {
            let (ext, body) = ExtLen::ref_from_prefix(rest).map_err(|_| FrameError::Truncated {
                needed: EXT_HEADER_LEN,
                got: bytes.len(),
            })?;
            let declared = ext.len.get() as usize;
            if declared <= SHORT_MAX_BODY {
                return Err(FrameError::NonCanonicalLength(declared));
            }
            (declared, body, EXT_HEADER_LEN, true)
        } else {
            (usize::from(len), rest, SHORT_HEADER_LEN, false)
        };
        if declared != body.len() {
            return Err(FrameError::LengthMismatch {
                declared,
                actual: body.len(),
            });
        }
        let (kind, payload, payload_offset) = if kind.has_op() {
            let (&op, payload) = body
                .split_first()
                .ok_or(FrameError::MissingOperand { kind })?;
            let kind = match kind {
                Kind::Exec => FrameKind::Exec { method: op },
                Kind::Nak => FrameKind::Nak { code: NakCode(op) },
                Kind::Retry => FrameKind::Retry { method: op },
                _ => FrameKind::Report { topic: op },
            };
            (kind, payload, body_offset + 1)
        } else {
            (FrameKind::Reply, body, body_offset)
        };
        Ok(Frame {
            header,
            kind,
            payload,
            payload_offset,
            extended,
        })
    }

    /// Decodes `bytes` and checks that the payload is a valid sequence of values.
    pub fn decode_strict(bytes: &'a [u8]) -> Result<Frame<'a>, FrameError> {
        let frame = Self::decode(bytes)?;
        for v in frame.values() {
            v?;
        }
        Ok(frame)
    }

    pub fn dst(&self) -> Addr {
        Addr(self.header.dst)
    }

    pub fn src(&self) -> Addr {
        Addr(self.header.src)
    }

    pub fn seq(&self) -> Seq {
        Seq(self.header.ctl & Seq::MAX)
    }

    pub fn kind(&self) -> FrameKind {
        self.kind
    }

    /// Whether the extended length form was used.
    pub fn is_extended(&self) -> bool {
        self.extended
    }

    /// The payload: the encoded values after the header and operand.
    pub fn payload(&self) -> &'a [u8] {
        self.payload
    }

    /// Where the payload starts in the frame.
    pub fn payload_offset(&self) -> usize {
        self.payload_offset
    }

    /// The payload's values, decoded lazily.
    pub fn values(&self) -> Values<'a> {
        Values::new(self.payload, self.payload_offset)
    }

    /// The header fields, to answer or re-encode the frame.
    pub fn spec(&self) -> FrameSpec {
        FrameSpec {
            dst: self.dst(),
            src: self.src(),
            seq: self.seq(),
            kind: self.kind,
        }
    }

    /// The frame's length in bytes.
    pub fn len(&self) -> usize {
        self.payload_offset + self.payload.len()
    }

    pub fn is_empty(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    fn spec(kind: FrameKind) -> FrameSpec {
        FrameSpec {
            dst: Addr(3),
            src: Addr(1),
            seq: Seq::new(5).unwrap(),
            kind,
        }
    }

    #[test]
    fn an_ack_is_exactly_three_bytes() {
        let bytes = spec(FrameKind::Ack).to_vec(&[]).unwrap();
        assert_eq!(hex::encode(&bytes), "030105");
        let frame = Frame::decode(&bytes).unwrap();
        assert_eq!(frame.kind(), FrameKind::Ack);
        assert_eq!(
            (frame.dst(), frame.src(), frame.seq().get()),
            (Addr(3), Addr(1), 5)
        );
    }

    #[test]
    fn an_exec_without_arguments_is_exactly_five_bytes() {
        let bytes = spec(FrameKind::Exec { method: 7 }).to_vec(&[]).unwrap();
        assert_eq!(hex::encode(&bytes), "0301250107");
        assert_eq!(
            Frame::decode(&bytes).unwrap().kind(),
            FrameKind::Exec { method: 7 }
        );
    }

    #[test]
    fn frames_encode_to_the_documented_golden_bytes() {
        let golden: &[(FrameKind, &[Value<'_>], &str)] = &[
            (
                FrameKind::Exec { method: 2 },
                &[Value::F64(0.61)],
                "0301250a02cb3fe3851eb851eb85",
            ),
            (
                FrameKind::Reply,
                &[Value::I64(42), Value::Text("ok")],
                "030145042aa26f6b",
            ),
            (
                FrameKind::Nak {
                    code: NakCode::UNKNOWN_METHOD,
                },
                &[],
                "0301650101",
            ),
            (
                FrameKind::Report { topic: 9 },
                &[Value::Bool(true)],
                "03018502 09c3",
            ),
        ];
        for (kind, values, want) in golden {
            let bytes = spec(*kind).to_vec(values).unwrap();
            assert_eq!(hex::encode(&bytes), want.replace(' ', ""), "{kind:?}");
            let frame = Frame::decode_strict(&bytes).unwrap();
            assert_eq!(frame.spec(), spec(*kind));
            let decoded: Vec<_> = frame.values().map(Result::unwrap).collect();
            assert_eq!(&decoded, values);
        }
    }

    #[test]
    fn a_large_payload_uses_the_extended_length_form() {
        let blob = vec![0xab_u8; 64 * 1024];
        let bytes = spec(FrameKind::Reply)
            .to_vec(&[Value::Bytes(&blob)])
            .unwrap();
        assert_eq!(&bytes[..8], &[3, 1, 0x45, 0xff, 0x05, 0x00, 0x01, 0x00]);
        let frame = Frame::decode_strict(&bytes).unwrap();
        assert!(frame.is_extended());
        assert_eq!(frame.values().next().unwrap().unwrap(), Value::Bytes(&blob));
    }

    #[test]
    fn malformed_frames_are_rejected_with_the_reason() {
        let cases: &[(&str, FrameError)] = &[
            ("", FrameError::Truncated { needed: 3, got: 0 }),
            ("0301", FrameError::Truncated { needed: 3, got: 2 }),
            ("0301e5", FrameError::UnknownKind(7)),
            ("0301c5", FrameError::UnknownKind(6)),
            ("030105ff", FrameError::AckWithBody(4)),
            ("030125", FrameError::Truncated { needed: 4, got: 3 }),
            (
                "0301250207",
                FrameError::LengthMismatch {
                    declared: 2,
                    actual: 1,
                },
            ),
            ("03012500", FrameError::MissingOperand { kind: Kind::Exec }),
            ("030145ff0100000000", FrameError::NonCanonicalLength(1)),
            ("030145ff01", FrameError::Truncated { needed: 8, got: 5 }),
            ("03ff05", FrameError::BadSource(0xff)),
            ("000105", FrameError::BadDestination),
        ];
        for (text, want) in cases {
            assert_eq!(
                Frame::decode(&hex::decode(text).unwrap()).unwrap_err(),
                *want,
                "{text}"
            );
        }
    }
}
