//! What crosses the network between two bridges: a call (the method by name, the arguments as
//! the caller encoded them), its answer (the kind of the answer frame, its NAK code, its
//! payload) and a report (the topic, the values). The values stay the MessagePack bytes of the
//! frames: a bridge never decodes what it forwards.
//!
//! ```text
//! call    [1 = version][n][method name, n bytes][arguments: the EXEC body after the method]
//! answer  [kind: 0 ACK, 1 REPLY, 2 NAK][NAK code, 0 otherwise][payload: values]
//! report  [topic][values]
//! ```

use modbot_ipc_schema::{FrameKind, NakCode};

/// The version byte of a call.
pub const VERSION: u8 = 1;

/// A call or an answer that cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WireError {
    #[error("empty message")]
    Empty,
    #[error("call of version {0}, this bridge speaks version {VERSION}")]
    Version(u8),
    #[error("call cut short: {0}")]
    Short(&'static str),
    #[error("method name is not UTF-8")]
    Name,
    #[error("answer of unknown kind {0}")]
    Kind(u8),
    #[error("method name of {0} bytes (at most 255)")]
    NameTooLong(usize),
}

/// A call as read from the network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Call<'a> {
    pub method: &'a str,
    pub args: &'a [u8],
}

/// Writes a call of `method` with the encoded `args` into `out` (cleared first).
pub fn put_call(method: &str, args: &[u8], out: &mut Vec<u8>) -> Result<(), WireError> {
    let n = u8::try_from(method.len()).map_err(|_| WireError::NameTooLong(method.len()))?;
    out.clear();
    out.extend_from_slice(&[VERSION, n]);
    out.extend_from_slice(method.as_bytes());
    out.extend_from_slice(args);
    Ok(())
}

/// Reads a call.
pub fn call(bytes: &[u8]) -> Result<Call<'_>, WireError> {
    let (&version, rest) = bytes.split_first().ok_or(WireError::Empty)?;
    if version != VERSION {
        return Err(WireError::Version(version));
    }
    let (&n, rest) = rest
        .split_first()
        .ok_or(WireError::Short("no name length"))?;
    let n = usize::from(n);
    if rest.len() < n {
        return Err(WireError::Short("method name"));
    }
    let method = std::str::from_utf8(&rest[..n]).map_err(|_| WireError::Name)?;
    Ok(Call {
        method,
        args: &rest[n..],
    })
}

/// An answer's kind as it goes over the network: the answer frame's kind, `None` for a
/// kind that is no answer.
fn kind_byte(kind: FrameKind) -> Option<[u8; 2]> {
    match kind {
        FrameKind::Ack => Some([0, 0]),
        FrameKind::Reply => Some([1, 0]),
        FrameKind::Nak { code } => Some([2, code.0]),
        _ => None,
    }
}

/// Writes the answer of `kind` with `payload` into `out` (cleared first); `kind` must be an
/// answer (ACK, REPLY or NAK).
pub fn put_answer(kind: FrameKind, payload: &[u8], out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&kind_byte(kind).unwrap_or([2, NakCode::FAILED.0]));
    out.extend_from_slice(payload);
}

/// Reads an answer: the answer frame's kind and its payload.
pub fn answer(bytes: &[u8]) -> Result<(FrameKind, &[u8]), WireError> {
    let [kind, code, payload @ ..] = bytes else {
        return Err(if bytes.is_empty() {
            WireError::Empty
        } else {
            WireError::Short("answer")
        });
    };
    let kind = match kind {
        0 => FrameKind::Ack,
        1 => FrameKind::Reply,
        2 => FrameKind::Nak {
            code: NakCode(*code),
        },
        k => return Err(WireError::Kind(*k)),
    };
    Ok((kind, payload))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_call_is_the_version_the_name_and_the_arguments_byte_for_byte() {
        let mut out = Vec::new();
        put_call("patrol", &[0x01], &mut out).unwrap();
        assert_eq!(out, [1, 6, b'p', b'a', b't', b'r', b'o', b'l', 0x01]);
        assert_eq!(
            call(&out).unwrap(),
            Call {
                method: "patrol",
                args: &[0x01]
            }
        );
    }

    #[test]
    fn an_answer_is_its_kind_its_code_and_its_payload() {
        let mut out = Vec::new();
        put_answer(
            FrameKind::Nak {
                code: NakCode::NOT_READY,
            },
            &[0xa1, b'x'],
            &mut out,
        );
        assert_eq!(out, [2, 8, 0xa1, b'x']);
        assert_eq!(
            answer(&out).unwrap(),
            (
                FrameKind::Nak {
                    code: NakCode::NOT_READY
                },
                &[0xa1, b'x'][..]
            )
        );
        put_answer(FrameKind::Ack, &[], &mut out);
        assert_eq!(out, [0, 0]);
        assert_eq!(answer(&out).unwrap(), (FrameKind::Ack, &[][..]));
    }

    #[test]
    fn malformed_calls_and_answers_are_refused_with_what_is_wrong() {
        assert_eq!(call(&[]), Err(WireError::Empty));
        assert_eq!(call(&[2, 0]), Err(WireError::Version(2)));
        assert_eq!(call(&[1]), Err(WireError::Short("no name length")));
        assert_eq!(call(&[1, 5, b'a']), Err(WireError::Short("method name")));
        assert_eq!(call(&[1, 1, 0xff]), Err(WireError::Name));
        assert_eq!(answer(&[9, 0]), Err(WireError::Kind(9)));
        assert_eq!(answer(&[1]), Err(WireError::Short("answer")));
        assert_eq!(
            put_call(&"m".repeat(256), &[], &mut Vec::new()),
            Err(WireError::NameTooLong(256))
        );
    }
}
