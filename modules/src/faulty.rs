//! A module that misbehaves on request, for fault-injection tests and demonstrations.
//!
//! Methods:
//! - `ping()` → the number of pings served so far (i64): shows that the module serves;
//! - `panic()`, `exit(code)`: acknowledges, then panics or exits with `code` right after;
//! - `hang()`: acknowledges, then stops serving and stops its heartbeat, busy in a loop;
//! - `work(ms)`: takes `ms` milliseconds before it answers `ms`, beating meanwhile
//!   ([`Ctx::keep_alive`]): a long method that is not a hang;
//! - `flood(module, n)`: sends `n` malformed frames to `module`'s inbox → `[sent, refused]`;
//! - `spam(module, n)`: sends `n` REPORTs to `module` as fast as it can, never waiting for
//!   room → `[sent, refused]` (a refused frame is counted as dropped by the runtime);
//! - `record(seq)`: appends `seq` as a line to the journal (`--journal PATH`) → `seq`: a call
//!   whose executions can be counted afterwards, even across SIGKILL (see [`record`]).
//!
//! With `--slow-ms N` the module takes N ms over every REPORT it receives: a slow consumer.
//!
//! A live upgrade (`modbot upgrade`) carries its pings, reports and upgrade count over
//! ([`upgrade_out`], [`upgrade_in`], state version [`STATE_VERSION`]); the blackboard item
//! `upgrades` shows the count, which only this state can carry.
//!
//! [`send_garbage`] and [`send_spam`] are the bodies of `flood` and `spam`, for a benchmark
//! that injects the same faults from its own endpoint.

use std::io::Write;

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
    /// `reports` as the blackboard last showed it.
    pub reports_shown: u64,
    /// Where `record` appends, opened for appending (`--journal PATH`); `None`: `record` fails.
    pub journal: Option<std::fs::File>,
    /// Live upgrades this module's state went through.
    pub upgrades: u32,
}

/// The version of the state [`upgrade_out`] writes.
pub const STATE_VERSION: u32 = 1;

/// The module's own state for a live upgrade: pings (i64 LE), reports (u64 LE), upgrades (u32
/// LE).
pub fn upgrade_out(f: &Faulty) -> Vec<u8> {
    let mut out = Vec::with_capacity(20);
    out.extend_from_slice(&f.pings.to_le_bytes());
    out.extend_from_slice(&f.reports.to_le_bytes());
    out.extend_from_slice(&f.upgrades.to_le_bytes());
    out
}

/// Takes [`upgrade_out`]'s state over, one upgrade more; refuses another version or length.
pub fn upgrade_in(f: &mut Faulty, ctx: &mut Ctx, version: u32, bytes: &[u8]) -> Result<(), String> {
    if version != STATE_VERSION {
        return Err(format!(
            "state version {version}; this program reads version {STATE_VERSION}"
        ));
    }
    let [p0, p1, p2, p3, p4, p5, p6, p7, r0, r1, r2, r3, r4, r5, r6, r7, u0, u1, u2, u3] = *bytes
    else {
        return Err(format!("{} bytes of state; version 1 has 20", bytes.len()));
    };
    f.pings = i64::from_le_bytes([p0, p1, p2, p3, p4, p5, p6, p7]);
    f.reports = u64::from_le_bytes([r0, r1, r2, r3, r4, r5, r6, r7]);
    f.upgrades = u32::from_le_bytes([u0, u1, u2, u3]) + 1;
    let _ = ctx.bb.write("upgrades", Value::I64(i64::from(f.upgrades)));
    Ok(())
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

/// Works `ms` milliseconds (sleeping 10 ms at a time, beating between), then answers `ms`.
pub fn work(
    _: &mut Faulty,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let ms = args.i64(0)?.clamp(0, 600_000);
    let until = std::time::Instant::now() + std::time::Duration::from_millis(ms as u64);
    while std::time::Instant::now() < until {
        std::thread::sleep(std::time::Duration::from_millis(10));
        ctx.keep_alive();
    }
    reply.push(Value::I64(ms));
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
    blast(ctx, args, reply, send_garbage)
}

/// Sends `n` malformed frames to `to`'s inbox, never waiting for room; returns how many were
/// sent (the rest were refused: the inbox was full).
pub fn send_garbage(ctx: &mut Ctx, to: Addr, n: u64) -> u64 {
    (0..n)
        .filter(|&i| {
            let mut frame = GARBAGE[i as usize % GARBAGE.len()].to_vec();
            if let Some(first) = frame.first_mut() {
                *first = to.0; // addressed right, so only its contents are wrong
            }
            ctx.send_bytes(Dest::Module(to), &frame).is_ok()
        })
        .count() as u64
}

/// The topic of `spam` reports.
pub const SPAM_TOPIC: u8 = 0x40;

pub fn spam(
    _: &mut Faulty,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    blast(ctx, args, reply, send_spam)
}

/// Sends `n` REPORTs to `to` as fast as it can, never waiting for room; returns how many were
/// sent (a refused one is counted as dropped by the runtime).
pub fn send_spam(ctx: &mut Ctx, to: Addr, n: u64) -> u64 {
    (0..n)
        .filter(|&i| {
            let i = i64::try_from(i).unwrap_or(i64::MAX);
            ctx.report(Dest::Module(to), SPAM_TOPIC, &[Value::I64(i)])
                .is_ok()
        })
        .count() as u64
}

/// Sends `n` frames with `send` to the module named by argument 0 (`n` is argument 1);
/// answers `[sent, refused]`.
fn blast(
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
    send: fn(&mut Ctx, Addr, u64) -> u64,
) -> Result<(), MethodError> {
    let (target, n) = (args.text(0)?, args.i64(1)?.max(0));
    let to = ctx
        .resolve(target)
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    let sent = i64::try_from(send(ctx, to, n.unsigned_abs())).unwrap_or(i64::MAX);
    reply.push(Value::I64(sent));
    reply.push(Value::I64(n - sent));
    Ok(())
}

/// `record(seq)`: appends the line `seq` to the journal, then answers `seq`.
///
/// The line goes out in one write(2) on a file opened for appending, before the answer is
/// sent: a process killed at any moment has either written the whole line or none of it, and
/// an answered call is always in the journal. Every process of the module (restarts included)
/// appends to the same file, so the journal lists every execution: a sequence number twice
/// means the call was executed twice.
pub fn record(
    f: &mut Faulty,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let seq = args.i64(0)?;
    let journal = f.journal.as_mut().ok_or_else(|| {
        MethodError::Failed("no journal: start the module with --journal PATH".into())
    })?;
    let line = format!("{seq}\n");
    match journal.write(line.as_bytes()) {
        Ok(n) if n == line.len() => {}
        Ok(n) => {
            return Err(MethodError::Failed(format!(
                "journal: {n} of {} bytes written",
                line.len()
            )))
        }
        Err(e) => return Err(MethodError::Failed(format!("journal: {e}"))),
    }
    // A module started without the item (a test's own builder) records all the same.
    let _ = ctx.bb.write("recorded", Value::I64(seq));
    reply.push(Value::I64(seq));
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

/// Periodic: shows the reports received on the blackboard (item `reports`, if the module has
/// it: a count, not one snapshot per report), and carries out the fault asked for, after its
/// call was answered.
pub fn tick(f: &mut Faulty, ctx: &mut Ctx) {
    if f.reports != f.reports_shown {
        f.reports_shown = f.reports;
        let _ = ctx.bb.write(
            "reports",
            Value::I64(i64::try_from(f.reports).unwrap_or(i64::MAX)),
        );
    }
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
