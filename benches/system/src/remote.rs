//! Benchmark 13, remote: a call to a module of another host through the Zenoh bridges against
//! a raw Zenoh query over the same link, in the same run.
//!
//! Two network namespaces of the benchmark's own joined by a veth pair are the two hosts. On
//! the first, a domain runs `target` (modbot-faulty) and a bridge exporting it; on the second,
//! a domain runs only a bridge importing it. This process calls `target.ping` through the
//! second domain's phone book (its import), one call at a time: `remote.call`. The baseline,
//! `remote.raw_zenoh_query`: `modbot-zenoh-probe` queries a raw Zenoh queryable across the
//! same link with a payload of the call's size (the call's request is 6 bytes on the wire, its
//! answer 3), one query at a time. The two alternate in blocks, so that a quiet or busy spell
//! of the machine falls on both.
//!
//! Then the snapshot delivery: a caller on the first host changes `target`'s blackboard once a
//! millisecond (`record(i)`: item `recorded` = i) while this process reads the import's
//! snapshot in the second domain's shared memory (the copy its bridge mirrors, `snapshot_hz`
//! = 50): how many new snapshots arrive a second, and how old each is when it arrives (from
//! the answer of the `record(i)` it shows; both times are this process's clock).

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use hdrhistogram::Histogram;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Proc, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_core::tool::{Calls, Tool};
use modbot_core::{CallOptions, Domain};
use modbot_ipc_schema::Value;

use super::ethercat::segment::ip;

const A_IP: &str = "10.78.0.1";
const B_IP: &str = "10.78.0.2";

/// Two namespaces with a veth pair between them; deleted when dropped.
struct Hosts {
    a: String,
    b: String,
}

impl Hosts {
    fn new() -> anyhow::Result<Hosts> {
        if !nix::unistd::Uid::effective().is_root() {
            bail!("the remote benchmark makes network namespaces: run it as root");
        }
        let id = format!("{:x}", std::process::id() & 0xfffff);
        let hosts = Hosts {
            a: format!("modbot-bra-{id}"),
            b: format!("modbot-brb-{id}"),
        };
        for ns in [&hosts.a, &hosts.b] {
            let _ = Command::new("ip")
                .args(["netns", "del", ns])
                .stderr(Stdio::null())
                .status();
            ip(&["netns", "add", ns])?;
        }
        let (ea, eb) = (format!("bra{id}"), format!("brb{id}"));
        ip(&[
            "-n", &hosts.a, "link", "add", &ea, "type", "veth", "peer", "name", &eb,
        ])?;
        ip(&["-n", &hosts.a, "link", "set", &eb, "netns", &hosts.b])?;
        ip(&[
            "-n",
            &hosts.a,
            "addr",
            "add",
            &format!("{A_IP}/24"),
            "dev",
            &ea,
        ])?;
        ip(&[
            "-n",
            &hosts.b,
            "addr",
            "add",
            &format!("{B_IP}/24"),
            "dev",
            &eb,
        ])?;
        for (ns, dev) in [
            (&hosts.a, "lo"),
            (&hosts.b, "lo"),
            (&hosts.a, &ea),
            (&hosts.b, &eb),
        ] {
            ip(&["-n", ns, "link", "set", dev, "up"])?;
        }
        Ok(hosts)
    }

    /// `program ARGS` in namespace `ns`.
    fn exec(ns: &str, program: &std::path::Path, args: &[&str]) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", ns]).arg(program).args(args);
        cmd
    }
}

impl Drop for Hosts {
    fn drop(&mut self) {
        for ns in [&self.a, &self.b] {
            let _ = Command::new("ip").args(["netns", "del", ns]).output();
        }
    }
}

/// The rate of snapshot mirroring the benchmark's bridge is given.
const SNAPSHOT_HZ: u32 = 50;
/// How long snapshots are watched.
const WATCH: Duration = Duration::from_secs(5);

/// What the snapshot watch saw: new snapshots a second, and each one's age when it arrived (ns).
struct Delivery {
    per_s: f64,
    changes_per_s: f64,
    age: Histogram<u64>,
}

