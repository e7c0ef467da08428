//! The data recorder (`record { ... }`, `modbot up --record FILE`) under `modbot up`, each test
//! in a domain of its own, its recordings read back by h5py: a run of the arm opens with its
//! datasets, shapes and attributes; a SIGKILLed recorder leaves a file that opens and misses
//! at most the last 100 ms of what it was given.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::arm::{arm, one_arm_at_a_time};
use common::python::{python, python_file};
use common::TestDomain;
use nix::sys::signal::Signal;

/// A recording file of the test's own, removed on drop (with what a restart wrote beside it).
struct Recording(PathBuf);

impl Recording {
    fn new(sut: &TestDomain) -> Recording {
        Recording(std::env::temp_dir().join(format!("{}.h5", sut.name())))
    }

    fn path(&self) -> &str {
        self.0.to_str().unwrap()
    }

    /// The file a restarted recorder wrote: `NAME.1.h5`.
    fn restarted(&self) -> PathBuf {
        self.0.with_extension("1.h5")
    }
}

impl Drop for Recording {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
        let _ = std::fs::remove_file(self.restarted());
    }
}

/// 10 s of the arm (10 000 ticks of 1 ms, in lockstep), holding and then moving (`ptp` from
/// tick 300), recorded with `--record`: h5py opens the file and finds the tick, time and
/// generation of every tick as (ticks,), each recorded signal as a 2-D dataset of ticks × 6
/// f64 (chunked, growing along the ticks) with its unit, the robot's state (operational once
/// the drives are enabled), the base
/// period and the description's text; the robot moved, within the monitor's following error;
/// and the plot script's numbers come from it.
#[test]
fn ten_seconds_of_the_arm_moving_open_in_h5py_with_datasets_shapes_and_attributes() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("recarm");
    let file = Recording::new(&sut);
    let domain = format!("domain={}", sut.name());
    let arm = arm();
    let args = [
        "up",
        arm.to_str().unwrap(),
        "--var",
        &domain,
        "--var",
        "dwell=0",
        "--lockstep",
        "--ticks",
        "10000",
        "--switch",
        "300:ptp",
        "--record",
        file.path(),
    ];
    let up = sut.spawn_logged("modbot", &args);
    let status = sut.wait_exit(up, Duration::from_secs(300));
    assert_eq!(status.code(), Some(0), "{}", sut.output_of(up));
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
    let checked = python(
        r#"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
signals = ["robot.link_position", "robot.demand_position", "robot.motor_position",
           "robot.motor_velocity", "robot.motor_torque", "robot.statusword"]
assert sorted(f.keys()) == sorted(signals + ["robot.state", "tick", "time", "generation", "state_hash"]), list(f.keys())
# The robot's state: disabled (0) while the drives are enabled, then operational (1) throughout.
state = f["robot.state"][:]
assert state.shape == (10000,) and state[-1] == 1.0 and set(np.unique(state)) <= {0.0, 1.0}, np.unique(state)
tick = f["tick"][:]
assert (tick == np.arange(10000)).all(), (tick[:3], tick[-3:], len(tick))
assert np.allclose(f["time"][:], tick * 0.001, rtol=0, atol=1e-12)
assert f["time"].attrs["unit"] == "s"
for name in ["tick", "time", "generation", "state_hash"]:
    assert f[name].shape == (10000,) and f[name].maxshape == (None,), (name, f[name].shape)
assert f["state_hash"].dtype == np.uint64 and "SipHash-2-4" in f["state_hash"].attrs["hash"]
# The grid's state changes as the robot moves: its hash is not one number.
assert len(np.unique(f["state_hash"][:])) > 1000, len(np.unique(f["state_hash"][:]))
for s in signals:
    d = f[s]
    assert d.shape == (10000, 6) and d.dtype == np.float64, (s, d.shape, d.dtype)
    assert d.maxshape == (None, 6) and d.chunks[1] == 6, (s, d.maxshape, d.chunks)
    assert d.attrs["type"] == "f64[6]"
assert f["robot.link_position"].attrs["unit"] == "rad"
assert f["robot.motor_velocity"].attrs["unit"] == "rad/s"
assert "unit" not in f["robot.statusword"].attrs
assert f.attrs["base_period"] == 0.001 and f.attrs["period"] == 0.001
assert f.attrs["description"] == open(sys.argv[2]).read()
assert f.attrs["description_file"] == sys.argv[2]
g = f["generation"][:]
assert g[0] == 1 and g[-1] == 2 and (np.diff(g) >= 0).all(), np.unique(g)
switch = int(tick[np.argmax(g == 2)])
assert 300 <= switch < 2300, switch
link, demand = f["robot.link_position"][:], f["robot.demand_position"][:]
assert (link.max(axis=0) - link.min(axis=0) > 0.2).all(), "the robot moved"
assert np.abs(demand - link).max() < 0.1, "within the monitor's following error"
print("switch", switch)
"#,
        &[file.path(), arm.to_str().unwrap()],
    );
    println!("{checked}");
    let plot = arm.parent().unwrap().join("plot_recording.py");
    let summary = python_file(&plot, &[file.path(), "--summary"]);
    assert!(
        summary.starts_with("rows 10000  from 0.000 s to 9.999 s"),
        "{summary}"
    );
    assert!(summary.contains("generations 1 2"), "{summary}");
    assert_eq!(
        summary.matches("max |following error|").count(),
        6,
        "{summary}"
    );
}

