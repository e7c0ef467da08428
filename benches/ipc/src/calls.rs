//! Benchmark 1: the round trip of a method call (EXEC→REPLY) between two module processes,
//! against raw iceoryx2 and a Unix socket, for payloads from 8 B to 1 MiB.
//!
//! Rows (param `bytes`, the payload):
//! - `calls.modbot_busy`: both modules in busy-poll mode; baseline `calls.raw_iceoryx2_busy`,
//!   measured interleaved with it ([`modbot_bench_kit::interleave`]: alternating blocks, the ratio the
//!   median of the blocks' ratios);
//! - `calls.modbot_blocking`: both in blocking mode (Event wake-ups); baseline
//!   `calls.uds_blocking`, interleaved the same way;
//! - `calls.raw_iceoryx2_busy`, `calls.raw_iceoryx2_event`, `calls.uds_blocking`: the
//!   baselines, each its own;
//! - `calls.modbot_work` against `calls.raw_iceoryx2_work`: the CPU work of a call, both sides
//!   in one thread ([`crate::work`]).
//!
//! Every path copies the payload in on the way out and out on the way back, on both sides:
//! the modbot client copies the answer out of shared memory, as the raw client does. The echo
//! module answers with its arguments. Frames beyond the default 64 KiB need a domain with a
//! larger maximum frame ([`modbot_core::Domain::with_max_frame`]): every size class runs in
//! a domain sized for it, so small calls are not measured in a 1 MiB system.
//!
//! The paths are in [`crate::paths`], the echo module in [`crate::echo`].

use std::time::Duration;

use anyhow::bail;
use modbot_bench_kit::interleave::{interleave, Side, BLOCKS};
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs;
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::sample::{self, size_label, Plan};
use modbot_core::transport::launch::inbox_senders_for;
use modbot_core::ReceiveMode;

use crate::paths::{ModbotPath, Path, RawPath, UdsPath, LOOK};
use crate::raw::Wait;

/// The payloads, in bytes.
pub const SIZES: [usize; 5] = [8, 64, 4096, 64 * 1024, 1 << 20];

/// SCHED_FIFO priority of both sides of the blocking rows under `--fifo`.
const FIFO_PRIO: u8 = 50;

/// The largest frame a call with a payload of `bytes` needs (encoding and header included).
pub fn frame_for(bytes: usize) -> usize {
    bytes + 64
}

/// Payload sizes grouped by the domain's max frame they need: the default, or larger.
fn size_classes(sizes: &[usize]) -> Vec<(usize, Vec<usize>)> {
    let mut classes: Vec<(usize, Vec<usize>)> = Vec::new();
    for &s in sizes {
        let frame = frame_for(s).max(modbot_core::domain::DEFAULT_MAX_FRAME);
        match classes.iter_mut().find(|(f, _)| *f == frame) {
            Some((_, v)) => v.push(s),
            None => classes.push((frame, vec![s])),
        }
    }
    classes
}

