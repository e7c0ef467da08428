//! Many modules: a fleet of 64 real processes comes up, answers, and leaves nothing behind;
//! the domain's files grow linearly with its modules; a module started by hand, with no
//! supervisor, still finds and calls the others (the directory scan it falls back to).

mod common;

use std::path::PathBuf;
use std::time::Duration;

use common::TestDomain;

fn fleet() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/fleet.lua"))
}

/// Starts `examples/fleet.lua` with `sensors` sensors and 4 aggregators, and waits until
/// `modbot ls` lists every module running; returns the pid of `modbot up`.
fn start_fleet(sut: &mut TestDomain, sensors: usize) -> u32 {
    let file = fleet();
    let domain = format!("domain={}", sut.name());
    let n = format!("n={sensors}");
    let up = sut.spawn_logged(
        "modbot",
        &["up", file.to_str().unwrap(), "--var", &domain, "--var", &n],
    );
    let total = sensors + 4;
    sut.wait_until(
        "every module of the fleet running",
        Duration::from_secs(60),
        || {
            let out = sut.modbot(&["ls", "--tsv"]);
            let text = String::from_utf8_lossy(&out.stdout);
            let running = text.lines().filter(|l| l.contains("\trunning\t")).count();
            if running == total {
                Ok(())
            } else {
                Err(format!(
                    "{running} of {total} running\n{text}\nmodbot up:\n{}",
                    sut.output_of(up)
                ))
            }
        },
    );
    up
}

/// Stops the fleet with `modbot down` and checks that it ended cleanly and left no file.
fn stop_fleet(sut: &mut TestDomain, up: u32) {
    sut.modbot_ok(&["down"]);
    let status = sut.wait_exit(up, Duration::from_secs(60));
    assert_eq!(status.code(), Some(0), "{}", sut.output_of(up));
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// The sensors each aggregator heard from, by `summary()`.
fn heard(sut: &TestDomain, aggregator: &str) -> usize {
    let out = sut.modbot(&["call", &format!("{aggregator}.summary")]);
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .next()
        .and_then(|l| l.trim().parse().ok())
        .unwrap_or(0)
}

/// 64 module processes come up under `modbot up`, each answers a call, every sensor is heard
/// by its aggregator, and `modbot down` leaves nothing in /dev/shm or the iceoryx2 folder.
#[test]
fn sixty_four_modules_come_up_answer_a_call_each_and_stop_leaving_nothing_behind() {
    let mut sut = TestDomain::new("fleet64");
    let up = start_fleet(&mut sut, 60);
    for i in 1..=60 {
        let out = sut.modbot_ok(&["call", &format!("sensor{i}.read")]);
        let value: f64 = out.trim().parse().unwrap_or(f64::NAN);
        assert!((15.0..=25.0).contains(&value), "sensor{i} read {out:?}");
    }
    for a in 1..=4 {
        let name = format!("agg{a}");
        sut.wait_for(
            &format!("{name} to hear its 15 sensors"),
            Duration::from_secs(30),
            || heard(&sut, &name) == 15,
        );
    }
    stop_fleet(&mut sut, up);
}

/// The number of files a domain holds in /dev/shm and the iceoryx2 folder grows linearly with
/// its modules: per module, 64 modules hold no more files than 16 do (and a little slack).
#[test]
fn the_files_of_a_domain_grow_linearly_with_its_modules() {
    let mut per_module = Vec::new();
    for sensors in [12, 60] {
        let mut sut = TestDomain::new(&format!("files{sensors}"));
        let up = start_fleet(&mut sut, sensors);
        // Every sensor has reached its aggregator (its link is open) before files are counted.
        for a in 1..=4 {
            let name = format!("agg{a}");
            let want = sensors / 4;
            sut.wait_for(
                &format!("{name} to hear {want} sensors"),
                Duration::from_secs(30),
                || heard(&sut, &name) == want,
            );
        }
        let files = sut.leftover_files().len();
        per_module.push((sensors + 4, files));
        stop_fleet(&mut sut, up);
    }
    let [(m16, f16), (m64, f64)] = per_module[..] else {
        unreachable!()
    };
    let (small, large) = (f16 as f64 / m16 as f64, f64 as f64 / m64 as f64);
    println!("{f16} files at {m16} modules, {f64} at {m64}");
    assert!(
        large <= small * 1.15,
        "{f16} files at {m16} modules ({small:.1} each), {f64} at {m64} ({large:.1} each): \
         more than linear"
    );
}

/// Without a supervisor, a sensor started by hand finds its aggregator, started by hand too,
/// and reports to it: the phone book falls back to reading iceoryx2's node directory.
#[test]
fn a_module_started_by_hand_without_a_supervisor_finds_and_calls_the_others() {
    let mut sut = TestDomain::new("byhand");
    let domain = sut.name().to_owned();
    sut.spawn(
        "modbot-fleet",
        &[
            "--domain",
            &domain,
            "--name",
            "agg",
            "--addr",
            "10",
            "aggregator",
        ],
    );
    sut.spawn(
        "modbot-fleet",
        &[
            "--domain",
            &domain,
            "--name",
            "s1",
            "--addr",
            "11",
            "sensor",
            "--aggregator",
            "agg",
            "--period-ms",
            "50",
        ],
    );
    sut.wait_for("agg to hear s1", Duration::from_secs(30), || {
        heard(&sut, "agg") == 1
    });
    let out = sut.modbot_ok(&["call", "s1.read"]);
    assert!(out.trim().parse::<f64>().is_ok(), "{out}");
}
