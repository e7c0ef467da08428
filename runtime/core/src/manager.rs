//! The message manager: serves one incoming frame.
//!
//! EXEC and RETRY go to the module's method table (or to the system methods every module
//! answers) and are answered with REPLY, ACK or NAK; a RETRY of a request already served is
//! answered from the [`crate::served`] record instead of executing twice. REPLY, ACK and NAK
//! complete calls in the method queue; REPORT goes to the module's report hook.
//!
//! While the operator has deactivated the module, its own methods are answered with NAK
//! not-ready; the system methods are always served. Every frame received is counted, and
//! every answer to a call of the module's code records the call's latency ([`crate::stats`]).

use modbot_ipc_schema::{sysmethod, Args, Frame, FrameKind, FrameSpec, NakCode, Value};

use crate::calls::Purpose;
use crate::ctx::Ctx;
use crate::error::{CallError, MethodError};
use crate::hooks::{Definition, Reply, Report, Waiter};
use crate::served::{Replay, KEPT_ANSWER};
use crate::transport::Dest;

/// Serves one frame.
pub(crate) fn dispatch<S>(
    def: &Definition<S>,
    state: &mut S,
    ctx: &mut Ctx,
    reply: &mut Reply,
    bytes: &[u8],
    waiter: &mut Waiter<'_>,
) {
    ctx.stats.frames_received += 1;
    let frame = match Frame::decode(bytes) {
        Ok(f) => f,
        Err(e) => {
            ctx.serving.rejected += 1;
            tracing::debug!("dropped a malformed frame of {} bytes: {e}", bytes.len());
            return;
        }
    };
    if frame.dst() != ctx.addr && !frame.dst().is_broadcast() {
        ctx.serving.rejected += 1;
        tracing::debug!(
            "dropped a frame for {} that reached {}",
            frame.dst(),
            ctx.addr
        );
        return;
    }
    let src = frame.src();
    if src == ctx.addr && frame.dst().is_broadcast() {
        return; // our own broadcast or multicast, back from the shared bus
    }
    ctx.serving.caller = src;
    match frame.kind() {
        FrameKind::Exec { method } | FrameKind::Retry { method } => {
            serve_request(def, state, ctx, reply, &frame, method);
        }
        FrameKind::Reply | FrameKind::Ack | FrameKind::Nak { .. } => {
            let now = ctx.now_ns();
            let Some(answered) = ctx.out.calls.answer(src, frame.seq(), now) else {
                ctx.out.stale += 1;
                return;
            };
            let (handle, purpose) = (answered.handle, answered.purpose);
            // The peer's name only when an error needs it: an answer allocates nothing.
            let module = |ctx: &Ctx| {
                ctx.book
                    .get(src)
                    .map(|e| e.name.clone())
                    .unwrap_or_else(|| format!("module {src}"))
            };
            // Decoded in place: `Args` is a few hundred bytes, not moved through results.
            let mut args = Args::EMPTY;
            let result: Result<&Args<'_>, CallError> = match frame.kind() {
                FrameKind::Nak { code } => {
                    let detail = match frame.values().next() {
                        Some(Ok(Value::Text(t))) => t.to_owned(),
                        _ => String::new(),
                    };
                    Err(CallError::Nak {
                        module: module(ctx),
                        code,
                        detail,
                    })
                }
                _ => match args.decode_from(frame.values()) {
                    Ok(()) => Ok(&args),
                    Err(e) => Err(CallError::BadAnswer {
                        module: module(ctx),
                        detail: e.to_string(),
                    }),
                },
            };
            match purpose {
                Purpose::Describe => {
                    ctx.out.describing[usize::from(src.0)] = false;
                    match &result {
                        Ok(args) => {
                            if let Err(e) = ctx.book.learn(src, args) {
                                tracing::warn!("bad describe answer from {src}: {e}");
                            }
                            ctx.flush_pending();
                        }
                        // A refusal is an answer: the calls waiting for the table fail
                        // with it (a bridge's module whose link is down says why) rather
                        // than describe again and again until their deadline.
                        Err(e @ CallError::Nak { .. }) => ctx.fail_pending(src, e),
                        Err(e) => tracing::warn!("describe of {src} failed: {e}"),
                    }
                }
                Purpose::User => {
                    if let Some(sent) = answered.first_sent_ns {
                        let latency = now.saturating_sub(sent);
                        ctx.stats.latency.record(latency);
                    }
                    match &result {
                        Ok(_) => ctx.stats.answered += 1,
                        Err(e) => {
                            tracing::debug!("a call to {src} failed: {e}");
                            ctx.stats.failed += 1
                        }
                    }
                    let result = result.as_ref().map(|a| *a);
                    match waiter {
                        Some((h, f)) if *h == handle => f(result),
                        _ => match def.on_done {
                            Some(done) => done(state, ctx, handle, result),
                            None => {
                                if let Err(e) = result {
                                    tracing::warn!("call failed: {e}");
                                }
                            }
                        },
                    }
                }
            }
        }
        FrameKind::Report { topic } => {
            if topic == sysmethod::ANNOUNCE_TOPIC {
                ctx.refresh_book();
                return;
            }
            match Args::decode(frame.values()) {
                Ok(values) => {
                    if let Some(f) = def.on_report {
                        f(
                            state,
                            ctx,
                            &Report {
                                from: src,
                                topic,
                                values,
                            },
                        );
                    }
                }
                Err(e) => {
                    ctx.serving.rejected += 1;
                    tracing::debug!("dropped a report from {src}: {e}");
                }
            }
        }
    }
}

