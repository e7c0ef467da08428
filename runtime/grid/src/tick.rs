//! Where the base tick comes from. The coordinator is the only process that reads the clock,
//! and it reads it through this trait, so tests can drive the grid tick by tick.

use std::os::fd::AsFd;

use modbot_core::signals::Shutdown;
use nix::sys::time::TimeSpec;
use nix::sys::timerfd::{ClockId, Expiration, TimerFd, TimerFlags, TimerSetTimeFlags};

/// A source of base ticks.
pub trait TickSource {
    /// Blocks until the next tick; returns how many ticks elapsed since the last call (more
    /// than 1 means ticks were missed).
    fn wait(&mut self) -> std::io::Result<u64>;

    /// When the `k`-th tick (counting from 0) was due, in ns of [`TickSource::now_ns`].
    fn due_ns(&self, k: u64) -> u64;

    /// The time of the clock the ticks follow, in ns.
    fn now_ns(&self) -> u64;
}

fn monotonic_ns() -> u64 {
    modbot_core::clock::Clock::now_ns(&modbot_core::clock::MonotonicClock)
}

/// Absolute CLOCK_MONOTONIC ticks from a timerfd: tick n is due at `start + n·period`,
/// whatever the latency of earlier wake-ups (no drift).
pub struct TimerTicks {
    fd: TimerFd,
    start_ns: u64,
    period_ns: u64,
    /// A wait interrupted by a signal ends when this is requested (else it goes on).
    shutdown: Shutdown,
}

impl TimerTicks {
    /// Ticks every `period_ns`, the first one `period_ns` from now; a wait ends early
    /// (`Interrupted`) when `shutdown` is requested and a signal interrupts it.
    pub fn new(period_ns: u64, shutdown: Shutdown) -> std::io::Result<TimerTicks> {
        let fd = TimerFd::new(ClockId::CLOCK_MONOTONIC, TimerFlags::TFD_CLOEXEC)?;
        let start_ns = monotonic_ns() + period_ns;
        let first = TimeSpec::from(core::time::Duration::from_nanos(start_ns));
        let every = TimeSpec::from(core::time::Duration::from_nanos(period_ns));
        fd.set(
            Expiration::IntervalDelayed(first, every),
            TimerSetTimeFlags::TFD_TIMER_ABSTIME,
        )?;
        Ok(TimerTicks {
            fd,
            start_ns,
            period_ns,
            shutdown,
        })
    }

    /// When the first tick was due.
    pub fn start_ns(&self) -> u64 {
        self.start_ns
    }
}

impl TickSource for TimerTicks {
    fn wait(&mut self) -> std::io::Result<u64> {
        let mut buf = [0u8; 8];
        loop {
            match nix::unistd::read(self.fd.as_fd(), &mut buf) {
                Ok(8) => return Ok(u64::from_ne_bytes(buf)),
                Ok(_) => return Err(std::io::Error::other("short read from the timerfd")),
                Err(nix::errno::Errno::EINTR) => {
                    if self.shutdown.requested() {
                        return Err(std::io::Error::from(std::io::ErrorKind::Interrupted));
                    }
                }
                Err(e) => return Err(e.into()),
            }
        }
    }

    fn now_ns(&self) -> u64 {
        monotonic_ns()
    }

    fn due_ns(&self, k: u64) -> u64 {
        self.start_ns + k * self.period_ns
    }
}

/// Ticks as fast as they are asked for (tests and trace runs that need no real time).
#[derive(Debug, Default)]
pub struct FreeTicks;

impl TickSource for FreeTicks {
    fn wait(&mut self) -> std::io::Result<u64> {
        Ok(1)
    }

    fn now_ns(&self) -> u64 {
        monotonic_ns()
    }

    fn due_ns(&self, _: u64) -> u64 {
        monotonic_ns()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_timerfd_ticks_at_its_period_without_drift() {
        let mut sut = TimerTicks::new(2_000_000, Shutdown::new()).unwrap();
        let mut n = 0;
        while n < 10 {
            n += sut.wait().unwrap();
        }
        let elapsed = sut.now_ns() - sut.start_ns();
        assert!(
            elapsed >= 9 * 2_000_000,
            "10 ticks take at least 9 periods: {elapsed} ns"
        );
    }
}
