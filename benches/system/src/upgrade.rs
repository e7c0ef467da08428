//! Benchmark 14, live upgrades (`modbot upgrade`).
//!
//! One `modbot-faulty` module (`target`) under `modbot up`; this process calls its `ping()` 1 000
//! times a second from a module endpoint of its own (asynchronous calls, blocking mode), for a
//! steady phase without upgrades, then for a phase in which `modbot upgrade target` runs again
//! and again (the same program, rebuilt in place as far as the runtime knows).
//!
//! - `upgrade.call_steady` (baseline): the round trip of the calls of the steady phase;
//! - `upgrade.call_during`: the round trip of the calls sent while an upgrade was under way
//!   (from the `modbot upgrade` command's start to its end): the latency an upgrade adds;
//! - `upgrade.handover`: per upgrade, from the moment the running process stopped serving
//!   (`upgrade_out`) to the new process serving the frames that came meanwhile (the new
//!   process's own record, "handover N us"): the longest a call waits for the switch;
//! - `upgrade.total`: per upgrade, the supervisor's time from the request to the new process's
//!   first heartbeat (the new process's start included), against the handover.
//!
//! - the grid part (`upgrade_grid`): a host of the time grid upgraded while the arm moves, its
//!   components' overruns and the missed ticks per upgrade against windows without.
//!
//! Every call must be answered exactly once: a call answered twice, not at all, or with an error
//! fails the benchmark.

use std::collections::HashMap;
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use hdrhistogram::Histogram;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::supervised::Supervised;
use modbot_core::calls::CallHandle;
use modbot_core::{Args, CallError, CallOptions, Ctx, IpcTransport, ModuleBuilder, ReceiveMode};

/// Calls a second.
const RATE_HZ: u64 = 1000;

/// Runs the upgrade benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    let upgrades = opts.samples(5, 30) as usize;
    let m = measure(opts, upgrades)?;
    report.push(Row::from_histogram("upgrade.call_steady", &m.steady).is_baseline());
    report.push(
        Row::from_histogram("upgrade.call_during", &m.during).against("upgrade.call_steady", &[]),
    );
    report.push(Row::from_histogram("upgrade.handover", &m.handover).is_baseline());
    report.push(Row::from_histogram("upgrade.total", &m.total).against("upgrade.handover", &[]));
    let mut slowest = m.slowest.clone();
    slowest.sort_unstable();
    let median = slowest.get(slowest.len() / 2).copied().unwrap_or_default();
    report.note(format!(
        "upgrade: {} live upgrades of a module under {RATE_HZ} calls/s ({} calls during upgrades, \
         {} steady); every call answered exactly once. The handover is the new process's own \
         record, from the old process's `upgrade_out` to the frames that came meanwhile served; \
         the total adds the new process's start and its first heartbeat. The median upgrade's \
         slowest call took {:.1} ms and was sent {:.1} ms after `modbot upgrade` started; {} \
         call(s) were held back (32 waited for the module already).",
        m.total.len(),
        m.during.len(),
        m.steady.len(),
        median.0 as f64 / 1e6,
        median.1 as f64 / 1e6,
        m.held_back
    ));
    crate::upgrade_grid::run(opts, report)
}

/// No child roles: the module is `modbot-faulty`.
pub fn child(_role: &str, _args: &[String]) -> Option<anyhow::Result<()>> {
    None
}

struct Measured {
    steady: Histogram<u64>,
    during: Histogram<u64>,
    handover: Histogram<u64>,
    total: Histogram<u64>,
    /// Per upgrade: its slowest call's round trip and when it was sent, from the upgrade's
    /// start (ns).
    slowest: Vec<(u64, u64)>,
    /// Calls not sent because 32 waited for the module already.
    held_back: u64,
}

/// The stream's caller: when each call was sent, and when it was answered.
#[derive(Default)]
struct Stream {
    sent: HashMap<u64, Instant>,
    /// (sent, answered) per answered call.
    answered: Vec<(Instant, Instant)>,
    failed: Vec<String>,
}

fn on_done(s: &mut Stream, _: &mut Ctx, h: CallHandle, r: Result<&Args<'_>, &CallError>) {
    let Some(sent) = s.sent.remove(&h.id()) else {
        s.failed
            .push(format!("an answer to call {} not waited for", h.id()));
        return;
    };
    match r {
        Ok(_) => s.answered.push((sent, Instant::now())),
        Err(e) => s.failed.push(e.to_string()),
    }
}

