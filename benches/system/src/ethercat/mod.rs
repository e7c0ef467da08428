//! Benchmark 10, ethercat: the bus bridge's EtherCAT backend (ethercrab as the master) against
//! modbot's slave emulator (`modbot-ecat-sim`) of 6 and 64 CiA 402 drives, on a veth pair in a
//! network namespace of the benchmark's own. Needs root (namespaces, raw sockets).
//!
//! What is measured, each against a baseline of the same run:
//!
//! - **bus cycle round trip** (`ethercat.cycle`): one `EthercatBackend::cycle`, back to back —
//!   the process data out, every slave of the emulator processing it, the reply read back.
//!   Baseline `ethercat.raw_pingpong`: frames of the same lengths as the cycle's (learned from a
//!   socket on the emulator's end, one cycle's frames in order) sent on a second veth pair of
//!   the same namespace, each answered by a tiny echo process (`ecat-echo`: the same bytes, the
//!   source MAC's locally administered bit set) before the next goes out — the least a frame
//!   exchange on this link costs. Both measured interleaved, in alternating blocks.
//! - **cycle jitter at 1 and 4 kHz**: a loop woken by an absolute timerfd every period that runs
//!   one bus cycle (`ethercat.cycle_lateness`: the wake-up's lateness; `ethercat.cycle_done`:
//!   from the due time to the end of the cycle; `ethercat.missed`: periods skipped or whose
//!   cycle ended after the next period's start), against the same loop without the cycle
//!   (`ethercat.bare_*`), in alternating blocks of the same process. The target —
//!   missed cycles ≤ the bare loop's + 0.5 % — is reported in the targets, never asserted.
//! - **SYNC0 offset** (`ethercat.sync0_offset`, with distributed clocks, 6 drives, 1 kHz):
//!   ethercrab's `cycle_start_offset` of every cycle — where in the SYNC0 cycle the frame lands
//!   — with each cycle given its timer's due time as the tick's time, as the bus bridge gives
//!   the grid's, so the master locks SYNC0 to the loop (`modbot_ethercat::dc::GridLock`);
//!   `ethercat.sync0_from_target`: how far from the lock's target (half a period after the
//!   tick) each frame landed once the lock was won.
//!
//! The measuring side (`ecat-master`, one process per configuration: ethercrab allows one
//! master per process) and the echo run under SCHED_FIFO (60; the emulator and the echo 59)
//! when permitted; the report says which.
//!
//! - [`segment`]: the namespace and its veth pairs (deleted on drop), the processes in it.
//! - [`sides`]: the child roles (the master's measurements, the echo).

pub(crate) mod segment;
mod sides;

use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context};
use modbot_bench_kit::interleave::Blocks;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs;
use modbot_bench_kit::report::{Report, Row, Target};
use serde_json::Value as Json;

use segment::{fifo_for, Lines, Segment};
use sides::{LoopSide, Measured, Stats};

pub use sides::child;

/// The segments measured: the arm's six drives, and a long line.
const SLAVES: [usize; 2] = [6, 64];
/// The loop rates.
const RATES: [u64; 2] = [1000, 4000];
/// SCHED_FIFO priority of the measuring side; the emulator and the echo get one less.
const PRIORITY: u8 = 60;
/// The margin: missed cycles ≤ the bare loop's + this, in percent.
const MISSED_MARGIN_PCT: f64 = 0.5;

/// An error unless this process may make network namespaces and raw sockets.
pub fn require_root() -> anyhow::Result<()> {
    if !nix::unistd::Uid::effective().is_root() {
        bail!(
            "the ethercat benchmark needs root (it makes a network namespace with veth pairs and \
             opens raw sockets): run it as root"
        );
    }
    Ok(())
}