/// Runs benchmark 1.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    if procs::cores() < 2 {
        bail!(
            "busy-poll round trips need two cores; this machine has {}",
            procs::cores()
        );
    }
    let _pinned = procs::pin(procs::core_for(opts, 0))?;
    let fifo = opts.fifo.then_some(FIFO_PRIO);
    for (max_frame, sizes) in size_classes(&SIZES) {
        let class = size_label(*sizes.last().unwrap_or(&0));
        let c = Class {
            opts,
            max_frame,
            sizes: &sizes,
            fifo,
        };
        let pairs: [(&str, PairFn); 3] = [
            ("modbot busy against raw iceoryx2 busy", busy_pair),
            ("modbot blocking against the Unix socket", blocking_pair),
            ("raw iceoryx2 event", raw_event),
        ];
        for (what, pair) in pairs {
            procs::check_interrupted()?;
            if let Err(e) = pair(&c, report) {
                procs::check_interrupted()?;
                report.note(format!(
                    "calls: {what} (payloads up to {class}) failed: {e:#}"
                ));
            }
        }
    }
    if let Err(e) = crate::work::run(opts, report) {
        procs::check_interrupted()?;
        report.note(format!("calls: the _work rows failed: {e:#}"));
    }
    report.note(format!(
        "calls: each modbot row and its baseline were measured interleaved, in {BLOCKS} \
         alternating blocks with both sides' processes kept up (the idle side's server stopped \
         with SIGSTOP), so the machine's changes hit both alike; a row's ratio is the median of \
         the blocks' ratios of medians, with their range. The modbot rows use \
         CallOptions::default() (2 s timeout, 2 retransmissions, so the request payload is also \
         kept for retransmission; in blocking mode the caller looks for its answer and the echo \
         module for the next call {} µs before sleeping, adaptively (ModuleBuilder::linger), \
         where the Unix-socket sides sleep at once, as both modbot sides of the _no_spin rows \
         do; the _paced rows pause 200 µs before each call, so that both sides sleep when it \
         starts) and \
         inboxes with the {} sender slots a supervisor gives a system of two modules \
         (MODBOT_INBOX_SENDERS); every path copies the payload in and out on both sides; {}",
        LOOK.as_micros(),
        inbox_senders_for(2),
        if opts.pin {
            "client pinned to core 0, servers to core 1"
        } else {
            "processes not pinned (--pin pins them to cores 0 and 1)"
        }
    ));
    if opts.fifo {
        report.note(format!(
            "calls: the blocking rows (modbot_blocking, raw_iceoryx2_event, uds_blocking) ran \
             both sides under SCHED_FIFO {FIFO_PRIO}; busy rows never run under SCHED_FIFO"
        ));
    }
    Ok(())
}

/// The payloads of one size class, measured in a domain of their max frame.
#[derive(Clone, Copy)]
struct Class<'a> {
    opts: &'a Opts,
    /// The domain's max frame.
    max_frame: usize,
    /// The payloads, in bytes.
    sizes: &'a [usize],
    /// The SCHED_FIFO priority of both sides of the blocking rows, if any.
    fifo: Option<u8>,
}

