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
//! - `snapshots.modbot`: stamp to the reader seeing it; baseline `snapshots.uds`. The item is
//!   written once per size and the blackboard published again for every sample: a sample that
//!   comes back to the writer still holds its earlier snapshot, so only the header is written;
//! - `snapshots.modbot_publish`: the writer's own cost, `publish_snapshot` alone (writing the
//!   snapshot into shared memory and sending); baseline `snapshots.modbot`, so its ratio is
//!   the share of the delivery latency spent writing the snapshot;
//! - `snapshots.modbot_one_changed` / `snapshots.modbot_publish_one_changed` (1 MiB): a
//!   blackboard of a 1 MiB bulk item and an f64 that changes before every sample (only the f64
//!   is written into the sample); baselines the 8 B `snapshots.modbot` / `modbot_publish`;
//! - `snapshots.modbot_rewritten` / `snapshots.modbot_publish_rewritten` (1 MiB): the bulk item
//!   rewritten whole before every sample (`Blackboard::write_bulk`, then the copy into the
//!   sample): what a camera that publishes every frame pays; same baselines;
//! - `snapshots.uds`: the baseline.
//!
//! Child role `snapshots-reader DOMAIN CORE`: the reader module.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Proc, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::sample::{self, now_ns, size_label, Plan};
use modbot_core::blackboard::ItemId;
use modbot_core::{Blackboard, Domain, IpcTransport, Module, ModuleBuilder, ReceiveMode};
use modbot_ipc_schema::{OwnedValue, Value};

use crate::paths::spawn_server;
use crate::raw::{RawPorts, Wait};
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
        modbot_bench_kit::targets::rows_with(report, name, &[("bytes", bytes.into())])
            .first()
            .map(|r| r.p50_ns)
    };
    let mib = 1 << 20;
    let (small, big) = (p50("snapshots.modbot", 8)?, p50("snapshots.modbot", mib)?);
    let publish = p50("snapshots.modbot_publish", mib)?;
    let f = |ns: u64| modbot_bench_kit::report::format_value(ns, None);
    let mut text = format!(
        "snapshots: 1 MiB over 8 B p50 is {:.1}× ({} against {}); publish_snapshot takes {} p50 \
         at 1 MiB: a sample that comes back to the writer still holds the snapshot written \
         into it, so only the header and the items changed since are written",
        big as f64 / small.max(1) as f64,
        f(big),
        f(small),
        f(publish),
    );
    if let Some(rewritten) = p50("snapshots.modbot_publish_rewritten", mib) {
        text += &format!(
            "; rewriting the whole 1 MiB item before each publish costs {} p50 (the item written \
             into the blackboard, then copied into the sample)",
            f(rewritten)
        );
    }
    Some(text)
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
        let payload = vec![0x5a_u8; size];
        writer
            .ctx()
            .bb
            .write("data", Value::Bytes(&payload))
            .context("writing the blackboard")?;
        match modbot_size(opts, &mut writer, &ports, &mut child, size, &mut |_, _| {}) {
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
                    modbot_bench_kit::report::format_value(m.handover.value_at_quantile(0.5), None)
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
    if let Err(e) = big_blackboard(opts, report, &mut writer, &ports, &mut child) {
        procs::check_interrupted()?;
        report.note(format!(
            "snapshots: the 1 MiB blackboard rows failed: {e:#}"
        ));
        child.check_running()?;
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

/// A 1 MiB bulk item and an f64 `t`: the rows `*_one_changed` (only `t` changes before each
/// sample) and `*_rewritten` (the whole item is rewritten before each sample).
fn big_blackboard(
    opts: &Opts,
    report: &mut Report,
    writer: &mut Module<()>,
    ports: &RawPorts,
    child: &mut Proc,
) -> anyhow::Result<()> {
    const MIB: usize = 1 << 20;
    writer.ctx().bb = Blackboard::builder()
        .bulk_item::<u64>("data", MIB / 8)
        .item("t", OwnedValue::F64(0.0))
        .build()?;
    let (data, t) = (writer.ctx().bb.id("data")?, writer.ctx().bb.id("t")?);
    let baseline = |row: Row, of: &str| row.param("bytes", MIB).against(of, &[("bytes", 8.into())]);
    let mut frame = vec![0u64; MIB / 8];
    let mut one_changed = |bb: &mut Blackboard, i: u64| bb.set_f64(t, i as f64);
    let mut rewrite = |bb: &mut Blackboard, i: u64| rewrite_bulk(bb, data, &mut frame, i);
    let steps: [(&str, &mut Step<'_>); 2] = [
        ("one_changed", &mut one_changed),
        ("rewritten", &mut rewrite),
    ];
    for (what, step) in steps {
        let m = modbot_size(opts, writer, ports, child, MIB, step)?;
        report.push(baseline(
            Row::from_histogram(&format!("snapshots.modbot_{what}"), &m.delivery),
            "snapshots.modbot",
        ));
        report.push(baseline(
            Row::from_histogram(&format!("snapshots.modbot_publish_{what}"), &m.publish),
            "snapshots.modbot_publish",
        ));
    }
    Ok(())
}

/// Changes the blackboard before a sample (the argument counts the samples).
type Step<'a> = dyn FnMut(&mut Blackboard, u64) + 'a;

/// A new frame `i` in `frame`, written whole into the bulk item `data`.
fn rewrite_bulk(bb: &mut Blackboard, data: ItemId, frame: &mut [u64], i: u64) {
    frame.fill(i);
    bb.write_bulk(data, frame)
        .expect("the frame has as many elements as the item");
}

/// Delivery latencies (from the reader), publish costs and hand-overs for one size; `step`
/// changes the blackboard before each sample (its argument counts the samples).
fn modbot_size(
    opts: &Opts,
    writer: &mut Module<()>,
    ports: &RawPorts,
    child: &mut Proc,
    size: usize,
    step: &mut Step<'_>,
) -> anyhow::Result<Measured> {
    let plan = Plan::for_bytes(opts, size);
    let mut publish = sample::histogram();
    let mut handover = sample::histogram();
    let mut taken = 0u64;
    let mut ack = vec![0u8; 8];
    let delivery = sample::record(&plan, || {
        step(&mut writer.ctx().bb, taken);
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
    // Not under SCHED_FIFO (priority `-`).
    let mut child = spawn_server(opts, "uds-sink", &[path.display().to_string()], None, &[])?;
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
