//! Benchmark 2: the delivery latency of a blackboard snapshot from a writer module to a
//! reader module, 8 B to 1 MiB, against the same bytes through a Unix socket.
//!
//! The writer (this process) holds a blackboard with one bytes item of the payload's size. For
//! each sample it takes CLOCK_MONOTONIC (the same clock in every process) and publishes the
//! blackboard with that stamp in the snapshot header (`Module::publish_snapshot`, the path a
//! module's housekeeping takes). The reader module, in its own process, spins on
//! `Ctx::snapshot_of` and, when a new sequence number shows up, answers with `now − stamp`
//! over a small raw iceoryx2 channel; the writer waits for that answer before the next sample,
//! so samples never queue. The Unix-socket baseline sends the same bytes with the stamp in
//! their first 8 bytes; its reader sleeps in a blocking read and answers the same way.
//!
//! Rows (param `bytes`, the size of the blackboard item; a snapshot adds about 60 bytes of
//! header, item table and name):
//! - `snapshots.modbot`: stamp to the reader seeing it; baseline `snapshots.uds`;
//! - `snapshots.modbot_publish`: the writer's own cost, `publish_snapshot` alone (encoding the
//!   blackboard into shared memory and sending); baseline `snapshots.modbot`, so its ratio is
//!   the share of the delivery latency spent writing the snapshot;
//! - `snapshots.uds`: the baseline.
//!
//! Child role `snapshots-reader DOMAIN CORE`: the reader module.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_ipc_schema::{OwnedValue, Value};
use modbot_runtime::{Blackboard, Domain, IpcTransport, Module, ModuleBuilder, ReceiveMode};

use crate::opts::Opts;
use crate::procs::{self, Proc, Scratch};
use crate::raw::{RawPorts, Wait};
use crate::report::{Report, Row};
use crate::sample::{self, now_ns, size_label, Plan};
use crate::uds;

/// The payloads: the size of the blackboard's one bytes item.
pub const SIZES: [usize; 5] = [8, 64, 4096, 64 * 1024, 1 << 20];

const WRITER: &str = "bench-writer";
const WRITER_ADDR: u8 = 10;
const READER_ADDR: u8 = 11;

/// Runs benchmark 2.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    if procs::cores() < 2 {
        bail!(
            "the snapshot reader spins: it needs a second core; this machine has {}",
            procs::cores()
        );
    }
    let _pinned = procs::pin(procs::core_for(opts, 0))?;
    if let Err(e) = modbot(opts, report) {
        procs::check_interrupted()?;
        report.note(format!("snapshots: the modbot rows failed: {e:#}"));
    }
    procs::check_interrupted()?;
    if let Err(e) = unix(opts, report) {
        procs::check_interrupted()?;
        report.note(format!("snapshots: the Unix-socket rows failed: {e:#}"));
    }
    if let Some(text) = publish_share(report) {
        report.note(text);
    }
    report.note(
        "snapshots: the modbot reader busy-polls Ctx::snapshot_of; the Unix-socket reader sleeps \
         in a blocking read (how each is normally used); latency = reader's CLOCK_MONOTONIC on \
         arrival − writer's stamp just before publishing/sending",
    );
    Ok(())
}

/// Where the time of a big snapshot goes: writing it, or handing it over.
fn publish_share(report: &Report) -> Option<String> {
    let p50 = |name: &str, bytes: usize| {
        crate::targets::rows_with(report, name, &[("bytes", bytes.into())])
            .first()
            .map(|r| r.p50_ns)
    };
    let (small, big) = (
        p50("snapshots.modbot", 8)?,
        p50("snapshots.modbot", 1 << 20)?,
    );
    let publish = p50("snapshots.modbot_publish", 1 << 20)?;
    let f = |ns: u64| crate::report::format_value(ns, None);
    Some(format!(
        "snapshots: 1 MiB over 8 B p50 is {:.1}× ({} against {}); publish_snapshot alone takes \
         {} p50 at 1 MiB in the writer: Blackboard::write_snapshot copies every item into the \
         shared-memory sample, so a snapshot costs a copy of the whole blackboard",
        big as f64 / small.max(1) as f64,
        f(big),
        f(small),
        f(publish),
    ))
}

