//! Fault injection under `modbot up`, with real processes: every test runs its own system (its
//! own domain and description), kills, stops or starves real module processes, and checks that
//! nothing of the domain is left in /dev/shm or iceoryx2's folders afterwards.

mod common;

use std::time::{Duration, Instant};

use common::TestDomain;
use nix::sys::signal::Signal;

/// Supervision settings for the tests: modules beat every 50 ms, and one silent for 5 s is
/// judged hung (quick enough for the hang test, and far beyond any pause a loaded machine gives
/// a module, so no other test sees a module killed as hung); a module has 10 s to stop.
const FAST: &str = r#"
supervision { heartbeat_timeout = tonumber(vars.hb or "5"), heartbeat_period = 0.05, start_timeout = 20, stop_grace = 10 }
"#;

/// Starts `modbot up` on `body` and waits until every module in `modules` runs.
fn start_up(sut: &mut TestDomain, body: &str, modules: &[&str]) -> u32 {
    start_up_with(sut, body, modules, &[])
}

/// [`start_up`] with more arguments for `modbot up` (`--var`, say).
fn start_up_with(sut: &mut TestDomain, body: &str, modules: &[&str], more: &[&str]) -> u32 {
    let file = sut.write_system(&format!("{FAST}{body}"));
    let mut args = vec!["up", file.to_str().unwrap()];
    args.extend_from_slice(more);
    let up = sut.spawn_logged("modbot", &args);
    let start = Instant::now();
    while !modules
        .iter()
        .all(|m| sut.ls_field(m, "STATE").as_deref() == Some("running"))
    {
        let ended = sut.exited(up);
        assert!(
            ended.is_none() && start.elapsed() < Duration::from_secs(60),
            "the system did not come up ({ended:?}); modbot up printed:\n{}\nfiles of the domain: {:?}\nmodbot ls:\n{}\nsupervisor.status: {}",
            sut.output_of(up),
            sut.leftover_files(),
            String::from_utf8_lossy(&sut.modbot(&["ls"]).stdout),
            {
                let out = std::process::Command::new(common::bin("modbot"))
                    .args(["call", "supervisor.status"])
                    .env("MODBOT_DOMAIN", sut.name())
                    .env("RUST_LOG", "debug")
                    .output()
                    .unwrap();
                String::from_utf8_lossy(&out.stderr).into_owned()
            }
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    up
}

/// Stops `modbot up` with SIGTERM; returns its exit code and output, and checks the domain is
/// clean.
fn stop(sut: &mut TestDomain, up: u32) -> (i32, String) {
    sut.signal(up, Signal::SIGTERM);
    let status = sut.wait_exit(up, Duration::from_secs(30));
    let output = sut.output_of(up);
    assert_eq!(
        sut.leftover_files(),
        Vec::<std::path::PathBuf>::new(),
        "files left behind; output:\n{output}"
    );
    (status.code().unwrap_or(-1), output)
}

fn pid_of(sut: &TestDomain, module: &str) -> u32 {
    let pid = sut.ls_field(module, "PID").expect("listed");
    pid.parse()
        .unwrap_or_else(|_| panic!("{module} has no pid: {pid}"))
}

fn restarts_of(sut: &TestDomain, module: &str) -> u32 {
    sut.ls_field(module, "RESTARTS")
        .and_then(|r| r.parse().ok())
        .unwrap_or(0)
}

fn is_gone(pid: u32) -> bool {
    // A zombie (killed, not reaped yet by whoever inherited it) counts as gone.
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Err(_) => true,
        Ok(stat) => stat
            .rsplit_once(')')
            .is_some_and(|(_, rest)| rest.trim_start().starts_with('Z')),
    }
}

const MRA: &str = r#"
module "sonar" { addr = 2, program = "modbot-sonar", args = { "--obstacle", "3,0" } }
module "mobility" { addr = 3, program = "modbot-mobility" }
"#;

/// SIGKILL of a module under the default policy (on-failure, 100 ms backoff): it comes back
/// with its address, `modbot ls` shows one restart and the signal, it answers again, and its
/// peer kept answering throughout.
#[test]
fn a_killed_module_is_restarted_and_answers_again_while_its_peer_keeps_working() {
    let mut sut = TestDomain::new("killedsup");
    let up = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    let sonar = pid_of(&sut, "sonar");

    sut.signal(sonar, Signal::SIGKILL);
    let killed = Instant::now();
    sut.modbot_ok(&["call", "mobility.turn", "10"]);
    sut.wait_for("the sonar to answer again", Duration::from_secs(20), || {
        sut.modbot(&["call", "sonar.ranges"]).status.success()
    });
    println!(
        "the killed sonar answered again after {:?}",
        killed.elapsed()
    );
    assert_ne!(pid_of(&sut, "sonar"), sonar, "a new process");
    assert_eq!(restarts_of(&sut, "sonar"), 1);
    assert_eq!(
        sut.ls_field("sonar", "LAST EXIT").as_deref(),
        Some("killed by SIGKILL")
    );
    assert_eq!(
        sut.ls_field("sonar", "ADDR").as_deref(),
        Some("2"),
        "same address"
    );
    assert_eq!(restarts_of(&sut, "mobility"), 0);

    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 0, "{output}");
}

