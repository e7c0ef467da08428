//! modbot-grid: the time grid — its component model, the checked description, the reference
//! run of its logical execution time (LET) semantics, and the hosts. Uses
//! `modbot-core` and `modbot-transport`; reads no Lua (the descriptions are `modbot-system`'s).
//! The robot controllers are components of `modbot-control`, the bus bridge and its drives of
//! `modbot-bus`; `modbot-components` assembles every built-in type in one registry. The
//! coordinator, which releases the components every tick, is `modbot-grid-processes`'s
//! (its grid and its process in one place); it uses [`wire`], [`tick`], [`ledger`] and
//! [`recorder`] from here.
//!
//! A grid is a set of *components* (FMI-style: named, typed inputs, outputs and parameters)
//! on *host* processes, each released every k base ticks, and the *connections* from outputs
//! to inputs. The coordinator ticks the base period and releases components; the hosts step
//! them and publish their outputs. Released at tick n, a component reads its inputs as they
//! were valid at n, and its outputs become valid at n + k, never earlier, so the values do not
//! depend on how the processes were scheduled. This module is everything about that which is
//! pure: the model, the checked description, and an in-process run that computes the values
//! every real run must reproduce bit for bit.
//!
//! The grid is declared in the system description (`grid`, `component`, `connect`; see
//! `modbot-system`) and arrives as [`GridSpec`] in `modbot_system::SystemSpec::grid`.
//!
//! # Layout
//! - [`component`]: ports, parameters, the [`Component`] trait (initialise → step → terminate)
//!   and the [`Registry`] of component types, which checks parameters and instantiates; what
//!   a type refuses for ([`ComponentError`], [`ParamError`]).
//! - [`builtin`]: the grid's built-in types (`counter`, `ramp`, `sine`, `gain`, `sum`,
//!   `integrator`, `lowpass`, `delay`, `vec_gain`, `pack`, `sleeper`).
//! - [`spec`]: the checked grid ([`GridSpec`]): components, hosts, periods in base ticks,
//!   connections, and the *sources* of a component (the release notice's order); built from
//!   declarations by [`GridSpec::build`], which says what is wrong with them ([`GridError`]).
//! - [`reference`](mod@reference): the LET semantics computed in one thread ([`reference_run`],
//!   [`reference_trace`]).
//! - [`replay`]: a recorded run computed again in one thread, with its switches, holds,
//!   faults and overruns as the coordinator's schedule of it says ([`replay::Schedule`]).
//! - [`trace`]: the text format of a run's outputs, tick by tick ([`TraceWriter`]), which
//!   the reference run and the real runs write so they can be compared.
//!
//! Across processes:
//! - [`wire`]: the grid's links over the transport layer's channels (outputs, release and done
//!   notices, wake-ups): iceoryx2 in real runs, in-process in tests.
//! - [`versions`]: the versions of a component's outputs a reader keeps (hosts, recorder).
//! - [`tick`]: where the base tick comes from (an absolute timerfd; a free-running source).
//! - [`host`]: a component host: steps its components on release, publishes their outputs.
//! - [`outputs_view`]: the latest outputs of a host's components, copied for its module
//!   (shown on its blackboard, read by robot programs).
//! - [`recorder`]: the coordinator's trace of every output as valid at every tick.
//! - [`record_type`]: the data recorder (`record { ... }`) as a component type: its params and
//!   ports (the component, which writes HDF5, is `modbot-record`'s).
//! - [`state_hash`]: the hash of a component's state after a step, and of the grid's at a
//!   tick (`# state_hash` trace lines, the recorder's `state_hash` dataset).
//! - [`offload`]: a writer whose bytes a thread of normal priority writes out (the trace).
//! - [`ledger`]: the overrun ledger as `modbot top` shows it.
//! - [`switch`]: swapping assemblies from a program (`modbot assembly switch`); the assembly
//!   files are read by `modbot_system::load_assembly`.

pub mod builtin;
pub mod carry;
pub mod component;
pub mod host;
pub mod ledger;
pub mod offload;
pub mod outputs_view;
pub mod record_type;
pub mod recorder;
pub mod reference;
pub mod replay;
pub mod spec;
pub mod state_hash;
pub mod switch;
pub mod tick;
pub mod trace;
pub mod versions;
pub mod wire;

pub use component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, ParamValue, Params,
    PortDecl, PortType, PortValue, Registry,
};
pub use reference::{reference_run, reference_trace, reference_trace_with, Overruns};
pub use spec::{
    ComponentSpec, Connection, GridClock, GridError, GridSpec, GridTiming, OverrunPolicy, PortRef,
};
pub use state_hash::StateHasher;
pub use trace::TraceWriter;
