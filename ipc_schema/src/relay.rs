//! Calls relayed by the supervisor, for tools that hold no module address (every address of
//! the domain is taken): the tool sends a request on the domain's `relay` request-response
//! service, the supervisor makes the call as its own and sends back the answer.
//!
//! ```text
//! request                              response
//! 0     1   module name length n (1..=48)     0   1   status: 0 answered, 1 failed
//! 1     n   module name                       1   ..  status 0: the answer's values
//! 1+n   1   method name length m (1..=48)             (MessagePack, as in a REPLY);
//! 2+n   m   method name                               status 1: why, UTF-8 text
//! 2+n+m 4   timeout, ms, u32 LE
//! 6+n+m ..  the arguments (MessagePack values, as in an EXEC)
//! ```

use thiserror::Error;

use crate::args::{ArgError, Args};
use crate::names::is_module_name;
use crate::value::{self, Value, Values};

/// The longest module or method name.
pub const NAME_MAX: usize = crate::names::MODULE_NAME_MAX;

/// A request, read in place.
#[derive(Debug, Clone, Copy)]
pub struct Request<'a> {
    pub module: &'a str,
    pub method: &'a str,
    pub timeout_ms: u32,
    /// The encoded arguments.
    pub args: &'a [u8],
}

/// An answer, read in place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Response<'a> {
    /// The call was answered: its values, encoded.
    Answered(&'a [u8]),
    /// The call failed: why.
    Failed(&'a str),
}

/// Why bytes are not a relay request or response.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RelayError {
    #[error("relay message truncated: {0}")]
    Truncated(&'static str),
    #[error("relay {what} name is not 1..={NAME_MAX} bytes of a-z A-Z 0-9 _ -")]
    BadName { what: &'static str },
    #[error("relay response status {0} is neither 0 (answered) nor 1 (failed)")]
    Status(u8),
    #[error("relay response: the reason is not UTF-8")]
    Text,
    #[error("relay values: {0}")]
    Values(#[from] ArgError),
}

fn name<'a>(bytes: &'a [u8], what: &'static str) -> Result<(&'a str, &'a [u8]), RelayError> {
    let (&len, rest) = bytes.split_first().ok_or(RelayError::Truncated(what))?;
    let len = usize::from(len);
    if rest.len() < len {
        return Err(RelayError::Truncated(what));
    }
    let (text, rest) = rest.split_at(len);
    if !is_module_name(text) {
        return Err(RelayError::BadName { what });
    }
    // Checked above: ASCII.
    Ok((core::str::from_utf8(text).unwrap_or_default(), rest))
}

impl<'a> Request<'a> {
    /// Reads a request; the arguments are checked to be well-formed values.
    pub fn parse(bytes: &'a [u8]) -> Result<Request<'a>, RelayError> {
        let (module, rest) = name(bytes, "module")?;
        let (method, rest) = name(rest, "method")?;
        if rest.len() < 4 {
            return Err(RelayError::Truncated("timeout"));
        }
        let (timeout, args) = rest.split_at(4);
        let timeout_ms = u32::from_le_bytes([timeout[0], timeout[1], timeout[2], timeout[3]]);
        Args::decode(Values::new(args, 0))?;
        Ok(Request {
            module,
            method,
            timeout_ms,
            args,
        })
    }

    /// The arguments, decoded.
    pub fn values(&self) -> Result<Args<'a>, RelayError> {
        Ok(Args::decode(Values::new(self.args, 0))?)
    }
}

/// Encodes a request.
pub fn encode_request(
    module: &str,
    method: &str,
    timeout_ms: u32,
    args: &[Value<'_>],
) -> Result<Vec<u8>, RelayError> {
    let mut out = Vec::with_capacity(6 + module.len() + method.len() + value::encoded_len(args));
    for (text, what) in [(module, "module"), (method, "method")] {
        if !is_module_name(text.as_bytes()) {
            return Err(RelayError::BadName { what });
        }
        out.push(text.len() as u8);
        out.extend_from_slice(text.as_bytes());
    }
    out.extend_from_slice(&timeout_ms.to_le_bytes());
    for v in args {
        v.encode_to_vec(&mut out).map_err(ArgError::from)?;
    }
    Request::parse(&out)?;
    Ok(out)
}

impl<'a> Response<'a> {
    pub fn parse(bytes: &'a [u8]) -> Result<Response<'a>, RelayError> {
        let (&status, rest) = bytes.split_first().ok_or(RelayError::Truncated("status"))?;
        match status {
            0 => {
                Args::decode(Values::new(rest, 1))?;
                Ok(Response::Answered(rest))
            }
            1 => Ok(Response::Failed(
                core::str::from_utf8(rest).map_err(|_| RelayError::Text)?,
            )),
            other => Err(RelayError::Status(other)),
        }
    }
}

/// Encodes the answer of a relayed call.
pub fn encode_answered(values: &[Value<'_>]) -> Result<Vec<u8>, RelayError> {
    let mut out = vec![0u8];
    for v in values {
        v.encode_to_vec(&mut out).map_err(ArgError::from)?;
    }
    Response::parse(&out)?;
    Ok(out)
}

/// Encodes why a relayed call failed.
pub fn encode_failed(why: &str) -> Vec<u8> {
    let mut out = vec![1u8];
    out.extend_from_slice(why.as_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    #[test]
    fn a_request_has_the_documented_layout() {
        let bytes = encode_request("nav", "go", 500, &[Value::I64(1)]).unwrap();
        assert_eq!(
            hex::encode(&bytes),
            "036e6176 02676f f4010000 01".replace(' ', "")
        );
        let r = Request::parse(&bytes).unwrap();
        assert_eq!((r.module, r.method, r.timeout_ms), ("nav", "go", 500));
        assert_eq!(r.values().unwrap().as_slice(), &[Value::I64(1)]);
    }

    #[test]
    fn responses_say_answered_or_failed() {
        let ok = encode_answered(&[Value::Bool(true)]).unwrap();
        assert_eq!(hex::encode(&ok), "00c3");
        assert_eq!(Response::parse(&ok).unwrap(), Response::Answered(&[0xc3]));
        let failed = encode_failed("no");
        assert_eq!(hex::encode(&failed), "016e6f");
        assert_eq!(Response::parse(&failed).unwrap(), Response::Failed("no"));
    }

    #[test]
    fn malformed_relay_messages_are_refused_with_the_reason() {
        assert_eq!(
            Request::parse(&[]).unwrap_err(),
            RelayError::Truncated("module")
        );
        assert_eq!(
            Request::parse(&[5, b'a']).unwrap_err(),
            RelayError::Truncated("module")
        );
        assert!(matches!(
            Request::parse(&[1, b'/', 1, b'a', 0, 0, 0, 0]),
            Err(RelayError::BadName { what: "module" })
        ));
        assert_eq!(
            Request::parse(&[1, b'a', 1, b'b', 0, 0]).unwrap_err(),
            RelayError::Truncated("timeout")
        );
        assert!(matches!(
            Request::parse(&[1, b'a', 1, b'b', 0, 0, 0, 0, 0xc1]),
            Err(RelayError::Values(_))
        ));
        assert_eq!(Response::parse(&[7]).unwrap_err(), RelayError::Status(7));
        assert_eq!(Response::parse(&[1, 0xff]).unwrap_err(), RelayError::Text);
        assert!(encode_request("", "m", 1, &[]).is_err());
    }
}
