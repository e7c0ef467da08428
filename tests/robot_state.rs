//! The robot's state and an operator's reset, on the simulated arm and the KR 16 under `modbot
//! up` in lockstep, each test in a domain of its own; faults are injected by command (`modbot
//! bus inject`) and the coordinator is stopped by signal, never by timing:
//! - each drive fault gives its reaction (the faulted drive disabled, the others in quick
//!   stop), its error code and its text, and a reset brings the robot back without a jump;
//! - a program started in a stop is refused at its first motion with the cause; a reset while
//!   the coordinator is stopped is refused, after it resumes succeeds, and the KR 16 program
//!   then gives its usual ratio;
//! - a motion during which the robot stops fails with the cause, never "ok";
//! - a normal `modbot down` stops the drives without an error of a lost coordinator.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::arm::{all_axes, arm, bus_ledger, one_arm_at_a_time, wait_enabled};
use common::TestDomain;
use modbot_testkit::TempDir;
use nix::sys::signal::Signal;

/// The robot of `system` in lockstep in the test's domain (its assembly data in `dir`);
/// returns when every drive is enabled.
fn up_system(sut: &mut TestDomain, dir: &TempDir, system: &Path, vars: &[&str]) -> u32 {
    sut.set_env("MODBOT_DATA_DIR", dir.path().join("data").to_str().unwrap());
    let domain = format!("domain={}", sut.name());
    let system = system.to_str().unwrap();
    let mut args = vec!["up", system, "--var", &domain, "--lockstep"];
    for var in vars {
        args.extend(["--var", var]);
    }
    let up = sut.spawn_logged("modbot", &args);
    wait_enabled(sut, up);
    up
}

fn down(sut: &mut TestDomain, up: u32) -> String {
    sut.modbot_ok(&["down"]);
    sut.wait_exit(up, Duration::from_secs(60));
    assert_eq!(
        sut.leftover_files(),
        Vec::<PathBuf>::new(),
        "{}",
        sut.output_of(up)
    );
    sut.output_of(up)
}

/// `modbot robot`'s line.
fn robot(sut: &TestDomain) -> String {
    sut.modbot_ok(&["robot"]).trim().to_owned()
}

/// The ledger's row of `axis`.
fn axis_row(ledger: &str, axis: usize) -> String {
    ledger
        .lines()
        .skip_while(|l| !l.starts_with("AXIS"))
        .nth(axis + 1)
        .unwrap_or_default()
        .to_owned()
}

