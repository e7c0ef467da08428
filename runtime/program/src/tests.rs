//! The interpreter against a fake robot: every tick() advances the grid by 10 ticks, `settle`
//! settles 200 ticks after a switch, and everything the program asks is logged.

use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use modbot_data::Store;
use modbot_ipc_schema::OwnedValue;

use super::*;

type Log = Rc<RefCell<Vec<String>>>;

struct FakeRobot {
    log: Log,
    ctrl_c: Arc<AtomicBool>,
    tick: u64,
    switched_at: u64,
    assembly: String,
    fault: Option<String>,
    /// A safe stop: since tick, cause.
    stop: Option<(u64, String)>,
    operational_since: u64,
    /// Stops the robot 50 ticks into the next motion.
    stop_during: bool,
    /// Steps the grid: its tick moves only by `run_to`.
    stepped: bool,
}

impl Robot for FakeRobot {
    fn switch(&mut self, name: &str) -> Result<u64, RobotError> {
        if name == "missing" {
            return Err(RobotError::Switch {
                assembly: name.into(),
                why: "no assembly named 'missing'".into(),
            });
        }
        self.tick += 100;
        self.switched_at = self.tick;
        self.assembly = name.to_owned();
        self.fault = None;
        self.log
            .borrow_mut()
            .push(format!("switch {name} at {}", self.tick));
        Ok(self.tick)
    }

    fn tick(&mut self) -> Result<u64, RobotError> {
        if !self.stepped {
            self.tick += 10;
        }
        Ok(self.tick)
    }

    fn stepped(&self) -> bool {
        self.stepped
    }

    fn run_to(&mut self, tick: u64) -> Result<u64, RobotError> {
        self.log.borrow_mut().push(format!("run_to {tick}"));
        self.tick = tick;
        Ok(tick)
    }

    fn base_period_s(&mut self) -> Result<f64, RobotError> {
        Ok(0.001)
    }

    fn read(&mut self, what: &str) -> Result<OwnedValue, RobotError> {
        if self.stop_during
            && self.switched_at > 0
            && self.stop.is_none()
            && self.tick >= self.switched_at + 50
        {
            self.stop = Some((self.tick, "the assembly faulted".into()));
        }
        let settled = self.tick >= self.switched_at + 200;
        Ok(match what {
            "robot.link_position" => OwnedValue::F64s(vec![0.0; 6]),
            "settle.settled" => OwnedValue::Bool(settled),
            "settle.peak_following" => OwnedValue::F64(0.0125),
            "settle.residual" => OwnedValue::F64(0.0005),
            "settle.settling_s" => OwnedValue::F64(0.05),
            "settle.arrival_tick" => OwnedValue::I64(self.switched_at as i64 + 150),
            "host_bus.tick" => OwnedValue::I64(self.tick as i64),
            _ => {
                return Err(RobotError::Read {
                    what: what.into(),
                    why: "no such module or component".into(),
                })
            }
        })
    }

    fn call(&mut self, target: &str, args: &[OwnedValue]) -> Result<Vec<OwnedValue>, RobotError> {
        self.log
            .borrow_mut()
            .push(format!("call {target} {}", args.len()));
        if target == "fake.ctrl_c" {
            self.ctrl_c.store(true, std::sync::atomic::Ordering::SeqCst);
        }
        if target == "fake.fault" {
            self.fault = Some("monitor watch: following error".into());
        }
        if target == "fake.stop_during" {
            self.stop_during = true;
        }
        if target == "fake.stop" {
            self.stop = Some((
                self.tick,
                "coordinator lost: no tick for 3 base periods".into(),
            ));
        }
        Ok(args.to_vec())
    }

    fn fault(&mut self) -> Result<Option<String>, RobotError> {
        Ok(self.fault.clone())
    }

    fn robot_state(&mut self) -> Result<Option<modbot_bus::RobotState>, RobotError> {
        Ok(Some(match &self.stop {
            Some((since_tick, cause)) => modbot_bus::RobotState::SafeStop {
                since_tick: *since_tick,
                cause: cause.clone(),
            },
            None => modbot_bus::RobotState::Operational {
                since_tick: self.operational_since,
            },
        }))
    }

    fn reset(&mut self) -> Result<String, RobotError> {
        self.log.borrow_mut().push("reset".into());
        if self.stop.take().is_none() {
            return Err(RobotError::Robot("nothing to reset".into()));
        }
        self.operational_since = self.tick;
        Ok("every drive enabled".into())
    }

