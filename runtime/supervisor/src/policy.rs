//! Restart bookkeeping: whether a module that ended comes back, and when.
//!
//! Pure logic over injected time (nanoseconds of a monotonic clock), so tests drive it by hand.

use modbot_system::{Restart, RestartPolicy};

/// How a module process ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ExitReason {
    /// It exited with this status.
    Exited(i32),
    /// A signal killed it.
    Signaled(i32),
    /// Its heartbeat stopped for this long, and the supervisor killed it.
    Hung { silent_ms: u64 },
    /// It did not announce itself within the start timeout, and the supervisor killed it.
    NoStart { waited_ms: u64 },
    /// The supervisor stopped it (shutdown).
    Stopped(i32),
}

impl ExitReason {
    /// Whether this counts as a failure for `on-failure`.
    pub fn is_failure(&self) -> bool {
        !matches!(self, ExitReason::Exited(0) | ExitReason::Stopped(_))
    }
}

impl core::fmt::Display for ExitReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ExitReason::Exited(code) => write!(f, "exit {code}"),
            ExitReason::Signaled(sig) => write!(f, "killed by {}", signal_name(*sig)),
            ExitReason::Hung { silent_ms } => write!(f, "hung ({silent_ms} ms silent), killed"),
            ExitReason::NoStart { waited_ms } => {
                write!(f, "no announcement in {waited_ms} ms, killed")
            }
            ExitReason::Stopped(0) => write!(f, "stopped"),
            ExitReason::Stopped(code) => write!(f, "stopped, exit {code}"),
        }
    }
}

/// The name of signal `sig`, e.g. `SIGKILL`.
pub fn signal_name(sig: i32) -> String {
    match nix::sys::signal::Signal::try_from(sig) {
        Ok(s) => s.as_str().to_owned(),
        Err(_) => format!("signal {sig}"),
    }
}

/// What to do after a module ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Start it again at this time.
    RestartAt(u64),
    /// Leave it down: its policy does not restart this kind of end.
    StayDown,
    /// It ended too often within the window: give up on it.
    GiveUp,
}

/// One module's restart history.
#[derive(Debug, Clone)]
pub struct RestartTracker {
    policy: RestartPolicy,
    /// When the restarts within the current window happened.
    recent_ns: Vec<u64>,
    /// Restarts since the supervisor started.
    pub total: u32,
}

impl RestartTracker {
    pub fn new(policy: RestartPolicy) -> RestartTracker {
        RestartTracker {
            policy,
            recent_ns: Vec::new(),
            total: 0,
        }
    }

    /// Decides what happens after the module ended for `reason` at `now_ns`.
    pub fn on_exit(&mut self, reason: &ExitReason, now_ns: u64) -> Decision {
        let wanted = match self.policy.when {
            Restart::Never => false,
            Restart::OnFailure => reason.is_failure(),
            Restart::Always => true,
        };
        if !wanted {
            return Decision::StayDown;
        }
        let window = self.policy.window.as_nanos() as u64;
        self.recent_ns
            .retain(|&t| now_ns.saturating_sub(t) < window);
        if self.recent_ns.len() as u32 >= self.policy.max_restarts {
            return Decision::GiveUp;
        }
        let delay = self.policy.delay(self.recent_ns.len() as u32);
        self.recent_ns.push(now_ns);
        self.total += 1;
        Decision::RestartAt(now_ns + delay.as_nanos() as u64)
    }

    /// Restarts within the current window.
    pub fn in_window(&self) -> usize {
        self.recent_ns.len()
    }
}

#[cfg(test)]
mod tests {
    use core::time::Duration;

    use super::*;

    const MS: u64 = 1_000_000;

    fn policy(when: Restart) -> RestartPolicy {
        RestartPolicy {
            when,
            max_restarts: 3,
            window: Duration::from_secs(10),
            backoff: Duration::from_millis(100),
            max_backoff: Duration::from_millis(300),
            give_up: modbot_system::GiveUp::KeepOthers,
        }
    }

    #[test]
    fn on_failure_restarts_crashes_but_not_a_clean_exit() {
        let mut sut = RestartTracker::new(policy(Restart::OnFailure));
        assert_eq!(sut.on_exit(&ExitReason::Exited(0), 0), Decision::StayDown);
        assert_eq!(
            sut.on_exit(&ExitReason::Exited(1), 0),
            Decision::RestartAt(100 * MS)
        );
        assert_eq!(
            sut.on_exit(&ExitReason::Signaled(9), 0),
            Decision::RestartAt(200 * MS)
        );
        assert_eq!(
            sut.on_exit(&ExitReason::Hung { silent_ms: 900 }, 0),
            Decision::RestartAt(300 * MS),
            "the backoff doubles and is capped"
        );
    }

    #[test]
    fn never_leaves_every_end_down_and_always_restarts_every_end() {
        let mut never = RestartTracker::new(policy(Restart::Never));
        assert_eq!(
            never.on_exit(&ExitReason::Signaled(9), 0),
            Decision::StayDown
        );
        let mut always = RestartTracker::new(policy(Restart::Always));
        assert!(matches!(
            always.on_exit(&ExitReason::Exited(0), 0),
            Decision::RestartAt(_)
        ));
    }

    #[test]
    fn more_restarts_than_the_maximum_within_the_window_give_up() {
        let mut sut = RestartTracker::new(policy(Restart::Always));
        for t in 0..3 {
            assert!(matches!(
                sut.on_exit(&ExitReason::Exited(1), t * MS),
                Decision::RestartAt(_)
            ));
        }
        assert_eq!(
            sut.on_exit(&ExitReason::Exited(1), 5 * MS),
            Decision::GiveUp
        );
        assert_eq!(sut.total, 3);
    }

    #[test]
    fn restarts_older_than_the_window_no_longer_count() {
        let mut sut = RestartTracker::new(policy(Restart::Always));
        for t in 0..3 {
            sut.on_exit(&ExitReason::Exited(1), t * MS);
        }
        assert_eq!(
            sut.on_exit(&ExitReason::Exited(1), 11_000 * MS),
            Decision::RestartAt(11_100 * MS),
            "a fresh window starts with the initial backoff"
        );
        assert_eq!(sut.in_window(), 1);
    }

    #[test]
    fn exit_reasons_read_as_words() {
        assert_eq!(ExitReason::Signaled(9).to_string(), "killed by SIGKILL");
        assert_eq!(ExitReason::Exited(1).to_string(), "exit 1");
        assert_eq!(
            ExitReason::Hung { silent_ms: 1200 }.to_string(),
            "hung (1200 ms silent), killed"
        );
    }
}
