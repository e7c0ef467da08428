//! Options shared by every benchmark of a run.

use std::path::PathBuf;

/// How a run is made.
#[derive(Debug, Clone)]
pub struct Opts {
    /// Fewer samples and sizes: the whole `all --quick` run finishes in under 3 minutes.
    pub quick: bool,
    /// Pin each benchmark process to its own core (cores 0 and 1 on a 2-core machine).
    pub pin: bool,
    /// Run the measuring processes under SCHED_FIFO where a benchmark compares with and
    /// without it (needs root or CAP_SYS_NICE; refused cleanly otherwise).
    pub fifo: bool,
    /// Where the report and plots go (`target/bench-report` by default).
    pub out: PathBuf,
    /// This benchmark executable, to spawn its own child roles.
    pub exe: PathBuf,
    /// The soak's duration and seed (`soak --minutes N --seed S`; the other benchmarks ignore it).
    pub soak: SoakPlan,
}

/// The soak's own options (`soak --minutes N --seed S`).
#[derive(Debug, Clone, Copy, Default)]
pub struct SoakPlan {
    /// How long faults are injected [default: 10, 1 with --quick].
    pub minutes: Option<f64>,
    /// The seed of the picks [default: from the clock].
    pub seed: Option<u64>,
}

impl Opts {
    /// `quick` or `full` samples.
    pub fn samples(&self, quick: u64, full: u64) -> u64 {
        if self.quick {
            quick
        } else {
            full
        }
    }
}
