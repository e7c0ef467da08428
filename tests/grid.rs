//! The multi-rate time grid across processes: a coordinator and component hosts started by
//! `modbot up`, each test in its own domain. Logical execution time makes every output a
//! function of the tick alone: a run's trace equals the in-process reference, byte for byte.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use common::TestDomain;
use modbot_grid::{reference_trace, reference_trace_with, Overruns};
use modbot_system::{self as system, DefaultResolver};
use nix::sys::signal::Signal;

/// One grid at a time: each is a coordinator and real-time hosts on a 2-core machine.
static ONE_GRID: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_grid() -> std::sync::MutexGuard<'static, ()> {
    ONE_GRID
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn demo() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/grid_demo.lua"
    ))
}

/// Which clock a run's grid keeps.
#[derive(Clone, Copy, PartialEq)]
enum Clock {
    RealTime,
    Lockstep,
}

/// Runs `modbot up FILE --ticks N --trace OUT [--lockstep]` in the test's domain; returns the
/// trace.
fn traced_run(
    sut: &mut TestDomain,
    file: &std::path::Path,
    ticks: u64,
    clock: Clock,
    tag: &str,
) -> String {
    let more: &[&str] = match clock {
        Clock::RealTime => &[],
        Clock::Lockstep => &["--lockstep"],
    };
    sut.traced_up(file, ticks, more, tag).0
}

fn grid_of(file: &std::path::Path, domain: &str) -> modbot_grid::GridSpec {
    let vars = vec![("domain".to_owned(), domain.to_owned())];
    let spec = system::load_with_vars(file, &DefaultResolver::for_file(file), &vars).unwrap();
    spec.grid.unwrap()
}

/// What logical execution time predicts, computed in this process.
fn expected(file: &std::path::Path, domain: &str, ticks: u64) -> String {
    reference_trace(&grid_of(file, domain), &modbot_components::builtin(), ticks)
}

/// Checks a run's trace line by line against the reference run with the overruns the run
/// recorded replayed (none, on a quiet machine): LET plus the hold policy, exactly.
fn assert_trace_is_let(file: &std::path::Path, domain: &str, ticks: u64, trace: &str) -> usize {
    let grid = grid_of(file, domain);
    let overruns = Overruns::from_trace(&grid, trace).unwrap();
    let want =
        reference_trace_with(&grid, &modbot_components::builtin(), ticks, &overruns).unwrap();
    let got: Vec<&str> = trace
        .lines()
        .filter(|l| !l.starts_with("# overrun"))
        .collect();
    assert_eq!(got.len(), want.lines().count(), "one line per tick");
    for (i, (got, exp)) in got.iter().zip(want.lines()).enumerate() {
        assert_eq!(*got, exp, "line {i} of the trace differs from LET");
    }
    overruns.skipped.len()
}

/// 5000 ticks of the demo grid (periods 1, 2, 5, 10 over three hosts) in lockstep: two runs
/// give byte-identical traces, equal to the in-process reference, whatever else the machine
/// does.
#[test]
fn lockstep_traces_of_two_runs_are_byte_identical_and_equal_to_the_reference() {
    let _one = one_grid();
    let mut sut = TestDomain::new("gridlock");
    let first = traced_run(&mut sut, &demo(), 5000, Clock::Lockstep, "a");
    let second = traced_run(&mut sut, &demo(), 5000, Clock::Lockstep, "b");
    assert!(!first.contains("# overrun"), "lockstep has no overruns");
    assert!(first == second, "two runs give byte-identical traces");
    // The grid's state hash at 1000, 2000, 3000, 4000 and the last tick, equal to the
    // reference's: the coordinator combines the hosts' hashes as the reference does.
    let hashes: Vec<&str> = first
        .lines()
        .filter(|l| l.starts_with("# state_hash "))
        .collect();
    assert_eq!(hashes.len(), 5, "{hashes:?}");
    assert!(hashes[4].starts_with("# state_hash tick=4999 hash=0x"));
    let want = expected(&demo(), sut.name(), 5000);
    for (i, (got, exp)) in first.lines().zip(want.lines()).enumerate() {
        assert_eq!(got, exp, "line {i} of the trace differs from the reference");
    }
    assert_eq!(first, want);
}

