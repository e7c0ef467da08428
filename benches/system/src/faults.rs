//! Benchmark 5, faults.
//!
//! **A killed module.** One `modbot-faulty` module under `modbot up` with the on-failure restart
//! policy, a 10 ms backoff and a 50 ms heartbeat (500 ms timeout). Each repetition sends it
//! SIGKILL and measures, from the kill (CLOCK_MONOTONIC in this process):
//! - `faults.detect`: until the supervisor's line "victim ended (killed by SIGKILL); restart
//!   ..." arrives here (the supervisor reaps its children with `waitpid` in its 5 ms loop, so
//!   a SIGKILL is seen without waiting for the heartbeat timeout);
//! - `faults.restart`: until its line "victim is up (pid P)" (the new process announced itself
//!   and sent its first heartbeat);
//! - `faults.first_call`: until a call `victim.ping()` from a long-lived tool endpoint in this
//!   process succeeds (20 ms per attempt, no retransmission, again at once after a failure).
//!   The lines are stamped when this process reads them from the supervisor's stdout pipe.
//!
//! **A lost coordinator.** `examples/arm.lua` (six simulated CiA 402 drives behind the bus
//! bridge, the `hold` assembly): once every drive is in operation enabled, SIGKILL of the
//! coordinator. `faults.quick_stop` is the bus bridge's own record: the time from the last tick
//! the grid served to the cycle at which every drive reported quick stop active (its watchdog
//! acts after 3 silent base periods). A fresh system per repetition: the coordinator is not
//! restarted.
//!
//! **Baselines.** `faults.heartbeat_timeout` (configured, 500 ms): what detection would take if
//! it relied on heartbeats; restart is compared with detection, the first call with the restart;
//! `faults.watchdog_budget` (3 base periods, 3 ms): the bridge's configured watchdog.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use hdrhistogram::Histogram;
use modbot_bench_kit::arm_system::{bus_ledger, start_arm};
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::supervised::{is_supervisor_line, Supervised};
use modbot_bus::bridge::LOST_AFTER;
use modbot_core::{CallOptions, RetryPolicy};
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

/// The victim's supervision settings (also written into the description).
const HEARTBEAT_TIMEOUT: Duration = Duration::from_millis(500);
const BACKOFF: Duration = Duration::from_millis(10);
/// The arm's base period.
const ARM_PERIOD_NS: u64 = 1_000_000;

/// Runs the faults benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    let killed = killed_module(opts, opts.samples(10, 30) as usize);
    match killed {
        Ok(k) => {
            report.push(
                Row::single(
                    "faults.heartbeat_timeout",
                    HEARTBEAT_TIMEOUT.as_nanos() as u64,
                )
                .is_baseline(),
            );
            report.push(
                Row::from_histogram("faults.detect", &k.detect)
                    .against("faults.heartbeat_timeout", &[]),
            );
            report.push(
                Row::from_histogram("faults.restart", &k.restart).against("faults.detect", &[]),
            );
            report.push(
                Row::from_histogram("faults.first_call", &k.first_call)
                    .against("faults.restart", &[]),
            );
            report.note(format!(
                "faults: a module killed {} times (SIGKILL; on-failure policy, backoff {} ms, \
                 heartbeat {} ms / timeout {} ms). Detection is the supervisor's waitpid in its 5 ms \
                 loop, not the heartbeat; its line comes after it cleaned the dead process's \
                 iceoryx2 resources (`reap_dead`), which is part of the time. Restart includes the \
                 {} ms backoff, the process start and the first heartbeat; the first call is a \
                 long-lived caller's ping, which fails fast while its phone book (refreshed every \
                 200 ms) knows the module dead.{}",
                k.detect.len(),
                BACKOFF.as_millis(),
                50,
                HEARTBEAT_TIMEOUT.as_millis(),
                BACKOFF.as_millis(),
                k.remarks
                    .iter()
                    .map(|r| format!(" {r}"))
                    .collect::<String>()
            ));
        }
        Err(e) => report.note(format!(
            "faults: the killed-module measurement failed: {e:#}"
        )),
    }
    let stops = lost_coordinator(opts, opts.samples(5, 20) as usize, report);
    match stops {
        Ok(h) => {
            report.push(
                Row::single("faults.watchdog_budget", LOST_AFTER * ARM_PERIOD_NS).is_baseline(),
            );
            report.push(
                Row::from_histogram("faults.quick_stop", &h).against("faults.watchdog_budget", &[]),
            );
        }
        Err(e) => report.note(format!(
            "faults: the lost-coordinator measurement failed: {e:#}"
        )),
    }
    Ok(())
}

