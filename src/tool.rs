//! `modbot ls`, `call` and `bb`: a short-lived tool endpoint in the system's domain.

use std::process::ExitCode;
use std::time::Duration;

use anyhow::{anyhow, bail, Context};
use modbot_core::tool::{Calls, Tool};
use modbot_core::{CallError, CallOptions, Domain, Stats};
use modbot_ipc_schema::{sysmethod, Args, OwnedValue, SnapshotView, Value};
use modbot_supervisor::status::{self, Row};

/// Joins the domain: at a free address, or through the supervisor when every address is
/// taken.
pub fn open(domain: &str) -> anyhow::Result<Tool> {
    let domain = Domain::new(domain)?;
    Tool::open(&domain, "modbot-cli").context("cannot join the domain")
}

/// One line of `modbot ls`.
struct LsLine {
    addr: u8,
    name: String,
    pid: u32,
    state: String,
    mode: &'static str,
    restarts: String,
    /// How often a live upgrade replaced its process.
    upgrades: String,
    last_exit: String,
    counters: [String; 3],
    methods: String,
}

/// The supervisor's status rows, if a supervisor runs in the domain.
fn supervisor_rows(tool: &mut Tool) -> Option<Vec<Row>> {
    tool.call_blocking(
        "supervisor",
        "status",
        &[],
        CallOptions::timeout(Duration::from_millis(1000)),
        |r| {
            r.ok()
                .and_then(|a| a.bytes(0).ok())
                .and_then(|b| status::decode(b).ok())
        },
    )
}

/// `modbot ls`.
pub fn ls(domain: &str, tsv: bool) -> anyhow::Result<ExitCode> {
    let mut tool = open(domain)?;
    let me = tool.addr();
    let modules = tool.list_modules()?;
    let supervised = if modules.iter().any(|m| m.alive && m.name == "supervisor") {
        supervisor_rows(&mut tool).unwrap_or_default()
    } else {
        Vec::new()
    };
    let shown: Vec<_> = modules
        .iter()
        .filter(|m| Some(m.addr) != me && m.name != "supervisor")
        .collect();
    // Every live module describes itself (methods, counters); the calls go out together.
    type Described = Result<([String; 3], String, bool), String>;
    let mut described: Vec<Option<Described>> = vec![None; shown.len()];
    let live: Vec<usize> = (0..shown.len()).filter(|&i| shown[i].alive).collect();
    let names: Vec<&str> = live.iter().map(|&i| shown[i].name.as_str()).collect();
    tool.call_each(
        &names,
        sysmethod::name(sysmethod::DESCRIBE).unwrap_or("describe"),
        CallOptions::timeout(Duration::from_millis(500)),
        |k, r| {
            described[live[k]] = Some(match r {
                Ok(a) => {
                    let count = |i| a.i64(i).map(|n| n.to_string()).unwrap_or("-".into());
                    a.text(3).map_err(|e| e.to_string()).map(|methods| {
                        // Modules older than `active` do not send it: active.
                        let active = !matches!(a.get(8), Some(Value::Bool(false)));
                        ([count(5), count(6), count(7)], methods.to_owned(), active)
                    })
                }
                Err(e) => Err(e.to_string()),
            });
        },
    );
    let mut lines = Vec::new();
    for (m, described) in shown.iter().zip(described) {
        let sup = supervised.iter().find(|r| r.addr == m.addr.0);
        let mut line = LsLine {
            addr: m.addr.0,
            name: m.name.clone(),
            pid: m.pid,
            state: if m.alive { "alive" } else { "dead" }.to_owned(),
            mode: m.mode.name(),
            restarts: "-".into(),
            upgrades: "-".into(),
            last_exit: "-".into(),
            counters: ["-".into(), "-".into(), "-".into()],
            methods: String::new(),
        };
        if let Some(r) = sup {
            line.state = if m.alive {
                r.state.clone()
            } else {
                "dead".into()
            };
            line.restarts = r.restarts.to_string();
            line.upgrades = r.upgrades.to_string();
            if !r.last_exit.is_empty() {
                line.last_exit = r.last_exit.clone();
            }
            line.counters = [
                r.counters.dropped.to_string(),
                r.counters.rejected.to_string(),
                r.counters.replayed.to_string(),
            ];
        }
        match described {
            Some(Ok((counters, methods, active))) => {
                line.counters = counters;
                line.methods = methods.replace(',', " ");
                if !active {
                    line.state = "deactivated".into();
                }
            }
            Some(Err(e)) => line.methods = format!("(no answer: {e})"),
            None => {}
        }
        lines.push(line);
    }
    // Supervised modules that are down have no node: list them from the supervisor.
    for r in &supervised {
        if !lines.iter().any(|l| l.addr == r.addr) {
            lines.push(LsLine {
                addr: r.addr,
                name: r.name.clone(),
                pid: r.pid,
                state: r.state.clone(),
                mode: "-",
                restarts: r.restarts.to_string(),
                upgrades: r.upgrades.to_string(),
                last_exit: if r.last_exit.is_empty() {
                    "-".into()
                } else {
                    r.last_exit.clone()
                },
                counters: [
                    r.counters.dropped.to_string(),
                    r.counters.rejected.to_string(),
                    r.counters.replayed.to_string(),
                ],
                methods: String::new(),
            });
        }
    }
    lines.sort_by_key(|l| l.addr);
    let width = lines.iter().map(|l| l.name.len()).max().unwrap_or(4).max(4);
    let header = LsLine {
        addr: 0,
        name: "NAME".into(),
        pid: 0,
        state: "STATE".into(),
        mode: "MODE",
        restarts: "RESTARTS".into(),
        upgrades: "UPGRADES".into(),
        last_exit: "LAST EXIT".into(),
        counters: ["DROPPED".into(), "REJECT".into(), "REPLAY".into()],
        methods: "METHODS".into(),
    };
    let print = |l: &LsLine, addr: &str, pid: &str| {
        if tsv {
            let [d, r, p] = &l.counters;
            let fields = [
                addr,
                &l.name,
                pid,
                &l.state,
                l.mode,
                &l.restarts,
                &l.upgrades,
                &l.last_exit,
                d,
                r,
                p,
                &l.methods,
            ];
            println!("{}", fields.join("\t"));
            return;
        }
        println!(
            "{addr:>4}  {:<width$}  {pid:>8}  {:<10} {:<9} {:>8} {:>8}  {:<30} {:>7} {:>7} {:>7}  {}",
            l.name,
            l.state,
            l.mode,
            l.restarts,
            l.upgrades,
            l.last_exit,
            l.counters[0],
            l.counters[1],
            l.counters[2],
            l.methods
        )
    };
    print(&header, "ADDR", "PID");
    for l in &lines {
        print(
            l,
            &l.addr.to_string(),
            &if l.pid == 0 {
                "-".into()
            } else {
                l.pid.to_string()
            },
        );
    }
    tool.reap_dead();
    Ok(ExitCode::SUCCESS)
}

