//! The simulated arm (`examples/arm.lua`) as the tests observe it: the bus ledger and the
//! drive lines in it.

use std::path::PathBuf;

use super::TestDomain;

/// The arm's system description.
pub fn arm() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/arm.lua"))
}

/// `modbot bus` of the test's domain.
pub fn bus_ledger(sut: &TestDomain) -> String {
    String::from_utf8_lossy(&sut.modbot(&["bus"]).stdout).into_owned()
}

/// The drive lines of the bus ledger.
pub fn axes(ledger: &str) -> Vec<String> {
    ledger
        .lines()
        .skip_while(|l| !l.starts_with("AXIS"))
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(str::to_owned)
        .collect()
}

/// Whether all six drives are in `state` ("operation enabled", "quick stop active").
pub fn all_axes(ledger: &str, state: &str) -> bool {
    let axes = axes(ledger);
    axes.len() == 6 && axes.iter().all(|l| l.contains(state))
}

/// Runs one arm at a time in this test binary: each arm is a real-time system (a coordinator
/// and hosts under SCHED_FIFO), and two on a 2-core machine would take each other's cycles.
pub fn one_arm_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ARM: std::sync::Mutex<()> = std::sync::Mutex::new(());
    ARM.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