/// 3000 ticks of the demo grid on the real-time clock: whatever the machine's load did (an
/// overrun, a release not executed because a host was held up), every output at every tick is
/// what LET predicts with those recorded misses replayed — never a value read from another
/// version.
#[test]
fn a_real_time_trace_with_its_overruns_replayed_equals_the_reference_on_every_line() {
    let _one = one_grid();
    let mut sut = TestDomain::new("gridlet");
    let trace = traced_run(&mut sut, &demo(), 3000, Clock::RealTime, "rt");
    let misses = assert_trace_is_let(&demo(), sut.name(), 3000, &trace);
    println!("overruns and stale releases in the run: {misses}");
}

/// A ramp on host `h1` feeding a sleeper `S` of period 10 on host `hs` that never sleeps,
/// feeding a gain on `h1`.
fn sleeper_grid(policy: &str) -> String {
    sleeper_grid_ms(policy, 10, -1, 15)
}

/// The same grid with `S` of `period` ticks sleeping `sleep_ms` at its release at `sleep_at`.
///
/// On the real-time clock a release is late when the machine holds its host up for a period,
/// so the tests that make `S` overrun give it a period of 100 ticks (100 ms: far longer than a
/// loaded machine holds a process up) and a sleep of three periods or more (which a late
/// coordinator does not miss): the overruns they look at are the sleep's.
fn sleeper_grid_ms(policy: &str, period: u64, sleep_at: i64, sleep_ms: i64) -> String {
    format!(
        r#"
supervision {{ heartbeat_timeout = 10, stop_grace = 30 }}
grid {{ base_period = 0.001 }}
component "A" {{ type = "ramp", host = "h1", period = 1 }}
component "S" {{ type = "sleeper", host = "hs", period = {period}, policy = "{policy}",
                params = {{ sleep_ms = {sleep_ms}, sleep_at = {sleep_at} }} }}
component "T" {{ type = "gain", host = "h1", period = 1, params = {{ k = 1 }} }}
connect "A.y -> S.u"
connect "S.y -> T.u"
"#
    )
}

/// The value of `port` at `tick` in a trace.
fn value_at(trace: &str, tick: u64, port: &str) -> String {
    let line = trace
        .lines()
        .find(|l| l.split_whitespace().next() == Some(&tick.to_string()))
        .unwrap_or_else(|| panic!("no tick {tick}"));
    line.split_whitespace()
        .find_map(|kv| kv.strip_prefix(&format!("{port}=")))
        .unwrap_or_else(|| panic!("no {port} in {line}"))
        .to_owned()
}

/// A component that sleeps far past its deadline once (300 ms at its release at 100, at
/// period 100) overruns, and downstream sees its last valid outputs until its next on-time
/// release: the trace equals LET with the recorded overruns replayed, and differs from the
/// run without them.
#[test]
fn a_sleep_past_the_deadline_is_an_overrun_and_downstream_sees_the_held_value() {
    let _one = one_grid();
    let mut sut = TestDomain::new("overrun");
    let file = sut.write_system(&sleeper_grid_ms("hold", 100, 100, 300));
    let trace = traced_run(&mut sut, &file, 600, Clock::RealTime, "hold");
    assert!(
        assert_trace_is_let(&file, sut.name(), 600, &trace) >= 1,
        "the overrun is recorded"
    );
    // S's release at 100 overruns its deadline at 200 (it sleeps 300 ms); at that deadline
    // S.y is held, and the reference without the overrun would have changed it.
    let overrun = trace
        .lines()
        .find(|l| {
            l.starts_with("# overrun") && l.contains("component=S ") && l.ends_with("release=100")
        })
        .unwrap_or_else(|| panic!("no overrun of S's release at 100 in\n{trace}"));
    let tick: u64 = overrun
        .split_whitespace()
        .find_map(|w| w.strip_prefix("tick="))
        .and_then(|t| t.parse().ok())
        .unwrap();
    assert_eq!(tick, 200, "{overrun}");
    assert_eq!(
        value_at(&trace, tick, "S.y"),
        value_at(&trace, tick - 1, "S.y"),
        "held at the missed deadline"
    );
    let reference = expected(&file, sut.name(), 600);
    assert_ne!(
        value_at(&reference, tick, "S.y"),
        value_at(&trace, tick, "S.y"),
        "without the overrun the value would have changed"
    );
}