/// A grid in lockstep recording two signals, whose recorder is SIGKILLed mid-run: the
/// coordinator waits for the release the dead recorder took (in lockstep nothing moves on
/// without it), so the last tick the recorder was given is the one before; the file it left
/// opens in h5py — as a SWMR reader while it carries the dead writer's mark, then as any file
/// once the restarted recorder took the mark off — every dataset holds at least the rows
/// `tick` counts, in order, and it misses at most the last 100 ms (100 ticks of 1 ms) of what
/// the recorder was given. The restarted recorder writes a file of its own beside it.
#[test]
fn a_sigkilled_recorder_leaves_a_file_h5py_opens_missing_at_most_100_ms() {
    let mut sut = TestDomain::new("reckill");
    let file = Recording::new(&sut);
    let system = sut.write_system(&format!(
        r#"supervision {{ heartbeat_timeout = 2.0 }}
grid {{ base_period = 0.001, clock = "lockstep" }}
component "A" {{ type = "ramp", host = "h1", period = 1 }}
component "B" {{ type = "counter", host = "h1", period = 2 }}
record {{ signals = {{ "A.y", "B.y" }}, file = "{}" }}
"#,
        file.path()
    ));
    let up = sut.spawn_logged(
        "modbot",
        &["up", system.to_str().unwrap(), "--ticks", "100000000"],
    );
    sut.wait_for(
        "the recording is 20 000 rows or more",
        Duration::from_secs(120),
        || rows(&file.0) >= 20_000,
    );
    let recorder: u32 = sut
        .ls_field("host_record", "PID")
        .and_then(|p| p.parse().ok())
        .expect("the recorder runs");
    sut.signal(recorder, Signal::SIGKILL);
    // In lockstep the coordinator waits 10 s for the release the recorder took, then says so.
    let stuck = "a release due at tick ";
    sut.wait_for(
        "the coordinator gives up the dead recorder's release",
        Duration::from_secs(120),
        || sut.output_of(up).contains(stuck),
    );
    sut.wait_for(
        "the restarted recorder writes",
        Duration::from_secs(120),
        || rows(&file.restarted()) > 0,
    );
    sut.modbot_ok(&["down"]);
    sut.wait_exit(up, Duration::from_secs(60));
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
    let output = sut.output_of(up);
    assert!(
        output.contains("took off the writer mark a recorder that died left"),
        "the restarted recorder unmarks the file: {output}"
    );
    let given: i64 = output
        .split(stuck)
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|t| t.parse::<i64>().ok())
        .map(|t| t - 1)
        .expect("the tick the coordinator waited for");
    let checked = python(
        r#"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
tick = f["tick"][:]
assert (tick == np.arange(len(tick))).all(), "every row, in order"
for name in ["A.y", "B.y", "time", "generation"]:
    assert len(f[name]) >= len(tick), (name, len(f[name]), len(tick))
assert np.allclose(np.diff(f["A.y"][1:len(tick)]), 0.001, rtol=0, atol=1e-9), "A.y is the ramp"
later = h5py.File(sys.argv[2], "r")["tick"][:]
assert later[0] > tick[-1], (later[0], tick[-1])
print(tick[-1])
"#,
        &[file.path(), file.restarted().to_str().unwrap()],
    );
    let last: i64 = checked.trim().parse().expect("the last tick in the file");
    let missing = given - last;
    println!("given up to tick {given}, the file holds up to {last}: {missing} ms missing");
    assert!(
        (0..=100).contains(&missing),
        "{missing} ticks of 1 ms are missing"
    );
}

