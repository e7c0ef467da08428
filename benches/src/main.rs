//! modbot's benchmarks. Every measurement runs between separate processes and is compared with
//! a baseline measured in the same run.
//!
//! `modbot-benches rtt [--quick]`: the round trip of an EXEC→REPLY method call between two
//! module processes in busy-poll mode, against a raw iceoryx2 `[u8]` publish-subscribe
//! ping-pong. Both copy the payload in and out, both spin on their own core.

use std::process::{Child, Command};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::{Parser, Subcommand};
use hdrhistogram::Histogram;
use iceoryx2::prelude::*;
use modbot_ipc_schema::{Args, Value};
use modbot_runtime::{
    CallOptions, Ctx, Domain, IpcTransport, MethodError, ModuleBuilder, ReceiveMode, Reply,
};

#[derive(Debug, Parser)]
#[command(name = "modbot-benches")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Debug, Subcommand)]
enum Cmd {
    /// Method-call round trip against raw iceoryx2, busy-poll, separate processes.
    Rtt {
        /// Fewer round trips.
        #[arg(long)]
        quick: bool,
    },
    /// (internal) the echo module.
    EchoModule { domain: String, core: usize },
    /// (internal) the raw iceoryx2 pong side.
    RawPong {
        domain: String,
        core: usize,
        max: usize,
    },
}

fn pin(core: usize) {
    let mut set = nix::sched::CpuSet::new();
    if set.set(core).is_ok() {
        if let Err(e) = nix::sched::sched_setaffinity(nix::unistd::Pid::from_raw(0), &set) {
            eprintln!("warning: cannot pin to core {core}: {e}");
        }
    }
}

fn echo(_: &mut (), _: &mut Ctx, args: &Args<'_>, reply: &mut Reply) -> Result<(), MethodError> {
    for v in args.as_slice() {
        reply.push(*v);
    }
    Ok(())
}

const SIZES: [usize; 3] = [8, 64, 4096];

fn stats(h: &Histogram<u64>) -> (u64, u64, u64, u64) {
    (
        h.value_at_quantile(0.5),
        h.value_at_quantile(0.99),
        h.value_at_quantile(0.999),
        h.max(),
    )
}

/// Removes a domain's files when dropped.
struct Cleanup(Domain);
impl Drop for Cleanup {
    fn drop(&mut self) {
        self.0.remove_files();
    }
}

struct Guard(Child);
impl Drop for Guard {
    fn drop(&mut self) {
        let _ = nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(self.0.id() as i32),
            nix::sys::signal::Signal::SIGTERM,
        );
        let _ = self.0.wait();
    }
}

fn rtt(quick: bool) -> anyhow::Result<()> {
    let n = if quick { 5_000 } else { 50_000 };
    let warm = n / 10;
    let name = format!("bench_{}", std::process::id());
    let domain = Domain::new(&name)?;
    // Declared first, dropped last: whatever happens, nothing of the run stays in /dev/shm.
    let _cleanup = Cleanup(domain.clone());
    let me = std::env::current_exe()?;
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    if cores < 2 {
        bail!("busy-poll round trips need two cores; this machine has {cores}");
    }
    pin(0);
    let mut rows = Vec::new();

    // modbot: EXEC → REPLY through the module runtime.
    {
        let _server = Guard(
            Command::new(&me)
                .args(["echo-module", &name, "1"])
                .spawn()?,
        );
        let mut tool = ModuleBuilder::new("bench", 0)
            .mode(ReceiveMode::BusyPoll)
            .open_tool(IpcTransport::new(&domain)?, ())?;
        let start = Instant::now();
        while tool
            .call_owned(
                "echo",
                "echo",
                &[],
                CallOptions::timeout(Duration::from_millis(200)),
            )
            .is_err()
        {
            if start.elapsed() > Duration::from_secs(10) {
                bail!("the echo module did not come up");
            }
        }
        for size in SIZES {
            let payload = vec![0x5a_u8; size];
            let mut h = Histogram::<u64>::new(3)?;
            for i in 0..n + warm {
                let t = Instant::now();
                tool.call_blocking(
                    "echo",
                    "echo",
                    &[Value::Bytes(&payload)],
                    CallOptions::default(),
                    |r| r.map(|a| a.len()).map_err(|e| e.clone()),
                )
                .context("echo call")?;
                if i >= warm {
                    h.record(t.elapsed().as_nanos() as u64)?;
                }
            }
            rows.push(("modbot call (busy)", size, stats(&h)));
        }
    }

    // raw iceoryx2: [u8] ping-pong, payload copied in and out.
    {
        let max = *SIZES.iter().max().unwrap();
        let _server = Guard(
            Command::new(&me)
                .args(["raw-pong", &name, "1", &max.to_string()])
                .spawn()?,
        );
        let (publisher, subscriber, _node) = raw_ports(&name, "ping", "pong", max)?;
        handshake(&publisher, &subscriber)?;
        let mut sink = vec![0u8; max];
        for size in SIZES {
            let payload = vec![0x5a_u8; size];
            let mut h = Histogram::<u64>::new(3)?;
            let deadline = Instant::now() + Duration::from_secs(30);
            for i in 0..n + warm {
                let t = Instant::now();
                let s = publisher.loan_slice_uninit(size)?;
                let s = s.write_from_slice(&payload);
                s.send()?;
                loop {
                    if let Some(r) = subscriber.receive()? {
                        sink[..r.payload().len()].copy_from_slice(r.payload());
                        break;
                    }
                    if Instant::now() > deadline {
                        bail!("the raw pong process does not answer");
                    }
                }
                if i >= warm {
                    h.record(t.elapsed().as_nanos() as u64)?;
                }
            }
            rows.push(("raw iceoryx2 (busy)", size, stats(&h)));
        }
    }
    domain.remove_files();

    println!("round trips: {n} per row after {warm} warm-up, two processes pinned to cores 0 and 1, busy-poll\n");
    println!("| path | payload | p50 µs | p99 µs | p99.9 µs | max µs | p50 ratio to raw |");
    println!("|---|---|---|---|---|---|---|");
    for (path, size, (p50, p99, p999, max)) in &rows {
        let raw = rows
            .iter()
            .find(|r| r.0.starts_with("raw") && r.1 == *size)
            .map(|r| r.2 .0)
            .unwrap_or(1);
        let us = |ns: u64| ns as f64 / 1000.0;
        println!(
            "| {path} | {size} B | {:.2} | {:.2} | {:.2} | {:.1} | {:.2} |",
            us(*p50),
            us(*p99),
            us(*p999),
            us(*max),
            *p50 as f64 / raw as f64
        );
    }
    // Every process of the run has exited: nothing of the domain may stay behind.
    domain.remove_files();
    Ok(())
}

