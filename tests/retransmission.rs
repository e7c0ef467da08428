//! Retransmission with real processes: a request to a module that is stopped (SIGSTOP) is sent
//! again per the caller's retry policy, and when the module resumes it executes the request once
//! and answers the retransmissions from its record.

mod common;

use std::time::Duration;

use common::TestDomain;
use nix::sys::signal::Signal;

/// The sonar's counters from `modbot ls`: (dropped, rejected, replayed).
fn sonar_counters(sut: &TestDomain) -> (u64, u64, u64) {
    let n = |column: &str| {
        let field = sut.ls_field("sonar", column).expect("sonar is listed");
        field
            .parse()
            .unwrap_or_else(|_| panic!("{column}: {field}"))
    };
    (n("DROPPED"), n("REJECT"), n("REPLAY"))
}

/// The mobility module asks the stopped sonar to monitor; the request is retransmitted while the
/// sonar is stopped; once resumed, the sonar serves it once, answers the retransmissions from its
/// record, and its report still stops the base short of the obstacle.
#[test]
fn a_request_to_a_stopped_module_is_retransmitted_and_served_once_when_it_resumes() {
    let mut sut = TestDomain::new("retransmit");
    let sonar = sut.spawn("modbot-sonar", &["--obstacle", "3,0"]);
    // Slow, as in mra_scenario.rs: where the base stops must not depend on scheduling delays.
    sut.spawn("modbot-mobility", &["--speed", "0.25"]);
    sut.wait_for("the sonar to answer", Duration::from_secs(30), || {
        sut.modbot(&["call", "sonar.ranges"]).status.success()
    });
    sut.wait_for(
        "mobility to know the sonar",
        Duration::from_secs(30),
        || sut.modbot(&["call", "mobility.stop"]).status.success(),
    );
    assert_eq!(sonar_counters(&sut).2, 0, "nothing replayed yet");

    sut.signal(sonar, Signal::SIGSTOP);
    assert_eq!(
        sut.modbot_ok(&["call", "mobility.forward", "10"]).trim(),
        "1",
        "the first motion command"
    );
    // mobility's monitor call has a 2 s timeout and 2 retransmissions, at 0.67 s and 1.33 s
    // after `forward` was served. Resumed 1 s after the answer to `forward` came back, the
    // sonar finds the first retransmission beside the request, and the call still has about
    // 1 s before its deadline for the answer to `forward` to come back, this thread to wake
    // and the sonar to answer (waiting 1.5 s left that 0.5 s).
    std::thread::sleep(Duration::from_millis(1000));
    sut.signal(sonar, Signal::SIGCONT);

    sut.wait_for("the base to stop", Duration::from_secs(60), || {
        sut.modbot_ok(&["bb", "mobility", "moving"]).trim() == "false"
    });
    let x: f64 = sut
        .modbot_ok(&["bb", "mobility", "x"])
        .trim()
        .parse()
        .unwrap();
    assert!(
        (2.3..=2.5).contains(&x),
        "the sonar's report stopped the base at x = {x}"
    );
    let (_, rejected, replayed) = sonar_counters(&sut);
    assert!(
        replayed >= 1,
        "the retransmissions were answered from the record, not executed again"
    );
    assert_eq!(rejected, 0);
    sut.stop_all_cleanly();
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}
