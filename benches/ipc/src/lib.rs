//! modbot's IPC benchmarks, 1 and 2 of `modbot-benches`: a method call's round trip and a
//! blackboard snapshot's delivery between two processes, each against raw iceoryx2 and a Unix
//! socket measured in the same run. Both sides of each are processes; the other side runs as
//! `modbot-benches child ROLE ...`, which the binary hands to the `child` functions here.
//!
//! # Layout
//! - [`calls`]: benchmark 1, the call round trip from 8 B to 1 MiB (`run`).
//! - [`work`]: part of benchmark 1, the CPU work of one call (both sides in one thread).
//! - [`paths`]: the round trips of benchmark 1: a modbot call ([`paths::ModbotPath`]), raw
//!   iceoryx2 ([`paths::RawPath`]) and a Unix socket ([`paths::UdsPath`]); the grid's lockstep
//!   run and the station benchmark use them too.
//! - [`echo`]: the echo module (child role `calls-echo`) and what its callers share.
//! - [`snapshots`]: benchmark 2, blackboard snapshots (`run`; child role `snapshots-reader`).
//! - [`raw`], [`uds`]: the baselines, raw iceoryx2 (child role `raw-echo`) and Unix-domain
//!   sockets (child roles `uds-echo`, `uds-sink`).

pub mod calls;
pub mod echo;
pub mod paths;
pub mod raw;
pub mod snapshots;
pub mod uds;
pub mod work;