fn measure(opts: &Opts, upgrades: usize) -> anyhow::Result<Measured> {
    let mut scratch = Scratch::new("upgrade", None)?;
    let file = scratch.path("upgrade.lua");
    std::fs::write(
        &file,
        format!(
            r#"-- modbot-benches upgrade: one module upgraded live, over and over.
domain "{}"
supervision {{ heartbeat_period = 0.05, heartbeat_timeout = 5, start_timeout = 20, stop_grace = 2 }}
module "target" {{ addr = 10, program = "modbot-faulty" }}
"#,
            scratch.domain.name()
        ),
    )?;
    let mut sys = Supervised::start(opts, &scratch.domain, &file, &[], Duration::from_secs(10))?;
    sys.wait_up(Duration::from_secs(30))?;
    let transport = IpcTransport::new(&scratch.domain)?;
    let mut caller = ModuleBuilder::<Stream>::new("upgrade-bench", 0)
        .mode(ReceiveMode::Blocking)
        .peer("target")
        .on_done(on_done)
        .open_tool(transport, Stream::default())?;
    let opts_call = CallOptions::timeout(Duration::from_secs(10));
    // Warm: the method table learned, the links open.
    caller
        .call_owned("target", "ping", &[], opts_call)
        .context("the first ping")?;
    // The upgrades run one after the other on a thread of their own; each one's window.
    let windows: Arc<Mutex<Vec<(Instant, Instant)>>> = Arc::default();
    let modbot = procs::binary(opts, "modbot")?;
    let domain = scratch.domain.name().to_owned();
    let steady_for = Duration::from_millis(200 * upgrades as u64).max(Duration::from_secs(2));
    let mut upgrader = None;
    let started = Instant::now();
    let mut next = started;
    let mut upgrades_done = None;
    let mut held_back = 0u64;
    loop {
        let now = Instant::now();
        if now >= next {
            match caller.ctx().call_with("target", "ping", &[], opts_call) {
                Ok(h) => {
                    caller.state_mut().sent.insert(h.id(), now);
                }
                // 32 calls wait already: not sent (the stream is held back), not a failure.
                Err(CallError::TooManyOutstanding(_)) => held_back += 1,
                Err(e) => caller.state_mut().failed.push(e.to_string()),
            }
            next += Duration::from_nanos(1_000_000_000 / RATE_HZ);
        }
        while caller.poll_once()? {}
        caller.housekeeping();
        if upgrader.is_none() && now.duration_since(started) >= steady_for {
            let (modbot, domain, windows) = (modbot.clone(), domain.clone(), windows.clone());
            upgrader = Some(std::thread::spawn(move || -> anyhow::Result<()> {
                for i in 0..upgrades {
                    let begin = Instant::now();
                    let out = Command::new(&modbot)
                        .args(["upgrade", "target", "--domain", &domain])
                        .output()?;
                    if !out.status.success() {
                        bail!(
                            "upgrade {}: {}{}",
                            i + 1,
                            String::from_utf8_lossy(&out.stdout),
                            String::from_utf8_lossy(&out.stderr)
                        );
                    }
                    windows
                        .lock()
                        .expect("not poisoned")
                        .push((begin, Instant::now()));
                    std::thread::sleep(Duration::from_millis(100));
                }
                Ok(())
            }));
        }
        if upgrades_done.is_none() && upgrader.as_ref().is_some_and(|u| u.is_finished()) {
            upgrades_done = Some(Instant::now());
        }
        if upgrades_done.is_some_and(|t| t.elapsed() > Duration::from_millis(200)) {
            break;
        }
        caller.wait_for_frame(next.saturating_duration_since(Instant::now()))?;
    }
    if let Some(u) = upgrader {
        u.join()
            .map_err(|_| anyhow::anyhow!("the upgrader panicked"))??;
    }
    let deadline = Instant::now() + Duration::from_secs(20);
    while !caller.state().sent.is_empty() && Instant::now() < deadline {
        while caller.poll_once()? {}
        caller.housekeeping();
        caller.wait_for_frame(Duration::from_millis(5))?;
    }
    let stream = caller.state();
    if !stream.failed.is_empty() || !stream.sent.is_empty() {
        bail!(
            "{} call(s) failed and {} unanswered; the first failure: {:?}",
            stream.failed.len(),
            stream.sent.len(),
            stream.failed.first()
        );
    }
    let windows = windows.lock().expect("not poisoned").clone();
    let first_upgrade = windows.first().map_or(next, |w| w.0);
    let mut m = Measured {
        steady: modbot_bench_kit::sample::histogram(),
        during: modbot_bench_kit::sample::histogram(),
        handover: modbot_bench_kit::sample::histogram(),
        total: modbot_bench_kit::sample::histogram(),
        slowest: vec![(0, 0); windows.len()],
        held_back,
    };
    for &(sent, answered) in &stream.answered {
        if let Some(w) = windows.iter().position(|&(a, b)| sent >= a && sent <= b) {
            let rtt = ns(answered - sent);
            if rtt > m.slowest[w].0 {
                m.slowest[w] = (rtt, ns(sent - windows[w].0));
            }
        }
        let rtt = ns(answered - sent);
        if sent < first_upgrade {
            m.steady.saturating_record(rtt);
        } else if windows.iter().any(|&(a, b)| sent >= a && sent <= b) {
            m.during.saturating_record(rtt);
        }
    }
    drop(caller);
    for line in sys.lines_with("handover ") {
        if let Some(us) = number_before(&line, " us") {
            m.handover.saturating_record(us * 1000);
        }
    }
    for line in sys.lines_with("target upgraded:") {
        if let Some(ms) = number_before(&line, " ms") {
            m.total.saturating_record(ms * 1_000_000);
        }
    }
    if m.handover.len() != upgrades as u64 || m.total.len() != upgrades as u64 {
        bail!(
            "{upgrades} upgrades, {} handover and {} total time(s) in the log",
            m.handover.len(),
            m.total.len()
        );
    }
    sys.stop()?;
    Ok(m)
}

fn ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX).max(1)
}

/// The number just before the last `unit` in `line` ("... in 41 ms" → 41).
fn number_before(line: &str, unit: &str) -> Option<u64> {
    let head = &line[..line.rfind(unit)?];
    head.rsplit(' ').next()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_times_are_read_from_the_modules_lines() {
        assert_eq!(
            number_before("target | ... served; handover 812 us", " us"),
            Some(812)
        );
        assert_eq!(
            number_before(
                "modbot | target upgraded: pid 1 -> 2, upgrade 3, in 41 ms",
                " ms"
            ),
            Some(41)
        );
        assert_eq!(number_before("no time here", " ms"), None);
    }
}