/// Pings until the pong process answers (its ports may not be connected yet), then drains what
/// the extra pings brought back.
fn handshake(publisher: &RawPub, subscriber: &RawSub) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(10);
    'ping: loop {
        publisher
            .loan_slice_uninit(1)?
            .write_from_slice(&[0])
            .send()?;
        let wait = Instant::now() + Duration::from_millis(20);
        while Instant::now() < wait {
            if subscriber.receive()?.is_some() {
                break 'ping;
            }
        }
        if Instant::now() > deadline {
            bail!("the raw pong process does not answer");
        }
    }
    let settle = Instant::now() + Duration::from_millis(50);
    while Instant::now() < settle {
        let _ = subscriber.receive()?;
    }
    Ok(())
}

type RawPub = iceoryx2::port::publisher::Publisher<ipc::Service, [u8], ()>;
type RawSub = iceoryx2::port::subscriber::Subscriber<ipc::Service, [u8], ()>;

fn raw_ports(
    domain: &str,
    out: &str,
    inp: &str,
    max: usize,
) -> anyhow::Result<(RawPub, RawSub, Node<ipc::Service>)> {
    let mut cfg = iceoryx2::config::Config::default();
    cfg.global.prefix = FileName::new(Domain::new(domain)?.prefix().as_bytes())?;
    let node = NodeBuilder::new()
        .config(&cfg)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()?;
    let svc = |n: &str| {
        node.service_builder(&n.try_into().unwrap())
            .publish_subscribe::<[u8]>()
            .subscriber_max_buffer_size(4)
            .open_or_create()
    };
    let publisher = svc(&format!("raw.{out}"))?
        .publisher_builder()
        .initial_max_slice_len(max)
        .create()?;
    let subscriber = svc(&format!("raw.{inp}"))?.subscriber_builder().create()?;
    Ok((publisher, subscriber, node))
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Cmd::Rtt { quick } => rtt(quick),
        Cmd::EchoModule { domain, core } => {
            pin(core);
            let module = ModuleBuilder::new("echo", 1)
                .mode(ReceiveMode::BusyPoll)
                .method("echo", echo)
                .open(IpcTransport::new(&Domain::new(&domain)?)?, ())?;
            module.run()?;
            Ok(())
        }
        Cmd::RawPong { domain, core, max } => {
            pin(core);
            modbot_runtime::signals::install_termination_handler()?;
            let (publisher, subscriber, _node) = raw_ports(&domain, "pong", "ping", max)?;
            let mut buf = vec![0u8; max];
            while !modbot_runtime::signals::termination_requested() {
                if let Some(r) = subscriber.receive()? {
                    let len = r.payload().len();
                    buf[..len].copy_from_slice(r.payload());
                    drop(r);
                    let s = publisher.loan_slice_uninit(len)?;
                    s.write_from_slice(&buf[..len]).send()?;
                }
            }
            Ok(())
        }
    }
}
