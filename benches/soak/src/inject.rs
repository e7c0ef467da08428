//! The soak's faults: which module, which fault, and doing it.
//!
//! Once a second a seeded generator picks a target among every module of the system and a
//! kind of fault among those the target takes ([`pick`]): the same seed and targets give the
//! same sequence of picks, whatever happens in the run. A pick whose target is not running at
//! that moment (it is being restarted, or still stopped by an earlier fault) is skipped and
//! counted.
//!
//! Never the supervisor. The coordinator takes floods only: it is the one process that is not
//! restarted (`restart = never`: without it the drives are brought to a safe stop and the grid
//! does not come back without a new `modbot up`), and any stall of its tick thread longer than
//! the bus bridge's watchdog (3 ms) stops every drive — both faults the faults benchmark
//! measures on their own (`faults.quick_stop`); here they would end the arm's part of the soak
//! in its first minutes.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use modbot_bench_kit::sample::Pick;
use modbot_bench_kit::supervised::Supervised;
use modbot_supervisor::status;
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

/// A kind of fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    /// SIGKILL.
    Kill,
    /// SIGSTOP, [`STALL`], SIGCONT.
    Stall,
    /// [`FLOOD_FRAMES`] malformed frames into its inbox.
    Flood,
    /// A consumer that stops reading: SIGSTOP for [`DEAF`] while [`SPAM_REPORTS`] REPORTs are
    /// sent to it as fast as they go (its inbox fills; the sender must not block).
    Deaf,
}

impl Kind {
    /// Every kind, in the order the report lists them.
    pub const ALL: [Kind; 4] = [Kind::Kill, Kind::Stall, Kind::Flood, Kind::Deaf];

    /// The name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Kill => "sigkill",
            Kind::Stall => "sigstop_2s",
            Kind::Flood => "flood",
            Kind::Deaf => "stops_reading",
        }
    }
}

/// How long a stalled module stays stopped.
pub const STALL: Duration = Duration::from_secs(2);
/// How long a consumer stops reading.
pub const DEAF: Duration = Duration::from_millis(500);
/// Garbage frames per flood.
pub const FLOOD_FRAMES: u64 = 500;
/// REPORTs sent to a consumer that stopped reading.
pub const SPAM_REPORTS: u64 = 1000;

/// The name of the grid's coordinator.
const COORDINATOR: &str = modbot_supervisor::processes::COORDINATOR;

/// A module faults are injected into, and the kinds it takes.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    pub name: String,
    pub kinds: Vec<Kind>,
}

/// The targets among the modules `names`: every one but the supervisor; the coordinator
/// takes floods only (see the module documentation).
pub fn targets<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<Target> {
    let mut out: Vec<Target> = names
        .into_iter()
        .filter(|n| *n != "supervisor")
        .map(|n| Target {
            name: n.to_owned(),
            kinds: if n == COORDINATOR {
                vec![Kind::Flood]
            } else {
                Kind::ALL.to_vec()
            },
        })
        .collect();
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out.dedup_by(|a, b| a.name == b.name);
    out
}

/// The next fault: a target (its index) and a kind it takes.
pub fn pick(rng: &mut Pick, targets: &[Target]) -> Option<(usize, Kind)> {
    let i = rng.below(targets.len());
    let t = targets.get(i)?;
    let kind = *t.kinds.get(rng.below(t.kinds.len()))?;
    Some((i, kind))
}

/// What was injected so far.
#[derive(Debug, Default)]
pub struct Injected {
    /// Faults by kind.
    pub by_kind: BTreeMap<Kind, u64>,
    /// Faults by target.
    pub by_target: BTreeMap<String, u64>,
    /// Picks skipped: the target was not running (restarting, or still stopped).
    pub skipped: u64,
    /// Garbage frames sent and refused (the inbox was full).
    pub garbage: (u64, u64),
    /// REPORTs to stopped consumers sent and refused.
    pub spam: (u64, u64),
    /// The longest a burst of [`SPAM_REPORTS`] took the sender.
    pub spam_burst_max: Duration,
    /// Every fault: when (since the injector started), into which module and process.
    pub log: Vec<(Duration, Kind, String, u32)>,
}

/// Injects faults and resumes the modules it stopped.
pub struct Injector {
    rng: Pick,
    targets: Vec<Target>,
    started: Instant,
    /// Processes stopped by a fault, and when to resume them.
    stopped: Vec<(u32, Instant)>,
    pub injected: Injected,
}

impl Injector {
    pub fn new(seed: u64, targets: Vec<Target>) -> Injector {
        Injector {
            rng: Pick::new(seed),
            targets,
            started: Instant::now(),
            stopped: Vec::new(),
            injected: Injected::default(),
        }
    }

