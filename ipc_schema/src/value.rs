//! Typed values carried by frames: f64, i64, bool, text, bytes and f64 arrays.
//!
//! Values are encoded as [MessagePack](https://github.com/msgpack/msgpack/blob/master/spec.md)
//! through the `rmp` crate, so any MessagePack library (Python's `msgpack`, C's `mpack`) can read
//! and write them:
//!
//! | value | MessagePack |
//! |---|---|
//! | f64 | float 64 (`0xcb`, 8 bytes big-endian) |
//! | i64 | the shortest int form (positive fixint, int 8..64, uint 8..64 up to `i64::MAX`) |
//! | bool | `0xc2` false, `0xc3` true |
//! | text | str (UTF-8) |
//! | bytes | bin |
//! | f64 array | ext, type `1`, the f64s little-endian back to back |
//!
//! A payload is a plain sequence of values (no array header): the frame's length says where it
//! ends. Decoding borrows from the input: text, bytes and f64 arrays are views into the frame.

use core::fmt;

use rmp::Marker;
use thiserror::Error;

/// MessagePack ext type used for f64 arrays.
pub const EXT_F64_ARRAY: i8 = 1;

/// The type of a value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum ValueKind {
    F64 = 1,
    I64 = 2,
    Bool = 3,
    Text = 4,
    Bytes = 5,
    F64s = 6,
}

impl ValueKind {
    /// The kind for a wire code, if it is one.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            1 => Self::F64,
            2 => Self::I64,
            3 => Self::Bool,
            4 => Self::Text,
            5 => Self::Bytes,
            6 => Self::F64s,
            _ => return None,
        })
    }

    /// The short name used in docs and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::F64 => "f64",
            Self::I64 => "i64",
            Self::Bool => "bool",
            Self::Text => "text",
            Self::Bytes => "bytes",
            Self::F64s => "f64[]",
        }
    }
}

impl fmt::Display for ValueKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A view of little-endian f64s inside a buffer; works whatever the buffer's alignment.
#[derive(Clone, Copy, PartialEq)]
pub struct F64s<'a>(&'a [u8]);

impl<'a> F64s<'a> {
    /// Views `bytes` as f64s; `None` unless the length is a multiple of 8.
    pub fn from_le_bytes(bytes: &'a [u8]) -> Option<Self> {
        bytes.len().is_multiple_of(8).then_some(Self(bytes))
    }

    /// Views a slice of f64s (this host is little-endian, see the crate root).
    pub fn from_slice(values: &'a [f64]) -> Self {
        Self(bytemuck::cast_slice(values))
    }

    pub fn len(&self) -> usize {
        self.0.len() / 8
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The `i`-th value.
    pub fn get(&self, i: usize) -> Option<f64> {
        let chunk = self.0.get(i * 8..i * 8 + 8)?;
        Some(f64::from_le_bytes(chunk.try_into().ok()?))
    }

    pub fn iter(&self) -> impl Iterator<Item = f64> + 'a {
        self.0
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
    }

    /// The raw little-endian bytes.
    pub fn as_le_bytes(&self) -> &'a [u8] {
        self.0
    }

    pub fn to_vec(&self) -> Vec<f64> {
        self.iter().collect()
    }
}

impl fmt::Debug for F64s<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

