//! The schedule of a run, as a replay needs it (`modbot up --replayable`): what decided which
//! component was released when, with which flags, beyond LET's rule — switches and when their
//! assemblies began to track, the robot held, faults, overruns and stale releases. Written as
//! text lines while the run goes (a thread of normal priority writes them out: the tick thread
//! does no file I/O), and kept in the recording when the run ends (`modbot_record::replay`).
//!
//! # Lines
//! ```text
//! announce tick=N generation=G from=F at=A     assembly G tracks from F and takes over at A
//! postpone tick=N generation=G at=A            (a late release near the switch) now at A
//! switch tick=N generation=G                   G took over at N
//! upgrade tick=N host=H                        a new process of H steps its components from
//!                                              N, their state carried (a live upgrade)
//! held tick=N on|off                           from N the running assembly tracks (or not)
//! fault tick=N from=C                          from component index C at tick N: faulted
//! overrun tick=T generation=G component=NAME release=M   M still ran at T; not released at T
//! late tick=M generation=G component=NAME      release M's outputs never became valid
//!                                              (finished late, failed, or dropped at a switch)
//! stale tick=M generation=G component=NAME     release M was not executed
//! restart tick=N host=H                        host H was restarted (its components anew)
//! end tick=N                                   the run ended cleanly after N ticks
//! ```
//! Components are named with the generation whose grid they belong to (0 for the system's own
//! components, which run in every generation), never by an index that a switch changes (a
//! fault's `from` is an index of the grid running at N). A fault logged at a tick before that
//! tick's switch was ended by the switch.

use std::io::Write;

use modbot_grid::component::Generation;

/// The log, if the run keeps one.
pub(super) struct ReplayLog {
    out: Option<Box<dyn Write + Send>>,
    /// Whether the running assembly is held (the last `held` line).
    held: bool,
}

impl ReplayLog {
    /// No log.
    pub(super) fn none() -> ReplayLog {
        ReplayLog {
            out: None,
            held: false,
        }
    }

    /// A log written to `out`.
    pub(super) fn to(out: Box<dyn Write + Send>) -> ReplayLog {
        ReplayLog {
            out: Some(out),
            held: false,
        }
    }

    pub(super) fn on(&self) -> bool {
        self.out.is_some()
    }

    fn line(&mut self, args: std::fmt::Arguments<'_>) {
        if let Some(out) = self.out.as_mut() {
            if let Err(e) = out.write_fmt(args).and_then(|()| out.write_all(b"\n")) {
                tracing::error!("the replay log is incomplete: {e}");
                self.out = None;
            }
        }
    }

    pub(super) fn announce(&mut self, n: u64, g: Generation, from: u64, at: u64) {
        self.line(format_args!(
            "announce tick={n} generation={g} from={from} at={at}"
        ));
    }

    pub(super) fn postpone(&mut self, n: u64, g: Generation, at: u64) {
        self.line(format_args!("postpone tick={n} generation={g} at={at}"));
    }

    pub(super) fn switch(&mut self, n: u64, g: Generation) {
        self.line(format_args!("switch tick={n} generation={g}"));
    }

    /// The running assembly is held at `n` (or not): a line where that changes.
    pub(super) fn held(&mut self, n: u64, held: bool) {
        if held != self.held {
            self.held = held;
            let state = if held { "on" } else { "off" };
            self.line(format_args!("held tick={n} {state}"));
        }
    }

    pub(super) fn fault(&mut self, n: u64, from: usize) {
        self.line(format_args!("fault tick={n} from={from}"));
    }

    pub(super) fn overrun(&mut self, n: u64, g: Generation, name: &str, release: u64) {
        self.line(format_args!(
            "overrun tick={n} generation={g} component={name} release={release}"
        ));
    }

    pub(super) fn late(&mut self, m: u64, g: Generation, name: &str) {
        self.line(format_args!(
            "late tick={m} generation={g} component={name}"
        ));
    }

    pub(super) fn restart(&mut self, n: u64, host: &str) {
        self.line(format_args!("restart tick={n} host={host}"));
    }

    /// A new process of `host` steps its components from tick `at` (a live upgrade).
    pub(super) fn upgrade(&mut self, at: u64, host: &str) {
        self.line(format_args!("upgrade tick={at} host={host}"));
    }

    pub(super) fn end(&mut self, n: u64) {
        self.line(format_args!("end tick={n}"));
    }

    pub(super) fn stale(&mut self, m: u64, g: Generation, name: &str) {
        self.line(format_args!(
            "stale tick={m} generation={g} component={name}"
        ));
    }

    /// Flushes the log (the run ends).
    pub(super) fn finish(&mut self) {
        if let Some(mut out) = self.out.take() {
            if let Err(e) = out.flush() {
                tracing::error!("the replay log is incomplete: {e}");
            }
        }
    }
}
