//! The operator's control station (`modbot station`) against real systems, looked at in a real
//! browser: Debian's chromium, headless, driven by playwright-core (`tests/browser/`, which
//! `./setup.sh --tests` installs), and through its HTTP API.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::TestDomain;
use nix::sys::signal::Signal;

const BROWSER_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/browser");

/// The station's tests run one at a time: each starts a whole system (MOSER's seven modules at
/// ten times real time, or the arm's real-time grid) and a browser, and two at once on a
/// 2-core machine starve each other's modules into restarts and the arm into safe stops.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    ONE.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Where the tests' screenshots go (`target/station-screenshots/`).
fn screenshots() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/station-screenshots");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Starts `modbot station` in the domain on a port the kernel picks; returns its pid and the
/// page's address.
fn station(sut: &mut TestDomain, more: &[&str]) -> (u32, String) {
    let mut args = vec!["station", "--listen", "127.0.0.1:0"];
    args.extend_from_slice(more);
    let pid = sut.spawn_logged("modbot", &args);
    let mut url = String::new();
    sut.wait_for("the station's address", Duration::from_secs(60), || {
        let out = sut.output_of(pid);
        match out.split_once(" at http://") {
            Some((_, rest)) => {
                let end = rest
                    .find(|c: char| c.is_whitespace() || c == '?')
                    .unwrap_or(rest.len());
                url = format!("http://{}", &rest[..end]);
                true
            }
            None => false,
        }
    });
    (pid, url)
}

/// A GET of `path` from the station at `url`, by hand (HTTP/1.0, the whole answer).
fn get(url: &str, path: &str) -> (u16, String) {
    use std::io::{Read, Write};
    let host = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = std::net::TcpStream::connect(host).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(s, "GET {path} HTTP/1.0\r\nHost: {host}\r\n\r\n").unwrap();
    let mut answer = String::new();
    s.read_to_string(&mut answer).unwrap();
    let status = answer
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = answer
        .split_once("\r\n\r\n")
        .map(|(_, b)| b.to_owned())
        .unwrap_or_default();
    (status, body)
}

/// Runs a browser test script; panics with what it printed, and the tail of the system's log
/// (`up`, the `modbot up` process), if a check failed.
fn browser_test(sut: &TestDomain, up: u32, script: &str, args: &[&str]) {
    let node_modules = Path::new(BROWSER_DIR).join("node_modules/playwright-core");
    assert!(
        node_modules.is_dir() && Path::new("/usr/bin/chromium").exists(),
        "the browser tests need Debian's chromium and playwright-core: run ./setup.sh --tests"
    );
    let out = Command::new("node")
        .arg(Path::new(BROWSER_DIR).join(script))
        .args(args)
        .current_dir(BROWSER_DIR)
        .output()
        .expect("node runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if !out.status.success() {
        let log = sut.output_of(up);
        let tail: Vec<&str> = log.lines().rev().take(60).collect();
        let tail: Vec<&str> = tail.into_iter().rev().collect();
        panic!(
            "{script} failed:\n{text}\nthe system's log, its last lines:\n{}",
            tail.join("\n")
        );
    }
    println!("{text}");
}

/// Spawns `modbot up examples/moser.lua` at ten times real time, patrolling until stopped,
/// with `more` arguments; returns its pid.
fn spawn_moser(sut: &mut TestDomain, more: &[&str]) -> u32 {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/moser.lua");
    let domain = format!("domain={}", sut.name());
    let mut args = vec![
        "up",
        file,
        "--var",
        &domain,
        "--var",
        "speed=10",
        "--var",
        "endless=1",
        "--for",
        "600",
    ];
    args.extend_from_slice(more);
    sut.spawn_logged("modbot", &args)
}

fn moser(sut: &mut TestDomain) -> u32 {
    let up = spawn_moser(sut, &[]);
    sut.wait_for("MOSER up", Duration::from_secs(120), || {
        sut.output_of(up).contains("module(s) up in")
    });
    up
}

