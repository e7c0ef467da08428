//! Assemblies swapped at runtime on the simulated 6-axis arm (`examples/arm.lua`), under
//! `modbot up`, each test in a domain of its own: swaps while the robot moves miss no bus
//! cycle, happen at the announced tick and do not make the command jump; a blocked axis
//! faults the assembly and quick-stops the drives, and a reset after a switch to `hold`
//! recovers; a killed host of an assembly with the `fault` policy stops the drives too.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::arm::{all_axes, arm, bus_ledger, one_arm_at_a_time, wait_enabled};
use common::TestDomain;
use modbot_bus::bridge::render_switches;
use modbot_ipc_schema::{bus, hex};
use nix::sys::signal::Signal;

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

/// Which clock a run's grid keeps.
#[derive(Clone, Copy, PartialEq)]
enum Clock {
    RealTime,
    Lockstep,
}

/// `modbot up` of the arm (`file`: its system description) with `vars`; returns when every
/// drive is enabled.
fn up_with(sut: &mut TestDomain, file: &Path, clock: Clock, vars: &[&str]) -> u32 {
    let domain = format!("domain={}", sut.name());
    let mut args = vec!["up", file.to_str().unwrap(), "--var", domain.as_str()];
    for v in vars {
        args.extend(["--var", v]);
    }
    match clock {
        Clock::Lockstep => args.push("--lockstep"),
        // The bus's watchdog (3 base periods by default) would quick-stop the drives at the
        // first few milliseconds the host steals, and a quick stop stays latched: these tests
        // are about the assemblies, so the coordinator counts as lost after 0.5 s.
        Clock::RealTime => args.extend(["--var", "watchdog=500"]),
    }
    let up = sut.spawn_logged("modbot", &args);
    wait_enabled(sut, up);
    up
}

/// The arm of `examples/arm.lua` in lockstep: no timing the machine may not give.
fn up(sut: &mut TestDomain, vars: &[&str]) -> u32 {
    up_with(sut, &arm(), Clock::Lockstep, vars)
}

/// A copy of the arm's description and assemblies in a directory of the test's own, with more
/// assemblies; removed on drop.
struct ArmCopy {
    dir: PathBuf,
}

impl ArmCopy {
    fn new(sut: &TestDomain, extra: &[(&str, &str)]) -> ArmCopy {
        let dir = std::env::temp_dir().join(format!("{}.arm", sut.name()));
        let examples = arm().parent().unwrap().to_path_buf();
        std::fs::create_dir_all(dir.join("arm")).unwrap();
        std::fs::copy(arm(), dir.join("arm.lua")).unwrap();
        for entry in std::fs::read_dir(examples.join("arm")).unwrap() {
            let path = entry.unwrap().path();
            std::fs::copy(&path, dir.join("arm").join(path.file_name().unwrap())).unwrap();
        }
        for (name, body) in extra {
            std::fs::write(dir.join("arm").join(format!("{name}.lua")), body).unwrap();
        }
        ArmCopy { dir }
    }

    fn system(&self) -> PathBuf {
        self.dir.join("arm.lua")
    }
}

impl Drop for ArmCopy {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// `hold.lua` and a `sleeper` with the `fault` policy on the same host, fed by a ramp: the
/// assembly's host stalls as the sleeper's params say.
fn hold_with_sleeper(params: &str) -> String {
    let hold = std::fs::read_to_string(arm().parent().unwrap().join("arm/hold.lua")).unwrap();
    format!(
        "{hold}\ncomponent \"clock\" {{ type = \"ramp\", host = \"ctrl\", period = 1 }}\n\
         component \"slow\" {{ type = \"sleeper\", host = \"ctrl\", period = 1, policy = \"fault\", \
         params = {{ {params} }} }}\nconnect \"clock.y -> slow.u\"\n"
    )
}

fn down(sut: &mut TestDomain, up: u32) -> String {
    sut.modbot_ok(&["down"]);
    sut.wait_exit(up, Duration::from_secs(60));
    let output = sut.output_of(up);
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new(), "{output}");
    output
}