/// While a killed module waits out its backoff, a call fails at once with "not available"
/// — or, if the caller chooses to wait, succeeds when the module is back. (The backoff of
/// 10 s leaves a slow machine the time to look and call while the module is down.)
#[test]
fn calls_to_a_module_that_is_down_fail_clearly_or_wait_for_it_as_the_caller_chooses() {
    let mut sut = TestDomain::new("downcalls");
    let body = r#"
module "sonar" { addr = 2, program = "modbot-sonar", restart = { policy = "on-failure", backoff = 10, max_backoff = 10 } }
module "mobility" { addr = 3, program = "modbot-mobility" }
"#;
    let up = start_up(&mut sut, body, &["sonar", "mobility"]);
    sut.signal(pid_of(&sut, "sonar"), Signal::SIGKILL);
    sut.wait_for(
        "the sonar to be restarting",
        Duration::from_secs(30),
        || sut.ls_field("sonar", "STATE").as_deref() == Some("restarting"),
    );

    let out = sut.modbot(&["call", "sonar.ranges"]);
    assert_eq!(out.status.code(), Some(1));
    let reason = String::from_utf8_lossy(&out.stderr);
    assert!(reason.contains("not available"), "{reason}");

    let waited = sut.modbot(&["call", "sonar.ranges", "--wait", "--timeout-ms", "60000"]);
    assert!(
        waited.status.success(),
        "a waiting call is served once the sonar is back: {}",
        String::from_utf8_lossy(&waited.stderr)
    );
    assert_eq!(restarts_of(&sut, "sonar"), 1);
    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 0, "{output}");
}

/// A module stopped with SIGSTOP stops beating: once silent for the heartbeat timeout it is
/// declared hung, killed and restarted.
#[test]
fn a_stopped_module_is_detected_as_hung_killed_and_restarted() {
    let mut sut = TestDomain::new("hung");
    let up = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    let sonar = pid_of(&sut, "sonar");
    sut.signal(sonar, Signal::SIGSTOP);
    sut.wait_for(
        "the hung sonar to be restarted",
        Duration::from_secs(60),
        || {
            restarts_of(&sut, "sonar") == 1
                && sut.ls_field("sonar", "STATE").as_deref() == Some("running")
        },
    );
    let last = sut.ls_field("sonar", "LAST EXIT").unwrap_or_default();
    assert!(last.starts_with("hung"), "{last}");
    assert!(is_gone(sonar), "the stopped process was killed");
    assert!(sut.modbot(&["call", "sonar.ranges"]).status.success());
    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 0, "{output}");
}