fn modbot(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    // Declared first, dropped last: after the processes, nothing of the run stays behind.
    let scratch = Scratch::new("snapshots", None)?;
    let domain = scratch.domain.clone();
    let mut child = procs::spawn_role(
        opts,
        "snapshots-reader",
        &[
            domain.name().to_owned(),
            procs::core_arg(procs::core_for(opts, 1)),
        ],
    )?;
    let bb = Blackboard::builder()
        .item("data", OwnedValue::Bytes(vec![0; SIZES[0]]))
        .build()?;
    let mut writer = ModuleBuilder::new(WRITER, WRITER_ADDR)
        .mode(ReceiveMode::BusyPoll)
        .blackboard(bb)
        // Only the benchmark publishes: no periodic snapshots in between.
        .snapshot_period(Duration::from_secs(3600))
        .open(IpcTransport::new(&domain)?, ())
        .context("opening the writer module")?;
    let ports = RawPorts::open(&domain, "snap_ctl", "snap_ack", 8, Wait::Busy)?;
    handshake(&mut writer, &ports, &mut child)?;
    let mut handovers = Vec::new();
    for size in SIZES {
        match modbot_size(opts, &mut writer, &ports, &mut child, size) {
            Ok(m) => {
                report.push(
                    Row::from_histogram("snapshots.modbot", &m.delivery)
                        .param("bytes", size)
                        .against("snapshots.uds", &[]),
                );
                report.push(
                    Row::from_histogram("snapshots.modbot_publish", &m.publish)
                        .param("bytes", size)
                        .against("snapshots.modbot", &[]),
                );
                handovers.push(format!(
                    "{} {}",
                    size_label(size),
                    crate::report::format_value(m.handover.value_at_quantile(0.5), None)
                ));
            }
            Err(e) => {
                procs::check_interrupted()?;
                report.note(format!(
                    "snapshots: modbot with {} failed: {e:#}",
                    size_label(size)
                ));
                child.check_running()?;
            }
        }
    }
    if !handovers.is_empty() {
        report.note(format!(
            "snapshots: hand-over p50 (per sample, the reader seeing the snapshot minus the end \
             of publish_snapshot in the writer): {}",
            handovers.join(", ")
        ));
    }
    drop(ports);
    drop(writer);
    child.stop()?;
    Ok(())
}

/// Publishes until the reader answers (it is starting), then drains the extra answers.
fn handshake(writer: &mut Module<()>, ports: &RawPorts, child: &mut Proc) -> anyhow::Result<()> {
    let end = Instant::now() + Duration::from_secs(15);
    let mut sink = Vec::new();
    loop {
        writer.publish_snapshot(now_ns());
        if ports
            .recv(&mut sink, Instant::now() + Duration::from_millis(20))?
            .is_some()
        {
            break;
        }
        child
            .check_running()
            .context("waiting for the snapshot reader")?;
        procs::check_interrupted()?;
        if Instant::now() > end {
            bail!("the snapshot reader did not answer within 15 s");
        }
    }
    let settle = Instant::now() + Duration::from_millis(50);
    while Instant::now() < settle {
        let _ = ports.try_recv(&mut sink)?;
    }
    Ok(())
}

type Hist = hdrhistogram::Histogram<u64>;

/// What one size measured.
struct Measured {
    /// Stamp to the reader seeing the snapshot.
    delivery: Hist,
    /// `publish_snapshot` alone, in the writer.
    publish: Hist,
    /// Per sample, delivery minus publish: from the end of `publish_snapshot` to the reader
    /// seeing it (0 when the reader saw it before the writer's call returned).
    handover: Hist,
}

