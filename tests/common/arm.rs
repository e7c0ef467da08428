//! The simulated arm (`examples/arm.lua`) as the tests observe it: the bus ledger and the
//! drive lines in it.

use std::path::PathBuf;
use std::time::Duration;

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

/// Waits until every drive of the arm that `modbot up` (pid `up`) runs is in operation
/// enabled. A machine that starves the coordinator for the watchdog's few base periods stops
/// the drives first (that is the watchdog doing its job, and the stop holds until a reset):
/// such a safe stop is recovered with `modbot robot reset`, at most 5 times.
/// On a timeout, fails with the ledger and the end of `modbot up`'s log.
pub fn wait_enabled(sut: &TestDomain, up: u32) {
    let mut recovered = 0;
    sut.wait_until("every drive enabled", Duration::from_secs(60), || {
        let ledger = bus_ledger(sut);
        if !ledger.contains("SAFE STOP") && all_axes(&ledger, "operation enabled") {
            return Ok(());
        }
        if ledger.contains("SAFE STOP") && recovered < 5 {
            recovered += 1;
            println!(
                "safe stop before the test began (the machine starved the coordinator): recovering"
            );
            sut.modbot(&["robot", "reset"]);
        }
        Err(format!(
            "{ledger}\n--- modbot up:\n{}",
            tail(&sut.output_of(up), 40)
        ))
    });
}

/// The last `n` lines of `text`.
fn tail(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}