    fn domain(&self) -> &str {
        "fake"
    }
}

struct Fixture {
    sut: Interpreter,
    log: Log,
    reports: Log,
    dir: modbot_testkit::TempDir,
}

fn fixture(test: &str) -> Fixture {
    fixture_stepped(test, false)
}

fn fixture_stepped(test: &str, stepped: bool) -> Fixture {
    let dir = modbot_testkit::TempDir::new(test);
    let log = Log::default();
    let reports = Log::default();
    let interrupt = Arc::new(AtomicBool::new(false));
    let robot = FakeRobot {
        log: log.clone(),
        ctrl_c: interrupt.clone(),
        tick: 1000,
        switched_at: 0,
        assembly: "hold".into(),
        fault: None,
        stop: None,
        operational_since: 0,
        stop_during: false,
        stepped,
    };
    let store = Store::open(&dir.path().join("data.redb")).unwrap();
    let to = reports.clone();
    let sut = Interpreter::new(
        Box::new(robot),
        store,
        Options {
            dir: dir.path().to_owned(),
            interrupt: Interrupt::Flag(interrupt.clone()),
            report: Box::new(move |line| to.borrow_mut().push(line.to_owned())),
        },
    )
    .unwrap();
    Fixture {
        sut,
        log,
        reports,
        dir,
    }
}

fn store_of(dir: &Path) -> Store {
    Store::open_existing(&dir.join("data.redb"))
        .unwrap()
        .unwrap()
}

fn switches(log: &Log) -> Vec<String> {
    log.borrow()
        .iter()
        .filter_map(|l| {
            l.strip_prefix("switch ")
                .map(|s| s.split(' ').next().unwrap().to_owned())
        })
        .collect()
}

/// On a stepped grid a command's finish condition is asked every 10 ms of grid time (10 ticks
/// at 1 kHz), the grid run exactly that far between two askings, so it finishes at the same
/// tick in every run; two runs of a program log the same steps and keep the same runs.
/// What a run of a program did: the fake's log, and each command's (start, end) tick.
type Steps = (Vec<String>, Vec<(u64, u64)>);

#[test]
fn on_a_stepped_grid_a_command_runs_the_grid_in_strides_and_two_runs_are_alike() {
    let runs: Vec<Steps> = (0..2)
        .map(|n| {
            let mut f = fixture_stepped(&format!("stepped{n}"), true);
            let program = f.dir.write(
                "stepped.lua",
                "wait { s = 0.05 }\nptp { q = { 0.1, 0, 0, 0, 0, 0 } }\n",
            );
            f.sut.run_file(&program).unwrap();
            let runs = store_of(f.dir.path()).runs().unwrap();
            let ticks = runs
                .iter()
                .map(|(_, r)| (r.start_tick, r.end_tick))
                .collect();
            let log = f.log.borrow().clone();
            (log, ticks)
        })
        .collect();
    let (log, ticks) = &runs[0];
    let steps: Vec<&str> = log
        .iter()
        .take_while(|l| l.starts_with("run_to"))
        .map(String::as_str)
        .collect();
    assert_eq!(
        steps,
        [
            "run_to 1010",
            "run_to 1020",
            "run_to 1030",
            "run_to 1040",
            "run_to 1050"
        ],
        "{log:?}"
    );
    assert_eq!(ticks[0], (1000, 1050));
    // The motion: switched at 1150 (the fake's switch takes 100 ticks), settled 200 ticks on,
    // seen at the first stride there.
    assert_eq!(ticks[1], (1150, 1350));
    assert_eq!(&runs[1], &runs[0], "the second run stepped otherwise");
}

