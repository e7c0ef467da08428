//! `modbot-sonar`: a ring of range sensors as its own process — the MRA's collision-avoidance
//! sonar by default, MOSER's navigation sonar or near-infrared ring with other options.

use std::time::Duration;

use clap::{Parser, ValueEnum};
use modbot_core::Blackboard;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::ModuleArgs;
use modbot_modules::moser::building::moser_building;
use modbot_modules::sonar::{self, Ring, SensorKind, Sonar, World};

/// A ring of simulated range sensors (default: 12 ultrasonic sonars over the front 180°).
///
/// Methods: `ranges()` returns every sensor's range in metres; `monitor(threshold_m)` sends one
/// REPORT to the caller when an object in the robot's path comes within the threshold, then
/// stops monitoring. Blackboard: `air_temp_c` (writable, corrects the speed of sound), `ranges`.
#[derive(Debug, Parser)]
#[command(name = "modbot-sonar", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// A point obstacle at X,Y metres; repeat for more.
    #[arg(long = "obstacle", value_parser = parse_point, allow_hyphen_values = true)]
    obstacles: Vec<(f64, f64)>,
    /// A simulated building to sense instead of point obstacles.
    #[arg(long, value_enum)]
    world: Option<WorldArg>,
    /// Number of sensors.
    #[arg(long, default_value_t = sonar::SENSORS)]
    sensors: usize,
    /// The arc they cover, in degrees, centred on the heading (180 front, 360 all around).
    #[arg(long, default_value_t = 180.0)]
    arc: f64,
    /// Farthest range, in metres.
    #[arg(long, default_value_t = sonar::MAX_RANGE_M)]
    max_range: f64,
    /// Sensor kind: ultrasonic sonar (temperature-corrected) or near-infrared.
    #[arg(long, value_enum, default_value = "sonar")]
    kind: KindArg,
    /// The module whose blackboard holds the robot's pose (x, y, heading).
    #[arg(long, default_value = "mobility")]
    pose_from: String,
    /// Ping period in milliseconds.
    #[arg(long, default_value_t = 10)]
    period_ms: u64,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum WorldArg {
    /// MOSER's office building.
    Moser,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum KindArg {
    Sonar,
    Ir,
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

fn main() -> std::process::ExitCode {
    modbot_modules::common::main("modbot-sonar", run)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=64).contains(&cli.sensors),
        "--sensors {}: use 1 to 64",
        cli.sensors
    );
    anyhow::ensure!(
        cli.arc > 0.0 && cli.arc <= 360.0,
        "--arc {}: use (0, 360] degrees",
        cli.arc
    );
    anyhow::ensure!(
        cli.max_range > 0.0 && cli.max_range.is_finite(),
        "--max-range {}: use a positive number of metres",
        cli.max_range
    );
    let ring = Ring {
        sensors: cli.sensors,
        arc_deg: cli.arc,
        max_range_m: cli.max_range,
        kind: match cli.kind {
            KindArg::Sonar => SensorKind::Sonar,
            KindArg::Ir => SensorKind::Infrared,
        },
    };
    let world = match (cli.world, cli.obstacles.is_empty()) {
        (Some(WorldArg::Moser), _) => World::Building(Box::new(moser_building())),
        (None, false) => World::Points(cli.obstacles.clone()),
        (None, true) => World::Empty,
    };
    let bb = Blackboard::builder()
        .writable_item("air_temp_c", OwnedValue::F64(20.0))
        .item("ranges", OwnedValue::F64s(vec![cli.max_range; cli.sensors]))
        .build()?;
    let state = Sonar::new(ring, world, &cli.pose_from);
    let module = cli
        .module
        .module("sonar", 1)
        .method("ranges", sonar::ranges)
        .method("monitor", sonar::monitor)
        .every(Duration::from_millis(cli.period_ms.max(1)), sonar::tick)
        .blackboard(bb)
        .peer(&cli.pose_from);
    Ok(cli.module.serve(module, state)?)
}
