//! Robot programs (`modbot program`, MoRC's program interpreter) on the simulated arm of
//! `examples/arm.lua` in lockstep, each test in a domain and an assembly data directory of its
//! own: a program's commands switch their assemblies in order and leave their runs in
//! assembly data; a failed precondition stops the program at its line with the robot
//! holding; the REPL reads commands from a pipe; assembly data outlives `modbot down`; and
//! the KR 16 experiment (`examples/kr16_ff.lua`) shows what the elastic feed-forward gains.

mod common;

use std::path::{Path, PathBuf};

use modbot_testkit::TempDir;
use std::time::Duration;

use common::arm::{arm, one_arm_at_a_time, wait_enabled};
use common::python::python;
use common::TestDomain;

/// The arm of one test: its domain, a directory for its programs and assembly data (one arm
/// at a time in this binary, as in the other arm tests).
fn arm_test(test: &str) -> (std::sync::MutexGuard<'static, ()>, TestDomain, TempDir) {
    let arm = one_arm_at_a_time();
    let sut = TestDomain::new(test);
    let dir = TempDir::new(test);
    (arm, sut, dir)
}

/// The example programs.
fn examples() -> PathBuf {
    arm().parent().unwrap().join("programs")
}

/// The arm in lockstep in the test's domain, its assembly data in `dir`; returns when every
/// drive is enabled.
fn up(sut: &mut TestDomain, dir: &TempDir) -> u32 {
    up_system(sut, dir, &arm())
}

/// The robot of `system` (an arm's description) in lockstep, as [`up`].
fn up_system(sut: &mut TestDomain, dir: &TempDir, system: &Path) -> u32 {
    up_system_with(sut, dir, system, &[])
}

/// [`up_system`] with more options for `modbot up` (`--gate 1000`).
fn up_system_with(sut: &mut TestDomain, dir: &TempDir, system: &Path, more: &[&str]) -> u32 {
    sut.set_env("MODBOT_DATA_DIR", dir.path().join("data").to_str().unwrap());
    // The test's domain comes from MODBOT_DOMAIN, as `--domain` would give it: the system
    // runs there with that domain's assembly data, where the program writes its moves' goals.
    let system = system.to_str().unwrap();
    let mut args = vec!["up", system, "--lockstep"];
    args.extend_from_slice(more);
    let up = sut.spawn_logged("modbot", &args);
    wait_enabled(sut, up);
    up
}

fn down(sut: &mut TestDomain, up: u32) {
    sut.modbot_ok(&["down"]);
    sut.wait_exit(up, Duration::from_secs(60));
    assert_eq!(
        sut.leftover_files(),
        Vec::<PathBuf>::new(),
        "{}",
        sut.output_of(up)
    );
}

/// `modbot program run FILE`: (exit code, stdout, stderr).
fn run(sut: &TestDomain, program: &Path) -> (i32, String, String) {
    let out = sut.modbot(&["program", "run", program.to_str().unwrap()]);
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The assemblies switched to, in order, as `modbot assembly` lists them (after the first).
fn switched(sut: &TestDomain) -> Vec<String> {
    let status = sut.modbot_ok(&["assembly"]);
    status
        .lines()
        .filter(|l| l.contains(": switched at tick"))
        .filter_map(|l| l.split_whitespace().nth(2))
        .map(|name| name.trim_end_matches(':').to_owned())
        .collect()
}

/// `examples/programs/three.lua`: a program of three commands — `ptp` (assembly `goto`), a
/// command of the program's own library (`tour`: assembly `ptp`, the robot going round) and
/// `hold` — switches the three
/// assemblies in that order, each once the one before is done, and leaves its runs and results
/// in assembly data: `modbot data` shows them, and the goal went there before the switch.
#[test]
fn a_program_of_three_commands_switches_three_assemblies_in_order_and_leaves_results_in_assembly_data(
) {
    let (_arm, mut sut, dir) = arm_test("program_three");
    let program = examples().join("three.lua");
    let up = up(&mut sut, &dir);
    let before = switched(&sut);
    let (code, out, err) = run(&sut, &program);
    assert_eq!(code, 0, "{out}{err}");
    let after = switched(&sut);
    assert_eq!(after[before.len()..], ["goto", "ptp", "hold"], "{after:?}");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 4, "{out}");
    let at = program.display();
    for (line, start) in lines.iter().zip([
        format!("run 1: ptp (goto) at {at}:9, ticks "),
        format!("run 2: tour (ptp) at {at}:10, ticks "),
        format!("run 3: hold (hold) at {at}:11, ticks "),
        "peak following error of the ptp: ".to_owned(),
    ]) {
        assert!(line.starts_with(&start), "{out}");
    }
    let data = sut.modbot_ok(&["data", "ls"]);
    assert!(
        data.contains("goto.q = [0.2, -0.1, 0.1, 0.0, 0.0, 0.0]"),
        "{data}"
    );
    assert!(data.contains("run.2: tour (ptp)"), "{data}");
    for key in [
        "ptp.peak_following",
        "ptp.settling_s",
        "ptp.residual",
        "tour.moved",
        "tour.ticks",
    ] {
        let value = sut.modbot_ok(&["data", "get", key]);
        let x: f64 = value
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("{key} = {value}"));
        assert!(x.is_finite() && x >= 0.0, "{key} = {x}");
    }
    let peak: f64 = sut
        .modbot_ok(&["data", "get", "ptp.peak_following"])
        .trim()
        .parse()
        .unwrap();
    assert!(peak > 0.0 && peak < 0.1, "peak following error {peak} rad");
    let run1 = sut.modbot_ok(&["data", "get", "run.1"]);
    assert!(run1.contains(", ok: arrival_tick="), "{run1}");
    down(&mut sut, up);
}