#[test]
fn a_program_of_three_commands_switches_their_assemblies_in_order_and_keeps_their_runs() {
    let mut f = fixture("three");
    let program = f.dir.write(
        "three.lua",
        "ptp { q = { 0.1, 0, 0, 0, 0, 0 }, v = 0.5 }\nhold {}\nwait { s = 0.05 }\n\
         ptp { q = { 0, 0, 0, 0, 0, 0 } }\n",
    );
    f.sut.run_file(&program).unwrap();
    assert_eq!(switches(&f.log), ["goto", "hold", "goto"]);
    let store = store_of(f.dir.path());
    let runs = store.runs().unwrap();
    let names: Vec<&str> = runs.iter().map(|(_, r)| r.command.as_str()).collect();
    assert_eq!(names, ["ptp", "hold", "wait", "ptp"]);
    let (_, first) = &runs[0];
    assert_eq!(first.origin, format!("{}:1", program.display()));
    assert_eq!(first.assembly, "goto");
    assert!(first.ok());
    assert!(first.end_tick >= first.start_tick + 200);
    assert_eq!(
        first.value("peak_following"),
        Some(&OwnedValue::F64(0.0125))
    );
    // The wait lasted 50 ticks of grid time at least.
    assert!(runs[2].1.end_tick >= runs[2].1.start_tick + 50);
    // The parameters went to assembly data before the switch, the results after the run.
    assert_eq!(
        store.get("goto.q").unwrap(),
        Some(OwnedValue::F64s(vec![0.0; 6]))
    );
    assert_eq!(store.get("goto.v").unwrap(), Some(OwnedValue::F64(1.0)));
    assert_eq!(
        store.get("ptp.settling_s").unwrap(),
        Some(OwnedValue::F64(0.05))
    );
    assert_eq!(f.reports.borrow().len(), 4);
    assert!(
        f.reports.borrow()[0].starts_with("run 1: ptp (goto) at "),
        "{:?}",
        f.reports
    );
}

#[test]
fn a_failing_precondition_stops_at_the_calling_line_and_leaves_the_robot_holding() {
    let mut f = fixture("pre");
    let program = f.dir.write(
        "bad.lua",
        "ptp { q = { 0.1, 0, 0, 0, 0, 0 } }\n\nptp { q = { 1, 2 } }\nhold {}\n",
    );
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}:3: ptp: precondition failed: q has 2 values; the robot has 6 axes",
            program.display()
        )
    );
    assert!(matches!(f.sut.left(), Left::Holding(_)));
    assert_eq!(switches(&f.log), ["goto", "hold"]);
    let runs = store_of(f.dir.path()).runs().unwrap();
    assert_eq!(runs.len(), 2);
    assert!(
        runs[1]
            .1
            .outcome
            .starts_with("failed: ptp: precondition failed"),
        "{}",
        runs[1].1
    );
}

#[test]
fn a_failure_before_any_motion_leaves_the_robot_untouched() {
    let mut f = fixture("untouched");
    let program = f.dir.write("bad.lua", "local x = 1\nptpp { q = {} }\n");
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(e.line, Some(2));
    assert!(e.message.contains("ptpp"), "{e}");
    assert_eq!(f.sut.left(), Left::Untouched);
    assert!(switches(&f.log).is_empty());
}

#[test]
fn bad_input_names_its_file_and_line() {
    let cases = [
        (
            "ptp { q = { 0, 0, 0, 0, 0, 0 }, speed = 2 }\n",
            1,
            "ptp: unknown parameter 'speed' (it takes a, band, bessel_hz, q, timeout, v)",
        ),
        (
            "\nlocal v = read(\"nobody.x\")\n",
            2,
            "read(\"nobody.x\"): no such module or component",
        ),
        (
            "ptp(3)\n",
            1,
            "ptp: takes a table of parameters (ptp{ ... }), not a integer",
        ),
        (
            "command \"read\" { }\n",
            1,
            "command \"read\": a command's name is",
        ),
        (
            "command \"x\" { runn = function() end }\n",
            1,
            "command \"x\": unknown field 'runn'",
        ),
        (
            "local t = {}\nt.x.y = 1\n",
            2,
            "attempt to index a nil value",
        ),
        ("x = = 1\n", 1, "unexpected symbol"),
        (
            "require \"../etc\"\n",
            1,
            "require \"../etc\": a library is named by",
        ),
        ("require \"absent\"\n", 1, "require \"absent\": cannot read"),
        (
            "string.gsub(\"a\", \"a\", \"b\")\n",
            1,
            "not available in a robot program",
        ),
        (
            "command \"go\" { run = function() return { assembly = \"missing\" } end }\ngo {}\n",
            2,
            "go: assembly 'missing' was not switched to",
        ),
    ];
    for (i, (source, line, message)) in cases.iter().enumerate() {
        let mut f = fixture(&format!("bad{i}"));
        let program = f.dir.write("p.lua", source);
        let e = f.sut.run_file(&program).unwrap_err();
        assert_eq!(e.file, program.display().to_string(), "{source}");
        assert_eq!(e.line, Some(*line), "{source}: {e}");
        assert!(
            e.message.starts_with(message) || e.message.contains(message),
            "{source}: {e}"
        );
    }
}