/// 100 swaps among `ptp_smooth`, `ptp` and `hold` while the robot moves, in lockstep: each
/// switch is at its announced tick (as the bus saw it), and no switch changes the commanded
/// position by more than one tick's motion at the speed limit, nor its velocity by more than
/// one tick's worth of the acceleration limit: the running generator hands over the exact
/// command the incoming one replaces (through the bus's `handover`), and the incoming one
/// brakes from it at its own limit. (Missed bus cycles around switches on the real-time clock
/// are measured by `modbot-benches swaps`.)
#[test]
fn a_hundred_swaps_while_the_robot_moves_switch_at_the_announced_tick_and_keep_the_command_continuous(
) {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("swaps");
    let up = up(&mut sut, &["dwell=0"]);
    sut.modbot_ok(&["assembly", "switch", "ptp", "--timeout", "60"]);
    std::thread::sleep(Duration::from_millis(300));
    let mut announced = Vec::new();
    for i in 0..100 {
        let name = ["ptp_smooth", "ptp", "hold", "ptp"][i % 4];
        let out = sut.modbot_ok(&["assembly", "switch", name, "--timeout", "60"]);
        let (generation, tick, at) = switched(out.lines().last().unwrap_or_default());
        assert_eq!(
            tick, at,
            "switch {i} to {name} happened at its announced tick: {out}"
        );
        announced.push((generation, at));
        // Let it move a little between swaps.
        std::thread::sleep(Duration::from_millis(20));
    }
    // The bus's own record (`modbot_ipc_schema::bus`): the tick of each generation's first
    // cycle and the step. `modbot call` prints a bytes answer as 0x and hex.
    // Generous timeouts: in lockstep on a loaded machine the bus's host answers between ticks.
    let answer = sut.modbot_ok(&["call", "host_bus.switches", "--timeout-ms", "60000"]);
    let bytes = hex::decode(answer.trim().trim_start_matches("0x"))
        .unwrap_or_else(|e| panic!("host_bus.switches answers bytes: {e}: {answer}"));
    let record = bus::decode(&bytes).expect("the bus's record of switches");
    let switches = render_switches(&record);
    // `modbot bus --switches` prints the same record: a line of the largest steps within an
    // assembly, then one per switch.
    let printed = sut.modbot_ok(&["bus", "--switches", "--timeout-ms", "60000"]);
    assert!(
        printed.starts_with("max_step ") && printed.lines().count() == record.switches.len() + 1,
        "{printed}"
    );
    // v_max (rad/s) × base period, and a_max (rad/s²) × base period; the margin is the Bessel
    // filter's overshoot of `ptp_smooth`'s lower limits (0.43 %) and rounding.
    let one_tick = 1.0 * 0.001 * 1.005;
    let one_tick_of_a = 4.0 * 0.001 * 1.005;
    let mut seen = 0;
    for s in &record.switches {
        let (g, t, step, velocity_step) = (s.generation, s.tick, s.step, s.velocity_step);
        if let Some(&(_, at)) = announced.iter().find(|a| a.0 == g) {
            seen += 1;
            assert_eq!(
                t, at,
                "generation {g} took over the bus at the announced tick"
            );
            assert!(
                step <= one_tick,
                "generation {g}: the command jumped {step} rad at the switch (one tick: {one_tick})"
            );
            assert!(
                velocity_step <= one_tick_of_a,
                "generation {g}: the commanded velocity jumped {velocity_step} rad/s at the switch \
                 (one tick of a_max: {one_tick_of_a})"
            );
        }
    }
    assert_eq!(seen, 100, "the bus saw every switch:\n{switches}");
    let max_step = record.max_step;
    assert!(
        max_step > 1e-4,
        "the robot was moving: largest step {max_step} rad\n{switches}\n{}",
        sut.output_of(up)
    );
    down(&mut sut, up);
}

