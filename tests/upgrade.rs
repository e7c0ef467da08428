//! Live upgrades with real processes (`modbot upgrade`): a new process of a module's program
//! takes the running one over — its address, blackboard, own state and the calls on their way
//! — while callers keep calling; a new program that cannot start or serves other methods is
//! refused and the running process serves on.

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use common::{bin, TestDomain};
use modbot_core::calls::CallHandle;
use modbot_core::{
    Args, CallError, CallOptions, Ctx, Domain, IpcTransport, ModuleBuilder, ReceiveMode, Value,
};

/// Supervision for these tests: quick heartbeats, a generous start (a loaded machine).
const SUPERVISION: &str = r#"
supervision { heartbeat_timeout = 5, heartbeat_period = 0.05, start_timeout = 20, stop_grace = 10 }
"#;

/// A system of one `target` (modbot-faulty journaling its `record` calls), up.
struct System {
    sut: TestDomain,
    up: u32,
    journal: PathBuf,
}

impl System {
    fn start(test: &str) -> System {
        let mut sut = TestDomain::new(test);
        let journal = std::env::temp_dir().join(format!("{}.journal", sut.name()));
        let _ = std::fs::remove_file(&journal);
        let body = format!(
            r#"{SUPERVISION}
module "target" {{ addr = 5, program = "modbot-faulty", args = {{ "--journal", "{}" }} }}
"#,
            journal.display()
        );
        let file = sut.write_system(&body);
        let up = sut.spawn_logged("modbot", &["up", file.to_str().unwrap()]);
        sut.wait_for("target to answer", Duration::from_secs(60), || {
            sut.modbot(&["call", "target.ping"]).status.success()
        });
        System { sut, up, journal }
    }

    /// `modbot upgrade target MORE...`: (exit code, stdout, stderr).
    fn upgrade(&self, more: &[&str]) -> (Option<i32>, String, String) {
        let mut args = vec!["upgrade", "target"];
        args.extend(more);
        let out = self.sut.modbot(&args);
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).trim().to_owned(),
            String::from_utf8_lossy(&out.stderr).trim().to_owned(),
        )
    }

    /// `modbot call CALL` that must succeed: its output, else a panic with `modbot up`'s log.
    fn call(&self, call: &str) -> String {
        let out = self.sut.modbot(&["call", call]);
        let text = String::from_utf8_lossy(&out.stdout).trim().to_owned();
        assert!(
            out.status.success(),
            "modbot call {call}: {}\n{}",
            String::from_utf8_lossy(&out.stderr),
            self.sut.output_of(self.up)
        );
        text
    }

    fn bb(&self, item: &str) -> String {
        self.sut
            .modbot_ok(&["bb", "target", item])
            .trim()
            .to_owned()
    }

    fn pid(&self) -> String {
        self.sut.ls_field("target", "PID").expect("target listed")
    }

    /// A program file of this test: `script` under `#!/bin/sh`.
    fn script(&mut self, name: &str, script: &str) -> PathBuf {
        use std::os::unix::fs::PermissionsExt;
        let path = std::env::temp_dir().join(format!("{}.{name}.sh", self.sut.name()));
        std::fs::write(&path, format!("#!/bin/sh\n{script}\n")).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        path
    }

    fn stop(mut self) {
        self.sut.modbot_ok(&["down"]);
        let status = self.sut.wait_exit(self.up, Duration::from_secs(60));
        let output = self.sut.output_of(self.up);
        assert_eq!(status.code(), Some(0), "{output}");
        let _ = std::fs::remove_file(&self.journal);
        assert_eq!(self.sut.leftover_files(), Vec::<PathBuf>::new(), "{output}");
        let name = self.sut.name().to_owned();
        let left: Vec<_> = std::fs::read_dir(std::env::temp_dir())
            .unwrap()
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains(&format!("modbot_{name}.tmp.")))
            .collect();
        assert_eq!(left, Vec::<String>::new(), "upgrade directories left");
    }
}

