//! Part of benchmark 1: the CPU work of one call, without the machine's part.
//!
//! A busy call's round trip between two processes is the two sides' work plus what the
//! machine adds (a cache line crossing cores twice, the spin loops' phase), and on a shared
//! VM the machine's part moves. Here the caller and the echo module live in one thread of one
//! process, on the same IPC transport and shared memory: the caller sends, the echo module
//! serves, the caller takes the answer, one after the other. What is measured is the CPU work
//! of a call on both sides, against raw iceoryx2's publish-receive-publish-receive with the
//! payload copied in and out on both sides, the same way (interleaved in alternating blocks).
//!
//! Rows (param `bytes`): `calls.modbot_work` against `calls.raw_iceoryx2_work`.

use std::time::Instant;

use anyhow::{bail, Context};
use modbot_bench_kit::interleave::{interleave, Side};
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::Scratch;
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::sample::{self, Plan};
use modbot_core::{CallError, CallHandle, CallOptions, Ctx, Module, ModuleBuilder, ReceiveMode};
use modbot_ipc_schema::{Args, Value};

use crate::echo::{copy_answer, echo, two_module_system};
use crate::raw::{RawPorts, Wait};

/// The payloads, in bytes.
const SIZES: [usize; 2] = [8, 4096];

/// How many looks at both inboxes a call may take before it counts as lost (the first call
/// also learns the echo module's methods).
const MAX_LOOKS: usize = 1000;

/// Measures the rows into `report`.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    let scratch = Scratch::new("work", None)?;
    let max = SIZES.iter().copied().max().unwrap_or(8);
    let mut modbot = Pair::open(&scratch)?;
    let ping = RawPorts::open(&scratch.domain, "ping", "pong", max, Wait::Busy)?;
    let pong = RawPorts::open(&scratch.domain, "pong", "ping", max, Wait::Busy)?;
    let mut raw = RawPair {
        ping,
        pong,
        sinks: (vec![0; max], vec![0; max]),
    };
    for size in SIZES {
        let payload = vec![0x5a_u8; size];
        let mut a = || modbot.one(&payload);
        let mut b = || raw.one(&payload);
        let pair = interleave(
            &Plan::for_bytes(opts, size),
            Side::alone(&mut a),
            Side::alone(&mut b),
        )?;
        report.push(
            Row::from_histogram("calls.modbot_work", &pair.subject)
                .param("bytes", size)
                .against("calls.raw_iceoryx2_work", &[])
                .blocks(pair.blocks),
        );
        report.push(
            Row::from_histogram("calls.raw_iceoryx2_work", &pair.baseline)
                .param("bytes", size)
                .is_baseline(),
        );
    }
    report.note(
        "calls: the _work rows are the CPU work of one round trip, both sides in one thread of \
         one process (no cross-core traffic, no spin loop): modbot's caller and echo module on \
         the IPC transport against raw iceoryx2's publish and receive, both copying the payload \
         in and out on both sides; interleaved in alternating blocks",
    );
    drop(modbot);
    drop(raw);
    drop(scratch);
    Ok(())
}

/// What the caller's `on_done` hook saw of the last answer.
#[derive(Default)]
struct Answers {
    /// The answer's payload, copied out of shared memory.
    sink: Vec<u8>,
    /// Its length, or why the call failed.
    last: Option<Result<usize, String>>,
}

fn done(s: &mut Answers, _: &mut Ctx, _: CallHandle, r: Result<&Args<'_>, &CallError>) {
    s.last = Some(copy_answer(r, &mut s.sink));
}

/// modbot's caller and echo module, in this thread.
struct Pair {
    caller: Module<Answers>,
    echo: Module<()>,
}

impl Pair {
    fn open(scratch: &Scratch) -> anyhow::Result<Pair> {
        let echo = ModuleBuilder::new("echo", 1)
            .mode(ReceiveMode::BusyPoll)
            .method("echo", echo)
            .open(two_module_system(&scratch.domain)?, ())
            .context("opening the echo module")?;
        let caller = ModuleBuilder::new("bench", 0)
            .mode(ReceiveMode::BusyPoll)
            .on_done(done)
            .open_tool(two_module_system(&scratch.domain)?, Answers::default())
            .context("opening the caller")?;
        Ok(Pair { caller, echo })
    }

    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64> {
        let t = Instant::now();
        self.caller.state_mut().last = None;
        self.caller
            .ctx()
            .call_with(
                "echo",
                "echo",
                &[Value::Bytes(payload)],
                CallOptions::default(),
            )
            .context("echo call")?;
        for _ in 0..MAX_LOOKS {
            self.echo.poll_once()?;
            self.caller.poll_once()?;
            if let Some(answer) = self.caller.state_mut().last.take() {
                let ns = sample::since(t);
                return match answer {
                    Ok(len) if len == payload.len() => Ok(ns),
                    Ok(len) => bail!("echo answered {len} bytes for {}", payload.len()),
                    Err(e) => bail!("echo call: {e}"),
                };
            }
        }
        bail!("no answer after {MAX_LOOKS} looks at both inboxes")
    }
}

/// Raw iceoryx2's two sides, in this thread.
struct RawPair {
    ping: RawPorts,
    pong: RawPorts,
    sinks: (Vec<u8>, Vec<u8>),
}

impl RawPair {
    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64> {
        let t = Instant::now();
        self.ping.send(payload)?;
        let Some(len) = self.pong.try_recv(&mut self.sinks.1)? else {
            bail!("raw ping not delivered");
        };
        self.pong.send(&self.sinks.1[..len])?;
        let Some(len) = self.ping.try_recv(&mut self.sinks.0)? else {
            bail!("raw pong not delivered");
        };
        let ns = sample::since(t);
        if len != payload.len() {
            bail!("raw echo answered {len} bytes for {}", payload.len());
        }
        Ok(ns)
    }
}
