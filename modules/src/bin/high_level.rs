//! `modbot-high-level`: MOSER's patrol planner as its own process.

use std::time::Duration;

use clap::Parser;
use modbot_core::Blackboard;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::ModuleArgs;
use modbot_modules::high_level::{self, HighLevel};
use modbot_modules::moser::building::moser_building;

/// The high-level processing module: turns "patrol wing N" into planned paths and drives the
/// mobility module along them, planning around obstacles its map does not know.
///
/// Methods: `patrol(wing)`, `stop()`. Blackboard: `state`, `wing`, `goal`, `replans`.
#[derive(Debug, Parser)]
#[command(name = "modbot-high-level", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// The mobility module.
    #[arg(long, default_value = "mobility")]
    mobility: String,
    /// The navigation sonar (24 sensors, 360°).
    #[arg(long, default_value = "nav_sonar")]
    nav_sonar: String,
    /// The control station, which gets the progress reports.
    #[arg(long, default_value = "control_station")]
    station: String,
    /// Planning period in milliseconds.
    #[arg(long, default_value_t = 20)]
    period_ms: u64,
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::main("modbot-high-level", run)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let bb = Blackboard::builder()
        .item("state", OwnedValue::Text("idle".into()))
        .item("wing", OwnedValue::I64(0))
        .item("goal", OwnedValue::I64(0))
        .item("replans", OwnedValue::I64(0))
        .build()?;
    let state = HighLevel::new(
        moser_building(),
        &cli.mobility,
        &cli.nav_sonar,
        &cli.station,
    );
    let module = cli
        .module
        .module("high_level", 10)
        .method("patrol", high_level::patrol)
        .method("stop", high_level::stop)
        .on_done(high_level::on_done)
        .on_upgrade_out(
            high_level::carried::VERSION,
            high_level::carried::upgrade_out,
        )
        .on_upgrade_in(high_level::carried::upgrade_in)
        .every(
            Duration::from_millis(cli.period_ms.max(1)),
            high_level::tick,
        )
        .blackboard(bb)
        .peer(&cli.mobility)
        .peer(&cli.station);
    Ok(cli.module.serve(module, state)?)
}
