//! modbot-core: the module core — what every module process links, and nothing of the time
//! grid, the bus or the system descriptions (no mlua).
//!
//! Each module of a robot is its own OS process. It declares a name, an 8-bit address, a table
//! of local methods and a blackboard; the core serves RVMF* frames to those methods, calls
//! other modules' methods through the phone book and the method queue, and publishes the
//! blackboard as zero-copy snapshots. It stands on `modbot-transport` only.
//!
//! # Layout
//! - [`module`]: declaring a module ([`ModuleBuilder`]), serving it, its main loop.
//! - [`hooks`]: what a module is made of for its manager: method table, hooks, reply, report.
//! - [`ctx`]: what a module's code can do: call, report, read snapshots, use its blackboard.
//! - [`calls`]: the method queue, matching answers by (peer, sequence), with retransmission.
//! - `manager`: the message manager, serving one incoming frame.
//! - [`served`]: the requests served lately, so a retransmission is not executed twice.
//! - [`upgrade`]: a live upgrade's handover between the running process and its successor.
//! - [`phonebook`]: names to addresses, liveness and method tables.
//! - [`blackboard`]: typed items, logical and virtual devices, snapshots.
//! - [`mod@run`]: the default application controller, for a program that needs no other.
//! - [`stats`]: traffic counters and the call latency histogram (the `stats` system method).
//! - [`sim`]: the simulated time all processes of a system share (`MODBOT_EPOCH_NS`).
//! - [`cli`]: the command line every module program takes ([`ModuleArgs`]).
//! - [`tool`]: how a tool (the CLI) reaches a running system, also when every address is taken.
//! - [`clock`], [`signals`], [`error`]: injected time, termination, error types.
//! - [`realtime`]: a grid process's one SCHED_FIFO thread.
//! - [`transport`], [`domain`]: re-exported from `modbot-transport`.
//!
//! No file imports another in a circle (`tests/layout.rs` checks every library crate): the
//! manager and the module both stand on `hooks`, the stats on neither.

mod beat;
pub mod blackboard;
pub mod calls;
pub mod cli;
pub mod clock;
pub mod ctx;
pub mod error;
pub mod hooks;
mod manager;
pub mod module;
pub mod phonebook;
pub mod realtime;
pub mod run;
pub mod served;
pub mod signals;
pub mod sim;
pub mod stats;
pub mod tool;
pub mod upgrade;

pub use modbot_transport as transport;
pub use modbot_transport::domain;

pub use blackboard::Blackboard;
pub use calls::{CallHandle, CallOptions, RetryPolicy};
pub use cli::ModuleArgs;
pub use ctx::Ctx;
pub use domain::Domain;
pub use error::{CallError, MethodError, ModuleError};
pub use modbot_ipc_schema::{Addr, Args, OwnedValue, Value};
pub use module::{Module, ModuleBuilder, Reply, Report};
pub use run::run;
pub use sim::SimTime;
pub use stats::{Histogram, Stats};
pub use transport::ipc::IpcTransport;
pub use transport::local::LocalTransport;
pub use transport::{Dest, ReceiveMode};
