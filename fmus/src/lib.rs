//! modbot-fmus: the project's own FMUs, built from source by the workspace's build (its build
//! script), so that nothing is downloaded to test FMU components:
//!
//! - [`FF2`], `modbot_ff2.fmu`: FMI 2.0 co-simulation, in C against the official FMI 2 headers
//!   (`ff2/include`, as fmi-sys ships them): the arm's elastic-joint feed-forward, the inverse
//!   of a two-mass joint, 6 axes (`ff2/ff2.c` says what it computes).
//! - [`STAIR2`], `modbot_stair2.fmu`: FMI 2.0 co-simulation, in C: a counter that steps up by
//!   its Integer input at every step from an Integer parameter with a declared range, and that
//!   asks to terminate (fmi2Discard, with a message to the logger) once its time passes
//!   `t_stop` (`stair2/stair2.c`).
//! - [`SS3`], `modbot_ss3.fmu`: FMI 3.0 co-simulation, in C against the official FMI 3 headers
//!   (`ss3/include`): a linear state-space system whose sizes are structural parameters and
//!   whose matrices are two-dimensional parameters; its output after initialisation is 2
//!   (`ss3/ss3.c`).
//! - [`FILTER3`], `modbot_filter3.fmu`: FMI 3.0 co-simulation, in Rust with fmi-export
//!   (`filter3/`, a workspace of its own the build script builds): a first-order low-pass
//!   filter with gain.
//!
//! The build script also copies them next to the workspace's programs (`target/<profile>/`),
//! where a description finds them by their bare names (`fmu = "modbot_ff2.fmu"`).

/// The FMI 2.0 FMU: the elastic-joint feed-forward.
pub const FF2: &str = env!("MODBOT_FF2_FMU");
/// The FMI 2.0 FMU that asks to terminate: the staircase.
pub const STAIR2: &str = env!("MODBOT_STAIR2_FMU");
/// The FMI 3.0 FMU sized by structural parameters: the state-space system.
pub const SS3: &str = env!("MODBOT_SS3_FMU");
/// The FMI 3.0 FMU: the low-pass filter.
pub const FILTER3: &str = env!("MODBOT_FILTER3_FMU");
