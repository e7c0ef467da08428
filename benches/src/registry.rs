//! Every benchmark of the crates, in the order `all` runs them, every child role, and the
//! targets the benchmarks keep themselves.

use modbot_bench_ipc::{calls, echo, raw, snapshots, uds};
use modbot_bench_kit::hogs;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::report::Report;
use modbot_bench_kit::targets::TargetsFn;
use modbot_bench_soak as soak;
use modbot_bench_system::{
    arm, ethercat, faults, fmu, grid, remote, replay, scale, station, swaps, upgrade,
};

type RunFn = fn(&Opts, &mut Report) -> anyhow::Result<()>;

/// A benchmark: its name, its entry point, and whether it starts the modbot binaries.
pub struct Bench {
    pub name: &'static str,
    pub run: RunFn,
    pub needs_binaries: bool,
}

/// Every benchmark, in the order `all` runs them.
pub const BENCHES: [Bench; 13] = [
    Bench {
        name: "calls",
        run: calls::run,
        needs_binaries: false,
    },
    Bench {
        name: "snapshots",
        run: snapshots::run,
        needs_binaries: false,
    },
    Bench {
        name: "grid",
        run: grid::run,
        needs_binaries: true,
    },
    Bench {
        name: "scale",
        run: scale::run,
        needs_binaries: true,
    },
    Bench {
        name: "faults",
        run: faults::run,
        needs_binaries: true,
    },
    Bench {
        name: "swaps",
        run: swaps::run,
        needs_binaries: true,
    },
    Bench {
        name: "arm",
        run: arm::run,
        needs_binaries: true,
    },
    Bench {
        name: "fmu",
        run: fmu::run,
        needs_binaries: true,
    },
    // Needs only modbot-ecat-sim (and root: without it, a note in `all`).
    Bench {
        name: "ethercat",
        run: ethercat::run,
        needs_binaries: false,
    },
    Bench {
        name: "station",
        run: station::run,
        needs_binaries: true,
    },
    Bench {
        name: "replay",
        run: replay::run,
        needs_binaries: true,
    },
    // Needs root (network namespaces).
    Bench {
        name: "remote",
        run: remote::run,
        needs_binaries: true,
    },
    Bench {
        name: "upgrade",
        run: upgrade::run,
        needs_binaries: true,
    },
];

/// The soak: not in `all` (it runs for minutes).
pub const SOAK: Bench = Bench {
    name: "soak",
    run: soak::run,
    needs_binaries: true,
};

/// The benchmark `name` of [`BENCHES`].
pub fn bench(name: &str) -> &'static Bench {
    BENCHES
        .iter()
        .find(|b| b.name == name)
        .expect("every subcommand names a benchmark")
}

/// Runs `role` with `args` if it is one of a benchmark's child roles.
type ChildFn = fn(&str, &[String]) -> Option<anyhow::Result<()>>;

/// The child roles of every benchmark; `None` from one means "not mine".
pub const CHILDREN: [ChildFn; 13] = [
    arm::child,
    hogs::child,
    echo::child,
    snapshots::child,
    raw::child,
    uds::child,
    grid::child,
    scale::child,
    faults::child,
    swaps::child,
    soak::child,
    ethercat::child,
    upgrade::child,
];

/// The targets the soak, EtherCAT and the station keep, checked after those of calls,
/// snapshots, the grid and scale.
pub const MORE_TARGETS: [TargetsFn; 3] = [soak::targets, ethercat::targets, station::targets];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_target_without_its_rows_is_not_measured() {
        let mut sut = Report::default();
        modbot_bench_kit::targets::evaluate(&mut sut, &MORE_TARGETS);
        // 11 of calls, snapshots, the grid and scale, the soak's 5, the missed cycles of the
        // EtherCAT bus at 6 and 64 slaves, 1 and 4 kHz, and the station's two (watching within
        // noise, its looks at 253 modules).
        assert_eq!(sut.targets.len(), 22);
        assert!(sut.targets.iter().all(|t| t.met.is_none()));
    }
}
