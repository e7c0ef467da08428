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
/// `PID.DOMAIN`: the supervisor that started this process, and its domain. A process of that
/// domain whose supervisor still lives knows it is supervised without asking iceoryx2 (whose
/// `Service::does_exist` reads the details of every node attached to the directory: at 253
/// modules starting together, quadratic work that took most of the start-up).
pub const SUPERVISOR: &str = "MODBOT_SUPERVISOR";
/// A directory the supervisor made for a live upgrade (`modbot upgrade`): the process it
/// started with this takes over the running module of its assigned address and name. Its
/// endpoint opens in standby (every service but its inbox and buses, which it subscribes to
/// when the handover begins: [`crate::Rx::attach`]); the files of the handover are in there.
pub const UPGRADE_DIR: &str = "MODBOT_UPGRADE_DIR";
/// Simulated seconds per real second (default 1); descriptions set it in a module's `env`.
/// Read by `modbot_core::sim::SimTime::from_env`.
pub const SIM_SPEED: &str = "MODBOT_SIM_SPEED";

/// How many processes may send to one module's inbox at once: the inbox's sender slots. A
/// supervisor sets it from its system (its modules, itself, and room for tools and for the
/// senders of dead processes until they are cleaned up); without it an inbox takes
/// [`DEFAULT_INBOX_SENDERS`]. Every receive looks at every slot, so a system's inboxes are
/// sized to it.
pub const INBOX_SENDERS: &str = "MODBOT_INBOX_SENDERS";

/// An inbox's sender slots without a supervisor's setting: every process a domain can hold.
pub const DEFAULT_INBOX_SENDERS: usize = 300;
/// The fewest sender slots an inbox gets, whatever it is told.
pub const MIN_INBOX_SENDERS: usize = 4;

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

/// The inbox sender slots a supervisor gives a system of `modules` modules: each may send to
/// an inbox, and once more while a restarted module's dead sender waits for its cleanup (or a
/// host of a new assembly runs beside the old one), plus the supervisor and 16 tools.
pub fn inbox_senders_for(modules: usize) -> usize {
    inbox_senders_within(2 * modules + 17)
}

/// `senders` brought into [`MIN_INBOX_SENDERS`]`..=`[`DEFAULT_INBOX_SENDERS`].
pub fn inbox_senders_within(senders: usize) -> usize {
    senders.clamp(MIN_INBOX_SENDERS, DEFAULT_INBOX_SENDERS)
}

/// The inbox sender slots this process was given ([`INBOX_SENDERS`]), or the default; a value
/// that is not a number is the default, and the result lies in
/// [`MIN_INBOX_SENDERS`]`..=`[`DEFAULT_INBOX_SENDERS`].
pub fn inbox_senders() -> usize {
    parse_inbox_senders(std::env::var(INBOX_SENDERS).ok().as_deref())
}

fn parse_inbox_senders(value: Option<&str>) -> usize {
    value
        .and_then(|v| v.trim().parse::<usize>().ok())
        .map_or(DEFAULT_INBOX_SENDERS, inbox_senders_within)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inbox_senders_default_to_the_whole_domain_and_stay_in_range() {
        assert_eq!(parse_inbox_senders(None), DEFAULT_INBOX_SENDERS);
        assert_eq!(parse_inbox_senders(Some("many")), DEFAULT_INBOX_SENDERS);
        assert_eq!(parse_inbox_senders(Some("40")), 40);
        assert_eq!(parse_inbox_senders(Some(" 40\n")), 40);
        assert_eq!(parse_inbox_senders(Some("0")), MIN_INBOX_SENDERS);
        assert_eq!(parse_inbox_senders(Some("100000")), DEFAULT_INBOX_SENDERS);
    }

    #[test]
    fn a_system_gets_two_slots_per_module_and_room_for_the_supervisor_and_tools() {
        assert_eq!(inbox_senders_for(2), 21);
        assert_eq!(inbox_senders_for(10), 37);
        assert_eq!(inbox_senders_for(254), DEFAULT_INBOX_SENDERS);
    }
}

/// Whether this process was started by a supervisor of `domain` that still lives
/// ([`SUPERVISOR`]).
pub fn launched_by_live_supervisor(domain: &str) -> bool {
    std::env::var(SUPERVISOR)
        .ok()
        .is_some_and(|v| names_live_supervisor(&v, domain))
}

fn names_live_supervisor(value: &str, domain: &str) -> bool {
    let Some((pid, of)) = value.split_once('.') else {
        return false;
    };
    let Ok(pid) = pid.parse::<i32>() else {
        return false;
    };
    of == domain && pid > 0 && nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid), None).is_ok()
}

#[cfg(test)]
mod supervisor_tests {
    use super::names_live_supervisor;

    #[test]
    fn a_live_supervisor_of_the_same_domain_is_recognised() {
        let me = format!("{}.arm", std::process::id());
        assert!(names_live_supervisor(&me, "arm"));
    }

    #[test]
    fn another_domain_a_dead_pid_or_a_malformed_value_is_not_a_supervisor() {
        let me = std::process::id();
        assert!(!names_live_supervisor(&format!("{me}.arm"), "base"));
        assert!(!names_live_supervisor(&format!("{me}.arm.x"), "arm"));
        assert!(!names_live_supervisor("0.arm", "arm"));
        assert!(!names_live_supervisor("-1.arm", "arm"));
        assert!(!names_live_supervisor("arm", "arm"));
        assert!(!names_live_supervisor("x.arm", "arm"));
        // Beyond pid_max: no such process.
        assert!(!names_live_supervisor("2147483646.arm", "arm"));
    }
}