/// An axis blocked in the simulation: the monitor's following-error check faults the `ptp`
/// assembly, the bus bridge quick-stops every drive; unblocked, a reset is refused while the
/// running assembly is the faulted one, a switch to `hold` alone re-enables nothing, and then
/// `modbot robot reset` brings every drive back to operation enabled.
#[test]
fn a_blocked_axis_faults_the_assembly_and_only_a_reset_after_a_switch_to_hold_recovers() {
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
    // The ledger `modbot top` reads is refreshed every 200 ms.
    // (Its last line, the robot's state, says "the assembly faulted" at once.)
    sut.wait_for("the ledger to say why", Duration::from_secs(20), || {
        sut.modbot_ok(&["top", "--once"])
            .contains("component watch reports an unsafe state")
    });
    sut.modbot_ok(&["call", "host_bus.block", "2", "false"]);
    let refused = sut.modbot(&["robot", "reset"]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{err}");
    assert!(
        err.contains("refused: the running assembly faulted"),
        "{err}"
    );
    let out = sut.modbot_ok(&["assembly", "switch", "hold"]);
    assert!(out.contains("switched to hold"), "{out}");
    // The switch alone: the grid goes on (in lockstep, hundreds of ticks), the drives stay
    // stopped.
    let cycles = |ledger: &str| -> u64 {
        let at = ledger.find("cycles ").map(|i| i + 7).unwrap_or(0);
        ledger[at..]
            .split_whitespace()
            .next()
            .unwrap_or("0")
            .parse()
            .unwrap_or(0)
    };
    let after_switch = cycles(&bus_ledger(&sut));
    sut.wait_for("the grid to go on", Duration::from_secs(30), || {
        cycles(&bus_ledger(&sut)) > after_switch + 500
    });
    let ledger = bus_ledger(&sut);
    assert!(all_axes(&ledger, "quick stop active"), "{ledger}");
    assert!(
        sut.modbot_ok(&["robot"])
            .starts_with("safe stop since tick"),
        "{ledger}"
    );
    let out = sut.modbot_ok(&["robot", "reset"]);
    assert!(
        out.starts_with("reset: every drive enabled at tick"),
        "{out}"
    );
    assert!(
        all_axes(&bus_ledger(&sut), "operation enabled"),
        "{}",
        bus_ledger(&sut)
    );
    assert!(sut
        .modbot_ok(&["robot"])
        .starts_with("operational since tick"));
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
        err.contains("no assembly named 'nope'") && err.contains("hold, ptp, ptp_fmu, ptp_smooth"),
        "{err}"
    );
    let status = sut.modbot_ok(&["assembly"]);
    assert!(status.contains("assembly hold (generation 1)"), "{status}");
    assert!(all_axes(&bus_ledger(&sut), "operation enabled"));
    down(&mut sut, up);
}

/// Runs the arm on the real-time clock (in lockstep the grid would wait for a killed host's
/// restart instead), switches to `assembly`, SIGKILLs its host `host` (generation 2) and waits
/// until every drive is in quick stop because the assembly faulted; returns `modbot up`'s pid.
/// `before_kill` looks at the host (its pid) just before.
fn kill_host_until_the_drives_stop(
    sut: &mut TestDomain,
    assembly: &str,
    host: &str,
    before_kill: impl FnOnce(&TestDomain, u32),
) -> u32 {
    let up = up_with(sut, &arm(), Clock::RealTime, &[]);
    sut.modbot_ok(&["assembly", "switch", assembly]);
    let pid: u32 = sut
        .ls_field(&format!("host_{host}_g2"), "PID")
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("the host {host} of {assembly} runs"));
    before_kill(sut, pid);
    sut.signal(pid, Signal::SIGKILL);
    sut.wait_for("every drive in quick stop", Duration::from_secs(20), || {
        all_axes(&bus_ledger(sut), "quick stop active")
    });
    let ledger = bus_ledger(sut);
    assert!(ledger.contains("the assembly faulted"), "{ledger}");
    up
}

/// SIGKILL of the host of an assembly whose components have the `fault` policy: the grid
/// faults the assembly and the bus bridge quick-stops every drive.
#[test]
fn a_killed_host_of_a_fault_policy_assembly_quick_stops_every_drive() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("killhost");
    let up = kill_host_until_the_drives_stop(&mut sut, "ptp", "ctrl", |_, _| {});
    down(&mut sut, up);
}

