//! modbot's module runtime: the MRA module model on iceoryx2 shared memory.
//!
//! Each module of a robot is its own OS process. It declares a name, an 8-bit address, a table
//! of local methods and a blackboard; the runtime serves RVMF* frames to those methods, calls
//! other modules' methods through the phone book and the method queue, and publishes the
//! blackboard as zero-copy snapshots.
//!
//! # Layout
//! The module core (`modbot-core`) and the transport (`modbot-transport`) are crates of their
//! own, re-exported here under their old paths; this crate adds the grid, the bus, the system
//! descriptions and the supervisor.
//!
//! - [`transport`] (the crate `modbot-transport`, re-exported): the transport traits, with the
//!   iceoryx2 backend ([`transport::ipc`]) and an in-process one for tests
//!   ([`transport::local`]); [`domain`] (from it too): the namespace of a system's shared
//!   memory (an iceoryx2 prefix).
//! - [`module`]: declaring a module ([`ModuleBuilder`]) and the message manager that serves it.
//! - [`ctx`]: what a module's code can do: call, report, read snapshots, use its blackboard.
//! - [`calls`]: the method queue, matching answers by (peer, sequence), with retransmission.
//! - `manager`: the message manager, serving one incoming frame.
//! - [`served`]: the requests served lately, so a retransmission is not executed twice.
//! - [`phonebook`]: names to addresses, liveness and method tables.
//! - [`blackboard`]: typed items, logical and virtual devices, snapshots.
//! - [`bus`]: the bus bridge's backends: simulated CiA 402 drives on an elastic-joint plant.
//! - [`grid`]: the time grid's components, their description and the reference LET run.
//! - [`run`]: the default application controller (main loop, signals, receive modes).
//! - [`stats`]: traffic counters and the call latency histogram (the `stats` system method).
//! - [`sim`]: the simulated time all processes of a system share (`MODBOT_EPOCH_NS`).
//! - [`system`]: the system description: the Lua file that lists a robot's module processes,
//!   loaded in a sandbox and checked ([`system::load`]).
//! - [`supervisor`]: `modbot up`: starts, watches and restarts a system's module processes.
//! - [`tool`]: how a tool (the CLI) reaches a running system, also when every address is taken.
//! - [`clock`], [`signals`], [`error`]: injected time, termination, error types.

pub mod bus;
pub mod grid;
pub mod supervisor;
pub mod system;

// The module core and the transport, under the paths they had in this crate.
pub use modbot_core::*;