/// A precondition that fails (a goal for two axes on a six-axis robot) stops the program with
/// `file:line: why` at the line that called the command, exit 1, after the command before it
/// ran; the robot is left holding (assembly `hold`), and the later command never runs.
#[test]
fn a_failing_precondition_stops_the_program_at_its_line_and_leaves_the_robot_holding() {
    let (_arm, mut sut, dir) = arm_test("program_pre");
    let program = dir.write(
        "bad.lua",
        "ptp { q = { 0.1, 0, 0, 0, 0, 0 } }\n\nptp { q = { 0.5, 0.5 } }\nptp { q = { 0, 0, 0, 0, 0, 0 } }\n",
    );
    let up = up(&mut sut, &dir);
    let before = switched(&sut);
    let (code, out, err) = run(&sut, &program);
    assert_eq!(code, 1, "{out}{err}");
    let first = err.lines().next().unwrap_or_default();
    assert_eq!(
        first,
        format!(
            "{}:3: ptp: precondition failed: q has 2 values; the robot has 6 axes",
            program.display()
        )
    );
    assert!(
        err.contains("the robot holds (assembly hold from tick "),
        "{err}"
    );
    assert_eq!(switched(&sut)[before.len()..], ["goto", "hold"]);
    assert!(sut.modbot_ok(&["assembly"]).starts_with("assembly hold "));
    let data = sut.modbot_ok(&["data", "ls"]);
    assert!(data.contains("run.2: ptp at"), "{data}");
    assert!(data.contains("failed: ptp: precondition failed"), "{data}");
    down(&mut sut, up);
}

/// The REPL reads one command per line from a pipe: `help` lists the commands with their
/// parameters, `ptp` and `hold` switch their assemblies and report their runs, an expression's
/// value is printed, and a bad line says why (`stdin:1: ...`) and the REPL goes on (the robot
/// at rest where the line before left it: that line moved nothing).
#[test]
fn the_repl_reads_commands_from_stdin_and_runs_ptp_and_hold() {
    let (_arm, mut sut, dir) = arm_test("program_repl");
    let up = up(&mut sut, &dir);
    let before = switched(&sut);
    let input = "help\nptp { q = { -0.1, 0, 0.05, 0, 0, 0 }, v = 0.5 }\nread(\"settle.settled\")\n\
                 ptp { speed = 1 }\nhold {}\n#read(\"robot.link_position\")\n";
    let out = sut.modbot_with_input(&["program", "repl"], input);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(
        stdout.contains("ptp { a, band, bessel_hz, q, timeout, v }"),
        "{stdout}"
    );
    assert!(
        stdout.contains("      q: the goal: one joint position per axis"),
        "{stdout}"
    );
    let lines: Vec<&str> = stdout
        .lines()
        .skip_while(|l| !l.starts_with("run 1:"))
        .collect();
    assert_eq!(lines.len(), 4, "{stdout}");
    assert!(
        lines[0].starts_with("run 1: ptp (goto) at stdin:1"),
        "{stdout}"
    );
    assert_eq!(lines[1], "true", "settled when the command was done");
    assert!(
        lines[2].starts_with("run 3: hold (hold) at stdin:1"),
        "{stdout}"
    );
    assert_eq!(lines[3], "6");
    assert!(
        stderr.starts_with("stdin:1: ptp: unknown parameter 'speed'"),
        "{stderr}"
    );
    assert_eq!(switched(&sut)[before.len()..], ["goto", "hold"]);
    down(&mut sut, up);
}

