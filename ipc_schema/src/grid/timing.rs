//! How a checked grid keeps time and treats a missed deadline: the names a description uses,
//! carried as they are in the checked grid (`grid_spec`).

/// Where the base tick comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GridClock {
    /// The coordinator's timerfd: tick n at start + n·T, whatever happens (the default).
    #[default]
    RealTime,
    /// The coordinator advances to tick n + 1 only when every release due at n + 1 can be
    /// made, as fast as the machine goes: no overruns by construction, byte-identical traces
    /// whatever the load. A simulation mode: no drive would follow it in real time.
    Lockstep,
}

impl GridClock {
    pub fn name(self) -> &'static str {
        match self {
            GridClock::RealTime => "realtime",
            GridClock::Lockstep => "lockstep",
        }
    }

    pub fn from_name(name: &str) -> Option<GridClock> {
        match name {
            "realtime" => Some(GridClock::RealTime),
            "lockstep" => Some(GridClock::Lockstep),
            _ => None,
        }
    }
}

/// What the coordinator does when a component misses its deadline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OverrunPolicy {
    /// Its previous outputs stay valid; the overrun is counted.
    #[default]
    Hold,
    /// The assembly is faulted.
    Fault,
}

impl OverrunPolicy {
    /// The name used in descriptions: `hold` or `fault`.
    pub fn name(self) -> &'static str {
        match self {
            OverrunPolicy::Hold => "hold",
            OverrunPolicy::Fault => "fault",
        }
    }

    pub fn from_name(name: &str) -> Option<OverrunPolicy> {
        match name {
            "hold" => Some(OverrunPolicy::Hold),
            "fault" => Some(OverrunPolicy::Fault),
            _ => None,
        }
    }
}