/// Serves an EXEC or RETRY for `method` and answers it (unless it was broadcast).
fn serve_request<S>(
    def: &Definition<S>,
    state: &mut S,
    ctx: &mut Ctx,
    reply: &mut Reply,
    frame: &Frame<'_>,
    method: u8,
) {
    let (src, seq) = (frame.src(), frame.seq());
    let answer = !frame.dst().is_broadcast();
    let me = ctx.addr;
    let spec = |kind| FrameSpec {
        dst: src,
        src: me,
        seq,
        kind,
    };
    if answer && matches!(frame.kind(), FrameKind::Retry { .. }) {
        let sent = match ctx.serving.served.replay(src, seq, method) {
            Some(Replay::Answer { kind, payload }) => {
                let mut kept = [0u8; KEPT_ANSWER];
                let len = payload.len();
                kept[..len].copy_from_slice(payload);
                Some(ctx.send_raw(Dest::Module(src), spec(kind), &kept[..len]))
            }
            Some(Replay::NotKept { len }) => {
                let detail = format!(
                    "request {seq} was already executed; its answer ({len} bytes) was sent and is not kept for replay"
                );
                Some(ctx.send_values(
                    Dest::Module(src),
                    spec(FrameKind::Nak {
                        code: NakCode::DUPLICATE,
                    }),
                    &[Value::Text(&detail)],
                ))
            }
            None => None,
        };
        if let Some(sent) = sent {
            ctx.serving.replayed += 1;
            if let Err(e) = sent {
                tracing::debug!("replayed answer to {src} not delivered: {e}");
            }
            return;
        }
    }
    reply.buf.clear();
    reply.count = 0;
    let mut args = Args::EMPTY;
    let result: Result<(), UnknownOr> = match args.decode_from(frame.values()) {
        Err(e) => Err(MethodError::from(e).into()),
        Ok(()) => {
            if method >= sysmethod::FIRST_RESERVED {
                system_method(def, state, ctx, method, &args, reply)
            } else {
                match def.methods.get(usize::from(method)) {
                    Some(_) if !ctx.liveness.active => {
                        Err(UnknownOr::Method(MethodError::NotReady(format!(
                            "module '{}' is deactivated by the operator",
                            ctx.name
                        ))))
                    }
                    Some((_, f)) => f(state, ctx, &args, reply).map_err(UnknownOr::from),
                    None => Err(unknown_method(method, def)),
                }
            }
        }
    };
    if !answer {
        return;
    }
    let kind = match result {
        Ok(()) if reply.count == 0 => {
            reply.buf.clear();
            FrameKind::Ack
        }
        Ok(()) => FrameKind::Reply,
        Err(e) => {
            let (code, detail) = match e {
                UnknownOr::Unknown(detail) => (NakCode::UNKNOWN_METHOD, detail),
                UnknownOr::Method(e) => {
                    let code = e.code();
                    let detail = match e {
                        MethodError::BadArguments(a) => a.to_string(),
                        MethodError::Busy(s)
                        | MethodError::Failed(s)
                        | MethodError::NotReady(s)
                        | MethodError::UnknownItem(s)
                        | MethodError::ReadOnly(s) => s,
                    };
                    (code, detail)
                }
            };
            reply.buf.clear();
            reply.count = 0;
            reply.push(Value::Text(&detail));
            FrameKind::Nak { code }
        }
    };
    let buf = core::mem::take(&mut reply.buf);
    let sent = ctx.send_raw(Dest::Module(src), spec(kind), &buf);
    // Recorded after the answer left: the copy is not on the caller's path, and no frame of
    // the caller can come in between (this thread serves them one after the other).
    ctx.serving.served.record(src, seq, method, kind, &buf);
    reply.buf = buf;
    if let Err(e) = sent {
        tracing::debug!("answer to {src} not delivered: {e}");
    }
}