#[test]
fn a_command_defined_in_a_library_next_to_the_program_runs_like_a_builtin() {
    let mut f = fixture("library");
    f.dir.write(
        "moves.lua",
        "command \"home\" {\n  doc = \"goes home\",\n  params = { v = \"speed\" },\n  \
         run = function(p) return { assembly = \"goto\", args = { q = { 0, 0, 0, 0, 0, 0 }, v = p.v } } end,\n  \
         done = function(p, r) return read(\"settle.settled\") end,\n  \
         eval = function(p, r) return { took = r.end_tick - r.start_tick } end,\n}\n\
         return { answer = 42 }\n",
    );
    let program = f.dir.write(
        "prog.lua",
        "local m = require \"moves\"\nassert(m.answer == 42)\nassert(require \"moves\" == m)\n\
         local r = home { v = 0.25 }\nassert(r.took >= 200)\ndata(\"note\", \"home done\")\n",
    );
    f.sut.run_file(&program).unwrap();
    let store = store_of(f.dir.path());
    assert_eq!(store.get("goto.v").unwrap(), Some(OwnedValue::F64(0.25)));
    assert_eq!(
        store.get("note").unwrap(),
        Some(OwnedValue::Text("home done".into()))
    );
    assert!(matches!(store.get("home.took").unwrap(), Some(OwnedValue::I64(t)) if t >= 200));
    let help = f.sut.help();
    assert!(help.contains("home { v }  goes home"), "{help}");
    assert!(
        help.contains("ptp { a, band, bessel_hz, q, timeout, v }"),
        "{help}"
    );
}

#[test]
fn an_error_in_a_librarys_hook_names_the_call_and_the_hook_line() {
    let mut f = fixture("hookerror");
    f.dir.write(
        "lib.lua",
        "command \"check\" {\n  pre = function(p)\n    error(\"the gripper is open\")\n  end,\n}\n",
    );
    let program = f.dir.write("prog.lua", "require \"lib\"\ncheck {}\n");
    let e = f.sut.run_file(&program).unwrap_err();
    let lib = f.dir.path().join("lib.lua");
    assert_eq!(
        e.to_string(),
        format!(
            "{}:2: check: precondition: {}:3: the gripper is open",
            program.display(),
            lib.display()
        )
    );
}

#[test]
fn a_failed_evaluation_stops_the_program() {
    let mut f = fixture("eval");
    let program = f.dir.write(
        "prog.lua",
        "command \"measure\" { eval = function(p, r) return false, \"too much overshoot\" end }\n\
         measure {}\nhold {}\n",
    );
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(e.line, Some(2));
    assert_eq!(e.message, "measure: evaluation failed: too much overshoot");
    assert!(switches(&f.log).is_empty());
}

#[test]
fn a_command_not_done_within_its_timeout_of_grid_time_stops_the_program() {
    let mut f = fixture("timeout");
    let program = f.dir.write(
        "prog.lua",
        "command \"never\" {\n  run = function() return { timeout = 0.5 } end,\n  done = function() return false end,\n}\nnever {}\n",
    );
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(e.line, Some(5));
    assert!(
        e.message
            .starts_with("never: not done within 0.5 s of grid time"),
        "{e}"
    );
}

#[test]
fn ctrl_c_stops_a_loop_and_a_command_waiting_and_leaves_the_robot_holding() {
    let mut f = fixture("interrupt");
    // The fake robot asks for the stop when called `fake.ctrl_c`, as Ctrl-C would.
    let program = f.dir.write(
        "loop.lua",
        "hold {}\ncall(\"fake.ctrl_c\")\nwhile true do end\n",
    );
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(
        (e.line, e.message.as_str()),
        (Some(3), "interrupted (Ctrl-C)")
    );
    assert!(matches!(f.sut.left(), Left::Holding(_)));
    let program = f.dir.write(
        "wait.lua",
        "command \"forever\" { done = function() call(\"fake.ctrl_c\") return false end }\nforever {}\n",
    );
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(
        (e.line, e.message.as_str()),
        (Some(2), "forever: interrupted (Ctrl-C)")
    );
    assert_eq!(
        f.sut.left(),
        Left::Untouched,
        "the second program moved nothing"
    );
}

#[test]
fn a_program_that_computes_forever_between_commands_is_stopped() {
    let mut f = fixture("budget");
    let program = f
        .dir
        .write("prog.lua", "local n = 0\nwhile true do n = n + 1 end\n");
    let e = f.sut.run_file(&program).unwrap_err();
    assert!(
        e.message.contains("computed too long between two commands"),
        "{e}"
    );
}

