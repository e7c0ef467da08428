//! modbot's system benchmarks, 3 to 7 and 9 to 11 of `modbot-benches`: whole systems under
//! `modbot up` (the grid, scale, faults, swaps, the arm, an FMU component, the control station)
//! and the EtherCAT bus against the slave emulator, each against a baseline measured in the
//! same run. A benchmark's other processes run as `modbot-benches child ROLE ...`, which the
//! binary hands to the `child` functions here.
//!
//! # Layout
//! One file a benchmark, each with `run` and its child roles in `child`:
//! - [`grid`] (3): tick error, release to done and coordinator CPU at 1 kHz, and the bare
//!   real-time loop the arm compares with; its [`lockstep`] runs (traces against LET, speed).
//! - [`scale`] (4): start-up, /dev/shm, memory and call round trip from 2 to 253 modules.
//! - [`faults`] (5): detection and restart of a killed module, the quick stop after a lost
//!   coordinator.
//! - [`swaps`] (6): assembly swaps of the arm.
//! - [`arm`] (7): the arm holding, bus cycles missed against a bare loop.
//! - [`fmu`] (9): an FMU component against a built-in doing the same.
//! - [`ethercat`] (10): the EtherCAT bus cycle against a raw AF_PACKET ping-pong and its jitter
//!   against a bare timerfd loop, on a veth pair against the slave emulator (root); its
//!   targets.
//! - [`station`] (11): the grid and a busy call with the control station and two browsers
//!   attached against none, and the station's looks at 253 modules; its targets.
//! - [`replay`] (12): `modbot replay` of a recorded arm against the lockstep run that
//!   recorded it.
//! - [`remote`] (13): a call through two Zenoh bridges against a raw Zenoh query.
//! - [`upgrade`] (14): live upgrades of a module under a stream of calls: the latency they add
//!   and the handover; a host of the time grid upgraded while the arm moves ([`upgrade_grid`]).
//!
//! The systems they start, the report and the samples are `modbot-bench-kit`'s; the call paths
//! the lockstep run and the station use are `modbot-bench-ipc`'s.

pub mod arm;
pub mod ethercat;
pub mod faults;
pub mod fmu;
pub mod grid;
pub mod lockstep;
pub mod remote;
pub mod replay;
pub mod scale;
pub mod station;
pub mod swaps;
pub mod upgrade;
pub mod upgrade_grid;