/// A method that works longer than the heartbeat timeout and beats meanwhile
/// (`Ctx::keep_alive`, as the recorder's `stop` while its file closes) is not a hang: it
/// answers, and its module is neither killed nor restarted.
#[test]
fn a_method_that_keeps_alive_while_it_works_past_the_heartbeat_timeout_is_not_judged_hung() {
    let mut sut = TestDomain::new("keep_alive");
    let body = r#"module "worker" { addr = 10, program = "modbot-faulty" }"#;
    let up = start_up_with(&mut sut, body, &["worker"], &["--var", "hb=1"]);
    let worker = pid_of(&sut, "worker");
    let out = sut.modbot_ok(&["call", "worker.work", "3000", "--timeout-ms", "60000"]);
    assert_eq!(out.trim(), "3000", "{out}");
    assert_eq!(restarts_of(&sut, "worker"), 0, "{}", sut.output_of(up));
    assert_eq!(pid_of(&sut, "worker"), worker);
    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 0, "{output}");
}

/// A panic and an exit(1) are restarted under `on-failure`; under `never` the module stays
/// down, and `modbot up` reports it and exits non-zero.
#[test]
fn on_failure_restarts_a_panic_and_an_exit_but_never_leaves_the_module_down() {
    let mut sut = TestDomain::new("policies");
    let body = r#"
module "fragile" { addr = 10, program = "modbot-faulty", restart = "on-failure" }
module "once" { addr = 11, program = "modbot-faulty", restart = "never" }
"#;
    let up = start_up(&mut sut, body, &["fragile", "once"]);

    sut.modbot_ok(&["call", "fragile.panic"]);
    sut.wait_for(
        "the panicked module to be back",
        Duration::from_secs(20),
        || {
            restarts_of(&sut, "fragile") == 1
                && sut.modbot(&["call", "fragile.ping"]).status.success()
        },
    );
    assert_eq!(
        sut.ls_field("fragile", "LAST EXIT").as_deref(),
        Some("exit 101")
    );

    sut.modbot_ok(&["call", "fragile.exit", "1"]);
    sut.wait_for(
        "the exited module to be back",
        Duration::from_secs(20),
        || {
            restarts_of(&sut, "fragile") == 2
                && sut.modbot(&["call", "fragile.ping"]).status.success()
        },
    );
    assert_eq!(
        sut.ls_field("fragile", "LAST EXIT").as_deref(),
        Some("exit 1")
    );

    sut.modbot_ok(&["call", "once.exit", "1"]);
    sut.wait_for(
        "the `never` module to be down",
        Duration::from_secs(30),
        || sut.ls_field("once", "STATE").as_deref() == Some("down"),
    );
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(restarts_of(&sut, "once"), 0, "never is never restarted");
    assert!(sut.modbot(&["call", "fragile.ping"]).status.success());

    let (code, output) = stop(&mut sut, up);
    assert_eq!(
        code, 1,
        "a module down against its will fails the run:\n{output}"
    );
    assert!(output.contains("once: exit 1, not restarted"), "{output}");
}

/// A module that ends more often than its maximum within the window is failed; with
/// `keep-others` the rest of the system goes on, with `stop-system` the supervisor stops.
#[test]
fn more_restarts_than_the_maximum_fail_the_module_and_stop_the_system_only_if_configured() {
    let mut sut = TestDomain::new("giveup");
    let body = r#"
module "flaky" { addr = 10, program = "modbot-faulty",
  restart = { policy = "always", max_restarts = 2, window = 60, backoff = 0.05, give_up = "keep-others" } }
module "steady" { addr = 11, program = "modbot-faulty" }
"#;
    let up = start_up(&mut sut, body, &["flaky", "steady"]);
    // Told to exit until it is given up. (An answer may be lost as it exits, and a call may
    // find it restarting: each exit is asked for until the supervisor says it failed.)
    sut.wait_for("flaky to be failed", Duration::from_secs(60), || {
        if sut.ls_field("flaky", "STATE").as_deref() == Some("failed") {
            return true;
        }
        let _ = sut.modbot(&["call", "flaky.exit", "0"]);
        false
    });
    assert_eq!(
        restarts_of(&sut, "flaky"),
        2,
        "restarted max_restarts times"
    );
    assert!(
        sut.modbot(&["call", "steady.ping"]).status.success(),
        "the rest keeps running"
    );
    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 1, "{output}");
    assert!(output.contains("flaky FAILED"), "{output}");

    let mut sut = TestDomain::new("giveupstop");
    let body = r#"
