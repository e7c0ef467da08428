//! A live upgrade: a new process takes a running module over — its address, its blackboard,
//! its own state and the calls on their way to it — while the robot runs (`modbot upgrade`).
//!
//! The supervisor makes a directory for the handover and starts the new program with
//! [`UPGRADE_DIR`](crate::transport::launch::UPGRADE_DIR) naming it. The two processes and the
//! supervisor meet through files in it, each written whole (written aside, then renamed):
//!
//! 1. The new process opens its endpoint in **standby** (every service but its inbox and
//!    buses) and writes [`READY`]: its pid and its method names in id order.
//! 2. The supervisor calls the old process's `upgrade_out(dir, methods, force)`. A method table
//!    other than its own is refused (NAK, the difference named) and it serves on. Else, from
//!    that frame on, it **hands over**: it serves no request and no report — it keeps each one
//!    it takes, unserved, for the new process — runs no task, and still takes the answers to
//!    its own calls.
//! 3. The supervisor writes [`SUBSCRIBE`]; the new process subscribes to the inbox (which has
//!    room for two subscribers) and writes [`SUBSCRIBED`]. From then on it receives every frame
//!    and keeps them, unserved. The supervisor publishes the directory with the new pid and the
//!    module's upgrade count one higher: callers see an upgrade, not a death (their calls wait
//!    on, nothing is sent again).
//! 4. Once it sees [`SUBSCRIBED`] and its own calls are answered (or 2 s passed), the old
//!    process takes what is left in its inbox (as in 2), unsubscribes, writes [`STATE`] —
//!    blackboard values, its `on_upgrade_out` bytes with their version, its record of served
//!    requests, the frames it kept — and ends.
//! 5. The new process reads [`STATE`], takes the blackboard's values over, gives the bytes to
//!    its `on_upgrade_in`, serves the frames the old one kept (then [`merge`]: those it also
//!    received itself, once) and then every frame it kept, and runs on.
//!
//! So every request is executed exactly once and answered once: before the handover by the old
//! process (a retransmission of it is answered from the record it hands over), after it by the
//! new one; a caller sees a delay, not an error. The supervisor writes [`ABORT`] when the new
//! process fails before step 4; the old one then serves what it kept and serves on, as
//! before.

use std::path::{Path, PathBuf};

use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::{OwnedValue, Value};

/// Written by the new process in standby: `pid\nmethod,method,…\n`.
pub const READY: &str = "ready";
/// Written by the supervisor once the old process hands over: subscribe now.
pub const SUBSCRIBE: &str = "subscribe";
/// Written by the new process once it receives the module's frames.
pub const SUBSCRIBED: &str = "subscribed";
/// Written by the old process: its state ([`Handover`]).
pub const STATE: &str = "state";
/// Written by the supervisor: the upgrade is called off.
pub const ABORT: &str = "abort";
/// Written by the new process of a time grid's host once it has taken the host's components
/// over (the tick it serves from): the supervisor hands the module over only then.
pub const GRID: &str = "grid";

/// The longest a handover step waits for the other side before it gives up (the old process
/// serves on; the new one ends with an error).
pub const STEP_LIMIT_NS: u64 = 30_000_000_000;

/// How long the old process waits for the answers to its own calls before it hands over.
pub const CALLS_LIMIT_NS: u64 = 2_000_000_000;

/// What the old process hands to the new one.
#[derive(Debug, Clone, PartialEq)]
pub struct Handover {
    /// The old process's pid.
    pub from_pid: u32,
    /// When it stopped serving (`upgrade_out`), on CLOCK_MONOTONIC: the new process's first
    /// frame served after it is the handover's gap.
    pub stopped_ns: u64,
    /// Whether the operator left the module active (`deactivate`d, it stays so).
    pub active: bool,
    /// Every blackboard item's value, by name.
    pub items: Vec<(String, OwnedValue)>,
    /// What its `on_upgrade_out` returned, with the version it declared.
    pub state: Option<(u32, Vec<u8>)>,
    /// Its record of served requests ([`crate::served::ServedLog::encode`]).
    pub served: Vec<u8>,
    /// The requests and reports it took while handing over, unserved.
    pub frames: Vec<Vec<u8>>,
}

/// The magic and version a state file starts with.
const MAGIC: &str = "modbot-handover";
const VERSION: i64 = 1;

/// Why a state file cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum HandoverError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("the handover state is not readable: {0}")]
    Format(String),
}

