//! Motions during the soak: a robot program that moves the arm back and forth without end
//! (`modbot program run`, a child of this process in the soak's domain, with the soak's own
//! assembly data), started again whenever it ends, and its command runs judged at the end.
//!
//! A program stops at the first motion refused (the robot is not operational) or failed (the
//! robot left operational during it, the assembly faulted, ...); the soak starts it again at
//! the next second, after its reset. Every run is kept in assembly data (`Store::runs`): a
//! motion is a `ptp` (assembly `goto`; a refused one never switched, so its assembly is
//! empty). **Falsely reported ok**: an ok motion whose ticks meet a span in which the soak saw
//! the robot not operational ([`crate::robot::Watch::spans`]) — nothing may pretend to move.

use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use anyhow::Context;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Proc};
use modbot_data::Run;

use crate::robot::Span;

/// The program: between two poses, 1 rad/s, for ever.
pub const PROGRAM: &str = "\
-- modbot-benches soak: the arm back and forth without end; a refused or failed motion ends it
-- and the soak starts it again.
while true do
  ptp { q = { 0.2, -0.1, 0.1, 0, 0, 0 }, v = 1 }
  ptp { q = { 0, 0, 0, 0, 0, 0 }, v = 1 }
end
";

/// The program's command whose runs are motions, and its assembly.
const MOTION: (&str, &str) = ("ptp", "goto");

/// The program, kept running.
pub struct Program {
    modbot: PathBuf,
    file: PathBuf,
    domain: String,
    /// `MODBOT_DATA_DIR` of the program (and of the system, whose assemblies read it).
    data_dir: PathBuf,
    /// Its stdout and stderr, every start after the other.
    log: File,
    child: Option<Proc>,
    /// How often it was started.
    pub starts: u64,
    /// How its runs ended: exit status → how many.
    pub exits: std::collections::BTreeMap<String, u64>,
}

impl Program {
    /// Writes [`PROGRAM`] to `file`; its output goes to `log`.
    pub fn new(
        opts: &Opts,
        file: &Path,
        domain: &str,
        data_dir: &Path,
        log: &Path,
    ) -> anyhow::Result<Program> {
        std::fs::write(file, PROGRAM)
            .with_context(|| format!("cannot write {}", file.display()))?;
        Ok(Program {
            modbot: procs::binary(opts, "modbot")?,
            file: file.to_owned(),
            domain: domain.to_owned(),
            data_dir: data_dir.to_owned(),
            log: File::create(log).with_context(|| format!("cannot write {}", log.display()))?,
            child: None,
            starts: 0,
            exits: Default::default(),
        })
    }

    /// Starts the program unless it runs; `at`: the soak's time, for the log.
    pub fn keep_running(&mut self, at: Duration) -> anyhow::Result<()> {
        if let Some(child) = self.child.as_mut() {
            match child.wait_timeout(Duration::ZERO)? {
                None => return Ok(()),
                Some(status) => {
                    *self.exits.entry(status.to_string()).or_default() += 1;
                    self.child = None;
                }
            }
        }
        self.starts += 1;
        writeln!(
            self.log,
            "--- soak {:.3} s: start {} of the program",
            at.as_secs_f64(),
            self.starts
        )?;
        let mut cmd = Command::new(&self.modbot);
        cmd.args(["program", "run"])
            .arg(&self.file)
            .args(["--domain", &self.domain])
            .env(modbot_data::DATA_DIR_ENV, &self.data_dir)
            .stdin(Stdio::null())
            .stdout(self.log.try_clone()?)
            .stderr(self.log.try_clone()?);
        modbot_bench_kit::supervised::die_with_parent(&mut cmd);
        let child = cmd
            .spawn()
            .with_context(|| format!("cannot start {} program run", self.modbot.display()))?;
        self.child =
            Some(Proc::new(child, "modbot program run").with_grace(Duration::from_secs(5)));
        Ok(())
    }

    /// Stops the program (SIGTERM: it stops its motion and leaves the robot holding).
    pub fn stop(&mut self) -> anyhow::Result<()> {
        if let Some(child) = self.child.take() {
            let status = child.stop()?;
            *self.exits.entry(status.to_string()).or_default() += 1;
        }
        Ok(())
    }

    /// The command runs the program left in the soak's assembly data.
    pub fn runs(&self) -> anyhow::Result<Vec<Run>> {
        // Where modbot_data::path_for puts a domain's file under MODBOT_DATA_DIR.
        let path = self.data_dir.join(format!("{}.redb", self.domain));
        let Some(store) = modbot_data::Store::open_existing(&path)? else {
            anyhow::bail!("the program left no assembly data in {}", path.display());
        };
        Ok(store.runs()?.into_iter().map(|(_, r)| r).collect())
    }
}

impl Drop for Program {
    fn drop(&mut self) {
        let _ = self.stop();
    }
}

/// What became of a motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    Ok,
    /// Refused: the robot was not operational ("the robot is in safe stop since ...").
    Refused,
    /// Failed: the robot left operational during it.
    LeftOperational,
    /// Stopped by the soak's end (SIGTERM: "interrupted (Ctrl-C)").
    Interrupted,
    /// Failed for another reason.
    Failed,
}

/// Whether `run` is a motion of the program.
pub fn is_motion(run: &Run) -> bool {
    run.command == MOTION.0 || run.assembly == MOTION.1
}

