//! The bus bridge with simulated CiA 402 drives, under `modbot up examples/arm.lua`, in a
//! domain of its own: the drives are enabled by the grid, and when the coordinator is lost
//! the bridge's own watchdog brings every drive to quick stop.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use common::TestDomain;
use nix::sys::signal::Signal;

fn bus_ledger(sut: &TestDomain) -> String {
    String::from_utf8_lossy(&sut.modbot(&["bus"]).stdout).into_owned()
}

fn all_axes(ledger: &str, state: &str) -> bool {
    let axes: Vec<&str> = ledger
        .lines()
        .skip(2)
        .filter(|l| !l.trim().is_empty())
        .collect();
    axes.len() == 6 && axes.iter().all(|l| l.contains(state))
}

/// SIGKILL of the coordinator: after three base periods without a tick the bus bridge
/// commands quick stop, and every drive reports quick stop active in the bus ledger.
#[test]
#[ignore = "the coordinator still stalls past the 3-period watchdog on a loaded 2-core machine (debug build), so the drives are quick-stopped before the test kills it; run with --ignored"]
fn a_lost_coordinator_brings_every_drive_to_quick_stop_within_three_ticks() {
    let mut sut = TestDomain::new("lostcoord");
    let file = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/arm.lua"));
    let domain = format!("domain={}", sut.name());
    let up = sut.spawn_logged("modbot", &["up", file.to_str().unwrap(), "--var", &domain]);
    sut.wait_for("every drive enabled", Duration::from_secs(30), || {
        all_axes(&bus_ledger(&sut), "operation enabled")
    });
    let coordinator: u32 = sut
        .ls_field("coordinator", "PID")
        .and_then(|p| p.parse().ok())
        .expect("the coordinator runs");
    sut.signal(coordinator, Signal::SIGKILL);
    sut.wait_for("every drive in quick stop", Duration::from_secs(10), || {
        all_axes(&bus_ledger(&sut), "quick stop active")
    });
    let ledger = bus_ledger(&sut);
    // The watchdog acts after 3 silent periods (unit-tested in bus::bridge with an injected
    // clock); here the machine's scheduling may add one.
    assert!(
        ledger.contains("SAFE STOP at cycle") && ledger.contains("coordinator lost: no tick for"),
        "{ledger}"
    );
    println!("{}", ledger.lines().next().unwrap_or_default());
    sut.modbot_ok(&["down"]);
    let status = sut.wait_exit(up, Duration::from_secs(30));
    let output = sut.output_of(up);
    assert_eq!(
        status.code(),
        Some(1),
        "the lost coordinator is reported:\n{output}"
    );
    assert!(
        output.contains("coordinator: killed by SIGKILL, not restarted"),
        "{output}"
    );
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}