/// A value, borrowed from the buffer it was decoded from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value<'a> {
    F64(f64),
    I64(i64),
    Bool(bool),
    Text(&'a str),
    Bytes(&'a [u8]),
    F64s(F64s<'a>),
}

/// Why a value could not be encoded or decoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ValueError {
    #[error("value truncated at byte {offset}: {needed} more bytes needed")]
    Truncated { offset: usize, needed: usize },
    #[error("unsupported MessagePack marker 0x{marker:02x} at byte {offset} (modbot values are f64, i64, bool, text, bytes and f64 arrays)")]
    Unsupported { offset: usize, marker: u8 },
    #[error("integer at byte {offset} does not fit in i64")]
    IntegerOutOfRange { offset: usize },
    #[error("text at byte {offset} is not valid UTF-8")]
    BadUtf8 { offset: usize },
    #[error("ext type {ty} at byte {offset} is not an f64 array (type 1)")]
    UnknownExt { offset: usize, ty: i8 },
    #[error("f64 array at byte {offset} has {len} bytes, not a multiple of 8")]
    BadF64ArrayLength { offset: usize, len: usize },
    #[error("value of {len} bytes is too long for MessagePack (at most 4 GiB)")]
    TooLong { len: usize },
    #[error("output buffer too small: {needed} bytes needed, {available} available")]
    BufferTooSmall { needed: usize, available: usize },
}

impl<'a> Value<'a> {
    pub fn kind(&self) -> ValueKind {
        match self {
            Value::F64(_) => ValueKind::F64,
            Value::I64(_) => ValueKind::I64,
            Value::Bool(_) => ValueKind::Bool,
            Value::Text(_) => ValueKind::Text,
            Value::Bytes(_) => ValueKind::Bytes,
            Value::F64s(_) => ValueKind::F64s,
        }
    }

    /// The number of bytes [`Value::encode`] writes.
    pub fn encoded_len(&self) -> usize {
        let len_prefix = |n: usize, fix_max: usize| match n {
            n if n <= fix_max => 1,
            n if n <= 0xff => 2,
            n if n <= 0xffff => 3,
            _ => 5,
        };
        match *self {
            Value::F64(_) => 9,
            Value::I64(v) => match v {
                -32..=127 => 1,
                -128..=255 => 2,
                -32768..=65535 => 3,
                -2147483648..=4294967295 => 5,
                _ => 9,
            },
            Value::Bool(_) => 1,
            Value::Text(s) => len_prefix(s.len(), 31) + s.len(),
            Value::Bytes(b) => len_prefix(b.len(), 0).max(2) + b.len(),
            Value::F64s(a) => {
                let n = a.as_le_bytes().len();
                let meta = match n {
                    1 | 2 | 4 | 8 | 16 => 2,
                    n if n <= 0xff => 3,
                    n if n <= 0xffff => 4,
                    _ => 6,
                };
                meta + n
            }
        }
    }

    /// Writes the value at the start of `out` and returns the number of bytes written.
    pub fn encode(&self, out: &mut [u8]) -> Result<usize, ValueError> {
        let needed = self.encoded_len();
        if out.len() < needed {
            return Err(ValueError::BufferTooSmall {
                needed,
                available: out.len(),
            });
        }
        let mut cursor = &mut out[..needed];
        self.write_to(&mut cursor)?;
        debug_assert!(cursor.is_empty(), "encoded_len disagrees with the encoder");
        Ok(needed)
    }

    /// Appends the value to `out`.
    pub fn encode_to_vec(&self, out: &mut Vec<u8>) -> Result<(), ValueError> {
        self.write_to(out)
    }

    fn write_to<W: std::io::Write>(&self, wr: &mut W) -> Result<(), ValueError> {
        let needed = self.encoded_len();
        // The only way these writers fail is running out of room (a `&mut [u8]` that is full).
        let short = || ValueError::BufferTooSmall {
            needed,
            available: 0,
        };
        let len32 = |len: usize| u32::try_from(len).map_err(|_| ValueError::TooLong { len });
        match *self {
            Value::F64(v) => rmp::encode::write_f64(wr, v).map_err(|_| short())?,
            Value::I64(v) => {
                rmp::encode::write_sint(wr, v).map_err(|_| short())?;
            }
            Value::Bool(v) => rmp::encode::write_bool(wr, v).map_err(|_| short())?,
            Value::Text(s) => {
                rmp::encode::write_str_len(wr, len32(s.len())?).map_err(|_| short())?;
                wr.write_all(s.as_bytes()).map_err(|_| short())?;
            }
            Value::Bytes(b) => {
                rmp::encode::write_bin_len(wr, len32(b.len())?).map_err(|_| short())?;
                wr.write_all(b).map_err(|_| short())?;
            }
            Value::F64s(a) => {
                let data = a.as_le_bytes();
                rmp::encode::write_ext_meta(wr, len32(data.len())?, EXT_F64_ARRAY)
                    .map_err(|_| short())?;
                wr.write_all(data).map_err(|_| short())?;
            }
        }
        Ok(())
    }

    /// Decodes one value from the start of `input`; returns it and the number of bytes used.
    ///
    /// `base` is added to byte offsets in errors (the position of `input` in its frame).
    pub fn decode(input: &'a [u8], base: usize) -> Result<(Value<'a>, usize), ValueError> {
        let truncated = |needed: usize| ValueError::Truncated {
            offset: base,
            needed,
        };
        let Some(&first) = input.first() else {
            return Err(truncated(1));
        };
        let take = |start: usize, len: usize| -> Result<&'a [u8], ValueError> {
            let end = start.checked_add(len).ok_or(truncated(len))?;
            input
                .get(start..end)
                .ok_or(truncated(end.saturating_sub(input.len())))
        };
        let be = |start: usize, len: usize| -> Result<u64, ValueError> {
            Ok(take(start, len)?
                .iter()
                .fold(0u64, |acc, b| acc << 8 | u64::from(*b)))
        };
        let int = |v: i128, used: usize| {
            i64::try_from(v)
                .map(|v| (Value::I64(v), used))
                .map_err(|_| ValueError::IntegerOutOfRange { offset: base })
        };
        let var = |prefix: usize, len: u64| -> Result<(&'a [u8], usize), ValueError> {
            let len = usize::try_from(len).map_err(|_| truncated(usize::MAX))?;
            Ok((take(prefix, len)?, prefix + len))
        };
        match Marker::from_u8(first) {
            Marker::FixPos(v) => Ok((Value::I64(i64::from(v)), 1)),
            Marker::FixNeg(v) => Ok((Value::I64(i64::from(v)), 1)),
            Marker::U8 => int(i128::from(be(1, 1)?), 2),
            Marker::U16 => int(i128::from(be(1, 2)?), 3),
            Marker::U32 => int(i128::from(be(1, 4)?), 5),
            Marker::U64 => int(i128::from(be(1, 8)?), 9),
            Marker::I8 => int(i128::from(be(1, 1)? as u8 as i8), 2),
            Marker::I16 => int(i128::from(be(1, 2)? as u16 as i16), 3),
            Marker::I32 => int(i128::from(be(1, 4)? as u32 as i32), 5),
            Marker::I64 => int(i128::from(be(1, 8)? as i64), 9),
            Marker::F64 => Ok((Value::F64(f64::from_bits(be(1, 8)?)), 9)),
            Marker::True => Ok((Value::Bool(true), 1)),
            Marker::False => Ok((Value::Bool(false), 1)),
            Marker::FixStr(_) | Marker::Str8 | Marker::Str16 | Marker::Str32 => {
                let (prefix, len) = match Marker::from_u8(first) {
                    Marker::FixStr(n) => (1, u64::from(n)),
                    Marker::Str8 => (2, be(1, 1)?),
                    Marker::Str16 => (3, be(1, 2)?),
                    _ => (5, be(1, 4)?),
                };
                let (bytes, used) = var(prefix, len)?;
                let text = core::str::from_utf8(bytes)
                    .map_err(|_| ValueError::BadUtf8 { offset: base })?;
                Ok((Value::Text(text), used))
            }
            Marker::Bin8 | Marker::Bin16 | Marker::Bin32 => {
                let width = match Marker::from_u8(first) {
                    Marker::Bin8 => 1,
                    Marker::Bin16 => 2,
                    _ => 4,
                };
                let (bytes, used) = var(1 + width, be(1, width)?)?;
                Ok((Value::Bytes(bytes), used))
            }
            m @ (Marker::FixExt1
            | Marker::FixExt2
            | Marker::FixExt4
            | Marker::FixExt8
            | Marker::FixExt16
            | Marker::Ext8
            | Marker::Ext16
            | Marker::Ext32) => {
                let (len, ty_at) = match m {
                    Marker::FixExt1 => (1, 1),
                    Marker::FixExt2 => (2, 1),
                    Marker::FixExt4 => (4, 1),
                    Marker::FixExt8 => (8, 1),
                    Marker::FixExt16 => (16, 1),
                    Marker::Ext8 => (be(1, 1)?, 2),
                    Marker::Ext16 => (be(1, 2)?, 3),
                    _ => (be(1, 4)?, 5),
                };
                let ty = take(ty_at, 1)?[0] as i8;
                if ty != EXT_F64_ARRAY {
                    return Err(ValueError::UnknownExt { offset: base, ty });
                }
                let (bytes, used) = var(ty_at + 1, len)?;
                let array = F64s::from_le_bytes(bytes).ok_or(ValueError::BadF64ArrayLength {
                    offset: base,
                    len: bytes.len(),
                })?;
                Ok((Value::F64s(array), used))
            }
            _ => Err(ValueError::Unsupported {
                offset: base,
                marker: first,
            }),
        }
    }

    /// The value as an f64, accepting integers (a command line's `10` is a fine distance).
    pub fn as_f64(&self) -> Option<f64> {
        match *self {
            Value::F64(v) => Some(v),
            Value::I64(v) => Some(v as f64),
            _ => None,
        }
    }

    /// An owned copy of the value.
    pub fn to_owned_value(&self) -> OwnedValue {
        match *self {
            Value::F64(v) => OwnedValue::F64(v),
            Value::I64(v) => OwnedValue::I64(v),
            Value::Bool(v) => OwnedValue::Bool(v),
            Value::Text(s) => OwnedValue::Text(s.to_owned()),
            Value::Bytes(b) => OwnedValue::Bytes(b.to_vec()),
            Value::F64s(a) => OwnedValue::F64s(a.to_vec()),
        }
    }
}