/// Runs the EtherCAT benchmark (as part of `all` without root: a note, nothing measured).
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    if let Err(e) = require_root() {
        report.note(format!("ethercat: skipped: {e}"));
        return Ok(());
    }
    let sim = procs::binary(opts, "modbot-ecat-sim")
        .context("the slave emulator is built with `cargo build --release -p modbot-ecat-sim`")?;
    let segment = Segment::new()?;
    let mut echo = Lines::spawn(
        child_cmd(
            &segment,
            opts,
            "ecat-echo",
            &[segment.echo.clone(), (PRIORITY - 1).to_string()],
        ),
        "the echo",
    )?;
    let ready = echo.wait_for("ready", Duration::from_secs(10))?;
    let mut done_any = false;
    for slaves in SLAVES {
        match measure(opts, &segment, &sim, slaves, false) {
            Ok((m, emulator_fifo)) => {
                push_rows(report, &m, emulator_fifo, &ready);
                done_any = true;
            }
            Err(e) => report.note(format!("ethercat: {slaves} slaves failed: {e:#}")),
        }
    }
    echo.proc.check_running()?;
    drop(echo);
    match measure(opts, &segment, &sim, SLAVES[0], true) {
        Ok((m, _)) => push_sync0(report, &m),
        Err(e) => report.note(format!(
            "ethercat: the SYNC0 offset with distributed clocks failed: {e:#}"
        )),
    }
    drop(segment);
    if !done_any {
        bail!("no EtherCAT measurement succeeded (see the notes)");
    }
    report.note(
        "ethercat: the master (ethercrab 0.7 through modbot-ethercat, every drive's controlword 0) \
         and modbot-ecat-sim on the two ends of a veth pair in a network namespace of the run; the \
         raw ping-pong on a second veth pair of the same namespace, its echo a process that \
         answers each 0x88A4 frame with the same bytes. cycle and raw_pingpong: back to back, \
         interleaved in 10 blocks (ratio: the median of the blocks' p50 ratios). Timed loops: an \
         absolute timerfd; lateness = the clock after the read minus the due time of the last \
         expiration; done = due time to the end of the cycle; a period is missed when it was \
         skipped or its cycle ended after the next period's start; bare and bus loops in \
         alternating blocks of the same process. The emulator's drives step at 1 kHz whatever \
         the loop's rate.",
    );
    Ok(())
}

/// `modbot-benches child ROLE ARGS...` inside the namespace.
fn child_cmd(segment: &Segment, opts: &Opts, role: &str, args: &[String]) -> std::process::Command {
    let mut cmd = segment.exec(&opts.exe);
    cmd.arg("child").arg(role).args(args);
    cmd
}

/// One configuration: the emulator with `slaves` drives, and a master process measuring it.
/// Returns what it measured and whether the emulator runs under SCHED_FIFO.
fn measure(
    opts: &Opts,
    segment: &Segment,
    sim: &Path,
    slaves: usize,
    dc: bool,
) -> anyhow::Result<(Measured, bool)> {
    let mut cmd = segment.exec(sim);
    cmd.args(["--interface", &segment.slaves, "--slaves"])
        .arg(slaves.to_string());
    let mut emulator = Lines::spawn(cmd, "modbot-ecat-sim")?;
    emulator.wait_for("serving", Duration::from_secs(30))?;
    let emulator_fifo = fifo_for(emulator.proc.pid(), PRIORITY - 1);
    let args = [
        segment.master.clone(),
        segment.slaves.clone(),
        segment.ping.clone(),
        slaves.to_string(),
        opts.quick.to_string(),
        dc.to_string(),
        PRIORITY.to_string(),
    ];
    let mut master = Lines::spawn(child_cmd(segment, opts, "ecat-master", &args), "the master")?;
    let line = master.wait_for("result ", Duration::from_secs(600))?;
    let measured: Measured =
        serde_json::from_str(&line["result ".len()..]).context("the master's result line")?;
    emulator.proc.check_running()?;
    Ok((measured, emulator_fifo))
}

/// A row of a distribution.
fn row(name: &str, s: &Stats) -> Row {
    let mut r = Row::single(name, 0);
    r.n = s.n;
    r.p50_ns = s.p50;
    r.p99_ns = s.p99;
    r.p999_ns = s.p999;
    r.max_ns = s.max;
    r
}

/// The frame of one cycle as the brief computes it, when it fits one frame: Ethernet header
/// (14), EtherCAT header (2), the LRW (10 + PDI + 2), per slave an FPRD of its AL status
/// (10 + 2 + 2); PDI per drive 13 output and 15 input bytes (no load-side encoder).
fn expected_frame(slaves: usize) -> usize {
    14 + 2 + (10 + slaves * (13 + 15) + 2) + slaves * 14
}

