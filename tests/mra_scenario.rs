//! The MRA paper's scenario with real processes: a sonar module and a mobility module, each
//! its own process, in a domain of their own.

mod common;

use std::time::Duration;

use common::TestDomain;
use nix::sys::signal::Signal;

/// The base's speed in the scenarios that drive it, m/s. It runs in real time, and where it
/// stops depends on how quickly the sonar's report reaches it: at a quarter metre a second the
/// 0.11 m between the sonar's threshold and the far end of the range the tests accept is
/// 440 ms of scheduling delay, which no loaded machine gives (at 1 m/s it was 110 ms, of
/// which the sonar's and the base's own periods take 65).
const SPEED: &str = "0.25";

/// An ACK is 3 bytes and an EXEC without arguments 5, and both decode back to their fields;
/// truncated or random bytes exit 2 with a reason.
#[test]
fn frames_have_the_sizes_of_the_paper_and_decode_back() {
    let sut = TestDomain::new("frames");
    let ack = sut.modbot_ok(&[
        "rvmf", "encode", "ack", "--dst", "3", "--src", "1", "--seq", "5",
    ]);
    assert_eq!(ack.trim().len(), 6, "3 bytes: {ack}");
    let exec = sut.modbot_ok(&[
        "rvmf", "encode", "exec", "--dst", "3", "--src", "1", "--seq", "5", "--method", "7",
    ]);
    assert_eq!(exec.trim().len(), 10, "5 bytes: {exec}");
    let fields = sut.modbot_ok(&["rvmf", "decode", exec.trim()]);
    for line in ["kind: exec", "dst: 3", "src: 1", "seq: 5", "method: 7"] {
        assert!(fields.contains(line), "{line} missing in {fields}");
    }
    let fields = sut.modbot_ok(&["rvmf", "decode", ack.trim()]);
    assert!(
        fields.contains("kind: ack") && fields.contains("seq: 5"),
        "{fields}"
    );
    for bad in ["0301", "03012502", "ffffffffffffffff", "zz", "0301e5"] {
        let out = sut.modbot(&["rvmf", "decode", bad]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
        let reason = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            reason.lines().count(),
            1,
            "one-line reason for {bad}: {reason}"
        );
    }
}

/// `encode` prints only frames a receiver accepts: an operand or payload the kind does not
/// carry, a missing operand, a sequence number beyond 5 bits, an address a receiver refuses, or
/// a payload that is not a sequence of values, is refused with the reason (exit 2).
#[test]
fn the_encoder_refuses_what_the_kind_does_not_carry_and_payloads_a_receiver_rejects() {
    let sut = TestDomain::new("encode_refusals");
    let frame = |extra: &[&str]| {
        let mut args = vec!["rvmf", "encode"];
        args.extend_from_slice(extra);
        for (opt, default) in [("--dst", "3"), ("--src", "1")] {
            if !extra.contains(&opt) {
                args.extend_from_slice(&[opt, default]);
            }
        }
        sut.modbot(&args)
    };
    for (extra, why) in [
        (&["ack", "--method", "1"][..], "leave out --method"),
        (&["reply", "--method", "1"][..], "leave out --method"),
        (&["ack", "--payload", "01"][..], "leave out --payload"),
        (
            &["reply", "--payload", "c1"][..],
            "not a sequence of values",
        ),
        (
            &["exec", "--method", "2", "--payload", "92"][..],
            "not a sequence of values",
        ),
        (&["exec"][..], "--method is required for exec"),
        (&["exec", "--method", "2", "--seq", "32"][..], "0..=31"),
        (
            &["exec", "--method", "2", "--src", "0"][..],
            "source address 0 is not a module address",
        ),
        (
            &["reply", "--dst", "0"][..],
            "destination address 0 is reserved",
        ),
    ] {
        let out = frame(extra);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(out.stdout.is_empty(), "{extra:?} printed a frame");
        assert!(
            stderr.contains(why) && stderr.lines().count() == 1,
            "{extra:?}: {stderr}"
        );
    }
    let reply = frame(&["reply", "--payload", "01"]);
    assert!(reply.status.success(), "a valid payload is encoded");
}