impl fmt::Display for Value<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::F64(v) => write!(f, "{v:?}"),
            Value::I64(v) => write!(f, "{v}"),
            Value::Bool(v) => write!(f, "{v}"),
            Value::Text(s) => write!(f, "{s:?}"),
            Value::Bytes(b) => write!(f, "0x{}", crate::hex::encode(b)),
            Value::F64s(a) => {
                f.write_str("[")?;
                for (i, v) in a.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{v:?}")?;
                }
                f.write_str("]")
            }
        }
    }
}

/// An owned value, for building arguments and keeping results.
#[derive(Debug, Clone, PartialEq)]
pub enum OwnedValue {
    F64(f64),
    I64(i64),
    Bool(bool),
    Text(String),
    Bytes(Vec<u8>),
    F64s(Vec<f64>),
}

/// Something that reads as a [`Value`]: a value itself, or an [`OwnedValue`] (so a list of
/// either encodes without first building a list of values).
pub trait AsValue {
    fn as_value(&self) -> Value<'_>;
}

impl AsValue for Value<'_> {
    fn as_value(&self) -> Value<'_> {
        *self
    }
}

impl AsValue for OwnedValue {
    fn as_value(&self) -> Value<'_> {
        OwnedValue::as_value(self)
    }
}

impl OwnedValue {
    pub fn as_value(&self) -> Value<'_> {
        match self {
            OwnedValue::F64(v) => Value::F64(*v),
            OwnedValue::I64(v) => Value::I64(*v),
            OwnedValue::Bool(v) => Value::Bool(*v),
            OwnedValue::Text(s) => Value::Text(s),
            OwnedValue::Bytes(b) => Value::Bytes(b),
            OwnedValue::F64s(a) => Value::F64s(F64s::from_slice(a)),
        }
    }

    pub fn kind(&self) -> ValueKind {
        self.as_value().kind()
    }

    /// Parses a command-line argument.
    ///
    /// `1.5` is an f64, `3` an i64, `true`/`false` a bool, `[1, 2.5]` an f64 array, `0x0a0b`
    /// bytes; a `kind:` prefix forces a kind (`f64:3`, `text:true`); anything else is text.
    pub fn parse(text: &str) -> Result<OwnedValue, ParseValueError> {
        let forced = text.split_once(':').and_then(|(kind, rest)| {
            let kind = match kind {
                "f64" => ValueKind::F64,
                "i64" => ValueKind::I64,
                "bool" => ValueKind::Bool,
                "text" => ValueKind::Text,
                "bytes" => ValueKind::Bytes,
                "f64[]" => ValueKind::F64s,
                _ => return None,
            };
            Some((kind, rest))
        });
        if let Some((kind, rest)) = forced {
            return Self::parse_as(kind, rest);
        }
        if let Ok(v) = text.parse::<i64>() {
            return Ok(OwnedValue::I64(v));
        }
        if let Ok(v) = text.parse::<f64>() {
            return Ok(OwnedValue::F64(v));
        }
        match text {
            "true" | "false" => return Self::parse_as(ValueKind::Bool, text),
            _ => {}
        }
        if text.starts_with('[') {
            return Self::parse_as(ValueKind::F64s, text);
        }
        if let Some(hex) = text.strip_prefix("0x") {
            if let Ok(bytes) = crate::hex::decode(hex) {
                return Ok(OwnedValue::Bytes(bytes));
            }
        }
        Ok(OwnedValue::Text(text.to_owned()))
    }

    /// Parses `text` as a value of `kind`.
    pub fn parse_as(kind: ValueKind, text: &str) -> Result<OwnedValue, ParseValueError> {
        let bad = || ParseValueError {
            text: text.to_owned(),
            kind,
            hex: None,
        };
        Ok(match kind {
            ValueKind::F64 => OwnedValue::F64(text.trim().parse().map_err(|_| bad())?),
            ValueKind::I64 => OwnedValue::I64(text.trim().parse().map_err(|_| bad())?),
            ValueKind::Bool => OwnedValue::Bool(match text.trim() {
                "true" | "1" | "on" => true,
                "false" | "0" | "off" => false,
                _ => return Err(bad()),
            }),
            ValueKind::Text => OwnedValue::Text(text.to_owned()),
            ValueKind::Bytes => {
                let hex = text.trim().trim_start_matches("0x");
                OwnedValue::Bytes(crate::hex::decode(hex).map_err(|e| ParseValueError {
                    hex: Some(e),
                    ..bad()
                })?)
            }
            ValueKind::F64s => {
                let inner = text.trim().trim_start_matches('[').trim_end_matches(']');
                let values = inner
                    .split(',')
                    .map(str::trim)
                    .filter(|s| !s.is_empty())
                    .map(|s| s.parse::<f64>().map_err(|_| bad()))
                    .collect::<Result<Vec<_>, _>>()?;
                OwnedValue::F64s(values)
            }
        })
    }
}

