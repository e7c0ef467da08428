//! Assemblies swapped at runtime on the simulated 6-axis arm (`examples/arm.lua`), under
//! `modbot up`, each test in a domain of its own: swaps while the robot moves miss no bus
//! cycle, happen at the announced tick and do not make the command jump; a blocked axis
//! faults the assembly and quick-stops the drives, and a switch to `hold` recovers; a killed
//! host of an assembly with the `fault` policy stops the drives too.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use common::arm::{all_axes, arm, bus_ledger, one_arm_at_a_time};
use common::TestDomain;
use nix::sys::signal::Signal;

/// A number in the bus ledger's first line after `label` (as in "missed 0").
fn ledger_number(ledger: &str, label: &str) -> u64 {
    let first = ledger.lines().next().unwrap_or_default();
    let words: Vec<&str> = first.split_whitespace().collect();
    let at = words
        .iter()
        .position(|w| *w == label)
        .unwrap_or_else(|| panic!("{label} in {first}"));
    words[at + 1].parse().unwrap()
}

/// `switched to NAME (generation G) at tick T, announced for tick A, ...` → (G, T, A).
fn switched(line: &str) -> (u16, u64, u64) {
    let words: Vec<&str> = line.split_whitespace().collect();
    let after = |w: &str| {
        let i = words
            .iter()
            .position(|x| *x == w)
            .unwrap_or_else(|| panic!("{w} in {line}"));
        words[i + 1]
            .trim_matches(|c: char| !c.is_ascii_digit())
            .to_owned()
    };
    let number = |w: String| -> u64 {
        w.parse()
            .unwrap_or_else(|_| panic!("a number, not '{w}', in: {line}"))
    };
    // "at tick T", "for tick A"
    let tick_after = |w: &str| -> String {
        words
            .iter()
            .position(|x| *x == w)
            .and_then(|i| words.get(i + 2))
            .unwrap_or_else(|| panic!("the tick after '{w}' in: {line}"))
            .trim_matches(|c: char| !c.is_ascii_digit())
            .to_owned()
    };
    let announced = tick_after("for");
    (
        number(after("(generation")) as u16,
        number(tick_after("at")),
        number(announced),
    )
}

fn up(sut: &mut TestDomain, vars: &[&str]) -> u32 {
    let domain = format!("domain={}", sut.name());
    let file = arm();
    let mut args = vec!["up", file.to_str().unwrap(), "--var", domain.as_str()];
    for v in vars {
        args.extend(["--var", v]);
    }
    let up = sut.spawn_logged("modbot", &args);
    sut.wait_for("every drive enabled", Duration::from_secs(60), || {
        all_axes(&bus_ledger(sut), "operation enabled")
    });
    up
}

fn down(sut: &mut TestDomain, up: u32) -> String {
    sut.modbot_ok(&["down"]);
    sut.wait_exit(up, Duration::from_secs(60));
    let output = sut.output_of(up);
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new(), "{output}");
    output
}

/// 100 swaps between `ptp` and `ptp_smooth` while the robot moves: no bus cycle is missed
/// around any switch (the bus records the cycles missed within five ticks of each), each
/// switch is at its announced tick (as the bus saw it), and no switch changes the commanded
/// position by more than one tick's motion at the speed limit.
#[test]
fn a_hundred_swaps_while_the_robot_moves_cost_no_bus_cycle_and_keep_the_command_continuous() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("swaps");
    let up = up(&mut sut, &["dwell=0"]);
    sut.modbot_ok(&["assembly", "switch", "ptp"]);
    std::thread::sleep(Duration::from_millis(300));
    let before = bus_ledger(&sut);
    let missed_before = ledger_number(&before, "missed");
    let mut announced = Vec::new();
    for i in 0..100 {
        let name = if i % 2 == 0 { "ptp_smooth" } else { "ptp" };
        let out = sut.modbot_ok(&["assembly", "switch", name, "--timeout", "30"]);
        let (generation, tick, at) = switched(out.lines().last().unwrap_or_default());
        assert_eq!(
            tick, at,
            "switch {i} to {name} happened at its announced tick: {out}"
        );
        announced.push((generation, at));
        // Let it move a little between swaps.
        std::thread::sleep(Duration::from_millis(20));
    }
    let after = bus_ledger(&sut);
    // `modbot call` prints the text answer quoted, with its newlines escaped.
    let switches = String::from_utf8_lossy(&sut.modbot(&["call", "host_bus.switches"]).stdout)
        .trim()
        .trim_matches('"')
        .replace("\\n", "\n");
    println!("{}", after.lines().take(2).collect::<Vec<_>>().join("\n"));
    let missed_anywhere = ledger_number(&after, "missed") - missed_before;
    let cycles = ledger_number(&after, "cycles") - ledger_number(&before, "cycles");
    // The bus's own record: the tick of each generation's first cycle, the step, and the
    // cycles missed within five ticks of the switch.
    let one_tick = 1.0 * 0.001 * 1.000_001; // v_max (rad/s) × base period, rounding allowed
    let mut seen = 0;
    let mut missed_near = 0;
    for line in switches.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let (Some(g), Some(t), Some(step), Some(missed)) = (
            words.first().and_then(|w| w.parse::<u16>().ok()),
            words.get(1).and_then(|w| w.parse::<u64>().ok()),
            words.get(2).and_then(|w| w.parse::<f64>().ok()),
            words.get(3).and_then(|w| w.parse::<u64>().ok()),
        ) else {
            continue;
        };
        if let Some(&(_, at)) = announced.iter().find(|a| a.0 == g) {
            seen += 1;
            missed_near += missed;
            assert_eq!(
                t, at,
                "generation {g} took over the bus at the announced tick"
            );
            assert!(
                step <= one_tick,
                "generation {g}: the command jumped {step} rad at the switch (one tick: {one_tick})"
            );
        }
    }
    assert_eq!(seen, 100, "the bus saw every switch:\n{switches}");
    // A debug build on a shared 2-core machine misses a cycle now and then whatever happens (a
    // late timer wake-up; the benchmark measures that in release). What the swaps must not do
    // is cost cycles: the misses within five ticks of the 100 switches (1100 cycles) are no
    // more frequent than elsewhere, up to chance (a switch that costs a cycle costs 100).
    let near_cycles = 100 * 11;
    let elsewhere = (missed_anywhere - missed_near) as f64 / (cycles - near_cycles).max(1) as f64;
    let expected = elsewhere * near_cycles as f64;
    println!(
        "bus cycles missed during the 100 swaps: {missed_anywhere} of {cycles}; within five ticks of a switch: {missed_near} (at the rate elsewhere: {expected:.1})"
    );
    assert!(
        (missed_near as f64) <= 3.0 * expected + 3.0,
        "the swaps cost bus cycles: {missed_near} missed within five ticks of a switch, {expected:.1} expected at the rate elsewhere\n{switches}"
    );
    let max_step: f64 = switches
        .lines()
        .find_map(|l| {
            l.split("max_step ")
                .nth(1)?
                .split_whitespace()
                .next()?
                .parse()
                .ok()
        })
        .unwrap_or(0.0);
    assert!(
        max_step > 1e-4,
        "the robot was moving: largest step {max_step} rad\n{after}\n{switches}\n{}",
        sut.output_of(up)
    );
    down(&mut sut, up);
}