/// No child roles: the victim is `modbot-faulty`, the arm the system's own programs.
pub fn child(_role: &str, _args: &[String]) -> Option<anyhow::Result<()>> {
    None
}

struct Killed {
    detect: Histogram<u64>,
    restart: Histogram<u64>,
    first_call: Histogram<u64>,
    remarks: Vec<String>,
}

fn ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX).max(1)
}

fn killed_module(opts: &Opts, reps: usize) -> anyhow::Result<Killed> {
    let mut scratch = Scratch::new("faults", None)?;
    let file = scratch.path("faults.lua");
    std::fs::write(
        &file,
        format!(
            r#"-- modbot-benches faults: one module, killed and restarted over and over.
domain "{}"
supervision {{ heartbeat_period = 0.05, heartbeat_timeout = {}, start_timeout = 10, stop_grace = 2 }}
module "victim" {{ addr = 10, program = "modbot-faulty",
  restart = {{ policy = "on-failure", max_restarts = 100000, window = 3600, backoff = {b},
              max_backoff = {b}, give_up = "keep-others" }} }}
"#,
            scratch.domain.name(),
            HEARTBEAT_TIMEOUT.as_secs_f64(),
            b = BACKOFF.as_secs_f64()
        ),
    )?;
    let mut sys = Supervised::start(opts, &scratch.domain, &file, &[], Duration::from_secs(10))?;
    sys.wait_up(Duration::from_secs(30))?;
    let mut k = Killed {
        detect: modbot_bench_kit::sample::histogram(),
        restart: modbot_bench_kit::sample::histogram(),
        first_call: modbot_bench_kit::sample::histogram(),
        remarks: Vec::new(),
    };
    let ping = CallOptions::timeout(Duration::from_millis(20)).with_retry(RetryPolicy::NONE);
    let mut attempts = Vec::new();
    for rep in 0..reps {
        // Steady state: the module serves, the caller knows it.
        sys.wait_with_tool("victim to answer ping", Duration::from_secs(10), |t| {
            Ok(t.call_owned("victim", "ping", &[], ping).ok())
        })?;
        let pid = sys.pid_of("victim")?;
        sys.sleep(Duration::from_millis(50))?;
        let killed = Instant::now();
        kill(Pid::from_raw(pid as i32), Signal::SIGKILL)
            .with_context(|| format!("kill the victim (pid {pid})"))?;
        let mut tries = 0u32;
        let served = sys.wait_with_tool("the first call served", Duration::from_secs(10), |t| {
            tries += 1;
            Ok(t.call_owned("victim", "ping", &[], ping)
                .ok()
                .map(|_| Instant::now()))
        })?;
        attempts.push(tries);
        let (detected, _) = sys
            .wait_line(
                "the supervisor to see the kill",
                killed,
                Duration::from_secs(5),
                |l| is_supervisor_line(l) && l.contains("victim ended ("),
            )
            .with_context(|| format!("repetition {rep}"))?;
        let (up, line) = sys.wait_line(
            "the restarted victim",
            killed,
            Duration::from_secs(5),
            |l| is_supervisor_line(l) && l.contains("victim is up (pid"),
        )?;
        if line.contains(&format!("(pid {pid})")) {
            bail!("repetition {rep}: the old process announced itself again: {line}");
        }
        k.detect.saturating_record(ns(detected - killed));
        k.restart.saturating_record(ns(up - killed));
        k.first_call.saturating_record(ns(served - killed));
    }
    attempts.sort_unstable();
    k.remarks.push(format!(
        "Calls tried until the first was served: median {}, most {}.",
        attempts.get(attempts.len() / 2).copied().unwrap_or(0),
        attempts.last().copied().unwrap_or(0)
    ));
    let left = sys.stop()?;
    if !left.is_empty() {
        k.remarks.push(format!(
            "{} file(s) of the domain were left after the stop and removed.",
            left.len()
        ));
    }
    Ok(k)
}