/// Runs `modbot up FILE --var domain=… --var VAR … --record DIR/NAME.TAG.h5 MORE` to its end
/// (exit 0) and returns the recording's path.
fn recorded_run(sut: &mut TestDomain, file: &Path, var: &str, more: &[&str], tag: &str) -> PathBuf {
    let recording = std::env::temp_dir().join(format!("{}.{tag}.h5", sut.name()));
    let domain = format!("domain={}", sut.name());
    let mut args = vec![
        "up",
        file.to_str().unwrap(),
        "--var",
        &domain,
        "--var",
        var,
        "--record",
        recording.to_str().unwrap(),
    ];
    args.extend(more);
    let up = sut.spawn_logged("modbot", &args);
    let status = sut.wait_exit(up, Duration::from_secs(300));
    assert_eq!(status.code(), Some(0), "{}", sut.output_of(up));
    recording
}

/// A grid of three components, only the first recorded: a ramp A (period 1) into a gain B
/// (period 2, gain `vars.k`) into an integrator C (period 5). Run in lockstep twice with k = 2
/// and once with k = 2.5: the two alike compare identical, signals and state hash; the third
/// records the same A.y in every row, and only the state hash (B and C are not recorded) says
/// where the runs part — at the tick LET predicts. Every row's hash is the reference run's:
/// the hosts and the coordinator hash and combine as the in-process reference does.
#[test]
fn two_lockstep_runs_hash_alike_and_a_changed_gain_no_signal_shows_is_found_by_the_state_hash() {
    let mut sut = TestDomain::new("rechash");
    let grid = |record: &str| {
        format!(
            r#"domain(vars.domain)
grid {{ base_period = 0.001, clock = "lockstep" }}
component "A" {{ type = "ramp", host = "h1", period = 1, params = {{ slope = 1 }} }}
component "B" {{ type = "gain", host = "h2", period = 2, params = {{ k = tonumber(vars.k) }} }}
component "C" {{ type = "integrator", host = "h1", period = 5 }}
connect "A.y -> B.u"
connect "B.y -> C.u"
{record}"#
        )
    };
    let dir = std::env::temp_dir();
    let (recorded, bare) = (
        dir.join(format!("{}.recorded.lua", sut.name())),
        dir.join(format!("{}.bare.lua", sut.name())),
    );
    std::fs::write(&recorded, grid(r#"record { signals = { "A.y" } }"#)).unwrap();
    std::fs::write(&bare, grid("")).unwrap();
    let ticks = 20_001u64;
    let more = ["--ticks", &ticks.to_string()];
    let mut run =
        |tag: &str, k: &str| recorded_run(&mut sut, &recorded, &format!("k={k}"), &more, tag);
    let (a, b, c) = (run("a", "2"), run("b", "2"), run("c", "2.5"));
    let compare = |x: &Path, y: &Path| sut.record_compare(x, y);
    let (code, said) = compare(&a, &b);
    assert_eq!(
        (code, said.trim_end()),
        (
            Some(0),
            "identical through tick 20000 (20001 rows, 1 signal and the state hash)"
        )
    );
    // What the reference run of the same grid (without its recorder, which hashes nothing
    // and comes last) gives for each k.
    let reference = |k: &str| {
        let vars = vec![
            ("domain".to_owned(), sut.name().to_owned()),
            ("k".to_owned(), k.to_owned()),
        ];
        let spec = modbot_system::load_with_vars(
            &bare,
            &modbot_system::DefaultResolver::for_file(&bare),
            &vars,
        )
        .unwrap();
        let mut hashes = Vec::new();
        modbot_grid::reference::run_hashed(
            &spec.grid.unwrap(),
            &modbot_components::builtin(),
            ticks,
            modbot_grid::reference::Order::Forward,
            &modbot_grid::Overruns::default(),
            &mut |_, _, _| {},
            &mut |_, hash| hashes.push(hash),
        )
        .unwrap();
        hashes
    };
    let (want_a, want_c) = (reference("2"), reference("2.5"));
    let got = |path: &Path| modbot_record::read::read_state_hash(path).unwrap().unwrap();
    assert!(got(&a) == want_a, "the recorded hashes are the reference's");
    assert!(got(&c) == want_c, "the recorded hashes are the reference's");
    let parted = (0..want_a.len())
        .find(|&n| want_a[n] != want_c[n])
        .expect("the runs part");
    let (code, said) = compare(&a, &c);
    assert_eq!(code, Some(1), "{said}");
    assert!(
        said.starts_with(&format!(
            "first differs at tick {parted}: the state hash 0x{:016x} in the first, 0x{:016x} in \
             the second (no recorded signal differs there",
            want_a[parted], want_c[parted]
        )),
        "{said}"
    );
    // B's first release reads A's initial 0 (0 × k alike); its second, at 2, reads A = 0.001:
    // valid at 4.
    assert_eq!(parted, 4);
    for f in [&a, &b, &c, &recorded, &bare] {
        let _ = std::fs::remove_file(f);
    }
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

/// The rows of the recording at `path` so far, as h5py counts them reading it as a SWMR
/// reader, while it is written (0 while there is none).
fn rows(path: &Path) -> u64 {
    let script = "import sys, h5py; print(len(h5py.File(sys.argv[1], 'r', swmr=True)['tick']))";
    std::process::Command::new("python3")
        .args(["-c", script, path.to_str().unwrap()])
        .output()
        .ok()
        .and_then(|out| String::from_utf8_lossy(&out.stdout).trim().parse().ok())
        .unwrap_or(0)
}

/// The arm in lockstep (holding, then `ptp` from tick 300), recorded three times: two runs
/// alike are identical to the last bit in every row (`modbot record compare`, exit 0); a run
/// whose `ptp` dwells 50 ms at its points differs, and the comparison names the first tick and
/// signal that differ (exit 1). The first, exported for Foxglove (`modbot record export
/// --mcap`), reads back with the mcap crate and with Foxglove's Python `mcap` package: a
/// channel per signal, a message per row.
#[test]
fn two_lockstep_recordings_of_the_arm_are_identical_and_a_changed_run_names_its_first_difference() {
    let _arm = one_arm_at_a_time();
    let mut sut = TestDomain::new("reccmp");
    let arm = arm();
    let more = ["--lockstep", "--ticks", "2500", "--switch", "300:ptp"];
    let mut run = |tag: &str, dwell: &str| {
        recorded_run(&mut sut, &arm, &format!("dwell={dwell}"), &more, tag)
    };
    let (a, b, c) = (run("a", "0"), run("b", "0"), run("c", "0.05"));
    let compare = |x: &Path, y: &Path| sut.record_compare(x, y);
    let (code, said) = compare(&a, &b);
    assert_eq!(code, Some(0), "{said}");
    assert!(
        said.starts_with("identical through tick 2499 (2500 rows,"),
        "{said}"
    );
    let (code, said) = compare(&a, &c);
    assert_eq!(code, Some(1), "{said}");
    assert!(said.starts_with("first differs at tick "), "{said}");
    let tick: i64 = said["first differs at tick ".len()..]
        .split(':')
        .next()
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{said}"));
    assert!(
        tick > 300,
        "the runs are alike until ptp has reached its first point: {said}"
    );
    // Every recorded signal is a component's output, which its state hash covers: the grid's
    // state parts no later than a signal does, and that is the tick named.
    let hashes = |p: &Path| modbot_record::read::read_state_hash(p).unwrap().unwrap();
    let (ha, hc) = (hashes(&a), hashes(&c));
    assert_eq!(ha, hashes(&b));
    assert_eq!(
        (0..ha.len()).find(|&r| ha[r] != hc[r]),
        Some(tick as usize),
        "{said}"
    );
    // The same recording for Foxglove: one channel per signal, a message per row and signal
    // at its tick's time, the values as recorded.
    let mcap = std::env::temp_dir().join(format!("{}.a.mcap", sut.name()));
    let exported = sut.modbot(&[
        "record",
        "export",
        a.to_str().unwrap(),
        "--mcap",
        mcap.to_str().unwrap(),
    ]);
    let said = String::from_utf8_lossy(&exported.stdout).into_owned();
    assert_eq!(exported.status.code(), Some(0), "{said}");
    let bytes = std::fs::read(&mcap).unwrap();
    let mut per_topic = std::collections::BTreeMap::<String, u64>::new();
    let mut link_at_2000 = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert_eq!(m.channel.message_encoding, "json");
        *per_topic.entry(m.channel.topic.clone()).or_default() += 1;
        if m.channel.topic == "/modbot/robot.link_position" && m.log_time == 2_000_000_000 {
            link_at_2000 = Some(String::from_utf8(m.data.to_vec()).unwrap());
        }
    }
    assert!(per_topic.values().all(|&n| n == 2500), "{per_topic:?}");
    assert!(
        per_topic.contains_key("/modbot/robot.state"),
        "{per_topic:?}"
    );
    let link = link_at_2000.expect("robot.link_position at 2 s");
    assert!(link.starts_with(r#"{"tick":2000,"value":["#), "{link}");
    assert_eq!(link.matches(',').count(), 6, "six values: {link}");
    let total = format!(
        "{} channels, {} messages",
        per_topic.len(),
        2500 * per_topic.len()
    );
    assert!(said.contains(&total), "{said}");
    // And as Foxglove's own reader sees it (the `mcap` package from PyPI): the same channels
    // and counts, each channel's schema JSON, and the value of a message by its log time.
    let seen = python(
        r#"
import json, sys
from collections import Counter
from mcap.reader import make_reader
counts, value, schemas = Counter(), None, set()
with open(sys.argv[1], "rb") as f:
    for schema, channel, message in make_reader(f).iter_messages():
        assert channel.message_encoding == "json", channel.message_encoding
        schemas.add((schema.encoding, json.loads(schema.data)["required"] == ["tick", "value"]))
        counts[channel.topic] += 1
        if channel.topic == "/modbot/robot.link_position" and message.log_time == 2_000_000_000:
            value = json.loads(message.data)
print(len(counts), sorted(set(counts.values())), sorted(schemas))
print(value["tick"], len(value["value"]))
"#,
        &[mcap.to_str().unwrap()],
    );
    assert_eq!(
        seen,
        format!(
            "{} [2500] [('jsonschema', True)]\n2000 6\n",
            per_topic.len()
        ),
        "{seen}"
    );
    let _ = std::fs::remove_file(mcap);
    for f in [a, b, c] {
        let _ = std::fs::remove_file(f);
    }
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}
