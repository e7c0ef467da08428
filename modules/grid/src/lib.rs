//! modbot's grid processes: the programs `modbot up` starts for a system's time grid.
//!
//! - `modbot-coordinator`: the grid's clock; releases every component on the base period
//!   (its tick thread), and serves methods, loads assemblies and drives a switch (its service
//!   thread).
//! - `modbot-host`: steps the components of one host of the description.
//! - `modbot-bus`: the bus bridge, the host named `bus`: serves the drives every tick, with its
//!   watchdog.
//! - `modbot-recorder`: the data recorder's host: steps `record` components (`modbot-record`),
//!   which write a run's signals to HDF5.
//!
//! [`coordinator`]: all of the coordinator, its grid (the tick thread) and its process (the
//! service thread), which the program `modbot-coordinator` runs;
//! [`grid_args`]: the options they share (the description, its variables, an assembly);
//! [`host_process`]: what a host process does around its clocked work (shared by the two hosts);
//! [`service_thread`]: a module served on a thread of normal priority beside the real-time one;
//! [`board`]: a host's blackboard, its components' latest outputs;
//! [`watchdog_check`]: whether the machine gives the grid what the bus watchdog assumes.
//! The module programs that use no grid are in `modbot-modules`, which links no grid, bus or
//! Lua.

pub mod board;
pub mod coordinator;
pub mod grid_args;
pub mod host_process;
pub mod service_thread;
pub mod watchdog_check;