/// What one repetition measured: the bridge's base periods from the last tick to every drive in
/// quick stop, when this process saw it after the kill, and a remark.
type QuickStop = (f64, Duration, Option<String>);

/// One repetition on a fresh arm, or why it was skipped.
fn stop_after_lost_coordinator(
    opts: &Opts,
    rep: usize,
) -> anyhow::Result<Result<QuickStop, String>> {
    let scratch = Scratch::new(&format!("lostcoord{rep}"), None)?;
    let (mut sys, _) = start_arm(opts, &scratch, &[])?;
    sys.sleep(Duration::from_millis(300))?;
    let before = sys.call_text("host_bus", "bus")?;
    let first = before.lines().next().unwrap_or_default().to_owned();
    if first.contains("SAFE STOP") {
        sys.stop()?;
        return Ok(Err(format!(
            "the drives were already in safe stop before the kill (the coordinator stalled \
             past the watchdog): {first}"
        )));
    }
    let pid = sys.pid_of("coordinator")?;
    let killed = Instant::now();
    kill(Pid::from_raw(pid as i32), Signal::SIGKILL)
        .with_context(|| format!("kill the coordinator (pid {pid})"))?;
    let (periods, at) =
        sys.wait_with_tool("every drive in quick stop", Duration::from_secs(10), |t| {
            Ok(bus_ledger(t)
                .as_deref()
                .and_then(stopped_after)
                .map(|x| (x, Instant::now())))
        })?;
    let left = sys.stop()?;
    let remark = (!left.is_empty())
        .then(|| format!("{} file(s) were left after the stop (removed)", left.len()));
    Ok(Ok((periods, at - killed, remark)))
}

/// "…; every drive stopped at cycle C, X base periods after the last tick" → X.
fn stopped_after(ledger: &str) -> Option<f64> {
    let first = ledger.lines().next()?;
    let rest = first.split("every drive stopped at cycle ").nth(1)?;
    let after = rest.split(", ").nth(1)?;
    after.split_whitespace().next()?.parse().ok()
}

fn lost_coordinator(
    opts: &Opts,
    reps: usize,
    report: &mut Report,
) -> anyhow::Result<Histogram<u64>> {
    let mut h = modbot_bench_kit::sample::histogram();
    let mut seen = Vec::new();
    let mut problems = Vec::new();
    for rep in 0..reps {
        match stop_after_lost_coordinator(opts, rep) {
            Ok(Ok((periods, after_kill, remark))) => {
                h.saturating_record(((periods * ARM_PERIOD_NS as f64) as u64).max(1));
                seen.push(after_kill.as_secs_f64() * 1e3);
                problems.extend(remark.map(|r| format!("repetition {rep}: {r}")));
            }
            Ok(Err(skipped)) => problems.push(format!("repetition {rep}: {skipped}")),
            Err(e) => {
                problems.push(format!("repetition {rep} failed: {e:#}"));
                procs::check_interrupted()?;
            }
        }
    }
    if h.is_empty() {
        bail!("no repetition measured: {}", problems.join("; "));
    }
    seen.sort_by(f64::total_cmp);
    report.note(format!(
        "faults: quick stop after SIGKILL of the coordinator ({} repetitions, a fresh \
         examples/arm.lua each): the bus bridge's record, last tick → every drive in quick stop \
         active; seen from this process (polling `host_bus.bus` every 2 ms) {:.1} ms after the \
         kill at the median.{}",
        h.len(),
        seen.get(seen.len() / 2).copied().unwrap_or(0.0),
        problems
            .iter()
            .map(|p| format!(" {p}."))
            .collect::<String>()
    ));
    Ok(h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stop_record_of_the_bus_ledger_reads_back() {
        let ledger = "bus sim  axes 6  cycles 900  missed 0  SAFE STOP at cycle 812: coordinator \
                      lost: no tick for 3 base periods; every drive stopped at cycle 815, 6.02 base \
                      periods after the last tick\nAXIS ...\n";
        assert_eq!(stopped_after(ledger), Some(6.02));
        assert_eq!(
            stopped_after("bus sim  axes 6  cycles 9  missed 0  running\n"),
            None
        );
    }
}
