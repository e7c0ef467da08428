//! `modbot-mobility`: a simulated mobile base as its own process.

use std::time::Duration;

use clap::{Parser, ValueEnum};
use modbot_core::sim::SimTime;
use modbot_core::Blackboard;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::ModuleArgs;
use modbot_modules::mobility::{self, Base, Ids};
use modbot_modules::moser::building::moser_building;

/// Simulated mobile base, starting at (0, 0) heading along +x, or at a building's start.
///
/// Methods: `forward(m)` (asks the collision-avoidance module to monitor at 0.61 m and stops on
/// its report), `turn(deg)`, `stop()`, `use_collision(module)`. Blackboard: `x`, `y` (m),
/// `heading` (deg), `moving`, `odometer` (m), `collisions`, `done` (last finished command).
#[derive(Debug, Parser)]
#[command(name = "modbot-mobility", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// The collision-avoidance module to ask for monitoring.
    #[arg(long, default_value = "sonar")]
    sonar: String,
    /// Forward speed in m/s (simulated time).
    #[arg(long, default_value_t = 0.5)]
    speed: f64,
    /// Turn rate in degrees/s (simulated time).
    #[arg(long, default_value_t = 90.0)]
    turn_rate: f64,
    /// A simulated building: the base starts at its start and cannot pass its walls.
    #[arg(long, value_enum)]
    world: Option<WorldArg>,
    /// Odometry period in milliseconds.
    #[arg(long, default_value_t = 5)]
    period_ms: u64,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum WorldArg {
    /// MOSER's office building.
    Moser,
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::main("modbot-mobility", run)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    anyhow::ensure!(
        cli.speed > 0.0 && cli.turn_rate > 0.0,
        "--speed and --turn-rate must be positive"
    );
    let building = cli.world.map(|WorldArg::Moser| Box::new(moser_building()));
    let (x0, y0, h0) = building.as_ref().map_or((0.0, 0.0, 0.0), |b| {
        (b.start.x, b.start.y, b.start_heading_deg)
    });
    let bb = Blackboard::builder()
        .item("x", OwnedValue::F64(x0))
        .item("y", OwnedValue::F64(y0))
        .item("heading", OwnedValue::F64(h0))
        .item("moving", OwnedValue::Bool(false))
        .item("odometer", OwnedValue::F64(0.0))
        .item("collisions", OwnedValue::I64(0))
        .item("done", OwnedValue::I64(0))
        .build()?;
    let ids = Ids {
        x: bb.id("x")?,
        y: bb.id("y")?,
        heading: bb.id("heading")?,
        moving: bb.id("moving")?,
        odometer: bb.id("odometer")?,
        collisions: bb.id("collisions")?,
        done: bb.id("done")?,
    };
    let state = Base {
        speed: cli.speed,
        turn_rate: cli.turn_rate,
        remaining_m: 0.0,
        remaining_deg: 0.0,
        sonar: cli.sonar.clone(),
        last_ns: 0,
        ids,
        monitor_call: None,
        building,
        sim_speed: SimTime::from_env().speed(),
        cmd_seq: 0,
        collisions: 0,
    };
    let module = cli
        .module
        .module("mobility", 2)
        .method("forward", mobility::forward)
        .method("turn", mobility::turn)
        .method("stop", mobility::stop)
        .method("use_collision", mobility::use_collision)
        .on_report(mobility::on_report)
        .on_done(mobility::on_done)
        .every(Duration::from_millis(cli.period_ms.max(1)), mobility::tick)
        .blackboard(bb)
        .snapshot_period(Duration::from_millis(50))
        .peer(&cli.sonar);
    Ok(cli.module.serve(module, state)?)
}