/// Changes `target`'s blackboard once a millisecond from the robot's domain while reading the
/// import's mirrored snapshot in the station's, for [`WATCH`].
fn watch_snapshots(robot: &Domain, station: &mut Tool) -> anyhow::Result<Delivery> {
    let Tool::Endpoint(reader) = station else {
        bail!("remote: the benchmark's tool got no address of its own");
    };
    let answered = std::sync::Arc::new(std::sync::Mutex::new(Vec::<Instant>::new()));
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let writer = {
        let (robot, answered, stop) = (robot.clone(), answered.clone(), stop.clone());
        std::thread::spawn(move || -> anyhow::Result<()> {
            let mut tool = Tool::open(&robot, "bench-remote-writer")?;
            let opts = CallOptions::timeout(Duration::from_secs(5));
            let mut i = 0i64;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                i += 1;
                tool.call_owned("target", "record", &[Value::I64(i)], opts)
                    .context("remote: record on the robot's host")?;
                answered.lock().expect("not poisoned").push(Instant::now());
                std::thread::sleep(Duration::from_millis(1));
            }
            Ok(())
        })
    };
    let mut age = Histogram::<u64>::new(3)?;
    let (mut last, mut seen) = (0i64, 0u64);
    let started = Instant::now();
    while started.elapsed() < WATCH {
        let shown = reader
            .ctx()
            .snapshot_of("target", |v| match v.value("recorded") {
                Ok(Value::I64(i)) => i,
                _ => 0,
            });
        let arrived = Instant::now();
        if let Ok(Some(i)) = shown {
            if i > last {
                last = i;
                let at = answered
                    .lock()
                    .expect("not poisoned")
                    .get(usize::try_from(i - 1).unwrap_or(usize::MAX))
                    .copied();
                if let Some(at) = at {
                    seen += 1;
                    age.record(arrived.saturating_duration_since(at).as_nanos() as u64)?;
                }
            }
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    writer
        .join()
        .map_err(|_| anyhow::anyhow!("remote: the writer thread panicked"))??;
    let secs = started.elapsed().as_secs_f64();
    let changes = answered.lock().expect("not poisoned").len();
    Ok(Delivery {
        per_s: seen as f64 / secs,
        changes_per_s: changes as f64 / secs,
        age,
    })
}

/// A description of `body` in domain `domain`, written to `path`.
fn write(path: &std::path::Path, domain: &str, body: &str) -> anyhow::Result<()> {
    let text = format!(
        "domain \"{domain}\"\nsupervision {{ heartbeat_timeout = 5, heartbeat_period = 0.1, \
         start_timeout = 20, stop_grace = 5 }}\n{body}"
    );
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    let (blocks, per_block) = if opts.quick { (4, 250) } else { (10, 500) };
    let mut robot = Scratch::new("remote_r", None)?;
    let mut station = Scratch::new("remote_s", None)?;
    let hosts = Hosts::new()?;
    let modbot = procs::binary(opts, "modbot")?;
    let probe = procs::binary(opts, "modbot-zenoh-probe")?;
    let robot_file = robot.path("robot.lua");
    let station_file = station.path("station.lua");
    let journal = robot.path("journal");
    write(
        &robot_file,
        robot.domain.name(),
        &format!(
            "module \"target\" {{ addr = 5, program = \"modbot-faulty\", \
             args = {{ \"--journal\", \"{}\" }} }}\n\
             bridge {{ addr = 200, listen = {{ \"tcp/{A_IP}:7447\" }}, \
             snapshot_hz = {SNAPSHOT_HZ}, exports = {{ target = {{ \"ping\" }} }} }}\n",
            journal.display()
        ),
    )?;
    write(
        &station_file,
        station.domain.name(),
        &format!(
            "bridge {{ addr = 200, connect = {{ \"tcp/{A_IP}:7447\" }}, \
             imports = {{ target = {{ addr = 40, domain = \"{}\" }} }} }}\n",
            robot.domain.name()
        ),
    )?;
    let up = |ns: &str, file: &std::path::Path, label: &str| -> anyhow::Result<Proc> {
        let mut cmd = Hosts::exec(ns, &modbot, &["up", file.to_str().unwrap_or_default()]);
        cmd.stdout(Stdio::null()).stderr(Stdio::null());
        Proc::spawn(cmd, label)
    };
    let up_robot = up(&hosts.a, &robot_file, "modbot up (robot)")?;
    let up_station = up(&hosts.b, &station_file, "modbot up (station)")?;
    let mut server = Hosts::exec(
        &hosts.a,
        &probe,
        &[
            "serve",
            "--listen",
            &format!("tcp/{A_IP}:7450"),
            "--key",
            "bench/echo",
        ],
    );
    server.stdout(Stdio::null());
    let server = Proc::spawn(server, "modbot-zenoh-probe serve")?;

    let mut tool = Tool::open(&station.domain, "bench-remote")?;
    let opts_call = CallOptions::timeout(Duration::from_secs(5));
    let deadline = Instant::now() + Duration::from_secs(60);
    while tool.call_owned("target", "ping", &[], opts_call).is_err() {
        if Instant::now() > deadline {
            bail!("remote: target.ping through the bridges did not answer within 60 s");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let mut call = Histogram::<u64>::new(3)?;
    let mut raw = Histogram::<u64>::new(3)?;
    for _ in 0..blocks {
        procs::check_interrupted()?;
        for _ in 0..per_block {
            let started = Instant::now();
            tool.call_owned("target", "ping", &[], opts_call)
                .context("remote: a call through the bridges failed")?;
            call.record(started.elapsed().as_nanos() as u64)?;
        }
        let out = Hosts::exec(
            &hosts.b,
            &probe,
            &[
                "query",
                "--connect",
                &format!("tcp/{A_IP}:7450"),
                "--key",
                "bench/echo",
                "-n",
                &per_block.to_string(),
                "--bytes",
                "6",
            ],
        )
        .output()
        .context("cannot run modbot-zenoh-probe")?;
        if !out.status.success() {
            bail!(
                "modbot-zenoh-probe query: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            );
        }
        for ns in String::from_utf8_lossy(&out.stdout).split_whitespace() {
            raw.record(ns.parse().context("modbot-zenoh-probe printed no number")?)?;
        }
    }
    let delivery = watch_snapshots(&robot.domain, &mut tool)?;
    drop(tool);
    drop(server);
    let _ = Command::new(&modbot)
        .args(["down", "--domain", station.domain.name()])
        .output();
    let _ = Command::new(&modbot)
        .args(["down", "--domain", robot.domain.name()])
        .output();
    let _ = up_station.stop();
    let _ = up_robot.stop();
    report.push(Row::from_histogram("remote.raw_zenoh_query", &raw).is_baseline());
    report.push(Row::from_histogram("remote.call", &call).against("remote.raw_zenoh_query", &[]));
    let p = |h: &Histogram<u64>, q: f64| h.value_at_quantile(q) as f64 / 1e3;
    report.note(format!(
        "remote: a call through two Zenoh bridges over a veth link between two network \
         namespaces, p50 {:.0} µs / p99 {:.0} µs, against a raw Zenoh query of the same size \
         over the same link, p50 {:.0} µs / p99 {:.0} µs ({:.2}× at p50, {:.2}× at p99; \
         {blocks} alternating blocks of {per_block}); the probe's queries include no \
         process start (one session per block)",
        p(&call, 0.5),
        p(&call, 0.99),
        p(&raw, 0.5),
        p(&raw, 0.99),
        p(&call, 0.5) / p(&raw, 0.5).max(1e-9),
        p(&call, 0.99) / p(&raw, 0.99).max(1e-9),
    ));
    report.note(format!(
        "remote: blackboard snapshots across the link at snapshot_hz {SNAPSHOT_HZ}, the \
         blackboard changing {:.0} times a second: {:.1} new snapshots a second arrived in the \
         importing domain's shared memory, {:.1} ms old at p50, {:.1} ms at p99 (from the \
         change they show; {} s)",
        delivery.changes_per_s,
        delivery.per_s,
        p(&delivery.age, 0.5) / 1e3,
        p(&delivery.age, 0.99) / 1e3,
        WATCH.as_secs()
    ));
    drop(hosts);
    Ok(())
}