module "flaky" { addr = 10, program = "modbot-faulty",
  restart = { policy = "always", max_restarts = 1, window = 60, backoff = 0.05, give_up = "stop-system" } }
module "steady" { addr = 11, program = "modbot-faulty" }
"#;
    let up = start_up(&mut sut, body, &["flaky", "steady"]);
    // The answer to `exit` may be lost as the module exits: what counts is the restart.
    let _ = sut.modbot(&["call", "flaky.exit", "0"]);
    sut.wait_for("flaky to be back", Duration::from_secs(20), || {
        restarts_of(&sut, "flaky") == 1 && sut.modbot(&["call", "flaky.ping"]).status.success()
    });
    let _ = sut.modbot(&["call", "flaky.exit", "0"]);
    let status = sut.wait_exit(up, Duration::from_secs(30));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(1), "{output}");
    assert!(output.contains("stopping the system"), "{output}");
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// Garbage frames flooding a module are counted and dropped, and it keeps serving calls.
#[test]
fn a_module_flooded_with_garbage_counts_and_drops_it_and_keeps_serving() {
    let mut sut = TestDomain::new("garbage");
    let body = r#"
module "mobility" { addr = 3, program = "modbot-mobility" }
module "vandal" { addr = 10, program = "modbot-faulty" }
"#;
    let up = start_up(&mut sut, body, &["mobility", "vandal"]);
    let mut delivered = 0;
    for _ in 0..5 {
        let out = sut.modbot_ok(&["call", "vandal.flood", "mobility", "100"]);
        delivered += out.lines().next().unwrap().trim().parse::<u64>().unwrap();
        sut.modbot_ok(&["call", "mobility.turn", "5"]);
    }
    assert!(delivered > 0);
    sut.wait_for(
        "every garbage frame counted",
        Duration::from_secs(30),
        || {
            sut.ls_field("mobility", "REJECT")
                .and_then(|r| r.parse::<u64>().ok())
                == Some(delivered)
        },
    );
    assert_eq!(restarts_of(&sut, "mobility"), 0);
    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 0, "{output}");
}

/// A sender that outpaces a slow receiver is never blocked: frames the full inbox refuses are
/// counted as dropped at the sender, and visible in `modbot ls`.
#[test]
fn a_slow_consumer_does_not_block_its_sender_and_the_loss_is_counted() {
    let mut sut = TestDomain::new("slow");
    let body = r#"
module "consumer" { addr = 10, program = "modbot-faulty", args = { "--slow-ms", "20" } }
module "producer" { addr = 11, program = "modbot-faulty" }
"#;
    // Draining its inbox keeps the consumer busy for over a second at a time: not a hang.
    let up = start_up_with(
        &mut sut,
        body,
        &["consumer", "producer"],
        &["--var", "hb=10"],
    );
    // 500 reports take the consumer 10 s; the call returns long before (its timeout is 2 s).
    let out = sut.modbot_ok(&["call", "producer.spam", "consumer", "500"]);
    let counts: Vec<u64> = out.lines().map(|l| l.trim().parse().unwrap()).collect();
    let (sent, refused) = (counts[0], counts[1]);
    assert_eq!(sent + refused, 500);
    assert!(refused > 0, "the consumer's inbox filled up: {counts:?}");
    sut.wait_for("the loss to be visible", Duration::from_secs(30), || {
        sut.ls_field("producer", "DROPPED")
            .and_then(|d| d.parse::<u64>().ok())
            == Some(refused)
    });
    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 0, "{output}");
}

/// SIGKILLs the supervisor `up` and waits until its `modules` died with it.
fn kill_supervisor(sut: &mut TestDomain, up: u32, modules: &[&str]) {
    let pids: Vec<u32> = modules.iter().map(|m| pid_of(sut, m)).collect();
    sut.signal(up, Signal::SIGKILL);
    sut.wait_exit(up, Duration::from_secs(30));
    let killed = Instant::now();
    sut.wait_for(
        "the modules to die with the supervisor",
        Duration::from_secs(30),
        || pids.iter().all(|&p| is_gone(p)),
    );
    println!("modules gone {:?} after the supervisor", killed.elapsed());
}

