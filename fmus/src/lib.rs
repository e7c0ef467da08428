//! modbot-fmus: the project's own FMUs, built from source by the workspace's build (its build
//! script), so that nothing is downloaded to test FMU components:
//!
//! - [`FF2`], `modbot_ff2.fmu`: FMI 2.0 co-simulation, in C against the official FMI 2 headers
//!   (`ff2/include`, as fmi-sys ships them): the arm's elastic-joint feed-forward, the inverse
//!   of a two-mass joint, 6 axes (`ff2/ff2.c` says what it computes).
//! - [`FILTER3`], `modbot_filter3.fmu`: FMI 3.0 co-simulation, in Rust with fmi-export
//!   (`filter3/`, a workspace of its own the build script builds): a first-order low-pass
//!   filter with gain.
//!
//! The build script also copies both next to the workspace's programs (`target/<profile>/`),
//! where a description finds them by their bare names (`fmu = "modbot_ff2.fmu"`).

/// The FMI 2.0 FMU: the elastic-joint feed-forward.
pub const FF2: &str = env!("MODBOT_FF2_FMU");
/// The FMI 3.0 FMU: the low-pass filter.
pub const FILTER3: &str = env!("MODBOT_FILTER3_FMU");
