//! `modbot-mobility`: a simulated mobile base as its own process.

use std::time::Duration;

use clap::Parser;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::{init_logging, ModuleArgs};
use modbot_modules::mobility::{self, Base, Ids};
use modbot_runtime::{Blackboard, ModuleBuilder};

/// Simulated mobile base, starting at (0, 0) heading along +x.
///
/// Methods: `forward(m)` (asks the sonar to monitor at 0.61 m and stops on its report),
/// `turn(deg)`, `stop()`. Blackboard: `x`, `y` (m), `heading` (deg), `moving`.
#[derive(Debug, Parser)]
#[command(name = "modbot-mobility", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// The collision-avoidance module to ask for monitoring.
    #[arg(long, default_value = "sonar")]
    sonar: String,
    /// Forward speed in m/s.
    #[arg(long, default_value_t = 0.5)]
    speed: f64,
    /// Odometry period in milliseconds.
    #[arg(long, default_value_t = 5)]
    period_ms: u64,
}

fn main() -> anyhow::Result<()> {
    init_logging();
    let cli = Cli::parse();
    let bb = Blackboard::builder()
        .item("x", OwnedValue::F64(0.0))
        .item("y", OwnedValue::F64(0.0))
        .item("heading", OwnedValue::F64(0.0))
        .item("moving", OwnedValue::Bool(false))
        .build()?;
    let ids = Ids {
        x: bb.id("x")?,
        y: bb.id("y")?,
        heading: bb.id("heading")?,
        moving: bb.id("moving")?,
    };
    let state = Base {
        speed: cli.speed,
        turn_rate: 90.0,
        remaining_m: 0.0,
        remaining_deg: 0.0,
        sonar: cli.sonar.clone(),
        last_ns: 0,
        ids,
        monitor_call: None,
    };
    let module = ModuleBuilder::new(
        cli.module.name.as_deref().unwrap_or("mobility"),
        cli.module.addr.unwrap_or(2),
    )
    .mode(cli.module.receive_mode())
    .method("forward", mobility::forward)
    .method("turn", mobility::turn)
    .method("stop", mobility::stop)
    .on_report(mobility::on_report)
    .on_done(mobility::on_done)
    .every(Duration::from_millis(cli.period_ms.max(1)), mobility::tick)
    .blackboard(bb)
    .snapshot_period(Duration::from_millis(50))
    .peer(&cli.sonar)
    .open(cli.module.transport()?, state)?;
    module.run()?;
    Ok(())
}
