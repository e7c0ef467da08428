//! The soak's note in the report: what ran, every count behind the rows, and what a reader
//! needs to judge them (reasons of refused and failed calls, restarts by cause, memory windows,
//! the arm's safe stops, the resets and what they ended, the motions).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitStatus;

use crate::ends::Ends;
use crate::{arm, driver, inject, journal, motions, robot, samples, Run};

/// What the note is written from.
pub struct Facts<'a> {
    pub run: &'a Run,
    pub tally: &'a journal::Tally,
    /// The program's motions, judged.
    pub moves: &'a motions::Tally,
    pub program: &'a motions::Program,
    pub ends: &'a Ends,
    /// Lines of the journal that were not a number.
    pub unreadable: u64,
    pub minutes: f64,
    pub seed: u64,
    /// The supervisor's "all N module(s) up in T ms".
    pub up_line: &'a str,
    /// The bus ledger after the soak.
    pub ledger: &'a str,
    /// How `modbot up` ended.
    pub up_status: Option<ExitStatus>,
    /// The domain's files left after the stop.
    pub left: &'a [PathBuf],
}

/// The note.
pub fn note(f: &Facts<'_>) -> String {
    let run = f.run;
    let mut note = String::new();
    let _ = write!(
        note,
        "soak: examples/moser.lua (patrolling without end) and examples/arm.lua (holding) in \
         one domain with the journal module ({}); faults for {} min, one a \
         second, seed {}, into {} ({}); the coordinator takes floods only (it is not \
         restarted by design, and a stall of it brings the drives to a safe stop). {}",
        f.up_line,
        f.minutes,
        f.seed,
        run.targets.join(", "),
        run.injected
            .by_target
            .iter()
            .map(|(t, n)| format!("{t} {n}"))
            .collect::<Vec<_>>()
            .join(", "),
        describe_calls(&run.calls, f.tally, f.unreadable),
    );
    let _ = write!(
        note,
        " {} {} {} {} {} Bus at the end: {}. `modbot up` ended {}.",
        describe_faults(run, f.ends),
        describe_memory(run),
        describe_arm(run),
        describe_resets(&run.robot),
        describe_motions(f.moves, f.program),
        f.ledger.lines().next().unwrap_or_default().trim(),
        f.up_status
            .map_or_else(|| "(not started)".to_owned(), |s| s.to_string()),
    );
    if !f.left.is_empty() {
        let _ = write!(
            note,
            " Left after the stop (removed now): {}.",
            f.left
                .iter()
                .take(5)
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    note
}

fn describe_calls(c: &driver::Outcome, t: &journal::Tally, unreadable: u64) -> String {
    let map = |m: &std::collections::BTreeMap<&str, u64>| {
        if m.is_empty() {
            "none".to_owned()
        } else {
            m.iter()
                .map(|(k, v)| format!("{k} {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    let mut s = format!(
        "Calls: `journal.record(seq)` every {} ms from a tool endpoint of this process \
         (timeout 5 s, waiting for the module across restarts, 4 retransmissions): {} issued, \
         {} acknowledged (slowest {:.0} ms), {} executed ({} of them without a reply to the \
         caller), {} lost, {} duplicated ({} extra executions); refused before sending: {}; \
         failed after sending: {}; {} still waiting at the end; {} answered with another \
         call's reply; {} unknown numbers and {} unreadable lines in the journal.",
        driver::PERIOD.as_millis(),
        t.issued,
        t.acknowledged,
        c.slowest.as_secs_f64() * 1e3,
        t.executed,
        t.executed_unacknowledged,
        t.lost.len(),
        t.duplicated.len(),
        t.extra_executions(),
        map(&c.refused),
        map(&c.failed),
        c.unfinished,
        c.misanswered.len(),
        t.unknown.len(),
        unreadable,
    );
    if !t.lost.is_empty() {
        let _ = write!(s, " Lost: {:?}.", &t.lost[..t.lost.len().min(10)]);
    }
    if !t.duplicated.is_empty() {
        let _ = write!(
            s,
            " Duplicated (number, executions): {:?}.",
            &t.duplicated[..t.duplicated.len().min(10)]
        );
    }
    if !c.misanswered.is_empty() {
        let earlier = c
            .misanswered
            .iter()
            .filter(|(_, got)| {
                got.and_then(|g| u64::try_from(g).ok())
                    .is_some_and(|g| c.acknowledged.binary_search(&g).is_ok())
            })
            .count();
        let _ = write!(
            s,
            " Answered with another call's reply (the call's number, the number in the reply): \
             {:?}; {earlier} of the numbers in those replies belong to calls that had their own \
             reply before. Consistent with: a request retransmitted while the journal was \
             stopped is answered twice when it resumes (the EXEC, then the RETRY from the \
             record), and the second reply arrives after the caller gave the same 5-bit \
             sequence number to a new call, which takes it for its own answer (a sequence number \
             is quarantined after a time-out, not after an answer).",
            &c.misanswered[..c.misanswered.len().min(10)]
        );
    }
    s
}

fn describe_faults(run: &Run, ends: &Ends) -> String {
    let i = &run.injected;
    let (_, rejected, replayed) = samples::counters(&run.samples);
    let mut s = format!(
        "Faults: {} picks skipped (the module was not running, or still stopped). Restarts: \
         {} ({}); modules given up: {}. Garbage frames: {} sent, {} refused (inbox full), {} \
         counted as rejected by their receivers (as last sampled: a process killed before the \
         next sample takes its count along). REPORTs to stopped consumers: {} sent, {} refused; \
         the longest burst of {} took this process {:.1} ms. RETRYs answered from the record: \
         {} (as sampled).",
        i.skipped,
        ends.total(),
        ends.restarts
            .iter()
            .map(|(w, n)| format!("{w} {n}"))
            .collect::<Vec<_>>()
            .join(", "),
        if ends.failed.is_empty() {
            "none".to_owned()
        } else {
            ends.failed.join("; ")
        },
        i.garbage.0,
        i.garbage.1,
        rejected,
        i.spam.0,
        i.spam.1,
        inject::SPAM_REPORTS,
        i.spam_burst_max.as_secs_f64() * 1e3,
        replayed,
    );
    if !run.status_errors.is_empty() {
        let _ = write!(
            s,
            " The supervisor's table could not be read {} time(s) (the one before was used): {}.",
            run.status_errors.len(),
            run.status_errors[0]
        );
    }
    s
}

fn describe_memory(run: &Run) -> String {
    let Some(w) = samples::windows(&run.samples) else {
        return String::new();
    };
    let mib = |b: u64| b as f64 / f64::from(1 << 20);
    let pct = |g: samples::Growth| (g.ratio() - 1.0) * 100.0;
    let (s, a, shm, files) = (w.survivors(), w.everyone(), w.shm(), w.files());
    let at = |x: &[samples::Sample]| {
        let secs = |s: Option<&samples::Sample>| s.map_or(0.0, |s| s.at.as_secs_f64());
        format!("{:.0}–{:.0} s", secs(x.first()), secs(x.last()))
    };
    let each = w
        .survivors_each()
        .iter()
        .map(|(name, g)| format!("{name} {:.1} → {:.1}", mib(g.mid), mib(g.end)))
        .collect::<Vec<_>>()
        .join(", ");
    format!(
        "Memory, means over {} and over {}: Rss of the {} processes alive through both {:.1} → \
         {:.1} MiB ({:+.1} %: {each}); of every process ({} at the end) {:.1} → {:.1} MiB \
         ({:+.1} %); /dev/shm {:.2} → {:.2} MiB ({:+.1} %), {} → {} files. Every sample: \
         soak_memory.tsv, soak_processes.tsv.",
        at(w.mid),
        at(w.end),
        s.processes,
        mib(s.mid),
        mib(s.end),
        pct(s),
        a.processes,
        mib(a.mid),
        mib(a.end),
        pct(a),
        mib(shm.mid),
        mib(shm.end),
        pct(shm),
        files.0,
        files.1,
    )
}

fn describe_arm(run: &Run) -> String {
    let a = arm::summarize(&run.bus);
    format!(
        "The arm: the bus bridge answered {} samples, {} of them in a safe stop (its ledger); \
         {} safe stops ({}). The bridge's watchdog stops the drives after 3 base periods \
         without a tick: on this 2-core VM the arm alone goes into one now and then (the arm \
         benchmark's bare real-time loop misses ticks too), and a stalled bus bridge goes into \
         one when it resumes; the soak resets it (below).",
        a.answered,
        a.stopped,
        a.safe_stops(),
        if a.by_reason.is_empty() {
            "none".to_owned()
        } else {
            a.by_reason
                .iter()
                .map(|(w, n)| format!("{w} {n}"))
                .collect::<Vec<_>>()
                .join(", ")
        },
    )
}

/// The stops the robot state showed, the resets and what they ended.
fn describe_resets(w: &robot::Watch) -> String {
    let list = |items: &mut dyn Iterator<Item = String>| {
        let v: Vec<String> = items.collect();
        if v.is_empty() {
            "none".to_owned()
        } else {
            v.join(", ")
        }
    };
    let (by_restart, open) = w.by_restart_and_open();
    let (recovery, reset) = w.histograms();
    let ms = |h: &hdrhistogram::Histogram<u64>, q: f64| h.value_at_quantile(q) as f64 / 1e6;
    let mut s = format!(
        "Resets: the robot state (method `robot` of the bus bridge, once a second unless the \
         bridge was stopped) answered {} times (not: {}); {} stops ({} faults), by cause: {}. \
         The soak asked {} resets (at most one a second, answer within {} ms): {} refused or \
         unanswered ({}); {} stops ended by a reset, {} by a restart of the bus bridge, {} still \
         held at the end; fresh bus bridges (after a SIGKILL): {}, {} of them never operational. From the stop to operational again (grid time, \
         {} recoveries): p50 {:.0} ms, p99 {:.0} ms, max {:.0} ms; the resets' own share, from \
         their beginning to every drive enabled: p50 {:.0} ms, max {:.0} ms. Switches to `hold` \
         after a reset refused for a faulted assembly: {}{}. Every stop: soak_stops.tsv.",
        w.answered,
        list(&mut w.unanswered.iter().map(|(k, n)| format!("{k} {n}"))),
        w.stops.len(),
        w.stops.iter().filter(|s| s.fault).count(),
        list(&mut w.causes().into_iter().map(|(c, n)| format!("{c} {n}"))),
        w.resets,
        1500,
        w.refused.values().sum::<u64>(),
        list(&mut w.refused.iter().map(|(k, n)| format!("{k} {n}"))),
        w.recovered().count(),
        by_restart,
        open,
        w.restarts.len(),
        w.restarts.iter().filter(|r| r.operational.is_none()).count(),
        recovery.len(),
        ms(&recovery, 0.5),
        ms(&recovery, 0.99),
        ms(&recovery, 1.0),
        ms(&reset, 0.5),
        ms(&reset, 1.0),
        w.switches.0,
        if w.switches.1.is_empty() {
            String::new()
        } else {
            format!(" ({} failed: {})", w.switches.1.len(), w.switches.1[0])
        },
    );
    if w.lagged > 0 {
        let _ = write!(
            s,
            " After {} of the resets' answers the state still said `disabled` for a moment (the \
             bridge publishes what `robot` answers every 20 ms, the reset's answer at once).",
            w.lagged
        );
    }
    if !w.not_back.is_empty() {
        let _ = write!(
            s,
            " Resets answered ok after which the robot was not operational: {} ({}).",
            w.not_back.len(),
            w.not_back[0]
        );
    }
    s
}

/// The program's motions by outcome, and the false oks.
fn describe_motions(m: &motions::Tally, p: &motions::Program) -> String {
    let mut s = format!(
        "Motions: `modbot program run` moving the arm between two poses without end \
         (soak_program.log), started {} times (exits: {}); {} motions: {} ok, {} refused (the \
         robot not operational), {} failed because the robot left operational, {} failed \
         otherwise, {} stopped by the soak's end; {} reported ok across a stop (must be 0); {} \
         runs of other commands. Every run: soak_runs.tsv.",
        p.starts,
        p.exits
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect::<Vec<_>>()
            .join(", "),
        m.motions,
        m.ok,
        m.refused,
        m.left_operational,
        m.failed.len(),
        m.interrupted,
        m.false_ok.len(),
        m.others,
    );
    if p.exits.keys().any(|k| k.contains("101")) {
        s.push_str(
            " Exit status 101 is a panic of `modbot program run` (its output is in the log); the \
             run it was in is not in assembly data.",
        );
    }
    if !m.failed.is_empty() {
        let _ = write!(s, " Failed otherwise, the first: {}.", m.failed[0]);
    }
    if !m.false_ok.is_empty() {
        let _ = write!(
            s,
            " Ok across a stop (start tick, end tick, the stop): {:?}.",
            &m.false_ok[..m.false_ok.len().min(5)]
        );
    }
    s
}
