//! Replayable recordings and `modbot replay`, each test in a domain of its own: the arm
//! recorded with `--replayable` (the bus's every output, what the controllers commanded it, the
//! grids of every generation and the coordinator's schedule) is run again offline against what
//! the drives did, and compared row by row, bit for bit.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::arm::{arm, one_arm_at_a_time};
use common::python::python;
use common::TestDomain;

/// The files of a test: removed on drop.
struct Files(Vec<PathBuf>);

impl Drop for Files {
    fn drop(&mut self) {
        for f in &self.0 {
            let _ = std::fs::remove_file(f);
            let _ = std::fs::remove_dir_all(f);
        }
    }
}

/// `modbot up DESCRIPTION --var domain=… MORE --record FILE --replayable` to its end (exit 0);
/// the recording.
fn replayable_run(sut: &mut TestDomain, description: &Path, more: &[&str], file: &Path) {
    let domain = format!("domain={}", sut.name());
    let mut args = vec!["up", description.to_str().unwrap(), "--var", &domain];
    args.extend(more);
    args.extend(["--record", file.to_str().unwrap(), "--replayable"]);
    let up = sut.spawn_logged("modbot", &args);
    let status = sut.wait_exit(up, Duration::from_secs(300));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(0), "{output}");
    assert!(output.contains("is replayable (modbot replay)"), "{output}");
}

/// `modbot replay ARGS`: exit code and what it printed (stdout, then stderr).
fn replay(sut: &TestDomain, args: &[&str]) -> (Option<i32>, String) {
    let mut all = vec!["replay"];
    all.extend(args);
    let out = sut.modbot(&all);
    let said =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code(), said)
}

