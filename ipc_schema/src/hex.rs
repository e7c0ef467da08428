//! Lowercase hex, for the command line and the golden vectors.

use thiserror::Error;

/// A hex string that is not an even number of hex digits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum HexError {
    #[error("hex text has an odd number of digits ({0})")]
    OddLength(usize),
    #[error("'{ch}' at position {pos} is not a hex digit")]
    BadDigit { pos: usize, ch: char },
}

/// Encodes bytes as lowercase hex.
pub fn encode(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut out = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        out.push(DIGITS[usize::from(b >> 4)] as char);
        out.push(DIGITS[usize::from(b & 0x0f)] as char);
    }
    out
}

/// Decodes hex (either case); spaces and `_` between digit pairs are ignored.
pub fn decode(text: &str) -> Result<Vec<u8>, HexError> {
    let digits: Vec<(usize, char)> = text
        .char_indices()
        .filter(|(_, c)| !c.is_whitespace() && *c != '_')
        .collect();
    if !digits.len().is_multiple_of(2) {
        return Err(HexError::OddLength(digits.len()));
    }
    let nibble = |(pos, ch): (usize, char)| {
        ch.to_digit(16)
            .map(|d| d as u8)
            .ok_or(HexError::BadDigit { pos, ch })
    };
    digits
        .chunks_exact(2)
        .map(|pair| Ok(nibble(pair[0])? << 4 | nibble(pair[1])?))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trips_and_rejects_bad_digits() {
        assert_eq!(encode(&[0x00, 0xab, 0x7f]), "00ab7f");
        assert_eq!(decode("00 AB_7f").unwrap(), vec![0x00, 0xab, 0x7f]);
        assert_eq!(decode("abc"), Err(HexError::OddLength(3)));
        assert_eq!(decode("zz"), Err(HexError::BadDigit { pos: 0, ch: 'z' }));
    }
}