/// What became of motion `run`.
pub fn verdict(run: &Run) -> Verdict {
    let o = run.outcome.as_str();
    if run.ok() {
        Verdict::Ok
    } else if o.contains("left operational during the motion") {
        Verdict::LeftOperational
    } else if o.contains("the robot is in ") || o.contains("the robot is disabled") {
        Verdict::Refused
    } else if o.contains("interrupted (Ctrl-C)") {
        Verdict::Interrupted
    } else {
        Verdict::Failed
    }
}

/// The motions, judged.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Tally {
    pub motions: u64,
    pub ok: u64,
    pub refused: u64,
    pub left_operational: u64,
    pub interrupted: u64,
    /// The other failures' outcomes.
    pub failed: Vec<String>,
    /// Ok motions that meet a span of a robot not operational: (start, end, the span).
    pub false_ok: Vec<(u64, u64, String)>,
    /// Runs of other commands (none expected).
    pub others: u64,
}

/// Judges `runs` against the `spans` in which the robot was not operational.
pub fn tally(runs: &[Run], spans: &[Span]) -> Tally {
    let mut t = Tally::default();
    for run in runs {
        if !is_motion(run) {
            t.others += 1;
            continue;
        }
        t.motions += 1;
        match verdict(run) {
            Verdict::Ok => {
                t.ok += 1;
                if let Some(s) = spans.iter().find(|s| meets(run, s)) {
                    t.false_ok
                        .push((run.start_tick, run.end_tick, s.what.clone()));
                }
            }
            Verdict::Refused => t.refused += 1,
            Verdict::LeftOperational => t.left_operational += 1,
            Verdict::Interrupted => t.interrupted += 1,
            Verdict::Failed => t.failed.push(run.outcome.clone()),
        }
    }
    t
}

/// Whether the ticks of `run`, start to end, meet `span`: the robot was not operational in
/// one of them. A run that starts at the tick the robot is operational again does not.
pub fn meets(run: &Run, span: &Span) -> bool {
    span.from <= run.end_tick && span.to.is_none_or(|to| run.start_tick < to)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(command: &str, assembly: &str, ticks: (u64, u64), outcome: &str) -> Run {
        Run {
            command: command.into(),
            assembly: assembly.into(),
            origin: "soak_program.lua:4".into(),
            start_tick: ticks.0,
            end_tick: ticks.1,
            outcome: outcome.into(),
            values: Vec::new(),
        }
    }

    fn span(from: u64, to: Option<u64>) -> Span {
        Span {
            from,
            to,
            what: format!("{from}..{to:?}"),
        }
    }

    #[test]
    fn motions_are_told_apart_by_what_became_of_them() {
        let refused = "failed: ptp: the robot is in safe stop since tick 4012 (coordinator \
                       lost: no tick for 3 base periods); `modbot robot reset --domain d` (or \
                       `reset {}`) brings it back";
        let left = "failed: ptp: the robot left operational during the motion: it is in fault \
                    since tick 7 (drive 2 fault 0x8611: following error)";
        let runs = [
            run("ptp", "goto", (10, 900), "ok"),
            run("ptp", "", (0, 0), refused),
            run("ptp", "goto", (1000, 1400), left),
            run(
                "ptp",
                "goto",
                (1500, 1600),
                "failed: ptp: interrupted (Ctrl-C)",
            ),
            run(
                "ptp",
                "goto",
                (1700, 1800),
                "failed: ptp: the assembly faulted: watch",
            ),
            run("wait", "", (1, 2), "ok"),
        ];
        let sut = tally(&runs, &[]);
        assert_eq!(
            (
                sut.motions,
                sut.ok,
                sut.refused,
                sut.left_operational,
                sut.interrupted
            ),
            (5, 1, 1, 1, 1)
        );
        assert_eq!(sut.failed, ["failed: ptp: the assembly faulted: watch"]);
        assert_eq!(sut.others, 1);
        assert!(sut.false_ok.is_empty());
    }

    #[test]
    fn an_ok_motion_across_a_stop_is_a_false_ok() {
        let spans = [span(4012, Some(4600)), span(9000, None)];
        let runs = [
            run("ptp", "goto", (3000, 4011), "ok"),
            run("ptp", "goto", (4600, 5000), "ok"),
            run("ptp", "goto", (4000, 4012), "ok"),
            run("ptp", "goto", (4599, 4700), "ok"),
            run("ptp", "goto", (8000, 9500), "ok"),
            run(
                "ptp",
                "goto",
                (4000, 5000),
                "failed: ptp: the robot left operational",
            ),
        ];
        let sut = tally(&runs, &spans);
        let starts: Vec<u64> = sut.false_ok.iter().map(|f| f.0).collect();
        assert_eq!(starts, [4000, 4599, 8000]);
        assert_eq!(sut.ok, 5);
    }

    #[test]
    fn a_run_meets_a_span_only_where_their_ticks_overlap() {
        let s = span(100, Some(200));
        assert!(meets(&run("ptp", "goto", (50, 100), "ok"), &s));
        assert!(meets(&run("ptp", "goto", (199, 300), "ok"), &s));
        assert!(!meets(&run("ptp", "goto", (200, 300), "ok"), &s));
        assert!(!meets(&run("ptp", "goto", (10, 99), "ok"), &s));
        assert!(meets(&run("ptp", "goto", (10, 99), "ok"), &span(99, None)));
    }
}
