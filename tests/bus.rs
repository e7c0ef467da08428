//! The bus bridge with simulated CiA 402 drives, under `modbot up examples/arm.lua`, in a
//! domain of its own: the drives are enabled by the grid, and when the coordinator is lost
//! the bridge's own watchdog brings every drive to quick stop.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use common::arm::{all_axes, arm, bus_ledger, one_arm_at_a_time, wait_enabled};
use common::TestDomain;
use nix::sys::signal::Signal;

/// SIGKILL of the coordinator: the bus bridge's watchdog judges it lost, commands quick stop,
/// and every drive reports quick stop active in the bus ledger, which says why and when.
#[test]
fn a_lost_coordinator_brings_every_drive_to_quick_stop() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("lostcoord");
    let file = arm();
    let domain = format!("domain={}", sut.name());
    // The watchdog's budget is 500 base periods here, not its 3 by default: on a machine that
    // runs the grid without SCHED_FIFO, under load, 3 ms without a tick come often enough to
    // stop the drives again and again before the kill. What is under test is that a lost
    // coordinator stops every drive; that the default budget is kept is unit-tested with an
    // injected clock (bus::bridge) and measured by the bench.
    let up = sut.spawn_logged(
        "modbot",
        &[
            "up",
            file.to_str().unwrap(),
            "--var",
            &domain,
            "--var",
            "watchdog=500",
        ],
    );
    wait_enabled(&sut, up);
    let coordinator: u32 = sut
        .ls_field("coordinator", "PID")
        .and_then(|p| p.parse().ok())
        .expect("the coordinator runs");
    sut.signal(coordinator, Signal::SIGKILL);
    sut.wait_for("every drive in quick stop", Duration::from_secs(60), || {
        all_axes(&bus_ledger(&sut), "quick stop active")
    });
    let ledger = bus_ledger(&sut);
    assert!(
        ledger.contains("SAFE STOP at cycle") && ledger.contains("coordinator lost: no tick for"),
        "{ledger}"
    );
    let first = ledger.lines().next().unwrap_or_default();
    println!("{first}");
    // How many base periods after the last tick every drive stopped is a real-time figure:
    // the bridge's watchdog is unit-tested for it with an injected clock (bus::bridge), and
    // `modbot-benches` measures it on the real processes. Here it only has to be there.
    assert!(
        first.contains(" base periods after the last tick"),
        "when the drives stopped, in: {first}"
    );
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

/// `modbot up` takes its domain from the command line (`--domain`, or MODBOT_DOMAIN) over the
/// one the description declares (`examples/arm.lua` says "arm"): two arms from the one
/// description run side by side, each in its own domain, each with its drives enabled.
#[test]
fn two_arms_from_one_description_run_side_by_side_in_the_domains_the_command_line_gives() {
    let _arm = one_arm_at_a_time();
    let mut first = TestDomain::new("armone");
    let mut second = TestDomain::new("armtwo");
    let file = arm();
    let file = file.to_str().unwrap();
    // The first through MODBOT_DOMAIN (the test's environment), the second through --domain.
    let up_first = first.spawn_logged("modbot", &["up", file, "--lockstep"]);
    let second_name = second.name().to_owned();
    let up_second = second.spawn_logged(
        "modbot",
        &["up", file, "--domain", &second_name, "--lockstep"],
    );
    wait_enabled(&first, up_first);
    wait_enabled(&second, up_second);
    for (sut, up) in [(&mut first, up_first), (&mut second, up_second)] {
        assert!(sut
            .modbot_ok(&["robot"])
            .starts_with("operational since tick"));
        sut.modbot_ok(&["down"]);
        sut.wait_exit(up, Duration::from_secs(60));
        let output = sut.output_of(up);
        assert!(
            output.contains("modbot up: ran ")
                && output.contains(&format!("in domain '{}'", sut.name())),
            "{output}"
        );
        assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
    }
}