/// A command-line argument that is not a value of the kind it asks for (`i64:x`).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("'{text}' is not a valid {kind}{}", .hex.as_ref().map(|e| format!(": {e}")).unwrap_or_default())]
pub struct ParseValueError {
    pub text: String,
    pub kind: ValueKind,
    /// Why the digits of bytes are not hex.
    pub hex: Option<crate::hex::HexError>,
}

impl fmt::Display for OwnedValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.as_value().fmt(f)
    }
}

/// The number of bytes `values` take encoded back to back.
pub fn encoded_len(values: &[Value<'_>]) -> usize {
    values.iter().map(Value::encoded_len).sum()
}

/// Encodes `values` back to back at the start of `out`; returns the number of bytes written.
pub fn encode_all(values: &[Value<'_>], out: &mut [u8]) -> Result<usize, ValueError> {
    let mut at = 0;
    for v in values {
        at += v.encode(&mut out[at..])?;
    }
    Ok(at)
}

/// Iterates over the values of a payload, borrowing from it.
#[derive(Debug, Clone)]
pub struct Values<'a> {
    rest: &'a [u8],
    offset: usize,
}

impl<'a> Values<'a> {
    /// Iterates over `payload`; `base` is its offset in the frame, for error messages.
    pub fn new(payload: &'a [u8], base: usize) -> Self {
        Self {
            rest: payload,
            offset: base,
        }
    }

    /// The bytes not read yet.
    pub(crate) fn rest(&self) -> &'a [u8] {
        self.rest
    }

    /// Where the next value starts, counted as `base` and the bytes read.
    pub(crate) fn offset(&self) -> usize {
        self.offset
    }
}

