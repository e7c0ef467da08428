//! A call through Zenoh to a module of another domain: one query to that domain's bridge,
//! answered once. Zenoh carries it reliably over its link (TCP); what can happen is that no
//! answer comes — the link is down, or went down while the call was under way — and then the
//! caller hears why, never nothing.

use std::time::Duration;

use modbot_ipc_schema::{FrameKind, NakCode, Value};
use zenoh::query::ConsolidationMode;
use zenoh::{Session, Wait};

use super::link::Link;
use super::wire;

/// An answer, or the NAK a bridge gives when none came: its kind and payload, as the answer
/// frame carries them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Answer {
    pub kind: FrameKind,
    pub payload: Vec<u8>,
}

impl Answer {
    /// A NAK of `code` saying `detail`.
    pub fn nak(code: NakCode, detail: &str) -> Answer {
        let mut payload = Vec::new();
        // A text value always encodes.
        let _ = Value::Text(detail).encode_to_vec(&mut payload);
        Answer {
            kind: FrameKind::Nak { code },
            payload,
        }
    }
}

/// Calls `method` of the module at `key` with the encoded `args`, waiting at most `timeout`
/// for the answer. `link` says how the link to the remote domain stands, for the NAK when no
/// answer comes.
pub fn call(
    session: &Session,
    key: &str,
    method: &str,
    args: &[u8],
    timeout: Duration,
    link: &Link,
) -> Answer {
    let mut request = Vec::with_capacity(2 + method.len() + args.len());
    if let Err(e) = wire::put_call(method, args, &mut request) {
        return Answer::nak(NakCode::BAD_ARGUMENTS, &e.to_string());
    }
    let replies = match session
        .get(key)
        .payload(request)
        .consolidation(ConsolidationMode::None)
        .timeout(timeout)
        .wait()
    {
        Ok(r) => r,
        Err(e) => return Answer::nak(NakCode::UNREACHABLE, &format!("{}: {e}", link.state())),
    };
    match replies.recv() {
        Ok(reply) => match reply.into_result() {
            Ok(sample) => match wire::answer(&sample.payload().to_bytes()) {
                Ok((kind, payload)) => Answer {
                    kind,
                    payload: payload.to_vec(),
                },
                Err(e) => Answer::nak(
                    NakCode::FAILED,
                    &format!("malformed answer from the remote bridge: {e}"),
                ),
            },
            Err(e) if e.payload().to_bytes().as_ref() == b"Timeout" => Answer::nak(
                NakCode::UNREACHABLE,
                &format!(
                    "no answer through the link within {} ms ({}): it may have run there",
                    timeout.as_millis(),
                    link.state()
                ),
            ),
            Err(e) => Answer::nak(
                NakCode::FAILED,
                &format!(
                    "the remote bridge failed: {}",
                    String::from_utf8_lossy(&e.payload().to_bytes())
                ),
            ),
        },
        // The query ended without a reply: no bridge of that domain is reachable, or the link
        // went down while the call was under way.
        Err(_) => Answer::nak(
            NakCode::UNREACHABLE,
            &format!(
                "{} (no answer came: if the call reached it, it may have run there)",
                link.state()
            ),
        ),
    }
}
