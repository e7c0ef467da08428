//! modbot-zenoh: the bridge between modbot domains on different hosts, through Zenoh.
//!
//! A domain's bridge is one of its modules (`bridge { ... }` in the description, the program
//! `modbot-zenoh`). It exports what the description names — modules' methods (all, or a list)
//! and the reports sent to them — under `modbot/<domain>/...` on Zenoh, and imports remote
//! modules into the local phone book under a local name and address: a local module calls a
//! remote method as it calls a local one (sequence numbers, retransmission, timeouts and NAK
//! codes as ever) and, when the link is down, gets a NAK `UNREACHABLE` that says since when.
//! Nothing of the time grid goes over the network.
//!
//! # Layout
//! - [`config`]: the exports, the imports and how to join Zenoh (mode, endpoints, a Zenoh
//!   configuration file), from the command line;
//! - [`keys`]: the key space on Zenoh; [`wire`]: calls, answers and reports as bytes;
//! - [`link`]: whether a remote domain's bridge is reachable, and since when (its liveliness
//!   token);
//! - [`remote`]: one call through Zenoh, answered once or refused with why;
//! - [`import`]: an imported module's proxy (a thread with an address and inbox here);
//! - [`export`]: the exported side (the bridge module calling local modules for remote
//!   callers, delivering remote reports);
//! - [`mirror`]: blackboard snapshots across hosts (put at a rate by the exporting side,
//!   published as the proxy's own by the importing side);
//! - `main.rs`: the program.
//!
//! Zenoh is heavy to build: only this crate links it, never a module or the runtime.

pub mod config;
pub mod export;
pub mod import;
pub mod keys;
pub mod link;
pub mod mirror;
pub mod remote;
pub mod wire;
