//! MOSER, the MRA paper's security robot, end to end: `modbot up examples/moser.lua` with every
//! module its own process, in simulated time sped up twice, in a domain of its own.

mod common;

use std::time::Duration;

use common::TestDomain;
use nix::sys::signal::Signal;

/// How much faster than real time the tests run the scenario. MOSER runs in simulated real
/// time: a module process the machine holds up reacts late by that much simulated time times
/// this factor (a collision sonar held up 100 ms at 5× lets the base drive 0.25 m further, into
/// the box, as seen once beside two CPU hogs and two builds); 2× keeps that within the sonar's
/// margin and the run about a minute.
const SPEED: &str = "2";

fn moser(sut: &mut TestDomain) -> u32 {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/moser.lua");
    let domain = format!("domain={}", sut.name());
    let speed = format!("speed={SPEED}");
    sut.spawn_logged(
        "modbot",
        &[
            "up", file, "--var", &domain, "--var", &speed, "--for", "240",
        ],
    )
}

/// What the summary says about `line` (the text after its label).
fn summary_line(output: &str, label: &str) -> String {
    output
        .lines()
        .find_map(|l| l.split_once(label).map(|(_, rest)| rest.trim().to_owned()))
        .unwrap_or_else(|| panic!("no '{label}' line in:\n{output}"))
}

fn assert_scenario_completed(output: &str) {
    assert!(output.contains("*** ALERT: intruder at"), "{output}");
    assert!(output.contains("==== MOSER summary ===="), "{output}");
    assert_eq!(summary_line(output, "collisions "), "0", "{output}");
    let driven: f64 = summary_line(output, "distance patrolled ")
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(driven > 10.0, "patrolled only {driven} m:\n{output}");
    assert!(
        summary_line(output, "alert ").starts_with("at "),
        "{output}"
    );
    // A clean run has no failed call (the patrol asked for before the base's first pose is
    // taken, not refused).
    assert!(
        summary_line(output, "calls ").contains("(0 failed)"),
        "{output}"
    );
    assert!(output.contains("every module stopped cleanly"), "{output}");
}

/// The robot patrols wing 3, goes around the box its map does not know, detects the intruder,
/// the control station shows the alert and the summary, and every module exits cleanly.
#[test]
fn moser_patrols_detects_the_intruder_without_a_collision_and_ends_cleanly() {
    let mut sut = TestDomain::new("moser");
    let up = moser(&mut sut);
    let status = sut.wait_exit(up, Duration::from_secs(200));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(0), "{output}");
    assert_scenario_completed(&output);
    assert!(
        output.contains("replan"),
        "the box in the server room was found and avoided:\n{output}"
    );
    // Found in the server room, where the robot goes round the box first.
    let alert = output
        .lines()
        .find(|l| l.contains("*** ALERT"))
        .unwrap_or_default();
    let at = |what: &str| -> f64 {
        let rest = &alert[alert.find(what).map_or(0, |i| i + what.len())..];
        rest.trim_start()
            .split([',', ')'])
            .next()
            .unwrap_or("")
            .trim()
            .parse()
            .unwrap_or(f64::NAN)
    };
    let (x, y) = (at("intruder at ("), at(", "));
    assert!(
        (20.0..30.0).contains(&x) && (0.0..8.0).contains(&y),
        "the alert places the intruder in the server room: {alert}\n{output}"
    );
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// The navigation sonar is killed mid-patrol: the supervisor restarts it and the patrol carries
/// on to the intruder.
#[test]
fn nav_sonar_killed_mid_patrol_is_restarted_and_the_patrol_carries_on() {
    let mut sut = TestDomain::new("moserkill");
    let up = moser(&mut sut);
    sut.wait_for(
        "the patrol to be under way",
        Duration::from_secs(60),
        || sut.output_of(up).contains("patrolling wing 3  point"),
    );
    std::thread::sleep(Duration::from_secs(2));
    let pid: u32 = sut
        .ls_field("nav_sonar", "PID")
        .and_then(|p| p.parse().ok())
        .expect("nav_sonar runs");
    sut.signal(pid, Signal::SIGKILL);
    sut.wait_for("nav_sonar to be back", Duration::from_secs(30), || {
        sut.ls_field("nav_sonar", "RESTARTS").as_deref() == Some("1")
            && sut.ls_field("nav_sonar", "STATE").as_deref() == Some("running")
    });
    let status = sut.wait_exit(up, Duration::from_secs(200));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(0), "{output}");
    assert!(
        output.contains("nav_sonar ended (killed by SIGKILL)"),
        "{output}"
    );
    assert_scenario_completed(&output);
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// The high-level module SIGKILLed mid-patrol forgets the patrol it was given; restarted, it
/// reports itself idle, and the control station, whose mission stands, sends it the patrol
/// again: the robot goes on to the intruder and the scenario completes.
#[test]
fn high_level_killed_mid_patrol_is_given_its_patrol_again_by_the_control_station() {
    let mut sut = TestDomain::new("moserhl");
    let up = moser(&mut sut);
    sut.wait_for(
        "the patrol to be under way",
        Duration::from_secs(60),
        || sut.output_of(up).contains("patrolling wing 3  point"),
    );
    let pid: u32 = sut
        .ls_field("high_level", "PID")
        .and_then(|p| p.parse().ok())
        .expect("high_level runs");
    sut.signal(pid, Signal::SIGKILL);
    sut.wait_for("the patrol sent again", Duration::from_secs(60), || {
        sut.output_of(up).contains("patrol of wing 3 sent again")
    });
    let status = sut.wait_exit(up, Duration::from_secs(200));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(0), "{output}");
    assert!(
        output.contains("high_level ended (killed by SIGKILL)"),
        "{output}"
    );
    assert_scenario_completed(&output);
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// The high-level module upgraded live mid-patrol (`modbot upgrade high_level`): the new process
/// takes the patrol over where the old one was — the control station need not send it again —
/// and the robot goes on to the intruder.
#[test]
fn high_level_upgraded_mid_patrol_carries_the_patrol_on_to_the_alert() {
    let mut sut = TestDomain::new("moserup");
    let up = moser(&mut sut);
    sut.wait_for(
        "the patrol to be under way",
        Duration::from_secs(60),
        || sut.output_of(up).contains("patrolling wing 3  point"),
    );
    let before = sut.ls_field("high_level", "PID").expect("high_level runs");
    let upgraded = sut.modbot_ok(&["upgrade", "high_level"]);
    assert!(upgraded.contains("high_level upgraded"), "{upgraded}");
    assert_ne!(sut.ls_field("high_level", "PID").unwrap(), before);
    assert_eq!(sut.ls_field("high_level", "UPGRADES").as_deref(), Some("1"));
    let status = sut.wait_exit(up, Duration::from_secs(200));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(0), "{output}");
    assert!(
        output.contains("took the patrol over: patrolling"),
        "{output}"
    );
    // The control station may send the patrol again at the start (it asked before the base's
    // first pose); after the upgrade it has no need to.
    let after = &output[output
        .find("high_level upgraded")
        .expect("the upgrade line")..];
    assert!(!after.contains("sent again"), "{output}");
    assert!(!output.contains("high_level ended"), "{output}");
    assert_scenario_completed(&output);
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}
