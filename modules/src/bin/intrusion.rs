//! `modbot-intrusion`: MOSER's intrusion detection module as its own process.

use std::time::Duration;

use clap::Parser;
use modbot_core::Blackboard;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::ModuleArgs;
use modbot_modules::intrusion::{self, Intrusion};
use modbot_modules::moser::building::moser_building;
use modbot_modules::moser::intruder::moser_intruder;

/// Heat, light and motion sensors fused into the probability of an intruder; above the
/// threshold, an alert to the control station with the position and the probability.
///
/// Blackboard: `heat`, `motion`, `light`, `probability`, `alerts`.
#[derive(Debug, Parser)]
#[command(name = "modbot-intrusion", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// Alert above this fused probability.
    #[arg(long, default_value_t = 0.8)]
    threshold: f64,
    /// The mobility module (the robot's pose).
    #[arg(long, default_value = "mobility")]
    mobility: String,
    /// The control station, which gets the alerts.
    #[arg(long, default_value = "control_station")]
    station: String,
    /// Sampling period in milliseconds.
    #[arg(long, default_value_t = 50)]
    period_ms: u64,
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::main("modbot-intrusion", run)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    anyhow::ensure!(
        cli.threshold > 0.0 && cli.threshold < 1.0,
        "--threshold {}: use a probability in (0, 1)",
        cli.threshold
    );
    let mut bb = Blackboard::builder();
    for name in ["heat", "motion", "light", "probability"] {
        bb = bb.item(name, OwnedValue::F64(0.0));
    }
    let bb = bb.item("alerts", OwnedValue::I64(0)).build()?;
    let state = Intrusion::new(
        moser_building(),
        moser_intruder(),
        cli.threshold,
        &cli.mobility,
        &cli.station,
    );
    let module = cli
        .module
        .module("intrusion", 12)
        .every(Duration::from_millis(cli.period_ms.max(1)), intrusion::tick)
        .blackboard(bb)
        .peer(&cli.mobility)
        .peer(&cli.station);
    Ok(cli.module.serve(module, state)?)
}
