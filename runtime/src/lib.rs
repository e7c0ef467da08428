//! modbot-runtime: the facade over modbot's runtime crates, under one name and the paths a
//! program uses (`modbot_runtime::Module`, `modbot_runtime::grid::GridSpec`, ...).
//!
//! # Layout (crate → what it holds → what it uses)
//! - `modbot-transport` ([`transport`], [`domain`]): frames between processes over iceoryx2 or
//!   in one process; domains; the launch contract → ipc_schema.
//! - `modbot-core` ([`module`], [`ctx`], [`calls`], [`phonebook`], [`blackboard`], [`run`],
//!   [`stats`], [`sim`], [`tool`], [`clock`], [`signals`], [`error`]): the module core: what
//!   every module program links → transport.
//! - `modbot-grid` ([`grid`]): the time grid (components, LET, coordinator, hosts, ledger,
//!   traces) → core; `modbot-control` ([`control`]): the robot controllers → grid;
//!   `modbot-bus` ([`bus`]): the bus bridge and its CiA 402 drives → control, grid;
//!   `modbot-components` ([`components`]): every built-in type in one registry → bus.
//! - `modbot-system` ([`system`]): system descriptions, the sandboxed Lua files (the only crate
//!   with mlua) → grid, core.
//! - `modbot-supervisor` ([`supervisor`]): `modbot up`: starts, watches and restarts a system's
//!   processes, grid processes included → system, grid, core.
//!
//! A module program that needs no grid depends on `modbot-core` alone.

pub use modbot_bus as bus;
pub use modbot_components as components;
pub use modbot_control as control;
pub use modbot_grid as grid;
pub use modbot_supervisor as supervisor;
pub use modbot_system as system;

// The module core and the transport, under the paths they had in this crate.
pub use modbot_core::*;