/// `modbot down`: asks the domain's supervisor to stop the system, and waits until it has.
pub fn down(domain: &str) -> anyhow::Result<ExitCode> {
    let mut tool = open(domain)?;
    let asked = tool.call_owned(
        "supervisor",
        "down",
        &[],
        CallOptions::timeout(Duration::from_secs(2)),
    );
    if let Err(e) = asked {
        eprintln!("modbot down: no supervisor answers in domain '{domain}': {e}");
        return Ok(ExitCode::from(1));
    }
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    while std::time::Instant::now() < deadline {
        let others = tool
            .list_modules()?
            .into_iter()
            .filter(|m| m.alive && Some(m.addr) != tool.addr())
            .count();
        if others == 0 {
            println!("domain '{domain}' is down");
            return Ok(ExitCode::SUCCESS);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    eprintln!("modbot down: domain '{domain}' still has live modules after 60 s");
    Ok(ExitCode::from(1))
}

/// `modbot call MODULE.METHOD ARGS...`.
pub fn call(
    domain: &str,
    target: &str,
    args: &[String],
    timeout_ms: u64,
    wait: bool,
) -> anyhow::Result<ExitCode> {
    let (module, method) = target
        .split_once('.')
        .ok_or_else(|| anyhow!("'{target}' is not MODULE.METHOD"))?;
    let owned = args
        .iter()
        .map(|a| OwnedValue::parse(a).map_err(|e| anyhow!(e)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let values: Vec<Value<'_>> = owned.iter().map(OwnedValue::as_value).collect();
    let mut tool = open(domain)?;
    let deadline = std::time::Instant::now() + Duration::from_millis(timeout_ms);
    let result = loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        let mut opts = CallOptions::timeout(left.max(Duration::from_millis(1)));
        opts.wait_for_peer = wait;
        match tool.call_owned(module, method, &values, opts) {
            // This tool has not seen the module before: wait until it (re)appears.
            Err(CallError::NotAvailable { .. } | CallError::UnknownModule(_))
                if wait && left > Duration::from_millis(50) =>
            {
                std::thread::sleep(Duration::from_millis(20));
            }
            other => break other,
        }
    };
    match result {
        Ok(values) if values.is_empty() => println!("ok"),
        Ok(values) if sysmethod::id(method) == Some(sysmethod::STATS) => {
            let shown: Vec<Value<'_>> = values.iter().map(OwnedValue::as_value).collect();
            let stats = Args::from_values(&shown)
                .map_err(|e| anyhow!("{e}"))
                .and_then(|a| Stats::from_answer(&a).map_err(|e| anyhow!("{e}")));
            match stats {
                Ok(stats) => print!("{}", stats_table(&stats)),
                Err(e) => {
                    eprintln!("modbot call {target}: {e}");
                    return Ok(ExitCode::from(1));
                }
            }
        }
        Ok(values) => {
            for v in values {
                println!("{v}");
            }
        }
        Err(e) => {
            eprintln!("modbot call {target}: {e}");
            return Ok(ExitCode::from(1));
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A `stats` answer as `modbot call MODULE.stats` prints it.
fn stats_table(s: &Stats) -> String {
    let h = &s.latency;
    let latency = if h.is_empty() {
        "-".to_owned()
    } else {
        format!(
            "p50 {}  p90 {}  p99 {}  max {}  ({} answers)",
            duration(h.percentile(50.0)),
            duration(h.percentile(90.0)),
            duration(h.percentile(99.0)),
            duration(h.max()),
            h.count()
        )
    };
    format!(
        "frames sent      {}\nframes received  {}\ncalls            {}\nanswered         {}\n\
         failed           {}\nlatency          {latency}\n",
        s.frames_sent, s.frames_received, s.calls, s.answered, s.failed
    )
}

/// `ns` in the unit that reads best.
fn duration(ns: u64) -> String {
    match ns {
        n if n < 1_000 => format!("{n} ns"),
        n if n < 1_000_000 => format!("{:.1} µs", n as f64 / 1e3),
        n if n < 1_000_000_000 => format!("{:.1} ms", n as f64 / 1e6),
        n => format!("{:.2} s", n as f64 / 1e9),
    }
}

/// `modbot bb MODULE [ITEM [VALUE]]`.
pub fn bb(
    domain: &str,
    module: &str,
    item: Option<&str>,
    value: Option<&str>,
) -> anyhow::Result<ExitCode> {
    let mut tool = open(domain)?;
    let opts = CallOptions::timeout(Duration::from_secs(2));
    let outcome: anyhow::Result<()> = match (item, value) {
        (None, _) => tool.call_blocking(module, "bb_snapshot", &[], opts, |r| {
            let args = r.map_err(|e| anyhow!("{e}"))?;
            let bytes = args.bytes(0).map_err(|e| anyhow!("{e}"))?;
            let view = SnapshotView::parse(bytes).map_err(|e| anyhow!("{e}"))?;
            print_snapshot(module, &view, "");
            Ok(())
        }),
        (Some(name), None) => {
            tool.call_blocking(module, "bb_get", &[Value::Text(name)], opts, |r| {
                let args = r.map_err(|e| anyhow!("{e}"))?;
                match args.get(0) {
                    Some(v) => println!("{v}"),
                    None => bail!("empty answer"),
                }
                Ok(())
            })
        }
        (Some(name), Some(text)) => {
            let v = OwnedValue::parse(text).map_err(|e| anyhow!(e))?;
            tool.call_blocking(
                module,
                "bb_set",
                &[Value::Text(name), v.as_value()],
                opts,
                |r| {
                    r.map_err(|e| anyhow!("{e}"))?;
                    println!("ok");
                    Ok(())
                },
            )
        }
    };
    match outcome {
        Ok(()) => Ok(ExitCode::SUCCESS),
        Err(e) => {
            eprintln!("modbot bb {module}: {e}");
            Ok(ExitCode::from(1))
        }
    }
}

/// Prints a snapshot: a header line, then one line per item.
fn print_snapshot(module: &str, view: &SnapshotView<'_>, source: &str) {
    println!(
        "# {module} (address {}), snapshot {}{source}",
        view.addr(),
        view.seq()
    );
    for it in view.iter() {
        let value = match it.value {
            // Images, scans, point clouds: their size and first bytes.
            Value::Bytes(b) if it.bulk => format!(
                "bulk, {} bytes: 0x{}{}",
                b.len(),
                modbot_ipc_schema::hex::encode(&b[..b.len().min(16)]),
                if b.len() > 16 { "…" } else { "" }
            ),
            v => v.to_string(),
        };
        println!(
            "{}: {value}{}",
            it.name,
            if it.writable { "  (writable)" } else { "" }
        );
    }
}

/// `modbot bb MODULE [ITEM] --shared`: the snapshot the module publishes in shared memory
/// (waiting up to 2 s for one), without a call.
pub fn bb_shared(domain: &str, module: &str, item: Option<&str>) -> anyhow::Result<ExitCode> {
    let mut tool = open(domain)?;
    let Tool::Endpoint(endpoint) = &mut tool else {
        eprintln!(
            "modbot bb {module} --shared: every address of the domain is taken, and a tool \
             without one reads no shared memory; leave out --shared"
        );
        return Ok(ExitCode::from(1));
    };
    let deadline = std::time::Instant::now() + Duration::from_secs(2);
    loop {
        let shown = endpoint.ctx().snapshot_of(module, |view| match item {
            None => {
                print_snapshot(module, &view, " (shared memory)");
                Ok(())
            }
            Some(name) => view
                .value(name)
                .map(|v| println!("{v}"))
                .map_err(|e| e.to_string()),
        });
        match shown {
            Ok(Some(Ok(()))) => return Ok(ExitCode::SUCCESS),
            Ok(Some(Err(why))) => {
                eprintln!("modbot bb {module}: {why}");
                return Ok(ExitCode::from(1));
            }
            Ok(None) if std::time::Instant::now() < deadline => {
                std::thread::sleep(Duration::from_millis(20))
            }
            Ok(None) => {
                eprintln!(
                    "modbot bb {module}: it published no snapshot within 2 s (a module without \
                     a blackboard never does; an imported one's comes as often as its bridge's \
                     snapshot_hz)"
                );
                return Ok(ExitCode::from(1));
            }
            Err(e) => {
                eprintln!("modbot bb {module}: {e}");
                return Ok(ExitCode::from(1));
            }
        }
    }
}

/// `modbot top`: the coordinator's ledger as a table, and the robot's state, refreshed in
/// place.
pub fn top(domain: &str, once: bool) -> anyhow::Result<ExitCode> {
    use modbot_grid::ledger;
    let mut tool = open(domain)?;
    loop {
        let frame = tool.call_blocking(
            "coordinator",
            "ledger",
            &[],
            CallOptions::timeout(Duration::from_secs(1)),
            |r| -> Result<String, String> {
                let args = r.map_err(|e| e.to_string())?;
                let bytes = args.bytes(0).map_err(|e| e.to_string())?;
                let (grid, rows) = ledger::decode(bytes)?;
                Ok(ledger::render(&grid, &rows))
            },
        );
        let mut frame = match frame {
            Ok(f) => f,
            Err(e) => {
                eprintln!("modbot top: no ledger from the coordinator of '{domain}': {e}");
                return Ok(ExitCode::from(1));
            }
        };
        // The robot's state, from the bus bridge (a grid without a bus has none).
        if let Ok(Some(state)) = modbot_bus::ask::robot_state(&mut tool, Duration::from_millis(500))
        {
            frame.push_str(&format!("robot {state}\n"));
        }
        if once {
            print!("{frame}");
            return Ok(ExitCode::SUCCESS);
        }
        // Home the cursor and clear: the table refreshes in place.
        print!("\x1b[H\x1b[2J{frame}");
        use std::io::Write;
        std::io::stdout().flush()?;
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// `modbot bus`: the bus bridge's ledger, or with `--switches` its record of switches.
pub fn bus(domain: &str, switches: bool, timeout_ms: u64) -> anyhow::Result<ExitCode> {
    use modbot_bus::bridge::render_switches;
    let mut tool = open(domain)?;
    let module = modbot_supervisor::processes::host_module(modbot_supervisor::processes::BUS_HOST);
    let text = tool.call_blocking(
        &module,
        if switches { "switches" } else { "bus" },
        &[],
        CallOptions::timeout(Duration::from_millis(timeout_ms)),
        |r| -> Result<String, String> {
            let args = r.map_err(|e| format!("no bus bridge answers in '{domain}': {e}"))?;
            let answer = |e: &dyn std::fmt::Display| format!("the bus bridge's answer: {e}");
            if switches {
                let bytes = args.bytes(0).map_err(|e| answer(&e))?;
                let record = modbot_ipc_schema::bus::decode(bytes).map_err(|e| answer(&e))?;
                Ok(render_switches(&record))
            } else {
                args.text(0).map(str::to_owned).map_err(|e| answer(&e))
            }
        },
    );
    match text {
        Ok(t) => {
            print!("{t}");
            Ok(ExitCode::SUCCESS)
        }
        Err(e) => {
            eprintln!("modbot bus: {e}");
            Ok(ExitCode::from(1))
        }
    }
}