/// An axis blocked in the simulation: the monitor's following-error check faults the `ptp`
/// assembly, the bus bridge quick-stops every drive; unblocked, a switch to `hold` (fault
/// reset, disable voltage, enable) brings every drive back to operation enabled.
#[test]
fn a_blocked_axis_faults_the_assembly_and_a_switch_to_hold_recovers() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("blocked");
    let up = up(&mut sut, &[]);
    sut.modbot_ok(&["assembly", "switch", "ptp"]);
    std::thread::sleep(Duration::from_millis(200));
    sut.modbot_ok(&["call", "host_bus.block", "2", "true"]);
    sut.wait_for("every drive in quick stop", Duration::from_secs(20), || {
        all_axes(&bus_ledger(&sut), "quick stop active")
    });
    let ledger = bus_ledger(&sut);
    assert!(
        ledger.contains("SAFE STOP") && ledger.contains("the assembly faulted"),
        "{ledger}"
    );
    let top = sut.modbot_ok(&["top", "--once"]);
    assert!(
        top.contains("faulted") && top.contains("component watch reports an unsafe state"),
        "{top}"
    );
    sut.modbot_ok(&["call", "host_bus.block", "2", "false"]);
    let out = sut.modbot_ok(&["assembly", "switch", "hold"]);
    assert!(out.contains("switched to hold"), "{out}");
    sut.wait_for("every drive enabled again", Duration::from_secs(20), || {
        all_axes(&bus_ledger(&sut), "operation enabled")
    });
    assert!(bus_ledger(&sut)
        .lines()
        .next()
        .unwrap_or_default()
        .contains("running"));
    down(&mut sut, up);
}

/// A switch to an assembly that does not exist fails with the reason, and the running one
/// stays.
#[test]
fn a_switch_to_an_unknown_assembly_fails_with_the_reason_and_the_robot_keeps_holding() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("unknownasm");
    let up = up(&mut sut, &[]);
    let out = sut.modbot(&["assembly", "switch", "nope"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no assembly named 'nope'") && err.contains("hold, ptp, ptp_smooth"),
        "{err}"
    );
    let status = sut.modbot_ok(&["assembly"]);
    assert!(status.contains("assembly hold (generation 1)"), "{status}");
    assert!(all_axes(&bus_ledger(&sut), "operation enabled"));
    down(&mut sut, up);
}

/// SIGKILL of the host of an assembly whose components have the `fault` policy: the grid
/// faults the assembly and the bus bridge quick-stops every drive.
#[test]
fn a_killed_host_of_a_fault_policy_assembly_quick_stops_every_drive() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("killhost");
    let up = up(&mut sut, &[]);
    sut.modbot_ok(&["assembly", "switch", "ptp"]);
    let host: u32 = sut
        .ls_field("host_ctrl_g2", "PID")
        .and_then(|p| p.parse().ok())
        .expect("the ptp assembly's host runs");
    sut.signal(host, Signal::SIGKILL);
    sut.wait_for("every drive in quick stop", Duration::from_secs(20), || {
        all_axes(&bus_ledger(&sut), "quick stop active")
    });
    let ledger = bus_ledger(&sut);
    assert!(ledger.contains("the assembly faulted"), "{ledger}");
    down(&mut sut, up);
}
