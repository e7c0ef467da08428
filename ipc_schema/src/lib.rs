//! Everything of modbot that crosses a process boundary.
//!
//! Plain bytes with a documented layout: no pointers, little-endian integers, headers read in
//! place with `zerocopy`. A frame that arrives from another process is untrusted: every decoder
//! here returns a typed error on malformed input and never panics.
//!
//! # Layout
//! - [`addr`]: 8-bit module addresses and the broadcast address.
//! - [`rvmf`]: RVMF* frames (EXEC, REPLY, ACK, NAK, REPORT), the one encode/decode entry point
//!   for messages between modules.
//! - [`value`]: the typed values carried by frames (f64, i64, bool, text, bytes, f64 arrays),
//!   encoded as MessagePack.
//! - [`args`]: a decoded argument list with typed accessors, without allocating.
//! - [`snapshot`]: the blackboard snapshot format: one buffer, header + item table + data,
//!   readable in place.
//! - [`grid`]: the time grid's port values, output records and release/done notices.
//! - [`grid_spec`]: the checked grid the supervisor writes once per assembly generation and
//!   every grid process reads (components, their interfaces, connections).
//! - [`ledger`]: the grid's overrun ledger (the coordinator's `ledger` answer).
//! - [`switch`]: the coordinator's answers about assembly switches (`switch`, `assembly`).
//! - [`bus`]: the bus bridge's record of assembly switches (its `switches` answer).
//! - [`directory`]: the phone book a supervisor publishes for its domain, one image read in
//!   place.
//! - [`heartbeat`]: the fixed record a module publishes periodically, for hang detection.
//! - [`sysmethod`]: method ids every module answers (describe, blackboard get/set, stats,
//!   activate/deactivate).
//! - [`relay`]: calls a supervisor makes for tools that hold no module address.
//! - [`status`]: the supervisor's status rows (its `status` answer, `modbot ls`).
//! - [`latency`]: the call latency histogram of the `stats` answer: its buckets and layout.
//! - [`fields`]: answers laid out as a run of values, read field by field with named errors.
//! - [`names`]: the rules for the module and assembly names the formats carry.
//! - `preamble`: the magic, version and record count that `bus` and `directory` begin with.
//! - [`hex`]: hex helpers for the command line and the golden vectors.
//!
//! The byte layouts are written down in `ipc_schema/README.md`, with golden vectors that the
//! tests check.

#[cfg(target_endian = "big")]
compile_error!("modbot's wire formats are little-endian and are read in place: big-endian hosts are not supported");

pub mod addr;
pub mod args;
pub mod bus;
pub mod directory;
pub mod fields;
pub mod fuzz;
pub mod grid;
pub mod grid_spec;
pub mod heartbeat;
pub mod hex;
pub mod latency;
pub mod ledger;
pub mod names;
mod preamble;
pub mod relay;
pub mod rvmf;
pub mod snapshot;
pub mod status;
pub mod switch;
pub mod sysmethod;
pub mod value;

pub use addr::Addr;
pub use args::{ArgError, Args};
pub use rvmf::{Frame, FrameError, FrameKind, FrameSpec, Kind, NakCode, Seq};
pub use snapshot::{SnapshotError, SnapshotLayout, SnapshotView};
pub use value::{AsValue, F64s, OwnedValue, ParseValueError, Value, ValueError, ValueKind};