/// SIGKILL of the supervisor itself: every module dies with it (the kernel kills them when
/// their parent dies: nothing waits for a timeout), and the next `modbot up` of the same
/// domain starts clean.
#[test]
fn when_the_supervisor_is_killed_its_modules_die_and_the_next_up_starts_clean() {
    let mut sut = TestDomain::new("supkill");
    let first = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    kill_supervisor(&mut sut, first, &["sonar", "mobility"]);

    // `start_up` polls with `modbot ls`: a tool in the domain while the new supervisor sweeps
    // what the killed one left.
    let second = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    assert!(sut.modbot(&["call", "sonar.ranges"]).status.success());
    let (code, output) = stop(&mut sut, second);
    assert_eq!(code, 0, "{output}");
}

/// A tool in the domain while `modbot up` starts again after its supervisor was SIGKILLed —
/// here a `modbot call --wait` started while the system was down, and `modbot ls` polling —
/// holds the directory the dead supervisor published, which iceoryx2 cannot let anyone write
/// again. The new supervisor cleans up after the dead and publishes its own beside it instead
/// of failing to create it ("AlreadyExists"); the waiting call is served by the new system, and
/// nothing is left once it stops.
#[test]
fn a_tool_in_the_domain_does_not_keep_the_next_up_from_starting_after_the_supervisor_was_killed() {
    let mut sut = TestDomain::new("suptool");
    let first = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    kill_supervisor(&mut sut, first, &["sonar", "mobility"]);

    let call = sut.spawn_logged(
        "modbot",
        &["call", "sonar.ranges", "--wait", "--timeout-ms", "120000"],
    );
    // The tool says it is up once it has joined the domain, the directory opened.
    sut.wait_until(
        "the call to wait in the domain",
        Duration::from_secs(60),
        || {
            let log = sut.output_of(call);
            if log.contains("module modbot-cli is up") {
                Ok(())
            } else {
                Err(log)
            }
        },
    );

    let second = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    let status = sut.wait_exit(call, Duration::from_secs(120));
    let answer = sut.output_of(call);
    assert!(status.success(), "the waiting call was served: {answer}");
    let (code, output) = stop(&mut sut, second);
    assert_eq!(code, 0, "{output}");
}