impl Handover {
    /// The state as bytes: a sequence of values (the RVMF* value encoding): magic, version,
    /// pid, stop time, active, item count and (name, value) pairs, whether hook state follows and if so its
    /// version and bytes, the served record's bytes, frame count and frames.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let mut put = |v: Value<'_>| {
            v.encode_to_vec(&mut out)
                .expect("a value of the handover encodes");
        };
        put(Value::Text(MAGIC));
        put(Value::I64(VERSION));
        put(Value::I64(i64::from(self.from_pid)));
        put(Value::I64(self.stopped_ns as i64));
        put(Value::Bool(self.active));
        put(Value::I64(self.items.len() as i64));
        for (name, value) in &self.items {
            put(Value::Text(name));
            put(value.as_value());
        }
        put(Value::Bool(self.state.is_some()));
        if let Some((version, bytes)) = &self.state {
            put(Value::I64(i64::from(*version)));
            put(Value::Bytes(bytes));
        }
        put(Value::Bytes(&self.served));
        put(Value::I64(self.frames.len() as i64));
        for f in &self.frames {
            put(Value::Bytes(f));
        }
        out
    }

    pub fn decode(bytes: &[u8]) -> Result<Handover, HandoverError> {
        let mut values = Values::new(bytes, 0);
        let mut next = |what: &str| -> Result<Value<'_>, HandoverError> {
            match values.next() {
                Some(Ok(v)) => Ok(v),
                Some(Err(e)) => Err(HandoverError::Format(format!("{what}: {e}"))),
                None => Err(HandoverError::Format(format!("{what}: missing"))),
            }
        };
        let bad = |what: &str| HandoverError::Format(format!("{what}: wrong kind"));
        if next("magic")? != Value::Text(MAGIC) {
            return Err(HandoverError::Format("not a handover state".into()));
        }
        let version = int(next("version")?).ok_or_else(|| bad("version"))?;
        if version != VERSION {
            return Err(HandoverError::Format(format!(
                "format version {version}, this build reads {VERSION}"
            )));
        }
        let count = |v: Value<'_>, what: &str| {
            int(v)
                .and_then(|n| usize::try_from(n).ok())
                .ok_or_else(|| bad(what))
        };
        let from_pid = count(next("pid")?, "pid")? as u32;
        let stopped_ns = count(next("stop time")?, "stop time")? as u64;
        let Value::Bool(active) = next("active")? else {
            return Err(bad("active"));
        };
        let n = count(next("item count")?, "item count")?;
        let mut items = Vec::with_capacity(n.min(4096));
        for _ in 0..n {
            let Value::Text(name) = next("item name")? else {
                return Err(bad("item name"));
            };
            let name = name.to_owned();
            items.push((name, next("item value")?.to_owned_value()));
        }
        let state = match next("hook state")? {
            Value::Bool(false) => None,
            Value::Bool(true) => {
                let version = count(next("hook version")?, "hook version")? as u32;
                let Value::Bytes(b) = next("hook bytes")? else {
                    return Err(bad("hook bytes"));
                };
                Some((version, b.to_vec()))
            }
            _ => return Err(bad("hook state")),
        };
        let Value::Bytes(served) = next("served record")? else {
            return Err(bad("served record"));
        };
        let served = served.to_vec();
        let n = count(next("frame count")?, "frame count")?;
        let mut frames = Vec::with_capacity(n.min(4096));
        for _ in 0..n {
            let Value::Bytes(f) = next("frame")? else {
                return Err(bad("frame"));
            };
            frames.push(f.to_vec());
        }
        Ok(Handover {
            from_pid,
            stopped_ns,
            active,
            items,
            state,
            served,
            frames,
        })
    }
}

fn int(v: Value<'_>) -> Option<i64> {
    match v {
        Value::I64(n) => Some(n),
        _ => None,
    }
}

/// Writes `bytes` to `dir/name` whole: aside first, then renamed, so a reader never sees a
/// part of it.
pub fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), HandoverError> {
    let aside = dir.join(format!(".{name}.{}", std::process::id()));
    let path = dir.join(name);
    std::fs::write(&aside, bytes)
        .and_then(|()| std::fs::rename(&aside, &path))
        .map_err(|source| HandoverError::Io { path, source })
}

/// Whether `dir/name` was written.
pub fn exists(dir: &Path, name: &str) -> bool {
    dir.join(name).exists()
}

/// Reads `dir/name`.
pub fn read_file(dir: &Path, name: &str) -> Result<Vec<u8>, HandoverError> {
    let path = dir.join(name);
    std::fs::read(&path).map_err(|source| HandoverError::Io { path, source })
}

/// The old process's side while it hands over (set by `upgrade_out`).
#[derive(Debug)]
pub(crate) struct Outgoing {
    pub(crate) dir: PathBuf,
    /// When it began (the module's clock).
    pub(crate) began_ns: u64,
    /// When it began, on CLOCK_MONOTONIC (see [`Handover::stopped_ns`]).
    pub(crate) began_mono_ns: u64,
    /// When it saw [`SUBSCRIBED`].
    pub(crate) subscribed_ns: Option<u64>,
    /// Requests and reports taken meanwhile, unserved, for the new process.
    pub(crate) kept: Vec<Vec<u8>>,
}