/// Assembly data outlives the system: what a program kept is listed by `modbot data` while
/// the system is down, and after `modbot up` a program reads it back and the `goto` assembly
/// is loaded with the goal kept there.
#[test]
fn assembly_data_survives_modbot_down_and_up() {
    let (_arm, mut sut, dir) = arm_test("program_data");
    let first = dir.write(
        "first.lua",
        "data(\"cell.part\", \"bracket 7\")\nptp { q = { 0.15, 0, 0, 0, 0, 0.1 } }\n",
    );
    let up1 = up(&mut sut, &dir);
    let (code, out, err) = run(&sut, &first);
    assert_eq!(code, 0, "{out}{err}");
    down(&mut sut, up1);
    let kept = sut.modbot_ok(&["data", "ls"]);
    assert!(kept.contains("cell.part = \"bracket 7\""), "{kept}");
    assert!(kept.contains("run.1: ptp (goto)"), "{kept}");

    let up2 = up(&mut sut, &dir);
    let second = dir.write(
        "second.lua",
        "assert(data(\"cell.part\") == \"bracket 7\", \"the part is kept\")\n\
         local q = data(\"goto.q\")\nassert(q[1] == 0.15 and q[6] == 0.1, \"the goal is kept\")\n\
         command \"again\" {\n  run = function() return { assembly = \"goto\" } end,\n  \
         done = function() return read(\"settle.settled\") end,\n}\nagain {}\n\
         local at = read(\"robot.demand_position\")\nassert(at[1] == 0.15 and at[6] == 0.1, \"moved to the kept goal\")\n",
    );
    let (code, out, err) = run(&sut, &second);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("run 2: again (goto)"), "{out}");
    down(&mut sut, up2);
}

/// Ctrl-C (SIGINT) while a command waits stops the program with the line it is at, exit 1,
/// and leaves the robot holding: the run is kept as failed.
#[test]
fn ctrl_c_stops_the_program_and_leaves_the_robot_holding() {
    let (_arm, mut sut, dir) = arm_test("program_ctrl_c");
    let program = dir.write(
        "long.lua",
        "ptp { q = { 0.05, 0, 0, 0, 0, 0 } }\nwait { s = 100000 }\n",
    );
    let up = up(&mut sut, &dir);
    let run = sut.spawn_logged("modbot", &["program", "run", program.to_str().unwrap()]);
    sut.wait_until("the program waits", Duration::from_secs(60), || {
        let out = sut.output_of(run);
        if out.contains("run 1: ptp (goto)") {
            Ok(())
        } else {
            Err(out)
        }
    });
    sut.signal(run, nix::sys::signal::Signal::SIGINT);
    let status = sut.wait_exit(run, Duration::from_secs(60));
    let out = sut.output_of(run);
    assert_eq!(status.code(), Some(1), "{out}");
    assert!(
        out.contains(&format!(
            "{}:2: wait: interrupted (Ctrl-C)",
            program.display()
        )),
        "{out}"
    );
    assert!(
        out.contains("the robot holds (assembly hold from tick "),
        "{out}"
    );
    assert!(sut.modbot_ok(&["assembly"]).starts_with("assembly hold "));
    let data = sut.modbot_ok(&["data", "ls"]);
    assert!(data.contains("run.2: wait at"), "{data}");
    assert!(
        data.contains("failed: wait: interrupted (Ctrl-C)"),
        "{data}"
    );
    down(&mut sut, up);
}