/// SIGKILL of the host of `ptp_fmu`'s feed-forward FMU (`modbot-fmu-host`, the `fault`
/// policy): the grid faults the assembly and the bus bridge quick-stops every drive; the
/// assembly's other host is left alone; and the directory the host had unpacked the FMU in
/// (a temporary directory of the domain, named after its pid) is gone after `modbot down`.
#[test]
fn a_killed_fmu_host_faults_its_assembly_the_drives_stop_and_its_unpacked_fmu_goes() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("killfmu");
    let mut unpacked = Vec::new();
    let up = kill_host_until_the_drives_stop(&mut sut, "ptp_fmu", "ff", |sut, pid| {
        unpacked = temp_entries(&sut.domain.temp_prefix(pid));
        assert_eq!(unpacked.len(), 1, "the host unpacked its FMU: {unpacked:?}");
        assert!(unpacked[0].join("modelDescription.xml").exists());
    });
    let other = sut.ls_field("host_ctrl_g2", "PID");
    assert!(other.is_some_and(|p| p != "-"), "the other host runs on");
    down(&mut sut, up);
    assert!(!unpacked[0].exists(), "{} is left", unpacked[0].display());
    assert_eq!(temp_entries(&sut.domain.prefix()), Vec::<PathBuf>::new());
}

/// The entries of the temporary directory whose names start with `prefix`.
fn temp_entries(prefix: &str) -> Vec<PathBuf> {
    let entries = std::fs::read_dir(std::env::temp_dir()).expect("the temporary directory");
    entries
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(prefix))
        .map(|e| e.path())
        .collect()
}

/// The arm in lockstep switches from `hold` to `ptp_fmu` (the feed-forward an FMU in a host of
/// its own) while holding, lets it move, and back to `hold` while it moves: each switch at its
/// announced tick, no bus cycle missed around it, the command continuous (at most one tick's
/// motion and one tick of the acceleration limit), and the robot moved under the FMU's
/// assembly.
#[test]
fn switching_to_the_fmu_assembly_and_back_misses_no_bus_cycle() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("fmuswap");
    let up = up(&mut sut, &["dwell=0"]);
    let mut announced = Vec::new();
    for (name, settle) in [("ptp_fmu", 1500), ("hold", 300)] {
        let out = sut.modbot_ok(&["assembly", "switch", name, "--timeout", "60"]);
        let (generation, tick, at) = switched(out.lines().last().unwrap_or_default());
        assert_eq!(
            tick, at,
            "the switch to {name} happened at its announced tick: {out}"
        );
        announced.push((generation, at));
        std::thread::sleep(Duration::from_millis(settle));
    }
    let answer = sut.modbot_ok(&["call", "host_bus.switches"]);
    let bytes = hex::decode(answer.trim().trim_start_matches("0x")).expect("bytes");
    let record = bus::decode(&bytes).expect("the bus's record of switches");
    let switches = render_switches(&record);
    for &(g, at) in &announced {
        let s = record
            .switches
            .iter()
            .find(|s| s.generation == g)
            .unwrap_or_else(|| panic!("the bus saw generation {g}:\n{switches}"));
        assert_eq!(s.tick, at, "generation {g}:\n{switches}");
        assert_eq!(
            s.missed_near, 0,
            "generation {g} missed bus cycles:\n{switches}"
        );
        assert!(s.step <= 1.0 * 0.001 * 1.005, "generation {g}:\n{switches}");
        assert!(
            s.velocity_step <= 4.0 * 0.001 * 1.005,
            "generation {g}:\n{switches}"
        );
    }
    assert!(record.max_step > 1e-4, "the robot moved:\n{switches}");
    println!("{switches}");
    down(&mut sut, up);
}

/// Runs the arm in lockstep for `ticks` with a switch to `ptp` at tick 300; returns the trace
/// of the system's own components (the bus's outputs at every tick).
fn lockstep_arm_trace(sut: &mut TestDomain, ticks: u64, tag: &str) -> String {
    let more = ["--var", "dwell=0", "--lockstep", "--switch", "300:ptp"];
    let (trace, output) = sut.traced_up(&arm(), ticks, &more, tag);
    assert!(
        output.contains("took over"),
        "the switch happened:\n{output}"
    );
    trace
}