#[test]
fn the_repl_prints_values_not_command_results_and_goes_on_after_an_error() {
    let mut f = fixture("repl");
    assert_eq!(f.sut.run_line("1 + 1").unwrap(), Some("2".into()));
    assert_eq!(f.sut.run_line("x = { 1.5, 2, a = true }").unwrap(), None);
    assert_eq!(
        f.sut.run_line("x").unwrap(),
        Some("{ 1.5, 2, a = true }".into())
    );
    assert_eq!(
        f.sut.run_line("ptp { q = { 0, 0, 0, 0, 0, 0 } }").unwrap(),
        None
    );
    let e = f.sut.run_line("ptp { q = 1 }").unwrap_err();
    assert_eq!(e.file, "stdin");
    assert!(
        e.message
            .starts_with("ptp: precondition failed: q is required"),
        "{e}"
    );
    assert_eq!(f.sut.left(), Left::Untouched, "the line moved nothing");
    assert_eq!(f.sut.run_line("hold {}").unwrap(), None);
    let e = f
        .sut
        .run_line("ptp { q = { 0, 0, 0, 0, 0, 0 } } ptp { q = 1 }")
        .unwrap_err();
    assert!(e.message.starts_with("ptp: precondition failed"), "{e}");
    assert!(
        matches!(f.sut.left(), Left::Holding(_)),
        "the line moved the robot"
    );
    assert_eq!(switches(&f.log), ["goto", "hold", "goto", "hold"]);
    assert_eq!(
        f.sut.run_line("call(\"host_bus.block\", 2, true)").unwrap(),
        Some("2\ttrue".into())
    );
    assert_eq!(
        f.sut.run_line("data(\"ptp.peak_following\")").unwrap(),
        Some("0.0125".into())
    );
}

#[test]
fn a_faulted_assembly_stops_its_command() {
    let mut f = fixture("fault");
    let program = f.dir.write(
        "prog.lua",
        "command \"boom\" {\n  run = function() return { assembly = \"goto\" } end,\n  \
         done = function() call(\"fake.fault\") return false end,\n}\nboom {}\n",
    );
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(e.line, Some(5));
    assert_eq!(
        e.message,
        "boom: the assembly faulted: monitor watch: following error"
    );
}

#[test]
fn a_motion_while_the_robot_is_in_safe_stop_is_refused_with_the_cause_and_moves_nothing() {
    let mut f = fixture("refused");
    let program = f.dir.write(
        "stopped.lua",
        "call(\"fake.stop\")\nptp { q = { 0.1, 0, 0, 0, 0, 0 } }\n",
    );
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}:2: ptp: the robot is in safe stop since tick 1000 (coordinator lost: no tick for 3 base periods); `modbot robot reset --domain fake` (or `reset {{}}`) brings it back",
            program.display()
        )
    );
    assert!(switches(&f.log).is_empty(), "nothing was switched to");
    assert_eq!(f.sut.left(), Left::Untouched);
}

#[test]
fn a_reset_in_the_program_brings_the_robot_back_and_the_next_motion_runs() {
    let mut f = fixture("reset");
    let program = f.dir.write(
        "reset.lua",
        "call(\"fake.stop\")\nassert(robot_state().kind == \"safe_stop\")\nreset {}\nassert(robot_state().kind == \"operational\")\nptp { q = { 0.1, 0, 0, 0, 0, 0 } }\n",
    );
    f.sut.run_file(&program).unwrap();
    assert_eq!(switches(&f.log), ["goto"]);
    assert!(f.log.borrow().iter().any(|l| l == "reset"));
}

#[test]
fn a_motion_during_which_the_robot_stops_fails_with_the_cause_never_ok() {
    let mut f = fixture("stopped_during");
    let program = f.dir.write(
        "during.lua",
        "call(\"fake.stop_during\")\nptp { q = { 0.1, 0, 0, 0, 0, 0 } }\n",
    );
    let e = f.sut.run_file(&program).unwrap_err();
    assert_eq!(e.line, Some(2));
    assert!(
        e.message.starts_with(
            "ptp: the robot left operational during the motion: it is in safe stop since tick"
        ) && e.message.contains("(the assembly faulted)"),
        "{e}"
    );
    let runs = store_of(f.dir.path()).runs().unwrap();
    assert!(
        runs.iter().all(|(_, r)| r.outcome != "ok"),
        "no run reported ok: {runs:?}"
    );
}