/// What the stream's caller keeps: per sequence number, the answers it got.
#[derive(Default)]
struct Ledger {
    /// Call handle → the sequence number it carried.
    seq_of: HashMap<u64, i64>,
    /// Per sequence number (index): how often it was answered, and with what.
    answers: Vec<Vec<Result<i64, String>>>,
}

fn on_done(l: &mut Ledger, _: &mut Ctx, h: CallHandle, r: Result<&Args<'_>, &CallError>) {
    let Some(seq) = l.seq_of.remove(&h.id()) else {
        return;
    };
    let answer = match r {
        Ok(args) => args.i64(0).map_err(|e| e.to_string()),
        Err(e) => Err(e.to_string()),
    };
    l.answers[seq as usize].push(answer);
}

/// A module under a stream of 1 000 calls a second is upgraded 20 times: every call is
/// answered exactly once and executed exactly once (the journal), the state hooks carry a
/// counter across every upgrade, and the blackboard's values continue into a process that never
/// served a call.
#[test]
fn a_module_under_a_stream_of_calls_upgraded_20_times_answers_every_call_exactly_once() {
    let sys = System::start("upstream");
    let domain = Domain::new(sys.sut.name()).unwrap();
    let transport = IpcTransport::new(&domain).unwrap();
    let mut caller = ModuleBuilder::<Ledger>::new("streamer", 0)
        .mode(ReceiveMode::Blocking)
        .peer("target")
        .on_done(on_done)
        .open_tool(transport, Ledger::default())
        .unwrap();
    let opts = CallOptions::timeout(Duration::from_secs(10));
    caller.state_mut().answers.push(Vec::new()); // sequence numbers start at 1
                                                 // The upgrades, one after the other, on a thread of their own.
    let upgrader = {
        let name = sys.sut.name().to_owned();
        std::thread::spawn(move || {
            let mut outcomes = Vec::new();
            std::thread::sleep(Duration::from_millis(300));
            for _ in 0..20 {
                let out = Command::new(bin("modbot"))
                    .args(["upgrade", "target", "--domain", &name])
                    .output()
                    .unwrap();
                outcomes.push((
                    out.status.code(),
                    String::from_utf8_lossy(&out.stdout).into_owned()
                        + &String::from_utf8_lossy(&out.stderr),
                ));
                std::thread::sleep(Duration::from_millis(100));
            }
            outcomes
        })
    };
    // 1 000 calls a second until the upgrades are done, and 200 ms more.
    let mut next = Instant::now();
    let mut seq: i64 = 0;
    let mut held_back = 0u64;
    let mut finished_at = None;
    loop {
        let now = Instant::now();
        if now >= next {
            let sent = caller
                .ctx()
                .call_with("target", "record", &[Value::I64(seq + 1)], opts);
            match sent {
                Ok(h) => {
                    seq += 1;
                    caller.state_mut().answers.push(Vec::new());
                    caller.state_mut().seq_of.insert(h.id(), seq);
                }
                // 32 calls wait for the module already (a loaded machine held it up): this
                // one is not sent, and goes out at the next millisecond.
                Err(CallError::TooManyOutstanding(_)) => held_back += 1,
                Err(e) => {
                    seq += 1;
                    caller.state_mut().answers.push(vec![Err(e.to_string())]);
                }
            }
            next += Duration::from_millis(1);
        }
        while caller.poll_once().unwrap() {}
        caller.housekeeping();
        if upgrader.is_finished() && finished_at.is_none() {
            finished_at = Some(Instant::now());
        }
        if finished_at.is_some_and(|t| t.elapsed() > Duration::from_millis(200)) {
            break;
        }
        caller
            .wait_for_frame(next.saturating_duration_since(Instant::now()))
            .unwrap();
    }
    let outcomes = upgrader.join().unwrap();
    // Every call's answer (or its deadline) comes.
    let deadline = Instant::now() + Duration::from_secs(30);
    while !caller.state().seq_of.is_empty() && Instant::now() < deadline {
        while caller.poll_once().unwrap() {}
        caller.housekeeping();
        caller.wait_for_frame(Duration::from_millis(5)).unwrap();
    }
    let ledger = caller.state();
    let log = sys.sut.output_of(sys.up);
    for (i, (code, out)) in outcomes.iter().enumerate() {
        assert_eq!(*code, Some(0), "upgrade {}: {out}\n{log}", i + 1);
    }
    let wrong: Vec<(i64, &Vec<Result<i64, String>>)> = (1..=seq)
        .map(|s| (s, &ledger.answers[s as usize]))
        .filter(|(s, a)| a.as_slice() != [Ok(*s)])
        .collect();
    let mut kinds: HashMap<String, (usize, i64)> = HashMap::new();
    for (s, a) in &wrong {
        let k = format!("{a:?}");
        let k: String = k.chars().filter(|c| !c.is_ascii_digit()).take(80).collect();
        kinds.entry(k).or_insert((0, *s)).0 += 1;
    }
    assert!(
        wrong.is_empty(),
        "{kinds:?}\n{} of {seq} calls not answered exactly once with their number; the first: {:?}\n{log}",
        wrong.len(),
        &wrong[..wrong.len().min(5)]
    );
    // Executed exactly once each, across 21 processes.
    let journal = std::fs::read_to_string(&sys.journal).unwrap();
    let mut executed = vec![0u32; seq as usize + 1];
    for line in journal.lines() {
        executed[line.parse::<usize>().unwrap()] += 1;
    }
    let twice: Vec<usize> = (1..=seq as usize).filter(|&s| executed[s] != 1).collect();
    assert!(
        twice.is_empty(),
        "calls not executed exactly once: {:?}",
        &twice[..twice.len().min(10)]
    );
    let latency = &caller.ctx().stats().latency;
    eprintln!(
        "{seq} calls ({held_back} held back a millisecond: 32 outstanding), 20 upgrades; \
         latency p50 {} µs, p99 {} µs, max {} µs",
        latency.percentile(50.0) / 1000,
        latency.percentile(99.0) / 1000,
        latency.max() / 1000
    );
    drop(caller);
    // The state hooks counted every upgrade; the supervisor too.
    assert_eq!(sys.bb("upgrades"), "20");
    assert_eq!(
        sys.sut.ls_field("target", "UPGRADES").as_deref(),
        Some("20")
    );
    // One more, with no call coming: the blackboard's last value is carried into a process
    // that never executed `record`.
    let before = sys.pid();
    let (code, out, err) = sys.upgrade(&[]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert_ne!(sys.pid(), before);
    assert_eq!(sys.bb("recorded"), seq.to_string());
    assert_eq!(sys.bb("upgrades"), "21");
    sys.stop();
}

/// A new program that ends at start is refused with its exit status, and the running process
/// serves on; so is one whose method table differs, unless forced; a deactivated module stays
/// deactivated.
#[test]
fn a_new_program_that_exits_at_start_or_has_other_methods_is_refused_and_the_old_one_serves_on() {
    let mut sys = System::start("uprefuse");
    assert_eq!(sys.call("target.ping"), "2");
    let pid = sys.pid();

    // Only the supervisor may make a module hand over.
    let out = sys
        .sut
        .modbot(&["call", "target.upgrade_out", "/tmp", "ping", "true"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("the supervisor's"),
        "{err}"
    );

    let failing = sys.script("failing", "echo 'cannot read the calibration' >&2\nexit 3");
    let (code, _, err) = sys.upgrade(&["--program", failing.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("ended before it took over (exit 3)") && err.contains("serves on"),
        "{err}"
    );
    assert_eq!(sys.pid(), pid);
    assert_eq!(sys.call("target.ping"), "3");

    let other = sys.script(
        "other",
        &format!(
            "exec {} --without-method spam \"$@\"",
            bin("modbot-faulty").display()
        ),
    );
    let (code, _, err) = sys.upgrade(&["--program", other.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("methods differ") && err.contains("it lacks spam"),
        "{err}"
    );
    assert_eq!(sys.pid(), pid);
    assert_eq!(sys.call("target.ping"), "4");
    assert_eq!(sys.sut.ls_field("target", "UPGRADES").as_deref(), Some("0"));

    // Forced, it is taken; its state (the pings) continues.
    let (code, out, err) = sys.upgrade(&["--program", other.to_str().unwrap(), "--force"]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert_ne!(sys.pid(), pid);
    assert_eq!(sys.call("target.ping"), "5");
    let methods = sys.sut.ls_field("target", "METHODS").unwrap();
    assert!(!methods.contains("spam"), "{methods}");

    // A module the operator deactivated stays deactivated across an upgrade.
    sys.sut.modbot_ok(&["deactivate", "target"]);
    let (code, out, err) = sys.upgrade(&["--program", other.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert_eq!(
        sys.sut.ls_field("target", "STATE").as_deref(),
        Some("deactivated")
    );
    sys.sut.modbot_ok(&["activate", "target"]);
    assert_eq!(sys.call("target.ping"), "6");
    let _ = std::fs::remove_file(failing);
    let _ = std::fs::remove_file(other);
    sys.stop();
}

/// `modbot up FILE --lockstep --record X …` in `sut`'s domain (the description's `--var
/// domain` too, so its assembly data is the test's): exits 0; its recording and output.
fn recorded(
    sut: &mut TestDomain,
    file: &std::path::Path,
    tag: &str,
    more: &[&str],
) -> (PathBuf, String) {
    let recording = std::env::temp_dir().join(format!("{}.{tag}.h5", sut.name()));
    let _ = std::fs::remove_file(&recording);
    sut.remove_at_end(recording.clone());
    let domain = format!("domain={}", sut.name());
    let mut args = vec!["up", file.to_str().unwrap(), "--var", &domain, "--record"];
    args.push(recording.to_str().unwrap());
    args.extend_from_slice(&["--lockstep", "--ticks", "3000"]);
    args.extend_from_slice(more);
    let up = sut.spawn_logged("modbot", &args);
    let status = sut.wait_exit(up, Duration::from_secs(300));
    let out = sut.output_of(up);
    assert_eq!(status.code(), Some(0), "{out}");
    (recording, out)
}

/// A host of the time grid upgraded live (`--upgrade TICK:HOST`, as `modbot upgrade
/// host_ctrl_g2` does it): the arm's `ptp` assembly moves the robot from A to B from tick 356,
/// and its host `ctrl` is replaced by a new process at tick 900 mid-motion and again at 1400
/// (braking into B). The components' state is carried to the bit, so the lockstep recording
/// is identical to a run without the upgrades — every signal and the grid's state hash in every
/// row — and no tick is missed. The KR 16's `ptp_ff` host (a setpoint, ptp, Bessel filters,
/// the elastic joints' feed-forward, the cascade's integrators, the monitor, the settle
/// measurement) is upgraded mid-motion the same way, to the same effect. A host whose
/// components cannot carry their state (a type of the user's own without `carry`) is refused:
/// the running process serves on and the run is again the same as one without.
#[test]
fn a_grid_host_upgraded_twice_during_a_ptp_motion_in_lockstep_records_the_same_as_a_run_without() {
    let _arm = common::arm::one_arm_at_a_time();
    let mut sut = TestDomain::new("upgrid");
    let arm = common::arm::arm();
    let plan = ["--var", "dwell=0", "--switch", "300:ptp"];
    let (a, _) = recorded(&mut sut, &arm, "plain", &plan);
    let mut upgraded: Vec<&str> = plan.to_vec();
    upgraded.extend_from_slice(&["--upgrade", "900:ctrl", "--upgrade", "1400:ctrl"]);
    let (b, out) = recorded(&mut sut, &arm, "upgraded", &upgraded);
    for at in [900, 1400] {
        assert!(
            out.contains(&format!(
                "host ctrl: took the components over at tick {at} ("
            )),
            "{out}"
        );
    }
    assert!(out.contains("host_ctrl_g2 upgraded: pid "), "{out}");
    assert!(out.contains(", upgrade 2, in "), "{out}");
    assert!(!out.contains("refused"), "{out}");
    let (code, said) = sut.record_compare(&a, &b);
    assert_eq!(code, Some(0), "{said}\n{out}");
    assert!(
        said.starts_with("identical through tick 2999 (3000 rows, "),
        "{said}"
    );
    // The robot moved through both handovers: the upgrades were mid-motion.
    let moving = common::python::python(
        "import sys, h5py\nf = h5py.File(sys.argv[1], 'r')\nq = f['robot.demand_position']\n\
         t = list(f['tick'])\nat = lambda n: q[t.index(n)][0]\n\
         print(at(899) != at(901), at(1399) != at(1401))",
        &[a.to_str().unwrap()],
    );
    assert_eq!(moving.trim(), "True True", "{moving}");

    // The KR 16's feed-forward assembly, every one of its control types carried, moving to a
    // goal of its own (a copy of the example whose `ptp_ff.q` default is not where it stands).
    let examples = arm.parent().unwrap();
    let copy = std::env::temp_dir().join(format!("{}.kr16", sut.name()));
    sut.remove_at_end(copy.clone());
    std::fs::create_dir_all(copy.join("kr16")).unwrap();
    std::fs::copy(examples.join("kr16.lua"), copy.join("kr16.lua")).unwrap();
    for entry in std::fs::read_dir(examples.join("kr16")).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        let moved = text.replace(
            "data(\"ptp_ff.q\") or { 0, 0, 0, 0, 0, 0 }",
            "data(\"ptp_ff.q\") or { 0.3, -0.2, 0.25, 0, 0, 0 }",
        );
        std::fs::write(copy.join("kr16").join(path.file_name().unwrap()), moved).unwrap();
    }
    let kr16 = copy.join("kr16.lua");
    let plan = ["--switch", "300:ptp_ff"];
    let (c, _) = recorded(&mut sut, &kr16, "kr16", &plan);
    let mut upgraded: Vec<&str> = plan.to_vec();
    upgraded.extend_from_slice(&["--upgrade", "900:ctrl"]);
    let (d, out) = recorded(&mut sut, &kr16, "kr16upgraded", &upgraded);
    assert!(
        out.contains("host ctrl: took the components over at tick 900 ("),
        "{out}"
    );
    assert!(!out.contains("refused"), "{out}");
    let (code, said) = sut.record_compare(&c, &d);
    assert_eq!(code, Some(0), "{said}\n{out}");
    let moving = common::python::python(
        "import sys, h5py\nf = h5py.File(sys.argv[1], 'r')\nq = f['robot.demand_position']\n\
         t = list(f['tick'])\nprint(q[t.index(899)][0] != q[t.index(901)][0])",
        &[c.to_str().unwrap()],
    );
    assert_eq!(
        moving.trim(),
        "True",
        "the KR 16 moved through the handover: {moving}"
    );

    // A host that cannot carry its components' state is refused; the run goes on unchanged.
    let limited =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/first_component/limited.lua");
    let (plain, _) = sut.traced_up(&limited, 1000, &["--lockstep"], "limited");
    let (refused, out) = sut.traced_up(
        &limited,
        1000,
        &["--lockstep", "--upgrade", "500:h_limit"],
        "limitedrefused",
    );
    assert!(
        out.contains("component 'limit' cannot carry its state to a new process"),
        "{out}"
    );
    assert!(
        out.contains("upgrade of host_h_limit refused: the new program ended before it took over"),
        "{out}"
    );
    assert!(out.contains("the running process serves on"), "{out}");
    let rows = |t: &str| {
        t.lines()
            .filter(|l| !l.starts_with('#'))
            .map(str::to_owned)
            .collect::<Vec<_>>()
    };
    assert_eq!(rows(&refused).len(), 1000, "{refused}");
    assert_eq!(rows(&refused), rows(&plain));
    // The recordings and the copy go with `sut`, whether the test passed or not.
}