#[test]
fn the_station_shows_moser_live_in_a_browser_and_commands_it_with_the_token_only() {
    let _one = one_at_a_time();
    let mut sut = TestDomain::new("station_moser");
    let up = moser(&mut sut);
    let token = format!("tok{}", std::process::id());
    let (station, url) = station(&mut sut, &["--token", &token]);
    let shots = screenshots();
    browser_test(
        &sut,
        up,
        "moser.mjs",
        &[&url, &token, shots.to_str().unwrap()],
    );
    assert!(shots.join("station-moser.png").is_file());

    // The page stopped the system (its last check): `modbot up` ends by itself, cleanly.
    let status = sut.wait_exit(up, Duration::from_secs(120));
    assert!(status.success(), "{}", sut.output_of(up));
    sut.signal(station, Signal::SIGTERM);
    let status = sut.wait_exit(station, Duration::from_secs(60));
    assert!(status.success(), "the station ended with {status}");
}

#[test]
fn the_station_serves_its_page_and_the_state_of_a_system_without_a_browser() {
    let _one = one_at_a_time();
    let mut sut = TestDomain::new("station_api");
    let up = moser(&mut sut);
    let (station, url) = station(&mut sut, &[]);
    let (status, page) = get(&url, "/");
    assert_eq!(status, 200);
    assert!(page.contains("<title>modbot station</title>"), "{page}");
    let (status, script) = get(&url, "/station.js");
    assert_eq!(status, 200);
    assert!(script.contains("new WebSocket"));
    // The state, as the page gets it: the seven modules with the age of their heartbeats,
    // MOSER's blackboards, how long the look took.
    sut.wait_for(
        "seven running modules in /api/state",
        Duration::from_secs(60),
        || {
            let (_, body) = get(&url, "/api/state");
            body.matches("\"state\":\"running\"").count() == 7
                && body.matches("\"heartbeat_age_ms\":").count() == 7
                && !body.contains("\"heartbeat_age_ms\":null")
                && body.contains("\"mobility\":{")
                && body.contains("\"look_ms\":")
                && body.contains("\"pages\":0")
        },
    );
    let (_, map) = get(&url, "/api/map");
    assert!(map.contains("server room"), "{map}");
    let (status, _) = get(&url, "/nothing");
    assert_eq!(status, 404);
    sut.signal(station, Signal::SIGTERM);
    assert!(sut.wait_exit(station, Duration::from_secs(60)).success());
    sut.signal(up, Signal::SIGINT);
    assert!(sut.wait_exit(up, Duration::from_secs(120)).success());
}

#[test]
fn the_station_switches_the_arm_to_ptp_from_the_page_and_its_joints_move() {
    let _one = one_at_a_time();
    let _arm = common::arm::one_arm_at_a_time();
    let mut sut = TestDomain::new("station_arm");
    let domain = format!("domain={}", sut.name());
    let file = common::arm::arm();
    let up = sut.spawn_logged(
        "modbot",
        &[
            "up",
            file.to_str().unwrap(),
            "--var",
            &domain,
            // A shared machine steals milliseconds from the real-time grid: the bus waits 50
            // base periods, not 3, before it judges the coordinator lost.
            "--var",
            "watchdog=50",
            "--for",
            "600",
        ],
    );
    sut.wait_for("the arm up", Duration::from_secs(120), || {
        sut.output_of(up).contains("module(s) up in")
    });
    let (station, url) = station(&mut sut, &[]);
    let shots = screenshots();
    browser_test(&sut, up, "arm.mjs", &[&url, shots.to_str().unwrap()]);
    assert!(shots.join("station-arm.png").is_file());
    let assembly = sut.modbot_ok(&["assembly"]);
    assert!(
        assembly.starts_with("assembly ptp (generation "),
        "{assembly}"
    );
    sut.signal(station, Signal::SIGTERM);
    assert!(sut.wait_exit(station, Duration::from_secs(60)).success());
    sut.signal(up, Signal::SIGINT);
    assert!(
        sut.wait_exit(up, Duration::from_secs(120)).success(),
        "{}",
        sut.output_of(up)
    );
}