/// The tick a "… differs at tick T: …" line names.
fn differs_at(said: &str) -> u64 {
    said.split("differs at tick ")
        .nth(1)
        .and_then(|rest| rest.split(':').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no 'differs at tick T:' in {said}"))
}

/// 10 s of the arm in lockstep, swapped from `hold` to `ptp` at tick 300 and back to `hold` at
/// 6000, recorded replayable: the recording holds the bus's outputs and every input of the bus
/// as `robot<input`, and the schedule of both switches; `modbot replay` runs the controllers of
/// all three generations again, the bus played back, and every row is identical — values,
/// generation and the grid's state hash — through tick 9999; `--until 5000` replays 5001.
#[test]
fn a_replayable_recording_of_the_arm_with_swaps_replays_identical() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("replay");
    let file = std::env::temp_dir().join(format!("{}.h5", sut.name()));
    let _files = Files(vec![file.clone()]);
    let more = [
        "--lockstep",
        "--ticks",
        "10000",
        "--switch",
        "300:ptp",
        "--switch",
        "6000:hold",
    ];
    replayable_run(&mut sut, &arm(), &more, &file);
    let info = modbot_record::replay_file::read(&file).unwrap().unwrap();
    assert_eq!(
        (info.recorder.as_str(), info.clock.as_str()),
        ("record", "lockstep")
    );
    assert_eq!(info.sources, ["robot"]);
    assert!(
        info.run_id.starts_with(&format!("{}-", sut.name())),
        "{}",
        info.run_id
    );
    let files: Vec<&str> = info.files.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(files, ["hold", "ptp"], "the assembly files that ran");
    let generations: Vec<u16> = info.specs.iter().map(|(g, _)| *g).collect();
    assert_eq!(generations, [1, 2, 3]);
    assert_eq!(
        info.log
            .lines()
            .filter(|l| l.starts_with("switch "))
            .count(),
        2,
        "{}",
        info.log
    );
    let signals = modbot_record::read::signals(&file).unwrap();
    for s in [
        "robot<target_position",
        "robot<controlword",
        "robot.link_position",
    ] {
        assert!(signals.iter().any(|x| x == s), "{s} in {signals:?}");
    }
    let (code, said) = replay(&sut, &[file.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{said}");
    assert_eq!(
        said.lines().next(),
        Some("replayed 10000 ticks (0..9999, 2 switch(es), 0 overrun(s) replayed): identical")
    );
    assert!(
        said.contains(&format!("recorded in run {}", info.run_id)),
        "{said}"
    );
    let (code, said) = replay(&sut, &[file.to_str().unwrap(), "--until", "5000"]);
    assert_eq!(code, Some(0), "{said}");
    assert!(
        said.starts_with("replayed 5001 ticks (0..5000, 1 switch(es)"),
        "{said}"
    );
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// The arm recorded as above (3 s, one swap), replayed with one controller gain changed: the
/// feed-forward's inertia of axis 1 (`--param ff.inertia=[2.5,2,1,0.2,0.2,0.1]`, 2.5 for 2).
/// The replay names the first tick that differs — after the switch to `ptp`, once the robot
/// accelerates — the input of the bus that differs and the component output that fed it
/// (`ff`'s); the what-if runs to the end and writes its own recording, which `modbot record
/// compare` finds first differing at the same tick. A param of the played-back bus, or of no
/// component, is refused (exit 2).
#[test]
fn a_replay_with_a_changed_gain_names_the_first_divergent_tick_and_component() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("replayif");
    let file = std::env::temp_dir().join(format!("{}.h5", sut.name()));
    let what_if = std::env::temp_dir().join(format!("{}.whatif.h5", sut.name()));
    let _files = Files(vec![file.clone(), what_if.clone()]);
    let more = ["--lockstep", "--ticks", "3000", "--switch", "300:ptp"];
    replayable_run(&mut sut, &arm(), &more, &file);
    let gain = "ff.inertia=[2.5,2,1,0.2,0.2,0.1]";
    let (code, said) = replay(&sut, &[file.to_str().unwrap(), "--param", gain]);
    assert_eq!(code, Some(1), "{said}");
    let tick = differs_at(&said);
    assert!(tick > 300, "alike until ptp runs: {said}");
    assert!(
        said.starts_with("replayed to tick 2999: differs at tick "),
        "{said}"
    );
    let first = said.lines().next().unwrap();
    assert!(
        first.contains(" from ff.tau_ff "),
        "the component that fed it: {first}"
    );
    assert!(
        said.contains(&format!("what-if recording: {}", what_if.display())),
        "{said}"
    );
    let compared = sut.modbot(&[
        "record",
        "compare",
        file.to_str().unwrap(),
        what_if.to_str().unwrap(),
    ]);
    let line = String::from_utf8_lossy(&compared.stdout).into_owned();
    assert_eq!(compared.status.code(), Some(1), "{line}");
    assert_eq!(differs_at(&line), tick, "{line}");
    let (code, said) = replay(&sut, &[file.to_str().unwrap(), "--param", "robot.axes=3"]);
    assert_eq!(code, Some(2), "{said}");
    assert!(
        said.contains("'robot' is played back or compared, not run"),
        "{said}"
    );
    let (code, said) = replay(&sut, &[file.to_str().unwrap(), "--param", "nobody.k=1"]);
    assert_eq!(code, Some(2), "{said}");
    assert!(said.contains("no component 'nobody' ran"), "{said}");
    let plain = std::env::temp_dir().join(format!("{}.plain.h5", sut.name()));
    let _plain = Files(vec![plain.clone()]);
    python(
        "import h5py, sys\nh5py.File(sys.argv[1], 'w').create_dataset('tick', data=[0])\n",
        &[plain.to_str().unwrap()],
    );
    let (code, said) = replay(&sut, &[plain.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{said}");
    assert!(said.contains("not replayable"), "{said}");
}

/// The arm on the real-time clock, swapped at tick 300 to an assembly whose controllers' host
/// is held up 3 ms every 50 ms (a `sleeper`): their releases overrun under the hold policy,
/// and the coordinator logs each. The replay applies them as they happened and is identical;
/// the same recording with one more overrun of `ptp` put into its schedule (h5py), while it
/// moves, differs — at that tick or after.
#[test]
fn a_real_time_recording_with_injected_overruns_replays_identical() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("replayrt");
    let dir = std::env::temp_dir().join(format!("{}.d", sut.name()));
    let file = dir.join("run.h5");
    let _files = Files(vec![dir.clone()]);
    std::fs::create_dir_all(dir.join("arm")).unwrap();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let description = dir.join("arm.lua");
    std::fs::copy(examples.join("arm.lua"), &description).unwrap();
    std::fs::copy(examples.join("arm/hold.lua"), dir.join("arm/hold.lua")).unwrap();
    let ptp = std::fs::read_to_string(examples.join("arm/ptp.lua")).unwrap();
    let slow = ptp.replace("policy = \"fault\"", "policy = \"hold\"")
        + r#"
component "slow" { type = "sleeper", host = "ctrl", period = 50,
                   params = { sleep_ms = 3, sleep_live = true } }
connect "robot.state -> slow.u"
"#;
    std::fs::write(dir.join("arm/ptp_slow.lua"), slow).unwrap();
    let more = ["--ticks", "3000", "--switch", "300:ptp_slow"];
    replayable_run(&mut sut, &description, &more, &file);
    let info = modbot_record::replay_file::read(&file).unwrap().unwrap();
    assert_eq!(info.clock, "real_time");
    let injected: Vec<&str> = info
        .log
        .lines()
        .filter(|l| l.starts_with("overrun ") && l.contains(" generation=2 "))
        .collect();
    assert!(
        !injected.is_empty(),
        "the sleeper made overruns: {}",
        info.log
    );
    let (code, said) = replay(&sut, &[file.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{said}");
    assert!(
        said.starts_with("replayed 3000 ticks (0..2999, 1 switch(es), "),
        "{said}"
    );
    assert!(said.contains("identical"), "{said}");
    // The schedule matters: one more overrun of `ptp`, 100 ticks into its first move (which of
    // the run's own overruns hit a moving output depends on how the machine was loaded),
    // makes the replay differ from that tick on.
    let at: u64 = python(
        r#"
import h5py, sys, numpy as np
f = h5py.File(sys.argv[1], "r+")
g = f["replay"]
log = bytes(g["log"][:]).decode().splitlines()
tick = lambda l: int(next(w for w in l.split() if w.startswith("tick="))[5:])
took_over = next(tick(l) for l in log if l.startswith("switch ") and " generation=2" in l)
q = f["robot<target_position"][:]
moving = [t for t in range(took_over + 1, len(q)) if np.any(q[t] != q[t - 1])]
ptp = [l for l in log if " component=ptp " in l or l.endswith(" component=ptp")]
taken = lambda t: any(l.startswith("overrun tick=%d " % t) or l.endswith(" release=%d" % (t - 1))
                      or l.startswith("late tick=%d " % (t - 1)) for l in ptp)
# 100 ticks into the move if it can (a machine loaded beside it may have overrun there).
at = next(t for t in moving[100:] + moving[:100] if not taken(t) and not taken(t + 1))
line = "overrun tick=%d generation=2 component=ptp release=%d" % (at, at - 1)
i = next(i for i, l in enumerate(log) if tick(l) > at)
log.insert(i, line)
del g["log"]
g.create_dataset("log", data=np.frombuffer("".join(l + "\n" for l in log).encode(), dtype=np.uint8))
print(at)
"#,
        &[file.to_str().unwrap()],
    )
    .trim()
    .parse()
    .unwrap();
    let (code, said) = replay(&sut, &[file.to_str().unwrap()]);
    assert_eq!(code, Some(1), "with an overrun added it differs: {said}");
    assert!(differs_at(&said) >= at, "{said} (overrun added at {at})");
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// The arm on the real-time clock, moving under `ptp`, through a drive fault and an operator's
/// reset: while the robot is held (the fault, the reset) the running assembly tracks (TRACK |
/// HELD), which the coordinator logs as held ranges; the replay applies them and is identical.
#[test]
fn a_recording_through_a_drive_fault_and_a_reset_replays_identical() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("replayheld");
    let file = std::env::temp_dir().join(format!("{}.h5", sut.name()));
    let _files = Files(vec![file.clone()]);
    let domain = format!("domain={}", sut.name());
    let description = arm();
    let file_arg = file.to_str().unwrap().to_owned();
    let args = [
        "up",
        description.to_str().unwrap(),
        "--var",
        &domain,
        "--switch",
        "300:ptp",
        "--record",
        &file_arg,
        "--replayable",
    ];
    let up = sut.spawn_logged("modbot", &args);
    common::arm::wait_enabled(&sut, up);
    sut.wait_for("the switch to ptp", Duration::from_secs(60), || {
        sut.output_of(up).contains("took over")
    });
    // Into the first move (ptp waits 0.2 s at A first); the outcome does not depend on it.
    std::thread::sleep(Duration::from_millis(800));
    let robot = |sut: &TestDomain| sut.modbot_ok(&["robot"]);
    sut.modbot_ok(&["bus", "inject", "--axis", "2", "--fault", "following"]);
    sut.wait_for("the robot in fault", Duration::from_secs(30), || {
        robot(&sut).starts_with("fault since tick")
    });
    let mut reset = sut.modbot(&["robot", "reset"]);
    let refused = String::from_utf8_lossy(&reset.stderr).into_owned();
    if refused.contains("the running assembly faulted") {
        // A starved machine can overrun `ptp` (policy fault) or let the monitor see the
        // quick stop's following error: then the operator does what the refusal says. The
        // replay covers the fault and the switch as well.
        println!(
            "the assembly faulted as well ({}): switching to hold\n{refused}",
            robot(&sut).trim()
        );
        sut.modbot_ok(&["assembly", "switch", "hold"]);
        reset = sut.modbot(&["robot", "reset"]);
    }
    assert_eq!(
        reset.status.code(),
        Some(0),
        "{}\n--- modbot robot: {}\n--- modbot up:\n{}",
        String::from_utf8_lossy(&reset.stderr),
        robot(&sut),
        sut.output_of(up)
    );
    // A machine that starves the coordinator again stops the drives again (the watchdog):
    // reset again, at most 5 times, as `wait_enabled` does.
    let mut again = 0;
    sut.wait_until(
        "the robot operational again",
        Duration::from_secs(90),
        || {
            let now = robot(&sut);
            if now.starts_with("operational since tick") {
                return Ok(());
            }
            if (now.starts_with("safe stop") || now.starts_with("fault")) && again < 5 {
                again += 1;
                println!("stopped again after the reset ({}): resetting", now.trim());
                sut.modbot(&["robot", "reset"]);
            }
            Err(now)
        },
    );
    sut.modbot_ok(&["down"]);
    let status = sut.wait_exit(up, Duration::from_secs(60));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(0), "{output}");
    assert!(output.contains("is replayable (modbot replay)"), "{output}");
    let info = modbot_record::replay_file::read(&file).unwrap().unwrap();
    let held: Vec<&str> = info
        .log
        .lines()
        .filter(|l| l.starts_with("held "))
        .collect();
    assert!(
        held.iter().any(|l| l.ends_with(" on")) && held.iter().any(|l| l.ends_with(" off")),
        "held while in fault and reset, then not: {held:?}"
    );
    let (code, said) = replay(&sut, &[file.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{said}");
    assert!(
        said.lines()
            .next()
            .unwrap_or_default()
            .ends_with(": identical"),
        "{said}"
    );
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}
