//! A module that misbehaves on request, for fault-injection tests and demonstrations.
//!
//! Methods:
//! - `ping()` → the number of pings served so far (i64): shows that the module serves;
//! - `panic()`, `exit(code)`: acknowledges, then panics or exits with `code` right after;
//! - `hang()`: acknowledges, then stops serving and stops its heartbeat, busy in a loop;
//! - `flood(module, n)`: sends `n` malformed frames to `module`'s inbox → `[sent, refused]`;
//! - `spam(module, n)`: sends `n` REPORTs to `module` as fast as it can, never waiting for
//!   room → `[sent, refused]` (a refused frame is counted as dropped by the runtime).
//!
//! With `--slow-ms N` the module takes N ms over every REPORT it receives: a slow consumer.

use modbot_core::module::Report;
use modbot_core::{Ctx, Dest, MethodError, Reply};
use modbot_ipc_schema::{Addr, Args, Value};

/// What the module was asked to do next.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Fault {
    #[default]
    None,
    Panic,
    Exit(i32),
    Hang,
}

/// The module's state.
#[derive(Debug, Default)]
pub struct Faulty {
    pub pings: i64,
    pub next: Fault,
    /// Time spent on each received REPORT.
    pub slow_ms: u64,
    /// REPORTs received.
    pub reports: u64,
}

pub fn ping(
    f: &mut Faulty,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    f.pings += 1;
    reply.push(Value::I64(f.pings));
    Ok(())
}

pub fn panic(f: &mut Faulty, _: &mut Ctx, _: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    f.next = Fault::Panic;
    Ok(())
}

pub fn exit(
    f: &mut Faulty,
    _: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let code = args.i64(0)?;
    f.next = Fault::Exit(code.clamp(0, 255) as i32);
    Ok(())
}

pub fn hang(f: &mut Faulty, _: &mut Ctx, _: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    f.next = Fault::Hang;
    Ok(())
}

/// Malformed frames: an unknown kind, a lying length, a truncated header, in turn.
const GARBAGE: [&[u8]; 3] = [
    &[0x01, 0x02, 0xe5],
    &[0x01, 0x02, 0x25, 0x09, 0x00],
    &[0x01],
];

pub fn flood(
    _: &mut Faulty,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    blast(ctx, args, reply, |ctx, to, i| {
        let mut frame = GARBAGE[i as usize % GARBAGE.len()].to_vec();
        if let Some(first) = frame.first_mut() {
            *first = to.0; // addressed right, so only its contents are wrong
        }
        ctx.send_bytes(Dest::Module(to), &frame).is_ok()
    })
}

/// The topic of `spam` reports.
pub const SPAM_TOPIC: u8 = 0x40;

pub fn spam(
    _: &mut Faulty,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    blast(ctx, args, reply, |ctx, to, i| {
        ctx.report(Dest::Module(to), SPAM_TOPIC, &[Value::I64(i)])
            .is_ok()
    })
}

/// Sends `n` frames with `send` to the module named by argument 0 (`n` is argument 1),
/// never waiting for room; answers `[sent, refused]`.
fn blast(
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
    mut send: impl FnMut(&mut Ctx, Addr, i64) -> bool,
) -> Result<(), MethodError> {
    let (target, n) = (args.text(0)?, args.i64(1)?.max(0));
    let to = ctx
        .resolve(target)
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    let sent = (0..n).filter(|&i| send(ctx, to, i)).count() as i64;
    reply.push(Value::I64(sent));
    reply.push(Value::I64(n - sent));
    Ok(())
}

/// A slow consumer: every REPORT costs `slow_ms`.
pub fn on_report(f: &mut Faulty, _: &mut Ctx, r: &Report<'_>) {
    if r.topic == SPAM_TOPIC {
        f.reports += 1;
        if f.slow_ms > 0 {
            std::thread::sleep(std::time::Duration::from_millis(f.slow_ms));
        }
    }
}

/// Periodic: carries out the fault asked for, after its call was answered.
pub fn tick(f: &mut Faulty, _: &mut Ctx) {
    match f.next {
        Fault::None => {}
        Fault::Panic => panic!("panic requested by a call to `panic`"),
        Fault::Exit(code) => {
            tracing::warn!("exiting with status {code} as requested");
            std::process::exit(code);
        }
        Fault::Hang => {
            tracing::warn!("hanging as requested: no more frames, no more heartbeats");
            loop {
                std::thread::sleep(std::time::Duration::from_millis(100));
            }
        }
    }
}