#[test]
fn modbot_up_with_station_serves_the_page_of_its_system_and_stops_it_with_the_system() {
    let _one = one_at_a_time();
    let mut sut = TestDomain::new("station_up");
    let up = spawn_moser(&mut sut, &["--station", "127.0.0.1:0"]);
    let mut url = String::new();
    sut.wait_for(
        "the station's address from modbot up",
        Duration::from_secs(120),
        || {
            let out = sut.output_of(up);
            match out.split_once("modbot station: domain") {
                Some((_, rest)) => {
                    let at = rest.split_once(" at ").map(|(_, a)| a).unwrap_or_default();
                    url = at.split_whitespace().next().unwrap_or_default().to_owned();
                    !url.is_empty()
                }
                None => false,
            }
        },
    );
    sut.wait_for(
        "seven running modules in /api/state",
        Duration::from_secs(60),
        || {
            let (_, body) = get(&url, "/api/state");
            body.matches("\"state\":\"running\"").count() == 7
        },
    );
    sut.signal(up, Signal::SIGINT);
    let status = sut.wait_exit(up, Duration::from_secs(120));
    assert!(status.success(), "{}", sut.output_of(up));
    assert!(sut.output_of(up).contains("modbot station: stopped"));
    let host = url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_owned();
    assert!(
        std::net::TcpStream::connect(&host).is_err(),
        "the station still answers at {url} after the system stopped"
    );
}

/// A tmux session of this test, killed however the test ends.
struct Tmux(String);

impl Tmux {
    fn run(&self, args: &[&str]) -> String {
        let out = Command::new("tmux").args(args).output().expect("tmux runs");
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    fn screen(&self) -> String {
        self.run(&["capture-pane", "-p", "-t", &self.0])
    }

    fn keys(&self, keys: &str) {
        self.run(&["send-keys", "-t", &self.0, keys]);
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        let _ = Command::new("tmux")
            .args(["kill-session", "-t", &self.0])
            .output();
    }
}

#[test]
fn modbot_top_shows_the_modules_sorts_them_and_opens_a_modules_detail_in_a_terminal() {
    let _one = one_at_a_time();
    let mut sut = TestDomain::new("station_top");
    let up = moser(&mut sut);
    let session = Tmux(format!("modbot-top-{}", sut.name()));
    let modbot = common::bin("modbot");
    let command = format!("env MODBOT_DOMAIN={} {} top", sut.name(), modbot.display());
    let started = Command::new("tmux")
        .args([
            "new-session",
            "-d",
            "-s",
            &session.0,
            "-x",
            "200",
            "-y",
            "50",
            &command,
        ])
        .status()
        .expect("tmux runs (./setup.sh --tests installs it)");
    assert!(started.success());
    let mut screen = String::new();
    sut.wait_for(
        "the seven modules on the screen",
        Duration::from_secs(60),
        || {
            screen = session.screen();
            screen.contains("7 modules, 7 running") && screen.contains("near_ir")
        },
    );
    assert!(screen.contains("sorted by address"), "{screen}");
    session.keys("n");
    sut.wait_for(
        "the modules sorted by name",
        Duration::from_secs(30),
        || {
            screen = session.screen();
            let order: Vec<usize> = [
                "collision_sonar",
                "control_station",
                "high_level",
                "intrusion",
            ]
            .iter()
            .filter_map(|n| screen.find(&format!(" {n} ")))
            .collect();
            screen.contains("sorted by name")
                && order.len() == 4
                && order.windows(2).all(|w| w[0] < w[1])
        },
    );
    // The first row is chosen: its detail.
    session.keys("Enter");
    sut.wait_for("collision_sonar's detail", Duration::from_secs(30), || {
        screen = session.screen();
        screen.contains("module collision_sonar at address 3") && screen.contains("methods:")
    });
    session.keys("Escape");
    session.keys("q");
    sut.wait_for("modbot top ended", Duration::from_secs(30), || {
        session.run(&["has-session", "-t", &session.0]).is_empty()
            && !Command::new("tmux")
                .args(["has-session", "-t", &session.0])
                .status()
                .map(|s| s.success())
                .unwrap_or(false)
    });
    sut.signal(up, Signal::SIGINT);
    assert!(
        sut.wait_exit(up, Duration::from_secs(120)).success(),
        "{}",
        sut.output_of(up)
    );
}