/// The arm in lockstep, with a switch from `hold` to `ptp` at tick 300 of a 1500-tick run:
/// two runs give byte-identical traces of the bus (the robot's every position and state), and
/// the robot moved.
#[test]
fn a_lockstep_arm_run_with_a_swap_gives_the_same_trace_twice() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("armlock");
    let first = lockstep_arm_trace(&mut sut, 1500, "a");
    let second = lockstep_arm_trace(&mut sut, 1500, "b");
    let ticks: Vec<&str> = first.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(ticks.len(), 1500, "a line per tick");
    assert!(first == second, "two lockstep runs give the same trace");
    let position = |tick: usize| {
        ticks
            .get(tick)
            .and_then(|l| {
                l.split_whitespace()
                    .find(|w| w.starts_with("robot.link_position="))
            })
            .unwrap_or_default()
            .to_owned()
    };
    assert_ne!(
        position(299),
        position(1499),
        "the robot moved after the switch"
    );
}

/// Starts the arm (real time) with an assembly `name` of `hold.lua` and a sleeper with
/// `params`, and switches to it; returns the copy of the arm (kept while the system runs),
/// `modbot up`'s pid and the tick of the switch.
fn switched_to_sleeper(sut: &mut TestDomain, name: &str, params: &str) -> (ArmCopy, u32, u64) {
    let copy = ArmCopy::new(sut, &[(name, &hold_with_sleeper(params))]);
    let up = up_with(sut, &copy.system(), Clock::RealTime, &[]);
    let out = sut.modbot_ok(&["assembly", "switch", name, "--timeout", "60"]);
    assert!(out.contains(&format!("switched to {name}")), "{out}");
    let (_, tick, _) = switched(out.lines().last().unwrap_or_default());
    (copy, up, tick)
}

/// The release that faulted the grid, from `modbot top`'s "... overran its deadline at tick N
/// (released at M)"; `None` if the grid did not fault.
fn faulted_release(top: &str) -> Option<u64> {
    if !top.contains("overran its deadline") {
        return None;
    }
    let m = top
        .split("(released at ")
        .nth(1)
        .and_then(|rest| rest.split(')').next())
        .and_then(|m| m.parse().ok());
    Some(m.unwrap_or_else(|| panic!("faulted, by which release? {top}")))
}

/// An incoming assembly whose host stalls (4 ms at each of its first 30 tracking releases of
/// a 1 ms grid, with the `fault` policy) is still switched to: its first ticks are slow, and
/// a late release near the switch postpones it instead of failing it, or faulting the
/// assembly once it is live.
#[test]
fn an_incoming_assembly_whose_host_stalls_for_its_first_ticks_is_still_switched_to() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("slowstart");
    let (_copy, up, switch) =
        switched_to_sleeper(&mut sut, "slowstart", "sleep_ms = 4, sleep_tracking = 30");
    let top = sut.modbot_ok(&["top", "--once"]);
    // Once live, the `fault` policy faults the assembly if the machine holds its host up for
    // three base periods (without SCHED_FIFO, under load, it may): then by a release at the
    // tick before the switch or later, whose outputs the live assembly reads, never by one of
    // the stalled tracking releases before it (the switch waits until none of them is late).
    if let Some(released) = faulted_release(&top) {
        assert!(
            released + 1 >= switch,
            "a tracking release (at {released}) was still late after the switch at tick {switch}:\n{top}"
        );
        println!("faulted once live, by its release at {released} (the machine held its host up):\n{top}");
    }
    down(&mut sut, up);
}

/// A `fault` component of an assembly that stalls once it is live (20 ms at every release of
/// a 1 ms grid) faults the assembly after the switch, and the bus stops the drives.
#[test]
fn a_fault_component_that_stalls_after_the_switch_still_faults_the_assembly() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("stalllive");
    let (_copy, up, _) =
        switched_to_sleeper(&mut sut, "stalllive", "sleep_ms = 20, sleep_live = true");
    sut.wait_for("every drive in quick stop", Duration::from_secs(20), || {
        all_axes(&bus_ledger(&sut), "quick stop active")
    });
    // The ledger `modbot top` reads is refreshed every 200 ms.
    // (Its last line, the robot's state, says "the assembly faulted" at once.)
    sut.wait_for("the ledger to say why", Duration::from_secs(20), || {
        sut.modbot_ok(&["top", "--once"])
            .contains("component slow overran its deadline")
    });
    down(&mut sut, up);
}

