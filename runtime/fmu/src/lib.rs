//! modbot-fmu: FMUs as grid components (MoRC's components): an FMI 2.0 or 3.0 co-simulation
//! FMU, exported by a modelling tool (OpenModelica, Dymola, Simulink, or Rust's fmi-export),
//! is a component of type `fmu` whose inputs, outputs and parameters are the FMU's:
//!
//! ```lua
//! component "ff" { type = "fmu", fmu = "ff.fmu", host = "h_ff", period = 1, params = { Jm = 0.5 } }
//! ```
//!
//! Every process that loads a description knows the type's interface (read from the FMU's
//! modelDescription.xml, without loading its binary: `modbot check` reports a missing or broken
//! FMU, or a port that does not fit, as `file:line`); the host program `modbot-fmu-host` runs
//! it, each FMU component on a host process of its own, through the `fmi` crate (feature
//! `import`).
//!
//! # Layout
//! - [`component_type`]: the type `fmu` — its interface from the FMU, its parameters checked
//!   against the FMU's; [`declare`] (what every process registers).
//! - [`interface`]: an FMU's inputs, outputs and parameters as ports and parameters, its
//!   arrays sized by its structural parameters; read by `model2` and `model3` (what each
//!   version's modelDescription.xml says; `model`, what they share), `gather` (variables
//!   into ports and parameters) and [`ranges`] (the declared `min` and `max`); its parts'
//!   types are in [`variables`].
//! - `params`: a description's parameters checked against the FMU's (known, typed, shaped,
//!   within range).
//! - [`archive`]: the .fmu archive — its modelDescription.xml, its binary for this platform.
//! - [`error`]: [`FmuError`], naming the file and what is wrong with it.
//! - with `import`: `component` (the running component; `register`), `running` (an FMU
//!   instance of either version), `exchange` (a release's values set and got), `call` (a
//!   failed FMI call: which, and the status),
//!   `fmu_log` (what the FMU logs through its logger callback, the last messages kept),
//!   `unpack` (where it is unpacked: a temporary directory of the domain), `values` (the
//!   values of a release, laid out once).

pub mod archive;
#[cfg(feature = "import")]
mod call;
#[cfg(feature = "import")]
pub mod component;
pub mod component_type;
pub mod error;
#[cfg(feature = "import")]
mod exchange;
#[cfg(feature = "import")]
mod fmu_log;
mod gather;
pub mod interface;
mod model;
mod model2;
mod model3;
mod params;
pub mod ranges;
#[cfg(feature = "import")]
mod running;
#[cfg(feature = "import")]
mod unpack;
#[cfg(feature = "import")]
pub mod values;
pub mod variables;

pub use component_type::{declare, FMU, PROGRAM, TYPE};
pub use error::{FmuError, FmuErrorKind};
pub use interface::Interface;

#[cfg(feature = "import")]
pub use component::register;