fn push_rows(report: &mut Report, m: &Measured, emulator_fifo: bool, echo: &str) {
    let n = m.slaves;
    let frames = m
        .frames
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join("+");
    if let (Some(cycle), Some(ping)) = (&m.cycle, &m.ping) {
        let blocks = match m.ratios[..] {
            [median, min, max, count] => Some(Blocks {
                count: count as usize,
                median,
                min,
                max,
            }),
            _ => None,
        };
        report.push(
            row("ethercat.raw_pingpong", ping)
                .param("slaves", n)
                .param("frame_bytes", frames.as_str())
                .is_baseline(),
        );
        report.push(
            row("ethercat.cycle", cycle)
                .param("slaves", n)
                .param("frame_bytes", frames.as_str())
                .against("ethercat.raw_pingpong", &[])
                .blocks(blocks),
        );
        let ratio = |a: u64, b: u64| a as f64 / b.max(1) as f64;
        report.note(format!(
            "ethercat: {n} slaves: bring-up {:.0} ms; one cycle = {} frame(s) of {frames} B \
             ({}); cycle p50 {:.1} µs p99 {:.1} µs max {:.1} µs, raw \
             ping-pong p50 {:.1} µs p99 {:.1} µs max {:.1} µs: cycle / raw {:.2} at p50, {:.2} at \
             p99; SCHED_FIFO: master {}, emulator {}, echo {}",
            m.bring_up_ms,
            m.frames.len(),
            match expected_frame(n) {
                b if b <= 1514 => format!("one frame of {b} B by the formula"),
                b => format!("{b} B by the formula: more than one Ethernet frame holds"),
            },
            cycle.p50 as f64 / 1e3,
            cycle.p99 as f64 / 1e3,
            cycle.max as f64 / 1e3,
            ping.p50 as f64 / 1e3,
            ping.p99 as f64 / 1e3,
            ping.max as f64 / 1e3,
            ratio(cycle.p50, ping.p50),
            ratio(cycle.p99, ping.p99),
            yes(m.fifo),
            yes(emulator_fifo),
            yes(echo.contains("fifo=true")),
        ));
    }
    if let Some(first) = &m.first_fault {
        report.note(format!(
            "ethercat: {n} slaves: {} cycle(s) of the run ended in a bus fault, {} of them without \
             a reply within the 10 ms PDU timeout (their times are kept in the rows); the first: \
             {first}",
            m.faults, m.no_replies
        ));
    }
    for l in &m.loops {
        let p = |r: Row| r.param("slaves", n).param("hz", l.hz).param("fifo", m.fifo);
        let count = |name: &str, v: u64| p(Row::single(name, v).unit("count"));
        report.push(p(row("ethercat.bare_lateness", &l.bare.lateness)).is_baseline());
        report.push(
            p(row("ethercat.cycle_lateness", &l.bus.lateness))
                .against("ethercat.bare_lateness", &[]),
        );
        report.push(
            p(row("ethercat.cycle_done", &l.bus.done)).against("ethercat.bare_lateness", &[]),
        );
        report.push(count("ethercat.bare_periods", l.bare.periods).is_baseline());
        report.push(count("ethercat.bare_missed", l.bare.missed).is_baseline());
        report.push(count("ethercat.periods", l.bus.periods).against("ethercat.bare_periods", &[]));
        report.push(count("ethercat.missed", l.bus.missed).against("ethercat.bare_missed", &[]));
        report.note(format!(
            "ethercat: {n} slaves at {} Hz (SCHED_FIFO {}): {} of {} periods missed ({:.3} %) \
             with a bus cycle, {} of {} ({:.3} %) bare; {} bus fault(s); cycle done p99 {:.1} µs \
             max {:.1} µs of a {:.0} µs period",
            l.hz,
            yes(m.fifo),
            l.bus.missed,
            l.bus.periods,
            pct(&l.bus),
            l.bare.missed,
            l.bare.periods,
            pct(&l.bare),
            l.bus.faults,
            l.bus.done.p99 as f64 / 1e3,
            l.bus.done.max as f64 / 1e3,
            1e6 / l.hz as f64,
        ));
    }
}