/// `decode -` reads the frame from standard input, as hex text or raw bytes, also a frame too
/// large for a command-line argument (an argument holds at most 128 KiB of hex).
#[test]
fn a_frame_decodes_from_standard_input_as_hex_or_raw_bytes_whatever_its_size() {
    use modbot_ipc_schema::{Addr, FrameKind, FrameSpec, Seq};
    use std::io::Write;
    use std::process::{Command, Stdio};
    // A REPLY whose one value is a 100 000-byte bin 32: c6, the length, the bytes.
    let mut payload = vec![0xc6];
    payload.extend_from_slice(&100_000u32.to_be_bytes());
    payload.extend(std::iter::repeat_n(0xab, 100_000));
    let spec = FrameSpec {
        dst: Addr(3),
        src: Addr(1),
        seq: Seq::new(4).unwrap(),
        kind: FrameKind::Reply,
    };
    let mut frame = vec![0; spec.encoded_len(payload.len())];
    spec.encode(&payload, &mut frame).unwrap();
    let hex: String = frame.iter().map(|b| format!("{b:02x}")).collect();
    let decode = |input: &[u8]| {
        let mut child = Command::new(common::bin("modbot"))
            .args(["rvmf", "decode", "-"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        child.stdin.take().unwrap().write_all(input).unwrap();
        child.wait_with_output().unwrap()
    };
    for (what, input) in [
        ("raw", frame.clone()),
        ("hex", format!("{hex}\n").into_bytes()),
    ] {
        let out = decode(&input);
        let fields = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{what}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        for line in [
            "kind: reply",
            "dst: 3",
            "src: 1",
            "seq: 4",
            "(extended form)",
            "value[0]: bytes",
        ] {
            assert!(
                fields.contains(line),
                "{what}: {line} missing in {:.300}",
                fields
            );
        }
    }
    let out = decode(&frame[..frame.len() - 1]);
    assert_eq!(out.status.code(), Some(2), "a truncated frame is malformed");
}

fn bb_f64(sut: &TestDomain, module: &str, item: &str) -> f64 {
    sut.modbot_ok(&["bb", module, item]).trim().parse().unwrap()
}

/// `forward 10` stops short of the obstacle at x = 3 because the sonar reports within 0.61 m.
#[test]
fn the_base_stops_short_of_the_obstacle_when_the_sonar_reports() {
    let mut sut = TestDomain::new("stops");
    let sonar = sut.spawn("modbot-sonar", &["--obstacle", "3,0", "--obstacle", "5,5"]);
    let mobility = sut.spawn("modbot-mobility", &["--speed", SPEED]);
    sut.wait_for("both modules in ls", Duration::from_secs(30), || {
        let ls = String::from_utf8_lossy(&sut.modbot(&["ls"]).stdout).to_string();
        let listed = |name: &str, pid: u32| {
            ls.lines()
                .any(|l| l.contains(name) && l.contains(&pid.to_string()) && l.contains("alive"))
        };
        listed(" sonar ", sonar) && listed(" mobility ", mobility)
    });
    assert_eq!(
        sut.modbot_ok(&["call", "mobility.forward", "10"]).trim(),
        "1",
        "the first motion command"
    );
    sut.wait_for("the base to stop", Duration::from_secs(60), || {
        sut.modbot_ok(&["bb", "mobility", "moving"]).trim() == "false"
    });
    let x = bb_f64(&sut, "mobility", "x");
    assert!((2.3..=2.5).contains(&x), "stopped at x = {x}");
    let snapshot = sut.modbot_ok(&["bb", "mobility"]);
    assert!(
        snapshot.contains("x: ") && snapshot.contains("heading: 0.0"),
        "{snapshot}"
    );
    sut.stop_all_cleanly();
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// A SIGKILLed sonar stops being listed as alive (its process is gone: no timeout to wait
/// out), calls to it fail with "not available", a restarted sonar answers again, and a clean
/// exit leaves no files behind.
#[test]
fn a_killed_module_is_not_available_until_it_is_restarted() {
    let mut sut = TestDomain::new("killed");
    let sonar = sut.spawn("modbot-sonar", &["--obstacle", "3,0"]);
    sut.spawn("modbot-mobility", &[]);
    sut.wait_for("the sonar to answer", Duration::from_secs(30), || {
        sut.modbot(&["call", "sonar.ranges"]).status.success()
    });

    sut.signal(sonar, Signal::SIGKILL);
    sut.reap(sonar);
    let killed = std::time::Instant::now();
    sut.wait_for(
        "ls to stop listing the sonar as alive",
        Duration::from_secs(30),
        || {
            !sut.modbot_ok(&["ls"])
                .lines()
                .any(|l| l.contains(" sonar ") && l.contains("alive"))
        },
    );
    println!(
        "the killed sonar was listed dead {:?} after",
        killed.elapsed()
    );
    let out = sut.modbot(&["call", "sonar.ranges"]);
    assert_eq!(out.status.code(), Some(1));
    let reason = String::from_utf8_lossy(&out.stderr);
    assert!(reason.contains("not available"), "{reason}");

    sut.spawn("modbot-sonar", &["--obstacle", "3,0"]);
    sut.wait_for(
        "the restarted sonar to answer",
        Duration::from_secs(30),
        || sut.modbot(&["call", "sonar.ranges"]).status.success(),
    );
    let ranges = sut.modbot_ok(&["call", "sonar.ranges"]);
    assert!(
        ranges.trim().starts_with('[') && ranges.matches(',').count() == 11,
        "{ranges}"
    );

    sut.stop_all_cleanly();
    assert_eq!(sut.leftover_files(), Vec::<std::path::PathBuf>::new());
}

/// Bad calls get clear, typed answers and never take the module down.
#[test]
fn bad_calls_get_clear_errors() {
    let mut sut = TestDomain::new("badcalls");
    sut.spawn("modbot-sonar", &[]);
    sut.wait_for("the sonar to answer", Duration::from_secs(30), || {
        sut.modbot(&["call", "sonar.ranges"]).status.success()
    });
    let cases: &[(&[&str], &str)] = &[
        (&["call", "sonar.fly"], "has no method 'fly'"),
        (
            &["call", "sonar.monitor", "north"],
            "argument 0 is text, expected f64",
        ),
        (&["call", "sonar.monitor", "-1"], "threshold must be"),
        (&["call", "nobody.ranges"], "not available"),
        (&["bb", "sonar", "ranges", "1.0"], "read-only"),
        (
            &["bb", "sonar", "nothing"],
            "no blackboard item named 'nothing'",
        ),
    ];
    for (args, want) in cases {
        let out = sut.modbot(args);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let text = String::from_utf8_lossy(&out.stderr);
        assert!(text.contains(want), "{args:?}: {text}");
    }
    assert_eq!(
        sut.modbot_ok(&["bb", "sonar", "air_temp_c", "30"]).trim(),
        "ok"
    );
    assert_eq!(sut.modbot_ok(&["bb", "sonar", "air_temp_c"]).trim(), "30.0");
    // Options may follow a call's arguments: `--domain` and `--timeout-ms` are options here,
    // not three more arguments (a negative number is an argument: `-1` above).
    let out = sut.modbot(&[
        "call",
        "sonar.monitor",
        "-1",
        "--domain",
        sut.name(),
        "--timeout-ms",
        "60000",
    ]);
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(text.contains("threshold must be"), "{text}");
    sut.stop_all_cleanly();
}