/// MoRC's experiment, `examples/kr16_ff.lua` on the KR 16 of `examples/kr16.lua` (elastic
/// joints on axes 1-3, 16 kg load): the same Bessel-filtered 5° move once with the rigid and
/// once with the elastic feed-forward, each its own assembly in one program; the elastic one
/// cuts the residual link oscillation after arrival at least six-fold (the program fails
/// otherwise) and settles sooner, and both runs are kept in assembly data. The program
/// records the experiment (`record { }` .. `stop_record { }`) to `kr16_ff.h5` in the directory
/// it runs in, which h5py opens, and writes beside it `kr16_ff.svg`: an SVG of two lines, the
/// residuals of both runs.
#[test]
fn the_kr16_program_shows_the_elastic_feed_forward_cutting_the_residual_oscillation_six_fold() {
    let (_arm, mut sut, dir) = arm_test("program_kr16");
    let examples = arm().parent().unwrap().to_path_buf();
    let up = up_system(&mut sut, &dir, &examples.join("kr16.lua"));
    let program = examples.join("kr16_ff.lua");
    let ran = sut.modbot_in(dir.path(), &["program", "run", program.to_str().unwrap()]);
    let (out, err) = (
        String::from_utf8_lossy(&ran.stdout),
        String::from_utf8_lossy(&ran.stderr),
    );
    assert_eq!(ran.status.code(), Some(0), "{out}{err}");
    let (h5, svg) = (
        dir.path().join("kr16_ff.h5"),
        dir.path().join("kr16_ff.svg"),
    );
    let said = format!(
        "residuals plotted in {}",
        std::path::absolute(&svg).unwrap().display()
    );
    assert!(out.contains(&said), "{out}");
    let text = std::fs::read_to_string(&svg).expect("the plot");
    assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"));
    assert_eq!(long_polylines(&text), 2, "two lines: {svg:?}");
    assert!(text.contains("rigid feed-forward") && text.contains("elastic feed-forward"));
    let rows = python(
        "import sys, h5py\nf = h5py.File(sys.argv[1], 'r')\nq = f['robot.link_position']\n\
         assert q.shape[1] == 6 and len(f['tick']) == q.shape[0]\nprint(q.shape[0])",
        &[h5.to_str().unwrap()],
    );
    assert!(
        out.contains(&format!("recorded {} rows", rows.trim())),
        "{out}"
    );
    let value = |prefix: &str, after: &str| -> f64 {
        let line = out
            .lines()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("{out}"));
        let rest = &line[line.find(after).unwrap_or_else(|| panic!("{line}")) + after.len()..];
        rest.split_whitespace().next().unwrap().parse().unwrap()
    };
    let (rigid, elastic) = (
        value("rigid ", "residual after arrival "),
        value("elastic ", "residual after arrival "),
    );
    assert!(
        rigid >= 6.0 * elastic,
        "rigid {rigid} mrad, elastic {elastic} mrad\n{out}"
    );
    assert!(elastic < 0.5 / 1.6, "under 0.5 mm at 1.6 m: {elastic} mrad");
    assert!(
        value("elastic ", "settling ") < value("rigid ", "settling "),
        "{out}"
    );
    let ratio: f64 = sut
        .modbot_ok(&["data", "get", "kr16.ratio"])
        .trim()
        .parse()
        .unwrap();
    assert!(ratio >= 6.0, "{ratio}");
    let data = sut.modbot_ok(&["data", "ls"]);
    assert!(data.contains("ptp_ff.model = \"elastic\""), "{data}");
    down(&mut sut, up);
}