/// A method error, or an unknown method (which has its own NAK code).
enum UnknownOr {
    Unknown(String),
    Method(MethodError),
}

impl From<MethodError> for UnknownOr {
    fn from(e: MethodError) -> Self {
        UnknownOr::Method(e)
    }
}

fn unknown_method<S>(id: u8, def: &Definition<S>) -> UnknownOr {
    let known: Vec<&str> = def.methods.iter().map(|(n, _)| n.as_str()).collect();
    UnknownOr::Unknown(format!(
        "no method with id {id} (known: {})",
        known.join(", ")
    ))
}

fn system_method<S>(
    def: &Definition<S>,
    state: &mut S,
    ctx: &mut Ctx,
    id: u8,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), UnknownOr> {
    match id {
        sysmethod::DESCRIBE => {
            let methods: Vec<&str> = def.methods.iter().map(|(n, _)| n.as_str()).collect();
            reply.push(Value::Text(&ctx.name));
            reply.push(Value::I64(i64::from(std::process::id())));
            reply.push(Value::Text(ctx.mode.name()));
            reply.push(Value::Text(&methods.join(",")));
            reply.push(Value::Text(&ctx.bb.describe()));
            reply.push(Value::I64(ctx.link.tx.dropped() as i64));
            reply.push(Value::I64(ctx.serving.rejected as i64));
            reply.push(Value::I64(ctx.serving.replayed as i64));
            reply.push(Value::Bool(ctx.liveness.active));
            Ok(())
        }
        sysmethod::BB_GET => {
            let name = args.text(0).map_err(MethodError::from)?;
            let v = ctx.bb.read(name).map_err(bb_refusal)?;
            reply.push(v);
            Ok(())
        }
        sysmethod::BB_SET => {
            let name = args.text(0).map_err(MethodError::from)?;
            let v = args.get(1).ok_or(MethodError::BadArguments(
                modbot_ipc_schema::ArgError::Missing {
                    index: 1,
                    expected: modbot_ipc_schema::ValueKind::F64,
                },
            ))?;
            ctx.bb.write_remote(name, v).map_err(bb_refusal)?;
            Ok(())
        }
        sysmethod::BB_SNAPSHOT => {
            let len = ctx.bb.snapshot_len();
            let mut buf = vec![0; len];
            let now = ctx.now_ns();
            let addr = ctx.addr;
            ctx.bb.write_snapshot(&mut buf, addr, now);
            reply.push(Value::Bytes(&buf));
            Ok(())
        }
        sysmethod::STATS => {
            ctx.stats.write_answer(&mut |v| reply.push(v));
            Ok(())
        }
        sysmethod::ACTIVATE | sysmethod::DEACTIVATE => {
            let active = id == sysmethod::ACTIVATE;
            if ctx.liveness.active != active {
                ctx.liveness.active = active;
                let (name, by) = (&ctx.name, ctx.serving.caller);
                if active {
                    tracing::info!("module {name} activated by {by}");
                } else {
                    tracing::warn!("module {name} deactivated by {by}: it refuses its methods and pauses its tasks");
                }
                if let Some(f) = def.on_activation {
                    f(state, ctx, active);
                }
            }
            Ok(())
        }
        sysmethod::UPGRADE_OUT => {
            let dir = args.text(0).map_err(MethodError::from)?;
            let methods = args.text(1).map_err(MethodError::from)?;
            let force = matches!(args.get(2), Some(Value::Bool(true)));
            if ctx.serving.handover.is_some() {
                return Err(MethodError::Busy("the module is handing over already".into()).into());
            }
            // The supervisor started the new process and made the directory: nobody else may
            // make a module stop serving and write its state somewhere.
            if ctx.caller_entry().is_none_or(|e| e.name != "supervisor") {
                return Err(MethodError::Failed(
                    "upgrade_out is the supervisor's (modbot upgrade MODULE)".into(),
                )
                .into());
            }
            if !std::path::Path::new(dir).is_dir() {
                return Err(MethodError::Failed(format!("{dir} is not a directory")).into());
            }
            let mine: Vec<&str> = def.methods.iter().map(|(n, _)| n.as_str()).collect();
            let theirs: Vec<&str> = methods.split(',').filter(|m| !m.is_empty()).collect();
            if mine != theirs && !force {
                return Err(MethodError::Failed(method_difference(&mine, &theirs)).into());
            }
            tracing::info!(
                "module {} hands over to the process of a live upgrade (asked by {})",
                ctx.name,
                ctx.serving.caller
            );
            ctx.serving.handover = Some(crate::upgrade::Outgoing {
                dir: dir.into(),
                began_ns: ctx.now_ns(),
                began_mono_ns: crate::clock::Clock::now_ns(&crate::clock::MonotonicClock),
                subscribed_ns: None,
                kept: Vec::new(),
            });
            Ok(())
        }
        _ => Err(UnknownOr::Unknown(format!("no system method with id {id}"))),
    }
}

