//! Whether a remote domain's bridge can be reached: its liveliness token, seen through Zenoh
//! (the token goes when the link has been silent for the lease, or the bridge stopped), and
//! since when.

use std::sync::Mutex;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// The state of the link to one remote domain.
#[derive(Debug)]
pub struct Link {
    domain: String,
    state: Mutex<State>,
}

#[derive(Debug, Clone, Copy)]
struct State {
    up: bool,
    since: SystemTime,
    /// Whether it was ever up.
    seen: bool,
    /// How many times it came up.
    epoch: u64,
}

impl Link {
    /// A link to `domain`, down until its bridge's token is seen.
    pub fn new(domain: &str) -> Link {
        Link {
            domain: domain.to_owned(),
            state: Mutex::new(State {
                up: false,
                since: SystemTime::now(),
                seen: false,
                epoch: 0,
            }),
        }
    }

    pub fn domain(&self) -> &str {
        &self.domain
    }

    /// The remote bridge's token came (`true`) or went.
    pub fn set(&self, up: bool) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if s.up != up {
            *s = State {
                up,
                since: SystemTime::now(),
                seen: s.seen || up,
                epoch: s.epoch + u64::from(up),
            };
            if up {
                tracing::info!("link to remote domain '{}' up", self.domain);
            } else {
                tracing::warn!("link to remote domain '{}' down", self.domain);
            }
        }
    }

    /// `Ok` while up, else why not, in words for a caller.
    pub fn check(&self) -> Result<(), String> {
        let s = *self.state.lock().unwrap_or_else(|e| e.into_inner());
        if s.up {
            return Ok(());
        }
        let for_ = s.since.elapsed().unwrap_or(Duration::ZERO).as_secs_f64();
        Err(if s.seen {
            format!(
                "remote domain '{}' unreachable since {} UTC ({for_:.1} s: its bridge's link is down)",
                self.domain,
                clock(s.since)
            )
        } else {
            format!(
                "remote domain '{}' unreachable: its bridge has not been seen since this bridge \
                 started at {} UTC ({for_:.1} s ago)",
                self.domain,
                clock(s.since)
            )
        })
    }

    /// How it stands, in words: [`Link::check`]'s refusal, or that it is up.
    pub fn state(&self) -> String {
        match self.check() {
            Ok(()) => format!("the link to remote domain '{}' is up", self.domain),
            Err(why) => why,
        }
    }

    /// How many times it came up: what was learned through it in an earlier epoch may have
    /// changed meanwhile.
    pub fn epoch(&self) -> u64 {
        self.state.lock().unwrap_or_else(|e| e.into_inner()).epoch
    }

    /// Whether it is up.
    pub fn is_up(&self) -> bool {
        self.state.lock().unwrap_or_else(|e| e.into_inner()).up
    }
}

/// `t` as HH:MM:SS.mmm of its UTC day.
pub fn clock(t: SystemTime) -> String {
    let d = t.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO);
    let s = d.as_secs() % 86_400;
    format!(
        "{:02}:{:02}:{:02}.{:03}",
        s / 3600,
        s / 60 % 60,
        s % 60,
        d.subsec_millis()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_link_is_down_until_seen_and_says_since_when_it_went_down() {
        let sut = Link::new("robot");
        let never = sut.check().unwrap_err();
        assert!(never.contains("has not been seen"), "{never}");
        sut.set(true);
        assert!(sut.check().is_ok());
        sut.set(false);
        let down = sut.check().unwrap_err();
        assert!(
            down.starts_with("remote domain 'robot' unreachable since "),
            "{down}"
        );
    }

    #[test]
    fn a_time_is_shown_as_its_utc_clock() {
        let t = UNIX_EPOCH + Duration::from_millis(86_400_000 * 3 + 3_723_456);
        assert_eq!(clock(t), "01:02:03.456");
    }
}
