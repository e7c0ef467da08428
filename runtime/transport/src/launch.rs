//! What a supervisor tells the module processes it starts, through their environment.
//!
//! Module programs also get `--domain`, `--name`, `--addr` and `--mode` on their command line;
//! these variables carry the rest, and the runtime reads them itself, so a module program needs
//! no code of its own for them.

use core::time::Duration;

/// Groups the module joins, comma-separated.
pub const GROUPS: &str = "MODBOT_GROUPS";
/// The heartbeat period in milliseconds.
pub const HEARTBEAT_MS: &str = "MODBOT_HEARTBEAT_MS";
/// `1`: lock the process's memory (mlockall) at start.
pub const MLOCKALL: &str = "MODBOT_MLOCKALL";
/// The system's domain (module programs also take `--domain`).
pub const DOMAIN: &str = "MODBOT_DOMAIN";
/// When `modbot up` started the system, ns of CLOCK_MONOTONIC: the same for every module of
/// the system, restarted ones included. The epoch of simulated time (`modbot_core::sim::SimTime`).
pub const EPOCH_NS: &str = "MODBOT_EPOCH_NS";
/// `ADDR.NAME`: the address and name the supervisor assigned this module, unique in its
/// domain by the supervisor's word. A module that opens with exactly these takes them without
/// claiming them in shared memory (two services fewer per module); any other address or name
/// is claimed as usual.
pub const ASSIGNED: &str = "MODBOT_ASSIGNED";
/// Simulated seconds per real second (default 1); descriptions set it in a module's `env`.
/// Read by `modbot_core::sim::SimTime::from_env`.
pub const SIM_SPEED: &str = "MODBOT_SIM_SPEED";

/// The heartbeat period without a supervisor's setting.
pub const DEFAULT_HEARTBEAT: Duration = Duration::from_millis(100);

/// The heartbeat period this process was given, or the default.
pub fn heartbeat_period() -> Duration {
    std::env::var(HEARTBEAT_MS)
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        .map(|ms| Duration::from_millis(ms.clamp(1, 10_000)))
        .unwrap_or(DEFAULT_HEARTBEAT)
}

/// Applies `MODBOT_MLOCKALL` to this process; a refusal is a warning, not a failure.
pub fn apply_mlockall() {
    if std::env::var(MLOCKALL).as_deref() != Ok("1") {
        return;
    }
    use nix::sys::mman::{mlockall, MlockAllFlags};
    match mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE) {
        Ok(()) => tracing::info!("memory locked (mlockall)"),
        Err(e) => tracing::warn!(
            "mlockall refused ({e}): running without locked memory; page faults may add latency"
        ),
    }
}
