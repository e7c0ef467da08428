//! `modbot-control-station`: MOSER's operator module as its own process.

use std::time::{Duration, Instant};

use clap::Parser;
use modbot_core::sim::SimTime;
use modbot_core::stats::Stats;
use modbot_core::{signals, CallError, CallOptions, Module};
use modbot_ipc_schema::{NakCode, OwnedValue, Value};
use modbot_modules::common::ModuleArgs;
use modbot_modules::control_station::{self, Station, Summary};

/// The control station: sends the robot on patrol, shows its progress and alerts as a line log,
/// and ends the scenario with a summary.
///
/// Methods (the operator's commands): `patrol(wing)`, `stop()`, `activate_module(module)`,
/// `deactivate_module(module)`.
#[derive(Debug, Parser)]
#[command(name = "modbot-control-station", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// The high-level processing module.
    #[arg(long, default_value = "high_level")]
    high_level: String,
    /// The mobility module (for the odometer at the end).
    #[arg(long, default_value = "mobility")]
    mobility: String,
    /// Patrol this wing from the start.
    #[arg(long)]
    patrol: Option<i64>,
    /// End the scenario this many simulated seconds after the first alert.
    #[arg(long, default_value_t = 5.0)]
    end_after_alert: f64,
    /// End the scenario after this many simulated seconds in any case.
    #[arg(long, default_value_t = 900.0)]
    max_duration: f64,
    /// A progress line every this many simulated seconds.
    #[arg(long, default_value_t = 5.0)]
    line_every: f64,
    /// At the end, leave the system running instead of asking the supervisor to stop it.
    #[arg(long)]
    keep_running: bool,
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::main("modbot-control-station", run)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let mut module = cli
        .module
        .module("control_station", 20)
        .method("patrol", control_station::patrol)
        .method("stop", control_station::stop)
        .method("activate_module", control_station::activate)
        .method("deactivate_module", control_station::deactivate)
        .on_report(control_station::on_report)
        .peer(&cli.high_level)
        .open(
            cli.module.transport()?,
            Station::new(&cli.high_level, cli.line_every),
        )?;
    signals::install_termination_handler()?;
    let sim = SimTime::from_env();
    let started = Instant::now();
    if let Some(wing) = cli.patrol {
        start_patrol(&mut module, &cli.high_level, wing)?;
    }
    let mut ended = false;
    let mut alert_heard_s = None;
    while !signals::termination_requested() {
        let mut served = 0;
        while served < 64 && module.poll_once()? {
            served += 1;
        }
        module.housekeeping();
        let now_s = sim.seconds(module.ctx().now_ns());
        control_station::progress_line(module.state_mut(), now_s);
        // When the alert came, by this host's clock (a robot on another host has another).
        if module.state().alert.is_some() && alert_heard_s.is_none() {
            alert_heard_s = Some(now_s);
        }
        let alert_done = alert_heard_s.is_some_and(|t| now_s >= t + cli.end_after_alert);
        if !ended && (alert_done || now_s >= cli.max_duration) {
            ended = true;
            let summary = finish(&mut module, &cli, &sim, started.elapsed())?;
            print!("{}", summary.render());
            if !cli.keep_running {
                let stop = module.call_owned("supervisor", "down", &[], CallOptions::default());
                if let Err(e) = stop {
                    println!("control station: the system keeps running ({e})");
                }
            }
        }
        if served == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    Ok(())
}

/// Sends the robot on patrol, waiting (up to 20 s) until the high-level module is ready (and,
/// for a robot on another host, the link to it is up).
fn start_patrol(module: &mut Module<Station>, high_level: &str, wing: i64) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let opts = CallOptions::timeout(Duration::from_secs(5)).waiting_for_peer();
        match module.call_owned(high_level, "patrol", &[Value::I64(wing)], opts) {
            Ok(_) => {
                println!("control station: patrolling wing {wing}");
                module.state_mut().mission = Some(wing);
                return Ok(());
            }
            // Not ready yet, or (a robot on another host) its link not up yet.
            Err(CallError::Nak { code, .. })
                if (code == NakCode::NOT_READY || code == NakCode::UNREACHABLE)
                    && Instant::now() < deadline =>
            {
                std::thread::sleep(Duration::from_millis(50));
            }
            // Not in the phone book yet (a robot on another host: its bridge's import).
            Err(CallError::UnknownModule(_)) if Instant::now() < deadline => {
                std::thread::sleep(Duration::from_millis(50));
            }
            Err(e) => anyhow::bail!("cannot send the robot on patrol: {e}"),
        }
    }
}

/// Stops the patrol and gathers the figures of the run.
fn finish(
    module: &mut Module<Station>,
    cli: &Cli,
    sim: &SimTime,
    real: Duration,
) -> anyhow::Result<Summary> {
    let opts = CallOptions::timeout(Duration::from_secs(2));
    let hl = cli.high_level.clone();
    module.state_mut().mission = None;
    if let Err(e) = module.call_owned(&hl, "stop", &[], opts) {
        println!("control station: stop not taken: {e}");
    }
    let mut summary = Summary {
        sim_s: sim.seconds(module.ctx().now_ns()),
        real_s: real.as_secs_f64(),
        speed: sim.speed(),
        alert: module.state().alert,
        ..Default::default()
    };
    let mobility = cli.mobility.clone();
    let item = |module: &mut Module<Station>, owner: &str, name: &str| {
        module
            .call_owned(owner, "bb_get", &[Value::Text(name)], opts)
            .ok()
            .and_then(|v| v.into_iter().next())
    };
    if let Some(OwnedValue::F64(odo)) = item(module, &mobility, "odometer") {
        summary.odometer_m = odo;
    }
    if let Some(OwnedValue::I64(n)) = item(module, &mobility, "collisions") {
        summary.collisions = n;
    }
    if let Some(OwnedValue::I64(n)) = item(module, &hl, "replans") {
        summary.replans = n;
    }
    let me = module.addr();
    let names: Vec<String> = module
        .ctx()
        .phone_book()
        .entries()
        .filter(|e| e.alive && e.addr != me)
        .map(|e| e.name.clone())
        .collect();
    summary.add(module.ctx().stats());
    for name in names {
        let stats = module.call_blocking(&name, "stats", &[], opts, |r| {
            r.map_err(|e| e.to_string())
                .and_then(|a| Stats::from_answer(a).map_err(|e| e.to_string()))
        });
        match stats {
            Ok(s) => summary.add(&s),
            Err(e) => println!("control station: no statistics from {name}: {e}"),
        }
    }
    Ok(summary)
}