    /// Picks the next fault and injects it into the system whose modules are `rows` now.
    pub fn inject(&mut self, sys: &mut Supervised, rows: &[status::Row]) -> anyhow::Result<()> {
        let Some((i, kind)) = pick(&mut self.rng, &self.targets) else {
            return Ok(());
        };
        let name = self.targets[i].name.clone();
        let pid = rows
            .iter()
            .find(|r| r.name == name && r.state == "running" && r.pid != 0)
            .map(|r| r.pid)
            .filter(|&pid| !self.is_stopped(pid));
        let Some(pid) = pid else {
            self.injected.skipped += 1;
            return Ok(());
        };
        match kind {
            Kind::Kill => signal(pid, Signal::SIGKILL),
            Kind::Stall => self.stop(pid, STALL),
            Kind::Flood => {
                let tool = sys.tool()?;
                tool.housekeeping();
                let to = tool.ctx().resolve(&name)?;
                let sent = modbot_modules::faulty::send_garbage(tool.ctx(), to, FLOOD_FRAMES);
                self.injected.garbage.0 += sent;
                self.injected.garbage.1 += FLOOD_FRAMES - sent;
            }
            Kind::Deaf => {
                let tool = sys.tool()?;
                tool.housekeeping();
                let to = tool.ctx().resolve(&name)?;
                self.stop(pid, DEAF);
                let t = Instant::now();
                let sent = modbot_modules::faulty::send_spam(tool.ctx(), to, SPAM_REPORTS);
                let took = t.elapsed();
                self.injected.spam.0 += sent;
                self.injected.spam.1 += SPAM_REPORTS - sent;
                self.injected.spam_burst_max = self.injected.spam_burst_max.max(took);
            }
        }
        *self.injected.by_kind.entry(kind).or_default() += 1;
        *self.injected.by_target.entry(name.clone()).or_default() += 1;
        self.injected
            .log
            .push((self.started.elapsed(), kind, name, pid));
        Ok(())
    }

    /// Whether process `pid` is stopped by a fault now.
    pub fn is_stopped(&self, pid: u32) -> bool {
        self.stopped.iter().any(|&(p, _)| p == pid)
    }

    fn stop(&mut self, pid: u32, for_: Duration) {
        signal(pid, Signal::SIGSTOP);
        self.stopped.push((pid, Instant::now() + for_));
    }

    /// Resumes the stopped modules whose time is up (all of them with `all`).
    pub fn resume(&mut self, all: bool) {
        let now = Instant::now();
        self.stopped.retain(|&(pid, at)| {
            let due = all || now >= at;
            if due {
                signal(pid, Signal::SIGCONT);
            }
            !due
        });
    }
}

impl Drop for Injector {
    fn drop(&mut self) {
        self.resume(true);
    }
}

/// Sends `sig` to `pid`; a process that is gone meanwhile (the supervisor restarted it) is no
/// error.
fn signal(pid: u32, sig: Signal) {
    if let Ok(pid) = i32::try_from(pid) {
        let _ = kill(Pid::from_raw(pid), sig);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names() -> Vec<&'static str> {
        vec![
            "supervisor",
            "journal",
            "mobility",
            "coordinator",
            "host_bus",
            "host_ctrl_g1",
        ]
    }

    #[test]
    fn the_supervisor_is_never_a_target_and_the_coordinator_takes_floods_only() {
        let sut = targets(names());
        assert!(sut.iter().all(|t| t.name != "supervisor"));
        let coordinator = sut.iter().find(|t| t.name == "coordinator").unwrap();
        assert_eq!(coordinator.kinds, [Kind::Flood]);
        let journal = sut.iter().find(|t| t.name == "journal").unwrap();
        assert_eq!(journal.kinds, Kind::ALL);
        assert_eq!(sut.len(), 5);
    }

    #[test]
    fn the_same_seed_gives_the_same_faults_on_every_kind_and_target() {
        let t = targets(names());
        let run = |seed| {
            let mut rng = Pick::new(seed);
            (0..400)
                .map(|_| pick(&mut rng, &t).unwrap())
                .collect::<Vec<_>>()
        };
        let sut = run(7);
        assert_eq!(sut, run(7));
        assert_ne!(sut, run(8));
        for kind in Kind::ALL {
            assert!(sut.iter().any(|&(_, k)| k == kind), "{kind:?} never picked");
        }
        for (i, target) in t.iter().enumerate() {
            let picked = sut.iter().any(|&(j, _)| j == i);
            assert!(picked, "{} never picked", target.name);
        }
        let coordinator = t.iter().position(|t| t.name == "coordinator").unwrap();
        assert!(sut
            .iter()
            .all(|&(i, k)| i != coordinator || k == Kind::Flood));
    }

    #[test]
    fn there_is_no_fault_without_a_target() {
        assert_eq!(pick(&mut Pick::new(1), &[]), None);
    }
}