/// Programs that repeat: `examples/kr16_ff.lua` on `examples/kr16.lua` in lockstep, three
/// times, each in a domain and directory of its own, the grid gated at tick 1000 (`modbot up
/// --lockstep --gate 1000`): the program steps the grid, so every command starts and ends at
/// the same tick and every printed number is the same to the last digit (the `run N:` lines
/// with their ticks and results at full precision, the residuals, the ratio), as are the
/// assembly data it kept, its plot, and its recording, row by row and bit by bit.
#[test]
fn the_kr16_program_in_lockstep_gives_the_same_numbers_to_the_last_digit_in_every_run() {
    let _arm = one_arm_at_a_time();
    let examples = arm().parent().unwrap().to_path_buf();
    let program = examples.join("kr16_ff.lua");
    let system = examples.join("kr16.lua");
    let mut runs = Vec::new();
    for n in 1..=3 {
        let mut sut = TestDomain::new(&format!("kr16rep{n}"));
        let dir = TempDir::new(&format!("kr16rep{n}"));
        let up = up_system_with(&mut sut, &dir, &system, &["--gate", "1000"]);
        let ran = sut.modbot_in(dir.path(), &["program", "run", program.to_str().unwrap()]);
        let (out, err) = (
            String::from_utf8_lossy(&ran.stdout).into_owned(),
            String::from_utf8_lossy(&ran.stderr).into_owned(),
        );
        assert_eq!(ran.status.code(), Some(0), "run {n}: {out}{err}");
        // The grid was the program's to step throughout: never lifted under it.
        assert!(
            !err.contains("not the same as another"),
            "run {n}: the program lost the gate: {err}"
        );
        let at = std::path::absolute(dir.path())
            .unwrap()
            .display()
            .to_string();
        // Its first line names the run's store file (the directory's name differs).
        let data: String = sut
            .modbot_ok(&["data", "ls"])
            .lines()
            .filter(|l| !l.starts_with("# "))
            .map(|l| format!("{l}\n"))
            .collect();
        let svg = std::fs::read(dir.path().join("kr16_ff.svg")).expect("the plot");
        down(&mut sut, up);
        // What the grid did (switches, postponements, the gate, warnings): shown when a run
        // differs.
        let grid: String = sut
            .output_of(up)
            .lines()
            .filter(|l| {
                [
                    "coordinator |",
                    "WARN",
                    "ERROR",
                    "gate",
                    "late",
                    "safe stop",
                ]
                .iter()
                .any(|w| l.contains(w))
            })
            .map(|l| format!("{l}\n"))
            .collect();
        runs.push((
            out.replace(&at, "DIR"),
            data.replace(&at, "DIR"),
            svg,
            dir,
            format!("{err}\n--- the system's grid lines:\n{grid}"),
        ));
    }
    let (first, data, svg, dir, _) = &runs[0];
    assert!(first.contains("run 2: move (ptp_ff)"), "{first}");
    // The arm moved: the same numbers in every run are numbers of a motion.
    assert!(first.contains("ratio rigid/elastic "), "{first}");
    let start: u64 = first
        .lines()
        .find(|l| l.starts_with("run 2: "))
        .and_then(|l| l.split("ticks ").nth(1))
        .and_then(|t| t.split("..").next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{first}"));
    assert!(
        start >= 1000,
        "the first move starts after the gate: {first}"
    );
    let h5 = dir.path().join("kr16_ff.h5");
    for (n, (out, d, s, other, err)) in runs.iter().enumerate().skip(1) {
        assert_eq!(
            out,
            first,
            "run {} printed other numbers; its stderr: {err}\nrun 1's: {}",
            n + 1,
            runs[0].4
        );
        assert_eq!(d, data, "run {} kept other data", n + 1);
        assert!(s == svg, "run {} plotted another SVG", n + 1);
        let compared = std::process::Command::new(env!("CARGO_BIN_EXE_modbot"))
            .args(["record", "compare"])
            .arg(&h5)
            .arg(other.path().join("kr16_ff.h5"))
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&compared.stdout);
        assert_eq!(compared.status.code(), Some(0), "run {}: {said}", n + 1);
        assert!(said.starts_with("identical through tick "), "{said}");
    }
}

/// A program stepping a gated grid resets the robot itself: a drive fault (injected through
/// the bus bridge) is the robot's fault, `robot_reset()` runs the held grid on until the bridge
/// has taken the reset and enabled every drive (a reset is taken at a release, which a held
/// grid makes only when the program runs it), and the next motion goes through.
#[test]
fn a_stepped_program_resets_a_faulted_robot_and_moves_on() {
    let (_arm, mut sut, dir) = arm_test("program_step_reset");
    let up = up_system_with(&mut sut, &dir, &arm(), &["--gate", "1000"]);
    let program = dir.write(
        "reset.lua",
        "ptp { q = { 0.1, 0, 0, 0, 0, 0 } }\n\
         call(\"host_bus.inject\", 2, \"following\", true)\n\
         wait { s = 0.05 }\n\
         print(\"after the fault:\", robot_state().kind)\n\
         call(\"host_bus.inject\", 2, \"following\", false)\n\
         print(robot_reset())\n\
         print(\"after the reset:\", robot_state().kind)\n\
         ptp { q = { 0, 0, 0, 0, 0, 0 } }\n",
    );
    let (code, out, err) = run(&sut, &program);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("after the fault:\tfault\n"), "{out}");
    assert!(out.contains("every drive enabled at tick "), "{out}");
    assert!(out.contains("after the reset:\toperational\n"), "{out}");
    assert!(
        out.contains("run 3: ptp (goto)") && out.contains(", ok: "),
        "{out}"
    );
    down(&mut sut, up);
}

