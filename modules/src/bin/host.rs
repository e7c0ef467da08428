//! `modbot-host`: a component host of the time grid — steps the components of one host name.

use std::time::Duration;

use clap::Parser;
use modbot_modules::common::{init_logging, GridArgs, ModuleArgs};
use modbot_runtime::clock::{Clock, MonotonicClock};
use modbot_runtime::grid::component::Registry;
use modbot_runtime::grid::host::Host;
use modbot_runtime::{signals, ModuleBuilder};

/// Steps the components the system description puts on `--host`, whenever the coordinator
/// releases them. The supervisor starts one per host name of the grid.
#[derive(Debug, Parser)]
#[command(name = "modbot-host", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    #[command(flatten)]
    grid: GridArgs,
    /// The host name whose components this process steps.
    #[arg(long)]
    host: String,
}

fn main() -> anyhow::Result<()> {
    init_logging();
    let cli = Cli::parse();
    let grid = cli.grid.load()?;
    let transport = cli.module.transport()?;
    let node = transport.node(&format!("grid.host.{}", cli.host))?;
    let mut host = Host::new(&node, &grid, &Registry::builtin(), &cli.host)?;
    let mut module = ModuleBuilder::new(
        cli.module
            .name
            .as_deref()
            .unwrap_or(&grid.host_module(&cli.host)),
        cli.module.addr.unwrap_or(200),
    )
    .mode(cli.module.receive_mode())
    .open(transport, ())?;
    signals::install_termination_handler()?;
    let now = || MonotonicClock.now_ns();
    while !signals::termination_requested() {
        host.wait_and_serve(Duration::from_millis(5), &now)?;
        host.prepare_step(&node, Registry::builtin)?;
        while module.poll_once()? {}
        module.housekeeping();
    }
    if host.missing > 0 {
        tracing::warn!("{} input version(s) were missing", host.missing);
    }
    Ok(())
}
