//! `modbot-host`: a component host of the time grid — steps the components of one host name.

use std::sync::Arc;
use std::time::Duration;

use clap::Parser;
use modbot_grid_processes::grid_args::GridArgs;
use modbot_grid_processes::service_thread::serve_module;
use modbot_modules::common::{init_logging, ModuleArgs};
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

fn main() -> std::process::ExitCode {
    modbot_modules::common::finish("modbot-host", run())
}

fn run() -> anyhow::Result<()> {
    init_logging();
    let cli = Cli::parse();
    let grid = cli.grid.load()?;
    let transport = cli.module.transport()?;
    let node = Arc::new(transport.threadsafe_node(&format!("grid.host.{}", cli.host))?);
    let mut host = Host::new(&node, &grid, &Registry::builtin(), &cli.host)?;
    signals::install_termination_handler()?;
    // Listening on the grid, the host announces itself: its module runs on a thread of its own.
    let name = cli
        .module
        .name
        .clone()
        .unwrap_or_else(|| grid.host_module(&cli.host));
    let (addr, mode) = (cli.module.addr.unwrap_or(200), cli.module.receive_mode());
    let service = serve_module(move || {
        Ok(ModuleBuilder::new(&name, addr)
            .mode(mode)
            .open(transport, ())?)
    })?;
    // `grid { mlock = true }`: locked before the clocked work begins.
    modbot_runtime::supervisor::env::apply_mlockall();
    modbot_runtime::supervisor::rt::real_time_thread(grid.host_priority(), "serving thread");
    let now = || MonotonicClock.now_ns();
    while !signals::termination_requested() && !service.is_finished() {
        // Wakes up for its releases; every 5 ms also to look at the termination flag.
        host.wait_and_serve(Some(Duration::from_millis(5)), &now)?;
        host.prepare_step(&node, modbot_grid_processes::grid_args::load_assembly)?;
    }
    if host.stale > 0 {
        tracing::warn!(
            "{} release(s) not executed: an input's version was gone",
            host.stale
        );
    }
    match service.join() {
        Ok(result) => result,
        Err(_) => anyhow::bail!("the service thread panicked"),
    }
}