/// `modbot robot reset`: (exit code, stdout, stderr).
fn reset(sut: &TestDomain) -> (i32, String, String) {
    let out = sut.modbot(&["robot", "reset"]);
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The largest step of the commanded position within an assembly, rad (`modbot bus
/// --switches`' first line).
fn max_step(sut: &TestDomain) -> f64 {
    let text = sut.modbot_ok(&["bus", "--switches"]);
    let first = text.lines().next().unwrap_or_default();
    first
        .split_whitespace()
        .nth(1)
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("{text}"))
}

#[test]
fn each_injected_drive_fault_gives_its_reaction_code_and_text_and_a_reset_brings_the_robot_back_without_a_jump(
) {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("drivefaults");
    let dir = TempDir::new("drivefaults");
    let up = up_system(&mut sut, &dir, &arm(), &[]);
    // The robot moves between two points (ptp: v_max 1 rad/s, a 1 ms tick).
    sut.modbot_ok(&["assembly", "switch", "ptp"]);
    let one_tick_at_v_max = 1.0 * 0.001;
    for (fault, code, text) in [
        ("following", "0x8611", "following error"),
        ("torque", "0x8311", "excess torque"),
        ("encoder", "0x7305", "encoder lost"),
    ] {
        let out = sut.modbot_ok(&["bus", "inject", "--axis", "2", "--fault", fault]);
        assert_eq!(
            out.trim(),
            format!("drive fault '{fault}' injected into axis 2")
        );
        sut.wait_for("the robot in fault", Duration::from_secs(30), || {
            robot(&sut).starts_with("fault since tick")
        });
        let state = robot(&sut);
        assert!(
            state.contains(&format!("drive 2 fault {code}: {text}")),
            "{fault}: {state}"
        );
        sut.wait_for("the others in quick stop", Duration::from_secs(30), || {
            let ledger = bus_ledger(&sut);
            (0..6)
                .filter(|a| *a != 2)
                .all(|a| axis_row(&ledger, a).contains("quick stop active"))
        });
        let row = axis_row(&bus_ledger(&sut), 2);
        assert!(
            row.contains("fault") && row.ends_with(code),
            "{fault}: the faulted drive disabled itself: {row}"
        );
        if fault == "encoder" {
            let (status, _, err) = reset(&sut);
            assert_eq!(status, 1, "{err}");
            assert!(
                err.contains(
                    "refused: drive 2 cannot leave its fault: its motor encoder is still lost"
                ),
                "{err}"
            );
            sut.modbot_ok(&[
                "bus", "inject", "--axis", "2", "--fault", "encoder", "--off",
            ]);
        }
        let (status, out, err) = reset(&sut);
        assert_eq!(status, 0, "{fault}: {out}{err}");
        assert!(
            out.starts_with("reset: every drive enabled at tick"),
            "{out}"
        );
        assert!(robot(&sut).starts_with("operational since tick"));
        let ledger = bus_ledger(&sut);
        assert!(all_axes(&ledger, "operation enabled"), "{fault}: {ledger}");
        assert!(axis_row(&ledger, 2).ends_with("0x0000"), "{ledger}");
        // The running assembly took over where the drives were found.
        let step = max_step(&sut);
        assert!(
            step <= one_tick_at_v_max + 1e-9,
            "{fault}: a step of {step} rad, more than one tick at v_max"
        );
    }
    let output = down(&mut sut, up);
    assert!(
        !output.contains("coordinator lost"),
        "a normal stop is no lost coordinator:\n{output}"
    );
    assert!(output.contains("the grid stops after tick"), "{output}");
}

#[test]
fn a_program_started_in_a_stop_is_refused_a_reset_waits_for_the_grid_and_the_kr16_program_then_gives_its_ratio(
) {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("kr16reset");
    let dir = TempDir::new("kr16reset");
    let examples = arm().parent().unwrap().to_path_buf();
    // The coordinator is stopped for a while below: the supervisor must not judge it hung.
    let up = up_system(
        &mut sut,
        &dir,
        &examples.join("kr16.lua"),
        &["heartbeat_timeout=30"],
    );
    sut.modbot_ok(&["bus", "inject", "--axis", "1", "--fault", "following"]);
    sut.wait_for("the robot in fault", Duration::from_secs(30), || {
        robot(&sut).starts_with("fault since tick")
    });
    let program = examples.join("kr16_ff.lua");
    let run = |sut: &TestDomain| {
        let ran = sut.modbot_in(dir.path(), &["program", "run", program.to_str().unwrap()]);
        (
            ran.status.code(),
            String::from_utf8_lossy(&ran.stdout).into_owned(),
            String::from_utf8_lossy(&ran.stderr).into_owned(),
        )
    };
    let (status, out, err) = run(&sut);
    assert_eq!(status, Some(1), "{out}{err}");
    let want = "kr16_ff.lua:69: move: the robot is in fault since tick";
    assert!(err.contains(want), "{err}");
    assert!(
        err.contains("(drive 1 fault 0x8611: following error")
            && err.contains(&format!("`modbot robot reset --domain {}`", sut.name())),
        "{err}"
    );
    assert!(!out.contains(": ok"), "nothing reported ok: {out}");
    // The coordinator stopped: no release comes, the reset is refused.
    let coordinator: u32 = sut
        .ls_field("coordinator", "PID")
        .and_then(|p| p.parse().ok())
        .expect("the coordinator runs");
    sut.signal(coordinator, Signal::SIGSTOP);
    let (status, out, err) = reset(&sut);
    sut.signal(coordinator, Signal::SIGCONT);
    assert_eq!(status, 1, "{out}{err}");
    assert!(
        err.contains("refused: the grid has not ticked for")
            && err.contains("the coordinator is stopped or lost"),
        "{err}"
    );
    let (status, out, err) = reset(&sut);
    assert_eq!(status, 0, "{out}{err}");
    let (status, out, err) = run(&sut);
    assert_eq!(status, Some(0), "{out}{err}");
    let ratio: f64 = sut
        .modbot_ok(&["data", "get", "kr16.ratio"])
        .trim()
        .parse()
        .unwrap();
    assert!(ratio >= 6.0, "{ratio}\n{out}");
    down(&mut sut, up);
}

#[test]
fn a_motion_during_which_the_robot_stops_fails_with_the_cause_and_is_never_reported_ok() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("stopmove");
    let dir = TempDir::new("stopmove");
    let up = up_system(&mut sut, &dir, &arm(), &[]);
    // A move whose finish condition injects a drive fault 50 ms of grid time in.
    let program = dir.write(
        "faulted_move.lua",
        r#"command "faulted_move" {
  run = function(p)
    return { assembly = "goto", args = { q = { 0.5, 0, 0, 0, 0, 0 } }, timeout = 30 }
  end,
  done = function(p, r)
    if r.elapsed > 0.05 and not p.injected then
      call("host_bus.inject", 3, "torque")
      p.injected = true
    end
    return read("settle.settled")
  end,
}
faulted_move {}
"#,
    );
    let ran = sut.modbot_in(dir.path(), &["program", "run", program.to_str().unwrap()]);
    let (out, err) = (
        String::from_utf8_lossy(&ran.stdout),
        String::from_utf8_lossy(&ran.stderr),
    );
    assert_eq!(ran.status.code(), Some(1), "{out}{err}");
    assert!(
        err.contains(
            "faulted_move.lua:13: faulted_move: the robot left operational during the motion: it is in fault since tick"
        ) && err.contains("drive 3 fault 0x8311"),
        "{err}"
    );
    assert!(!out.contains(": ok"), "{out}");
    let runs = sut.modbot_ok(&["data", "ls"]);
    assert!(
        runs.contains("failed: faulted_move: the robot left operational"),
        "{runs}"
    );
    down(&mut sut, up);
}
