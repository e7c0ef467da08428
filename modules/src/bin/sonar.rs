//! `modbot-sonar`: the MRA's collision-avoidance sonar module as its own process.

use std::time::Duration;

use clap::Parser;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::{init_logging, ModuleArgs};
use modbot_modules::sonar::{self, Sonar, SENSORS};
use modbot_runtime::{Blackboard, ModuleBuilder};

/// Collision-avoidance sonar: 12 simulated ultrasonic sensors over the front 180°.
///
/// Methods: `ranges()` returns the 12 ranges in metres; `monitor(threshold_m)` sends one REPORT
/// to the caller when an object comes within the threshold, then stops monitoring.
/// Blackboard: `air_temp_c` (writable, corrects the speed of sound), `ranges`.
#[derive(Debug, Parser)]
#[command(name = "modbot-sonar", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// A point obstacle at X,Y metres; repeat for more.
    #[arg(long = "obstacle", value_parser = parse_point, allow_hyphen_values = true)]
    obstacles: Vec<(f64, f64)>,
    /// The module whose blackboard holds the robot's pose (x, y, heading).
    #[arg(long, default_value = "mobility")]
    pose_from: String,
    /// Ping period in milliseconds.
    #[arg(long, default_value_t = 10)]
    period_ms: u64,
}

fn parse_point(text: &str) -> Result<(f64, f64), String> {
    let (x, y) = text
        .split_once(',')
        .ok_or_else(|| format!("'{text}' is not X,Y"))?;
    let num = |s: &str| {
        s.trim()
            .parse::<f64>()
            .map_err(|_| format!("'{s}' in '{text}' is not a number"))
    };
    Ok((num(x)?, num(y)?))
}

fn main() -> anyhow::Result<()> {
    init_logging();
    let cli = Cli::parse();
    let bb = Blackboard::builder()
        .writable_item("air_temp_c", OwnedValue::F64(20.0))
        .item(
            "ranges",
            OwnedValue::F64s(vec![sonar::MAX_RANGE_M; SENSORS]),
        )
        .build()?;
    let state = Sonar {
        obstacles: cli.obstacles.clone(),
        pose_source: cli.pose_from.clone(),
        ..Default::default()
    };
    let module = ModuleBuilder::new(
        cli.module.name.as_deref().unwrap_or("sonar"),
        cli.module.addr.unwrap_or(1),
    )
    .mode(cli.module.receive_mode())
    .method("ranges", sonar::ranges)
    .method("monitor", sonar::monitor)
    .every(Duration::from_millis(cli.period_ms.max(1)), sonar::tick)
    .blackboard(bb)
    .peer(&cli.pose_from)
    .open(cli.module.transport()?, state)?;
    module.run()?;
    Ok(())
}