/// How a new program's method table differs from this one's (ids are positions: a method
/// that moved is a difference too).
fn method_difference(mine: &[&str], theirs: &[&str]) -> String {
    let missing: Vec<&str> = mine
        .iter()
        .filter(|m| !theirs.contains(m))
        .copied()
        .collect();
    let added: Vec<&str> = theirs
        .iter()
        .filter(|m| !mine.contains(m))
        .copied()
        .collect();
    let mut parts = Vec::new();
    if !missing.is_empty() {
        parts.push(format!("it lacks {}", missing.join(", ")));
    }
    if !added.is_empty() {
        parts.push(format!("it adds {}", added.join(", ")));
    }
    if parts.is_empty() {
        parts.push("the same methods in another order (a method's id is its position)".into());
    }
    format!(
        "the new program's methods differ from the running one's: {} (running: {}; new: {}); \
         upgrade with --force to take it anyway",
        parts.join("; "),
        mine.join(","),
        theirs.join(",")
    )
}

/// The NAK a blackboard error becomes.
fn bb_refusal(e: crate::blackboard::BlackboardError) -> MethodError {
    use crate::blackboard::BlackboardError;
    match e {
        BlackboardError::UnknownItem(_) => MethodError::UnknownItem(e.to_string()),
        BlackboardError::ReadOnly(_) => MethodError::ReadOnly(e.to_string()),
        other => MethodError::Failed(other.to_string()),
    }
}