/// Delivery latencies (from the reader), publish costs and hand-overs for one size.
fn modbot_size(
    opts: &Opts,
    writer: &mut Module<()>,
    ports: &RawPorts,
    child: &mut Proc,
    size: usize,
) -> anyhow::Result<Measured> {
    let payload = vec![0x5a_u8; size];
    writer
        .ctx()
        .bb
        .write("data", Value::Bytes(&payload))
        .context("writing the blackboard")?;
    let plan = Plan::for_bytes(opts, size);
    let mut publish = sample::histogram();
    let mut handover = sample::histogram();
    let mut taken = 0u64;
    let mut ack = vec![0u8; 8];
    let delivery = sample::record(&plan, || {
        let t0 = now_ns();
        writer.publish_snapshot(t0);
        let t1 = now_ns();
        taken += 1;
        let latency = match ports.recv(&mut ack, Instant::now() + Duration::from_secs(5))? {
            Some(8) => u64::from_le_bytes(ack[..8].try_into().expect("8 bytes")),
            Some(len) => bail!("the reader answered {len} bytes"),
            None => {
                procs::check_interrupted()?;
                child.check_running()?;
                bail!("the reader did not see the snapshot within 5 s")
            }
        };
        if taken > plan.warm {
            let cost = t1.saturating_sub(t0);
            publish.saturating_record(cost.max(1));
            handover.saturating_record(latency.saturating_sub(cost).max(1));
        }
        Ok(latency)
    })?;
    Ok(Measured {
        delivery,
        publish,
        handover,
    })
}

fn unix(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    let mut scratch = Scratch::new("snapshots_uds", None)?;
    let path = scratch.path("sink.sock");
    let mut child = procs::spawn_role(
        opts,
        "uds-sink",
        &[
            path.display().to_string(),
            procs::core_arg(procs::core_for(opts, 1)),
            "-".to_owned(),
        ],
    )?;
    let mut client = uds::Client::connect(&path, &mut child)?;
    for size in SIZES {
        let mut payload = vec![0x5a_u8; size.max(8)];
        let plan = Plan::for_bytes(opts, size);
        let h = sample::record(&plan, || client.deliver(&mut payload))?;
        report.push(
            Row::from_histogram("snapshots.uds", &h)
                .param("bytes", size)
                .is_baseline(),
        );
    }
    drop(client);
    child.stop()?;
    drop(scratch);
    Ok(())
}

/// The child roles of this benchmark.
pub fn child(role: &str, args: &[String]) -> Option<anyhow::Result<()>> {
    (role == "snapshots-reader").then(|| reader(args))
}

fn reader(args: &[String]) -> anyhow::Result<()> {
    let [domain, core] = args else {
        bail!("usage: child snapshots-reader DOMAIN CORE");
    };
    let _pinned = procs::pin(procs::parse_core(core)?)?;
    let domain = Domain::new(domain)?;
    let mut module = ModuleBuilder::new("bench-reader", READER_ADDR)
        .mode(ReceiveMode::BusyPoll)
        .open(IpcTransport::new(&domain)?, ())?;
    let ports = RawPorts::open(&domain, "snap_ack", "snap_ctl", 8, Wait::Busy)?;
    let mut last_seq = 0;
    while !procs::interrupted() {
        match module
            .ctx()
            .snapshot_of(WRITER, |v| (v.seq(), v.stamp_ns(), now_ns()))
        {
            Ok(Some((seq, stamp, now))) if seq != last_seq => {
                last_seq = seq;
                ports.send(&now.saturating_sub(stamp).to_le_bytes())?;
            }
            Ok(_) => core::hint::spin_loop(),
            // The writer is not up yet (or gone): look again soon.
            Err(_) => std::thread::sleep(Duration::from_millis(1)),
        }
    }
    Ok(())
}