/// `modbot down` stops a running system from another terminal.
#[test]
fn modbot_down_stops_the_system_from_another_terminal() {
    let mut sut = TestDomain::new("down");
    let up = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    let out = sut.modbot_ok(&["down"]);
    assert!(out.contains("is down"), "{out}");
    let status = sut.wait_exit(up, Duration::from_secs(20));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(0), "{output}");
    assert!(output.contains("every module stopped cleanly"), "{output}");
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// A module that never announces itself fails the start with an error naming it, and nothing
/// of the domain is left behind. (The start timeout of 10 s is for the sonar beside it: a real
/// module, which a slow machine must still see announce itself in time.)
#[test]
fn a_module_that_does_not_come_up_fails_the_start_with_its_name() {
    let mut sut = TestDomain::new("nostart");
    let script = std::env::temp_dir().join(format!("{}-lazy.sh", sut.name()));
    std::fs::write(&script, "#!/bin/sh\nexec sleep 60\n").unwrap();
    std::fs::set_permissions(&script, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let body = format!(
        r#"
supervision {{ start_timeout = 10 }}
module "sonar" {{ addr = 2, program = "modbot-sonar" }}
module "lazy" {{ addr = 5, program = "{}" }}
"#,
        script.display()
    );
    let file = sut.write_system(&body);
    let up = sut.spawn_logged("modbot", &["up", file.to_str().unwrap()]);
    let status = sut.wait_exit(up, Duration::from_secs(30));
    let output = sut.output_of(up);
    let _ = std::fs::remove_file(&script);
    assert_eq!(status.code(), Some(1), "{output}");
    assert!(
        output.contains("lazy did not announce themselves within 10000 ms"),
        "{output}"
    );
    assert!(!output.contains("sonar did not"), "{output}");
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// `modbot check` of a broken description names the file and the line, and exits 2.
#[test]
fn modbot_check_names_the_file_and_line_of_a_broken_description() {
    let mut sut = TestDomain::new("check");
    let file = sut.write_system(
        r#"
module "sonar" { addr = 2, program = "modbot-sonar" }
module "sonar2" { addr = 2, program = "modbot-sonar" }
"#,
    );
    let out = sut.modbot(&["check", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    // line 1 is the `domain` line the fixture writes, line 2 is blank
    let want = format!(
        "{}:4: address 2 is already used by 'sonar' (line 3)",
        file.display()
    );
    assert_eq!(err.trim(), want);
}

/// The value of `name` in the environment of process `pid`.
fn env_of(pid: u32, name: &str) -> Option<String> {
    let environ = std::fs::read(format!("/proc/{pid}/environ")).ok()?;
    environ.split(|b| *b == 0).find_map(|var| {
        let var = String::from_utf8_lossy(var);
        let (k, v) = var.split_once('=')?;
        (k == name).then(|| v.to_owned())
    })
}

/// Every module of a system, and a module restarted later, gets the same `MODBOT_EPOCH_NS`
/// (when `modbot up` started, on CLOCK_MONOTONIC), so their simulated clocks agree; a
/// `--var` of `modbot up` reaches the description, here as a module's `MODBOT_SIM_SPEED`.
#[test]
fn every_module_and_every_restart_share_the_systems_epoch_and_vars_reach_the_description() {
    let mut sut = TestDomain::new("epoch");
    let body = r#"
module "sonar" { addr = 2, program = "modbot-sonar", env = { MODBOT_SIM_SPEED = vars.speed or "1" } }
module "mobility" { addr = 3, program = "modbot-mobility" }
"#;
    let up = start_up_with(
        &mut sut,
        body,
        &["sonar", "mobility"],
        &["--var", "speed=3"],
    );
    let sonar = pid_of(&sut, "sonar");
    let epoch = env_of(sonar, "MODBOT_EPOCH_NS").expect("the sonar has an epoch");
    let epoch_ns: u64 = epoch.parse().expect("ns");
    let now = nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC).unwrap();
    let now_ns = now.tv_sec() as u64 * 1_000_000_000 + now.tv_nsec() as u64;
    assert!(
        epoch_ns <= now_ns && now_ns - epoch_ns < 120_000_000_000,
        "an instant of this run on CLOCK_MONOTONIC: {epoch_ns} vs now {now_ns}"
    );
    let mobility = pid_of(&sut, "mobility");
    assert_eq!(env_of(mobility, "MODBOT_EPOCH_NS"), Some(epoch.clone()));
    assert_eq!(env_of(sonar, "MODBOT_SIM_SPEED").as_deref(), Some("3"));
    assert_eq!(env_of(mobility, "MODBOT_SIM_SPEED"), None);

    sut.signal(sonar, Signal::SIGKILL);
    sut.wait_for("the sonar to be back", Duration::from_secs(20), || {
        restarts_of(&sut, "sonar") == 1
            && sut.ls_field("sonar", "STATE").as_deref() == Some("running")
    });
    let restarted = pid_of(&sut, "sonar");
    assert_ne!(restarted, sonar);
    assert_eq!(
        env_of(restarted, "MODBOT_EPOCH_NS"),
        Some(epoch),
        "a restart keeps the system's epoch"
    );

    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 0, "{output}");
}

/// From the command line an operator reads a module's traffic and latency (`stats`), and
/// deactivates it (its methods are refused, `modbot ls` shows it) and activates it again.
#[test]
fn an_operator_reads_stats_and_deactivates_and_activates_a_module_from_the_command_line() {
    let mut sut = TestDomain::new("operator");
    let up = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    sut.modbot_ok(&["call", "sonar.ranges"]);
    let stats = sut.modbot_ok(&["call", "sonar.stats"]);
    for row in [
        "frames sent",
        "frames received",
        "calls",
        "answered",
        "failed",
        "latency",
    ] {
        assert!(stats.contains(row), "no {row} in:\n{stats}");
    }

    assert_eq!(sut.modbot_ok(&["deactivate", "sonar"]).trim(), "ok");
    let refused = sut.modbot(&["call", "sonar.ranges"]);
    assert_eq!(refused.status.code(), Some(1));
    let why = String::from_utf8_lossy(&refused.stderr);
    assert!(
        why.contains("not ready") && why.contains("module 'sonar' is deactivated by the operator"),
        "{why}"
    );
    assert_eq!(
        sut.ls_field("sonar", "STATE").as_deref(),
        Some("deactivated")
    );
    assert_eq!(
        sut.ls_field("mobility", "STATE").as_deref(),
        Some("running")
    );
    sut.modbot_ok(&["call", "sonar.describe"]);

    assert_eq!(sut.modbot_ok(&["call", "sonar.activate"]).trim(), "ok");
    sut.modbot_ok(&["call", "sonar.ranges"]);
    assert_eq!(sut.ls_field("sonar", "STATE").as_deref(), Some("running"));

    let (code, output) = stop(&mut sut, up);
    assert_eq!(code, 0, "{output}");
}

/// `modbot check --var KEY=VALUE` hands the variable to the description; a malformed `--var`
/// is a usage error (exit 2) that says what is wrong.
#[test]
fn modbot_check_takes_variables_and_refuses_a_malformed_one() {
    let mut sut = TestDomain::new("checkvars");
    let file = sut.write_system(
        r#"
module "sonar" { addr = tonumber(vars.addr or "2"), program = "modbot-sonar" }
"#,
    );
    let file = file.to_str().unwrap();
    let out = sut.modbot_ok(&["check", file, "--var", "addr=7"]);
    assert!(out.contains("   7  sonar"), "{out}");
    assert!(out.contains("vars: addr=\"7\""), "{out}");
    for bad in ["addr", "=7"] {
        let out = sut.modbot(&["check", file, "--var", bad]);
        assert_eq!(out.status.code(), Some(2), "--var {bad}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("KEY=VALUE"), "--var {bad}: {err}");
    }
    let out = sut.modbot(&["up", file, "--var", "no-equals"]);
    assert_eq!(out.status.code(), Some(2));
}

/// A module program that refuses its input says why in one line and exits 1, without a
/// backtrace even with RUST_BACKTRACE=1 (these machines set it); so does a module of a system.
#[test]
fn a_refused_start_is_one_line_without_a_backtrace() {
    let out = std::process::Command::new(common::bin("modbot-sonar"))
        .args(["--sensors", "100"])
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(
        stderr.trim_end(),
        "modbot-sonar: --sensors 100: use 1 to 64",
        "{stderr}"
    );
    let mut sut = TestDomain::new("oneline");
    let file = sut.write_system(&format!(
        "{FAST}module \"sonar\" {{ addr = 2, program = \"modbot-sonar\", args = {{ \"--sensors\", \"100\" }}, restart = \"never\" }}\n"
    ));
    let up = sut.spawn_logged("modbot", &["up", file.to_str().unwrap()]);
    sut.wait_exit(up, Duration::from_secs(30));
    let log = sut.output_of(up);
    assert!(
        log.contains("modbot-sonar: --sensors 100: use 1 to 64"),
        "{log}"
    );
    assert!(!log.contains("stack backtrace"), "{log}");
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// The command line and the benchmarks refuse what they cannot do in one line with its
/// causes, without a backtrace even with RUST_BACKTRACE=1: a domain name that is not one, a
/// call into a domain where nothing runs, and a benchmark child role that does not exist.
#[test]
fn the_cli_and_the_benchmarks_refuse_in_one_line_without_a_backtrace() {
    let sut = TestDomain::new("onelinecli");
    let cases: [(&str, Vec<&str>, &str); 3] = [
        (
            "modbot",
            vec!["ls", "--domain", "Not-A-Domain"],
            "invalid domain name 'Not-A-Domain'",
        ),
        (
            "modbot",
            vec!["call", "nobody.ping", "--domain", sut.name()],
            "module 'nobody'",
        ),
        (
            "modbot-benches",
            vec!["child", "no-such-role"],
            "unknown child role 'no-such-role'",
        ),
    ];
    for (program, args, why) in cases {
        let out = std::process::Command::new(common::bin(program))
            .args(&args)
            .env("RUST_BACKTRACE", "1")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{program} {args:?}: {stderr}");
        assert!(
            stderr.contains(why) && stderr.trim_end().lines().count() == 1,
            "{program} {args:?}: one line saying {why:?}, got:\n{stderr}"
        );
    }
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// An operator's console that stays open (here a tool in this test's own process) outlives
/// `modbot up`: the stopping supervisor leaves the files of processes that still live alone, so
/// the console reaches the system that comes up next, and the last process to leave the domain
/// removes what is left.
#[test]
fn a_tool_that_outlives_modbot_up_keeps_its_files_and_reaches_the_next_system() {
    use modbot_core::{CallOptions, IpcTransport, ModuleBuilder};
    let mut sut = TestDomain::new("outlive");
    let first = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    let domain = modbot_core::Domain::new(sut.name()).unwrap();
    let mut console = ModuleBuilder::new("console", 0)
        .open_tool(IpcTransport::new(&domain).unwrap(), ())
        .unwrap();
    let patient = CallOptions::timeout(Duration::from_secs(60)).waiting_for_peer();
    let ranges =
        |console: &mut modbot_core::Module<()>| console.call_owned("sonar", "ranges", &[], patient);
    assert!(ranges(&mut console).is_ok(), "the first system answers");

    sut.signal(first, Signal::SIGTERM);
    let status = sut.wait_exit(first, Duration::from_secs(30));
    assert_eq!(status.code(), Some(0), "{}", sut.output_of(first));
    assert!(
        !sut.leftover_files().is_empty(),
        "the console's files were removed while it runs"
    );

    let second = start_up(&mut sut, MRA, &["sonar", "mobility"]);
    let answer = ranges(&mut console);
    assert!(
        answer.is_ok(),
        "the console reaches the next system: {answer:?}"
    );

    // The system stops before the console: the console, last to leave, removes what is left.
    sut.signal(second, Signal::SIGTERM);
    let status = sut.wait_exit(second, Duration::from_secs(30));
    assert_eq!(status.code(), Some(0), "{}", sut.output_of(second));
    drop(console);
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// Two `modbot up` of one domain started at the same moment: one system runs, the other start
/// is refused with the domain in use (whichever step of the start finds the other supervisor),
/// and the refused one leaves the running system and its files alone.
#[test]
fn two_systems_started_at_once_in_one_domain_run_one_and_refuse_the_other() {
    let mut sut = TestDomain::new("twin");
    let file = sut.write_system(&format!("{FAST}{MRA}"));
    let ups = [
        sut.spawn_logged("modbot", &["up", file.to_str().unwrap()]),
        sut.spawn_logged("modbot", &["up", file.to_str().unwrap()]),
    ];
    // Whichever ends first is the refused one (the other runs until it is stopped).
    let start = Instant::now();
    let refused = loop {
        if let Some(&up) = ups.iter().find(|&&up| sut.exited(up).is_some()) {
            break up;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "neither start ended:\n{}\n{}",
            sut.output_of(ups[0]),
            sut.output_of(ups[1])
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let running = ups.into_iter().find(|&up| up != refused).expect("two");
    let status = sut.wait_exit(refused, Duration::from_secs(10));
    let output = sut.output_of(refused);
    assert_eq!(status.code(), Some(1), "{output}");
    assert!(output.contains("is in use by a running system"), "{output}");

    sut.wait_for("the system to run", Duration::from_secs(60), || {
        ["sonar", "mobility"]
            .iter()
            .all(|m| sut.ls_field(m, "STATE").as_deref() == Some("running"))
    });
    sut.modbot_ok(&["call", "sonar.ranges"]);
    let (code, output) = stop(&mut sut, running);
    assert_eq!(code, 0, "{output}");
    assert!(output.contains("every module stopped cleanly"), "{output}");
}