/// What the old process does with a frame while it hands over.
pub(crate) enum Route {
    /// Serve it as usual (an answer to one of its own calls, an announcement, garbage).
    Serve,
    /// Kept for the new process (a request, a report): done with.
    Done,
}

/// Decides what happens to `bytes` while handing over, and keeps it for the new process.
pub(crate) fn route(out: &mut Outgoing, bytes: &[u8]) -> Route {
    use modbot_ipc_schema::{sysmethod, Frame, FrameKind};
    let Ok(frame) = Frame::decode(bytes) else {
        return Route::Serve;
    };
    match frame.kind() {
        FrameKind::Report { topic } if topic == sysmethod::ANNOUNCE_TOPIC => Route::Serve,
        FrameKind::Exec { .. } | FrameKind::Retry { .. } | FrameKind::Report { .. } => {
            out.kept.push(bytes.to_vec());
            Route::Done
        }
        FrameKind::Reply | FrameKind::Ack | FrameKind::Nak { .. } => Route::Serve,
    }
}

/// The frames the new process serves, in order: the ones the old process kept, then its own
/// except those it received too. Per sender, frames come in the order sent; the old process's
/// last frames from a sender may be the first ones the new process received from it (both
/// were subscribed): that overlap, the longest run that ends the one and begins the other, is
/// served once.
pub fn merge(kept: Vec<Vec<u8>>, received: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
    let src = |f: &[u8]| modbot_ipc_schema::Frame::decode(f).ok().map(|f| f.src());
    let mut skip = vec![false; received.len()];
    let mut senders: Vec<_> = kept.iter().filter_map(|f| src(f)).collect();
    senders.sort_unstable();
    senders.dedup();
    for s in senders {
        let old: Vec<&Vec<u8>> = kept.iter().filter(|f| src(f) == Some(s)).collect();
        let new: Vec<usize> = (0..received.len())
            .filter(|&i| src(&received[i]) == Some(s))
            .collect();
        let longest = (1..=old.len().min(new.len()))
            .rev()
            .find(|&j| (0..j).all(|k| *old[old.len() - j + k] == received[new[k]]))
            .unwrap_or(0);
        for &i in &new[..longest] {
            skip[i] = true;
        }
    }
    kept.into_iter()
        .chain(
            received
                .into_iter()
                .zip(skip)
                .filter(|(_, skip)| !skip)
                .map(|(f, _)| f),
        )
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_ipc_schema::{Addr, FrameKind, FrameSpec, Seq};

    fn report(src: u8, seq: u8, n: i64) -> Vec<u8> {
        let spec = FrameSpec {
            dst: Addr(9),
            src: Addr(src),
            seq: Seq::new(seq).unwrap(),
            kind: FrameKind::Report { topic: 1 },
        };
        let mut payload = Vec::new();
        Value::I64(n).encode_to_vec(&mut payload).unwrap();
        let mut out = vec![0; spec.encoded_len(payload.len())];
        spec.encode(&payload, &mut out).unwrap();
        out
    }

    #[test]
    fn a_handover_state_reads_back_as_written() {
        let sut = Handover {
            from_pid: 4242,
            stopped_ns: 123_456_789,
            active: false,
            items: vec![
                ("total".into(), OwnedValue::F64(3.5)),
                ("mode".into(), OwnedValue::Text("patrol".into())),
            ],
            state: Some((3, vec![1, 2, 3])),
            served: vec![9; 20],
            frames: vec![report(3, 1, 7)],
        };
        assert_eq!(Handover::decode(&sut.encode()).unwrap(), sut);
        let bytes = sut.encode();
        let refused = Handover::decode(&bytes[..bytes.len() - 2]).unwrap_err();
        assert!(refused.to_string().contains("frame"), "{refused}");
        assert!(Handover::decode(b"\xa3abc").is_err());
    }

    #[test]
    fn reports_both_processes_took_are_served_once() {
        // Sender 3: the old process took 1, 2, 3; the new one received 2, 3, 4.
        // Sender 5: only the new one received its report; sender 6 only the old one.
        let kept = vec![
            report(3, 1, 1),
            report(6, 0, 60),
            report(3, 2, 2),
            report(3, 3, 3),
        ];
        let received = vec![
            report(3, 2, 2),
            report(5, 0, 50),
            report(3, 3, 3),
            report(3, 4, 4),
        ];
        let merged = merge(kept.clone(), received);
        let expected = vec![
            report(3, 1, 1),
            report(6, 0, 60),
            report(3, 2, 2),
            report(3, 3, 3),
            report(5, 0, 50),
            report(3, 4, 4),
        ];
        assert_eq!(merged, expected);
        // Nothing in common: everything is served.
        assert_eq!(merge(kept.clone(), vec![]).len(), 4);
        assert_eq!(merge(vec![], kept).len(), 4);
    }
}