/// The overrun ledger counts it, seen through `modbot top --once`.
fn top(sut: &TestDomain) -> String {
    String::from_utf8_lossy(&sut.modbot(&["top", "--once"]).stdout).into_owned()
}

fn overruns_of(top: &str, component: &str) -> u64 {
    top.lines()
        .find(|l| l.split_whitespace().next() == Some(component))
        .and_then(|l| l.split_whitespace().nth(5))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no {component} in\n{top}"))
}

fn releases_of(top: &str, component: &str) -> u64 {
    top.lines()
        .find(|l| l.split_whitespace().next() == Some(component))
        .and_then(|l| l.split_whitespace().nth(4))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no {component} in\n{top}"))
}

fn ticks_of(top: &str) -> u64 {
    top.split_whitespace()
        .skip_while(|w| *w != "ticks")
        .nth(1)
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no ticks in\n{top}"))
}

fn start(sut: &mut TestDomain, body: &str) -> u32 {
    start_file(sut, body).0
}

/// [`start`], also giving the description's file.
fn start_file(sut: &mut TestDomain, body: &str) -> (u32, PathBuf) {
    let file = sut.write_system(body);
    let up = sut.spawn_logged("modbot", &["up", file.to_str().unwrap()]);
    let start = std::time::Instant::now();
    loop {
        let t = top(sut);
        if t.contains("ticks") && ticks_of(&t) > 200 {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the grid did not tick; top:\n{t}\nmodbot up:\n{}",
            sut.output_of(up)
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    (up, file)
}

/// A SIGSTOPped host does not stop the tick: the other components keep being released and the
/// stopped one's overruns count up; `modbot top` shows it.
#[test]
fn a_stopped_host_does_not_stop_the_tick_and_its_overruns_count_up() {
    let _one = one_grid();
    let mut sut = TestDomain::new("stophost");
    let up = start(&mut sut, &sleeper_grid("hold"));
    let hs: u32 = sut
        .ls_field("host_hs", "PID")
        .and_then(|p| p.parse().ok())
        .expect("host_hs runs");
    sut.signal(hs, Signal::SIGSTOP);
    let before = top(&sut);
    // How many of T's releases in 300 ticks its host serves in time depends on the machine's
    // load; that they go on does not: waited for, as the tick.
    let mut after = before.clone();
    sut.wait_until(
        "the tick and T's releases to go on",
        Duration::from_secs(60),
        || {
            after = top(&sut);
            if ticks_of(&after) > ticks_of(&before) + 300
                && releases_of(&after, "T") > releases_of(&before, "T") + 200
            {
                Ok(())
            } else {
                Err(format!("{before}\n{after}"))
            }
        },
    );
    sut.signal(hs, Signal::SIGCONT);
    assert!(
        overruns_of(&after, "S") > overruns_of(&before, "S"),
        "{after}"
    );
    assert!(
        after.contains("COMPONENT") && after.contains("EXEC p99"),
        "{after}"
    );
    sut.signal(up, Signal::SIGTERM);
    let status = sut.wait_exit(up, Duration::from_secs(30));
    assert_eq!(status.code(), Some(0), "{}", sut.output_of(up));
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// With the `fault` policy, three deadlines missed in a row fault the grid: it stops
/// releasing and says why (S, of period 100, sleeps 600 ms at its release at 300: its
/// deadlines at 400, 500 and 600 pass).
#[test]
fn three_overruns_in_a_row_under_the_fault_policy_fault_the_grid() {
    let _one = one_grid();
    let mut sut = TestDomain::new("gridfault");
    let up = start(&mut sut, &sleeper_grid_ms("fault", 100, 300, 600));
    sut.wait_for("the grid to fault", Duration::from_secs(60), || {
        top(&sut).contains("faulted")
    });
    let t = top(&sut);
    assert!(
        t.contains("component S overran its deadline at tick 600 (released at 300)"),
        "{t}"
    );
    sut.signal(up, Signal::SIGTERM);
    sut.wait_exit(up, Duration::from_secs(30));
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// A grid description with a type mismatch is refused at load with its file and line.
#[test]
fn a_type_mismatch_is_a_load_error_naming_file_and_line() {
    let mut sut = TestDomain::new("gridload");
    let file = sut.write_system(
        r#"grid {}
component "A" { type = "counter", host = "h1", period = 1 }
component "B" { type = "gain", host = "h2", period = 2, params = { k = 1 } }
connect "A.y -> B.u"
"#,
    );
    let out = sut.modbot(&["check", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with(&format!("{}:5:", file.display())), "{err}");
    assert!(err.contains("i64") && err.contains("f64"), "{err}");
}

/// A host killed and restarted by the supervisor: the releases that died with it are dropped,
/// and its components are released again by the new process.
#[test]
fn a_restarted_host_is_released_again() {
    let _one = one_grid();
    let mut sut = TestDomain::new("hostrestart");
    let up = start(&mut sut, &sleeper_grid("hold"));
    kill_and_wait_for_restart(&mut sut, up, "host_hs");
    let before = releases_of(&top(&sut), "S");
    sut.wait_until("S to be released again", Duration::from_secs(60), || {
        let top = top(&sut);
        if releases_of(&top, "S") > before + 20 {
            Ok(())
        } else {
            Err(format!("{top}\nmodbot up:\n{}", sut.output_of(up)))
        }
    });
    sut.signal(up, Signal::SIGTERM);
    sut.wait_exit(up, Duration::from_secs(30));
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// The description is read once, by `modbot up`: edited while the system runs (a component
/// renamed, a gain changed, a line that fails to load) it changes nothing; a host killed
/// afterwards comes back serving the grid the system started with.
#[test]
fn a_host_restarted_after_the_description_was_edited_serves_the_original_grid() {
    let _one = one_grid();
    let mut sut = TestDomain::new("speconce");
    let body = sleeper_grid("hold");
    let (up, file) = start_file(&mut sut, &body);
    let edited = std::fs::read_to_string(&file)
        .unwrap()
        .replace("\"T\"", "\"U\"")
        .replace("S.y -> T.u", "S.y -> U.u")
        .replace("k = 1", "k = 5")
        + "error('edited after modbot up')\n";
    std::fs::write(&file, edited).unwrap();
    kill_and_wait_for_restart(&mut sut, up, "host_h1");
    let bb = String::from_utf8_lossy(&sut.modbot(&["bb", "host_h1"]).stdout).into_owned();
    assert!(bb.contains("T.y") && !bb.contains("U.y"), "{bb}");
    let before = releases_of(&top(&sut), "T");
    sut.wait_until("T to be released again", Duration::from_secs(60), || {
        let top = top(&sut);
        if releases_of(&top, "T") > before + 20 {
            Ok(())
        } else {
            Err(format!("{top}\nmodbot up:\n{}", sut.output_of(up)))
        }
    });
    sut.signal(up, Signal::SIGTERM);
    sut.wait_exit(up, Duration::from_secs(30));
    // The checked grids went with the domain's other files.
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// SIGKILLs the grid process `module` and waits until the supervisor restarted it and it runs.
fn kill_and_wait_for_restart(sut: &mut TestDomain, up: u32, module: &str) {
    let pid: u32 = sut
        .ls_field(module, "PID")
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("{module} runs"));
    sut.signal(pid, Signal::SIGKILL);
    // Restarted (once, or again if a restart failed under load) and running; what the
    // supervisor said otherwise is in the failure.
    sut.wait_until(
        &format!("{module} to be back"),
        Duration::from_secs(30),
        || {
            let restarts: u32 = sut
                .ls_field(module, "RESTARTS")
                .and_then(|r| r.parse().ok())
                .unwrap_or(0);
            let running = sut.ls_field(module, "STATE").as_deref() == Some("running");
            if restarts >= 1 && running {
                Ok(())
            } else {
                let ls = String::from_utf8_lossy(&sut.modbot(&["ls"]).stdout).into_owned();
                Err(format!("{ls}\nmodbot up:\n{}", sut.output_of(up)))
            }
        },
    );
}

/// `modbot up --lockstep --gate 500`: the grid runs ticks 0..499 and holds before tick 500
/// until the gate's owner moves it. A caller that names its process (`gate(until, pid)`, as a
/// robot program does) owns the gate: the grid runs to 600 and is held there, every release
/// done; another caller is refused while that process lives; once it ends, the gate lifts by
/// itself and the grid runs on. Without `--lockstep` the gate is refused at start.
#[test]
fn a_gated_lockstep_grid_holds_until_its_owner_steps_it_and_runs_on_when_the_owner_ends() {
    let _one = one_grid();
    let mut sut = TestDomain::new("gate");
    let demo = demo();
    let domain = format!("domain={}", sut.name());
    let refused = sut.modbot(&[
        "up",
        demo.to_str().unwrap(),
        "--var",
        &domain,
        "--gate",
        "5",
    ]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "{err}");
    assert!(
        err.contains("--gate holds a grid in lockstep; add --lockstep"),
        "{err}"
    );
    let up = sut.spawn_logged(
        "modbot",
        &[
            "up",
            demo.to_str().unwrap(),
            "--var",
            &domain,
            "--lockstep",
            "--gate",
            "500",
        ],
    );
    sut.wait_for("the grid at tick 500", Duration::from_secs(60), || {
        let t = top(&sut);
        t.contains("ticks") && ticks_of(&t) == 500
    });
    // `modbot top` says why the grid stands.
    sut.wait_for("top saying the gate holds", Duration::from_secs(10), || {
        top(&sut).contains("held by the gate before tick 500")
    });
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(ticks_of(&top(&sut)), 500, "held before tick 500");
    // The owner: a process of the test's, named in the call (killed however the test ends).
    struct Owner(std::process::Child);
    impl Drop for Owner {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let owner = Owner(
        std::process::Command::new("sleep")
            .arg("600")
            .spawn()
            .expect("start sleep"),
    );
    let pid = owner.0.id().to_string();
    let moved = sut.modbot_ok(&["call", "coordinator.gate", "600", &pid]);
    assert!(moved.starts_with("600\n"), "{moved}");
    sut.wait_for("held before tick 600", Duration::from_secs(60), || {
        sut.modbot_ok(&["call", "coordinator.gate", "600", &pid]) == "600\ntrue\n"
    });
    // The ledger `modbot top` shows is refreshed every 200 ms.
    sut.wait_for("the ledger at tick 600", Duration::from_secs(10), || {
        ticks_of(&top(&sut)) == 600
    });
    let other = sut.modbot(&["call", "coordinator.gate", "700"]);
    let err = String::from_utf8_lossy(&other.stderr);
    assert!(!other.status.success(), "{err}");
    assert!(
        err.contains(&format!("busy (3): the grid is stepped by process {pid}")),
        "{err}"
    );
    assert_eq!(ticks_of(&top(&sut)), 600, "a refused caller moved nothing");
    drop(owner);
    sut.wait_for("the grid running on", Duration::from_secs(60), || {
        ticks_of(&top(&sut)) > 700
    });
    sut.modbot_ok(&["down"]);
    sut.wait_exit(up, Duration::from_secs(60));
    let log = sut.output_of(up);
    assert!(
        log.contains("the gate was lifted at tick 600 (its owner (address")
            && log.contains(&format!("pid {pid}) is gone)")),
        "{log}"
    );
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}
