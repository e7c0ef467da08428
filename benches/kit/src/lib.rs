//! What every benchmark of `modbot-benches` uses: the options of a run, rows measured against
//! a baseline of the same run, the report (`report.md`, `report.json`) with its plots and the
//! issue's targets, the benchmark's child processes, samples and histograms, and systems under
//! `modbot up`.
//!
//! The benchmarks themselves are in `modbot-bench-ipc` (calls, snapshots),
//! `modbot-bench-system` (the grid, scale, faults, swaps, the arm, FMU, EtherCAT, the station)
//! and `modbot-bench-soak` (the fault soak); the `modbot-benches` binary runs them.
//!
//! # Layout
//! - [`opts`]: the options of a run (the soak's among them).
//! - [`report`]: rows, baselines and ratios, `report.json` and `report.md`.
//! - [`targets`]: the targets, checked against the rows (met, missed by how much, or
//!   not measured and why), and the helpers the benchmarks with targets of their own use.
//! - [`plots`]: the SVG plots.
//! - [`machine`]: the date and the machine the run was made on.
//! - [`procs`]: child processes (stopped on drop, dying with their parent), pinning,
//!   SCHED_FIFO, isolated domains cleaned on drop, the modbot binaries the system benchmarks
//!   start.
//! - [`checkout`]: the workspace root and the examples of this checkout.
//! - [`sample`]: warm-up, sample counts, histograms, the cross-process clock, seeded picks.
//! - [`interleave`]: a subject and its baseline measured in alternating blocks.
//! - [`hogs`]: CPU hogs of normal priority, for measurements on a busy machine (child role
//!   `hog`).
//! - [`supervised`]: a system under `modbot up`, its lines, a tool endpoint into it, its stop.
//! - [`arm_system`]: `examples/arm.lua` started and its drives enabled; the bus ledger.
//! - [`memory`]: a process's Pss and Rss, a domain's /dev/shm bytes.

pub mod arm_system;
pub mod checkout;
pub mod hogs;
pub mod interleave;
pub mod machine;
pub mod memory;
pub mod opts;
pub mod plots;
pub mod procs;
pub mod report;
pub mod sample;
pub mod supervised;
pub mod targets;