/// Measures one pair of paths (or one path) of a size class into the report.
type PairFn = fn(&Class<'_>, &mut Report) -> anyhow::Result<()>;

/// `calls.modbot_busy` interleaved with `calls.raw_iceoryx2_busy`.
fn busy_pair(c: &Class<'_>, report: &mut Report) -> anyhow::Result<()> {
    let mut modbot = ModbotPath::open(c.opts, ReceiveMode::BusyPoll, c.max_frame, None, LOOK)?;
    let mut raw = RawPath::open(c.opts, Wait::Busy, c.max_frame, c.sizes, None)?;
    let rows = ("calls.modbot_busy", "calls.raw_iceoryx2_busy");
    let result = pair_sizes(c.opts, report, c.sizes, rows, &mut modbot, &mut raw, None);
    modbot.close(report, c.sizes)?;
    raw.close()?;
    result
}

/// `calls.modbot_blocking` interleaved with `calls.uds_blocking`.
fn blocking_pair(c: &Class<'_>, report: &mut Report) -> anyhow::Result<()> {
    let mut modbot = ModbotPath::open(c.opts, ReceiveMode::Blocking, c.max_frame, c.fifo, LOOK)?;
    let mut uds = UdsPath::open(c.opts, c.sizes, c.fifo)?;
    let _fifo = procs::set_fifo(c.fifo)?;
    let rows = ("calls.modbot_blocking", "calls.uds_blocking");
    let mut result = pair_sizes(c.opts, report, c.sizes, rows, &mut modbot, &mut uds, None);
    // The c.sizes of the targets again: each call after a pause, so that both sides sleep when
    // it starts (calls back to back find a server that has not gone to sleep yet); then back
    // to back with both sides sleeping at once (no look, no linger), the wake-ups alone.
    let target_sizes: Vec<usize> = c
        .sizes
        .iter()
        .copied()
        .filter(|s| [8, 4096].contains(s))
        .collect();
    if result.is_ok() && !target_sizes.is_empty() {
        let rows = ("calls.modbot_blocking_paced", "calls.uds_blocking_paced");
        let pace = Some(PACE);
        result = pair_sizes(
            c.opts,
            report,
            &target_sizes,
            rows,
            &mut modbot,
            &mut uds,
            pace,
        );
    }
    if result.is_ok() && !target_sizes.is_empty() {
        // An echo module of its own, which sleeps at once too.
        let mut sleeper = ModbotPath::open(
            c.opts,
            ReceiveMode::Blocking,
            c.max_frame,
            c.fifo,
            Duration::ZERO,
        )?;
        let rows = (
            "calls.modbot_blocking_no_spin",
            "calls.uds_blocking_beside_no_spin",
        );
        result = pair_sizes(
            c.opts,
            report,
            &target_sizes,
            rows,
            &mut sleeper,
            &mut uds,
            None,
        );
        sleeper.close(report, c.sizes)?;
    }
    modbot.close(report, c.sizes)?;
    uds.close()?;
    result
}

/// The pause before each call of the paced rows: long enough for both sides to sleep.
const PACE: Duration = Duration::from_micros(200);

/// Every size of `sizes` with `subject` interleaved with `baseline`: rows `names.0` (ratio over
/// the blocks) and `names.1` (the baseline, its own). With `pace`, each round trip follows a
/// pause of that long (not measured), with a tenth of the samples.
fn pair_sizes(
    opts: &Opts,
    report: &mut Report,
    sizes: &[usize],
    names: (&str, &str),
    subject: &mut dyn Path,
    baseline: &mut dyn Path,
    pace: Option<Duration>,
) -> anyhow::Result<()> {
    for &size in sizes {
        let payload = vec![0x5a_u8; size];
        let plan = match pace {
            None => Plan::for_bytes(opts, size),
            Some(_) => Plan::new(opts, Plan::for_bytes(opts, size).n / 10),
        };
        let servers = (subject.server().pid(), baseline.server().pid());
        let pause = || {
            if let Some(p) = pace {
                std::thread::sleep(p);
            }
        };
        let mut a = || {
            pause();
            subject.one(&payload)
        };
        let mut b = || {
            pause();
            baseline.one(&payload)
        };
        let measured = interleave(
            &plan,
            Side {
                one: &mut a,
                server: Some(servers.0),
            },
            Side {
                one: &mut b,
                server: Some(servers.1),
            },
        );
        match measured {
            Ok(pair) => {
                report.push(
                    Row::from_histogram(names.0, &pair.subject)
                        .param("bytes", size)
                        .against(names.1, &[])
                        .blocks(pair.blocks),
                );
                report.push(
                    Row::from_histogram(names.1, &pair.baseline)
                        .param("bytes", size)
                        .is_baseline(),
                );
            }
            Err(e) => {
                procs::check_interrupted()?;
                report.note(format!(
                    "calls: {} against {} with {} failed: {e:#}",
                    names.0,
                    names.1,
                    size_label(size)
                ));
                subject.server().check_running()?;
                baseline.server().check_running()?;
            }
        }
    }
    Ok(())
}

/// The raw iceoryx2 rows with Event wake-ups (a baseline of its own, not interleaved).
fn raw_event(c: &Class<'_>, report: &mut Report) -> anyhow::Result<()> {
    let mut raw = RawPath::open(c.opts, Wait::Event, c.max_frame, c.sizes, c.fifo)?;
    let _fifo = procs::set_fifo(c.fifo)?;
    for &size in c.sizes {
        let payload = vec![0x5a_u8; size];
        let h = sample::record(&Plan::for_bytes(c.opts, size), || raw.one(&payload))?;
        report.push(
            Row::from_histogram("calls.raw_iceoryx2_event", &h)
                .param("bytes", size)
                .is_baseline(),
        );
    }
    raw.close()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payloads_up_to_64_kib_share_the_default_domain() {
        let classes = size_classes(&SIZES);
        assert_eq!(classes.len(), 2);
        assert_eq!(
            classes[0],
            (
                modbot_core::domain::DEFAULT_MAX_FRAME,
                vec![8, 64, 4096, 65536]
            )
        );
        assert_eq!(classes[1].1, vec![1 << 20]);
    }
}