/// `modbot up --ticks N` is a run meant to complete: when its grid faulted (here the monitor
/// of `ptp`, given a following-error limit no motion keeps) or it was stopped before its N
/// ticks, `modbot up` exits 1 and says why — never "every module stopped cleanly".
#[test]
fn a_run_of_n_ticks_whose_grid_faulted_or_that_stopped_short_exits_non_zero_with_the_reason() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("runfails");
    let file = arm();
    let domain = format!("domain={}", sut.name());
    let faulted = sut.spawn_logged(
        "modbot",
        &[
            "up",
            file.to_str().unwrap(),
            "--var",
            &domain,
            "--var",
            "following_max=0.000001",
            "--lockstep",
            "--ticks",
            "3000",
            "--switch",
            "300:ptp",
        ],
    );
    let status = sut.wait_exit(faulted, Duration::from_secs(120));
    let output = sut.output_of(faulted);
    assert_eq!(status.code(), Some(1), "{output}");
    assert!(
        output.contains("the grid faulted, so the run of 3000 ticks failed")
            && output.contains("component watch reports an unsafe state"),
        "{output}"
    );
    assert!(!output.contains("every module stopped cleanly"), "{output}");
    let stopped = sut.spawn_logged(
        "modbot",
        &[
            "up",
            file.to_str().unwrap(),
            "--var",
            &domain,
            "--lockstep",
            "--ticks",
            "100000000",
        ],
    );
    wait_enabled(&sut, stopped);
    sut.modbot_ok(&["down"]);
    let status = sut.wait_exit(stopped, Duration::from_secs(60));
    let output = sut.output_of(stopped);
    assert_eq!(status.code(), Some(1), "{output}");
    assert!(
        output.contains("the run stopped at tick ")
            && output.contains(" of the 100000000 it was to run"),
        "{output}"
    );
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// SIGKILL of the bus bridge after assembly switches: the supervisor restarts it with the
/// running assembly (generation 3 here), not the one the system started with, so the grid
/// serves it again: its fresh drives are enabled and the robot is operational. The description
/// and the running assembly's file were broken meanwhile: the restarted bridge serves the
/// checked grid the supervisor wrote for generation 3, and reads no file.
#[test]
fn a_bus_bridge_killed_after_a_switch_comes_back_with_the_running_assembly() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("busrestart");
    let copy = ArmCopy::new(&sut, &[]);
    let up = up_with(&mut sut, &copy.system(), Clock::RealTime, &[]);
    sut.modbot_ok(&["assembly", "switch", "ptp"]);
    sut.modbot_ok(&["assembly", "switch", "hold"]);
    for file in [copy.system(), copy.dir.join("arm/hold.lua")] {
        let text = std::fs::read_to_string(&file).unwrap();
        std::fs::write(&file, text + "error('edited after modbot up')\n").unwrap();
    }
    let pid: u32 = sut
        .ls_field("host_bus", "PID")
        .and_then(|p| p.parse().ok())
        .expect("the bus bridge runs");
    sut.signal(pid, Signal::SIGKILL);
    sut.wait_for("the bus bridge restarted", Duration::from_secs(60), || {
        sut.ls_field("host_bus", "PID")
            .and_then(|p| p.parse::<u32>().ok())
            .is_some_and(|p| p != pid)
    });
    sut.wait_for(
        "the restarted bridge's drives enabled",
        Duration::from_secs(60),
        || all_axes(&bus_ledger(&sut), "operation enabled"),
    );
    let ledger = bus_ledger(&sut);
    assert!(ledger.contains("assembly generation 3"), "{ledger}");
    assert!(
        sut.modbot_ok(&["robot"])
            .starts_with("operational since tick"),
        "{ledger}"
    );
    down(&mut sut, up);
}