/// The polylines of the SVG `svg` with 10 points or more: its data lines (the axes and the
/// legend's marks have fewer).
fn long_polylines(svg: &str) -> usize {
    svg.split("<polyline")
        .skip(1)
        .filter_map(|e| e.split("points=\"").nth(1)?.split('"').next())
        .filter(|points| points.split_whitespace().count() >= 10)
        .count()
}

/// `record { file, signals }` and `stop_record { }` on the KR 16 (whose recorder is on demand):
/// a signal the recorder does not have stops the program at the line of `record`, exit 1;
/// then a program records two signals for 0.5 s of grid time to a file in the directory it
/// runs in, which h5py opens with those two signals as ticks × 6 and the rows `stop_record`
/// reported, tick after tick; the file is kept in assembly data (`record.file`).
#[test]
fn record_and_stop_record_write_the_chosen_signals_and_an_unknown_one_stops_the_program() {
    let (_arm, mut sut, dir) = arm_test("program_record");
    let examples = arm().parent().unwrap().to_path_buf();
    let up = up_system(&mut sut, &dir, &examples.join("kr16.lua"));
    let bad = dir.write(
        "bad.lua",
        "hold {}\nrecord { file = \"x.h5\", signals = { \"robot.nope\" } }\n",
    );
    let ran = sut.modbot_in(dir.path(), &["program", "run", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&ran.stderr);
    assert_eq!(ran.status.code(), Some(1), "{err}");
    let first = err.lines().next().unwrap_or_default();
    assert!(
        first.starts_with(&format!("{}:2: record: ", bad.display()))
            && first.contains(
                "signal 'robot.nope' is not the recorder's: it records robot.link_position"
            ),
        "{err}"
    );
    let good = dir.write(
        "good.lua",
        "record { file = \"rec.h5\", signals = { \"robot.link_position\", \"robot.motor_torque\" } }\n\
         wait { s = 0.5 }\nlocal r = stop_record {}\nprint(r.file, r.rows)\n",
    );
    let ran = sut.modbot_in(dir.path(), &["program", "run", good.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&ran.stdout);
    assert_eq!(
        ran.status.code(),
        Some(0),
        "{out}{}\nmodbot up:\n{}",
        String::from_utf8_lossy(&ran.stderr),
        sut.output_of(up)
    );
    let file = std::path::absolute(dir.path().join("rec.h5")).unwrap();
    let last = out.lines().last().unwrap_or_default();
    let rows: u64 = last
        .strip_prefix(&format!("{}\t", file.display()))
        .and_then(|r| r.trim().parse().ok())
        .unwrap_or_else(|| panic!("file and rows: {out}"));
    assert!(rows >= 500, "0.5 s of 1 ms ticks at least: {rows}");
    let checked = python(
        r#"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
assert sorted(f.keys()) == ["generation", "robot.link_position", "robot.motor_torque", "state_hash", "tick", "time"], list(f.keys())
tick = f["tick"][:]
assert len(tick) == int(sys.argv[2]) and (np.diff(tick) == 1).all(), (len(tick), sys.argv[2])
for s in ["robot.link_position", "robot.motor_torque"]:
    assert f[s].shape == (len(tick), 6), (s, f[s].shape)
print("ok")
"#,
        &[file.to_str().unwrap(), &rows.to_string()],
    );
    assert_eq!(checked.trim(), "ok");
    let kept = sut.modbot_ok(&["data", "get", "record.file"]);
    assert!(kept.contains(file.to_str().unwrap()), "{kept}");
    down(&mut sut, up);
}