impl<'a> Iterator for Values<'a> {
    type Item = Result<Value<'a>, ValueError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.rest.is_empty() {
            return None;
        }
        match Value::decode(self.rest, self.offset) {
            Ok((v, used)) => {
                self.rest = &self.rest[used..];
                self.offset += used;
                Some(Ok(v))
            }
            Err(e) => {
                self.rest = &[];
                Some(Err(e))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn enc(v: Value<'_>) -> Vec<u8> {
        let mut out = vec![0; v.encoded_len()];
        assert_eq!(v.encode(&mut out).unwrap(), out.len());
        let mut via_vec = Vec::new();
        v.encode_to_vec(&mut via_vec).unwrap();
        assert_eq!(via_vec, out, "slice and vec encoders agree");
        out
    }

    #[test]
    fn values_encode_to_the_documented_golden_bytes() {
        assert_eq!(enc(Value::F64(1.5)), [0xcb, 0x3f, 0xf8, 0, 0, 0, 0, 0, 0]);
        assert_eq!(enc(Value::I64(7)), [0x07]);
        assert_eq!(enc(Value::I64(-1)), [0xff]);
        assert_eq!(enc(Value::I64(300)), [0xcd, 0x01, 0x2c]);
        assert_eq!(enc(Value::I64(-200)), [0xd1, 0xff, 0x38]);
        assert_eq!(enc(Value::Bool(true)), [0xc3]);
        assert_eq!(enc(Value::Text("hi")), [0xa2, b'h', b'i']);
        assert_eq!(enc(Value::Bytes(&[1, 2])), [0xc4, 0x02, 0x01, 0x02]);
        assert_eq!(
            enc(Value::F64s(F64s::from_slice(&[1.0]))),
            [0xd7, 0x01, 0, 0, 0, 0, 0, 0, 0xf0, 0x3f]
        );
        assert_eq!(
            enc(Value::F64s(F64s::from_slice(&[1.0, 2.0, 3.0]))),
            [
                0xc7, 24, 0x01, 0, 0, 0, 0, 0, 0, 0xf0, 0x3f, 0, 0, 0, 0, 0, 0, 0, 0x40, 0, 0, 0,
                0, 0, 0, 0x08, 0x40
            ]
        );
    }

    #[test]
    fn encoded_len_matches_the_encoder_at_every_length_boundary() {
        let blob = vec![7u8; 70_000];
        for n in [
            0, 1, 2, 3, 4, 8, 15, 16, 17, 31, 32, 255, 256, 65535, 65536, 70_000,
        ] {
            let bytes = &blob[..n];
            let text = core::str::from_utf8(bytes).unwrap();
            enc(Value::Bytes(bytes));
            enc(Value::Text(text));
            if n % 8 == 0 {
                enc(Value::F64s(F64s::from_le_bytes(bytes).unwrap()));
            }
        }
        for v in [
            i64::MIN,
            -2147483649,
            -2147483648,
            -32769,
            -32768,
            -129,
            -128,
            -33,
            -32,
            0,
            127,
            128,
            255,
            256,
            65535,
            65536,
            4294967295,
            4294967296,
            i64::MAX,
        ] {
            let bytes = enc(Value::I64(v));
            assert_eq!(
                Value::decode(&bytes, 0).unwrap(),
                (Value::I64(v), bytes.len())
            );
        }
    }

    #[test]
    fn decoding_rejects_what_modbot_does_not_carry() {
        assert_eq!(
            Value::decode(&[0xc0], 4),
            Err(ValueError::Unsupported {
                offset: 4,
                marker: 0xc0
            })
        );
        assert_eq!(
            Value::decode(&[0xd4, 0x02, 0x00], 0),
            Err(ValueError::UnknownExt { offset: 0, ty: 2 })
        );
        assert_eq!(
            Value::decode(&[0xd6, 0x01, 0, 0, 0, 0], 0),
            Err(ValueError::BadF64ArrayLength { offset: 0, len: 4 })
        );
        assert_eq!(
            Value::decode(&[0xcf, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff], 0),
            Err(ValueError::IntegerOutOfRange { offset: 0 })
        );
        assert_eq!(
            Value::decode(&[0xa2, 0xff, 0xfe], 0),
            Err(ValueError::BadUtf8 { offset: 0 })
        );
        assert!(matches!(
            Value::decode(&[0xdb, 0xff, 0xff, 0xff, 0xff], 0),
            Err(ValueError::Truncated { .. })
        ));
    }

    #[test]
    fn command_line_arguments_parse_to_the_expected_kinds() {
        assert_eq!(OwnedValue::parse("10").unwrap(), OwnedValue::I64(10));
        assert_eq!(OwnedValue::parse("0.61").unwrap(), OwnedValue::F64(0.61));
        assert_eq!(OwnedValue::parse("true").unwrap(), OwnedValue::Bool(true));
        assert_eq!(
            OwnedValue::parse("[1, 2.5]").unwrap(),
            OwnedValue::F64s(vec![1.0, 2.5])
        );
        assert_eq!(
            OwnedValue::parse("0x0a0b").unwrap(),
            OwnedValue::Bytes(vec![10, 11])
        );
        assert_eq!(
            OwnedValue::parse("text:true").unwrap(),
            OwnedValue::Text("true".into())
        );
        assert_eq!(OwnedValue::parse("f64:3").unwrap(), OwnedValue::F64(3.0));
        assert_eq!(
            OwnedValue::parse("north").unwrap(),
            OwnedValue::Text("north".into())
        );
        assert!(OwnedValue::parse("i64:x").is_err());
    }
}
