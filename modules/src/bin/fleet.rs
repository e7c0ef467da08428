//! `modbot-fleet`: one module of a sensor fleet, a sensor or an aggregator
//! (see `modbot_modules::fleet`).

use std::time::Duration;

use clap::{Parser, Subcommand};
use modbot_core::Blackboard;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::ModuleArgs;
use modbot_modules::fleet::{self, Aggregator, Sensor};

/// A module of a sensor fleet.
///
/// `sensor --aggregator NAME`: reports a simulated temperature to its aggregator every period;
/// answers `read()` (a reading taken then); blackboard `value`. `aggregator`: keeps every sensor's latest reading;
/// answers `summary()` (sensors, mean, min, max, reports); blackboard `sensors`, `mean`,
/// `reports`.
#[derive(Debug, Parser)]
#[command(name = "modbot-fleet", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    #[command(subcommand)]
    role: Role,
}

#[derive(Debug, Subcommand)]
enum Role {
    /// A sensor.
    Sensor {
        /// The module it reports to.
        #[arg(long)]
        aggregator: String,
        /// Report period in milliseconds.
        #[arg(long, default_value_t = 1000)]
        period_ms: u64,
    },
    /// An aggregator.
    Aggregator,
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::main("modbot-fleet", run)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.role {
        Role::Sensor {
            aggregator,
            period_ms,
        } => {
            let bb = Blackboard::builder()
                .item("value", OwnedValue::F64(f64::NAN))
                .build()?;
            let module = cli
                .module
                .module("fleet", 1)
                .method("read", fleet::read)
                .every(Duration::from_millis(period_ms.max(1)), fleet::sense)
                .blackboard(bb)
                .snapshot_period(Duration::from_secs(1))
                .peer(&aggregator);
            cli.module.serve(module, Sensor::new(&aggregator))?;
        }
        Role::Aggregator => {
            let bb = Blackboard::builder()
                .item("sensors", OwnedValue::I64(0))
                .item("mean", OwnedValue::F64(f64::NAN))
                .item("reports", OwnedValue::I64(0))
                .build()?;
            let module = cli
                .module
                .module("fleet", 1)
                .method("summary", fleet::summary)
                .on_report(fleet::on_reading)
                .blackboard(bb)
                .snapshot_period(Duration::from_secs(1));
            cli.module.serve(module, Aggregator::default())?;
        }
    }
    Ok(())
}