fn push_sync0(report: &mut Report, m: &Measured) {
    let Some(s) = &m.sync0 else {
        return;
    };
    // Both rows of the 1 kHz distributed-clocks loop, each its own baseline.
    let dc_row = |name: &str, stats: &Stats| {
        row(name, stats)
            .param("slaves", m.slaves)
            .param("hz", 1000)
            .param("fifo", m.fifo)
            .is_baseline()
    };
    report.push(dc_row("ethercat.sync0_offset", s));
    if let Some(t) = &m.sync0_from_target {
        report.push(dc_row("ethercat.sync0_from_target", t));
    }
    let faults = m.loops.first().map_or(0, |l| l.bus.faults);
    let lock =
        match (m.locked_at, &m.sync0_from_target) {
            (Some(at), Some(t)) => format!(
            "locked at cycle {at}{}; from then on each frame within p50 {:.1} µs, p99 {:.1} µs, \
             max {:.1} µs of the target (half a period after the tick)",
            if m.locked_at_end { ", still locked at the end" } else { ", lost by the end" },
            t.p50 as f64 / 1e3,
            t.p99 as f64 / 1e3,
            t.max as f64 / 1e3
        ),
            _ => "the lock was not won".to_owned(),
        };
    report.note(format!(
        "ethercat: distributed clocks (SYNC0 every 1 ms, {} slaves, bring-up {:.0} ms), each \
         cycle given its timer's due time as the tick's: where each cycle's frame landed in the \
         SYNC0 cycle (ethercrab's cycle_start_offset) p50 {:.1} µs p99 {:.1} µs max {:.1} µs \
         over {} cycles of the 1 kHz loop; {lock}; {} bus fault(s)",
        m.slaves,
        m.bring_up_ms,
        s.p50 as f64 / 1e3,
        s.p99 as f64 / 1e3,
        s.max as f64 / 1e3,
        s.n,
        faults
    ));
}

fn yes(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

fn pct(side: &LoopSide) -> f64 {
    100.0 * side.missed as f64 / side.periods.max(1) as f64
}

/// The target per segment and rate: missed cycles ≤ the bare loop's + 0.5 %.
pub fn targets(report: &Report) -> Vec<Target> {
    let mut out = Vec::new();
    for slaves in SLAVES {
        for hz in RATES {
            let measure = format!("EtherCAT cycles missed, {slaves} slaves at {hz} Hz");
            let goal = format!("≤ the bare timerfd loop's + {MISSED_MARGIN_PCT} %");
            let params = [("slaves", Json::from(slaves)), ("hz", Json::from(hz))];
            let value = |name: &str| {
                modbot_bench_kit::targets::rows_with(report, name, &params)
                    .first()
                    .map(|r| r.p50_ns)
            };
            let rows = (
                value("ethercat.missed"),
                value("ethercat.periods"),
                value("ethercat.bare_missed"),
                value("ethercat.bare_periods"),
            );
            let (Some(missed), Some(periods), Some(bare_missed), Some(bare_periods)) = rows else {
                out.push(modbot_bench_kit::targets::target(
                    &measure,
                    &goal,
                    "not measured in this run (`modbot-benches ethercat`, as root)".to_owned(),
                    None,
                ));
                continue;
            };
            let p = |m: u64, n: u64| 100.0 * m as f64 / n.max(1) as f64;
            let (bus, bare) = (p(missed, periods), p(bare_missed, bare_periods));
            out.push(modbot_bench_kit::targets::target(
                &measure,
                &goal,
                format!("{bus:.3} % ({missed} of {periods}); bare {bare:.3} %"),
                Some(bus <= bare + MISSED_MARGIN_PCT),
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_of_six_drives_is_280_bytes_by_the_formula() {
        assert_eq!(expected_frame(6), 280);
    }

    #[test]
    fn the_missed_cycles_target_allows_half_a_percent_over_the_bare_loop() {
        let mut r = Report::default();
        let p = |row: Row| row.param("slaves", 6).param("hz", 1000).param("fifo", true);
        r.push(p(Row::single("ethercat.bare_periods", 10_000)));
        r.push(p(Row::single("ethercat.bare_missed", 10)));
        r.push(p(Row::single("ethercat.periods", 10_000)));
        r.push(p(Row::single("ethercat.missed", 59)));
        let sut = targets(&r);
        assert_eq!(sut.len(), SLAVES.len() * RATES.len());
        assert_eq!(sut[0].met, Some(true), "{:?}", sut[0]);
        assert!(
            sut[0].measured.starts_with("0.590 %"),
            "{}",
            sut[0].measured
        );
        assert_eq!(sut[1].met, None);
        r.rows[3].p50_ns = 61;
        assert_eq!(targets(&r)[0].met, Some(false));
    }
}
