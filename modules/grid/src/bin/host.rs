//! `modbot-host`: a component host of the time grid — steps the components of one host name.

use std::time::Duration;

use clap::Parser;
use modbot_grid_processes::grid_args::load_assembly;
use modbot_grid_processes::host_process::{HostArgs, HostProcess};
use modbot_modules::common::init_logging;
use modbot_runtime::clock::{Clock, MonotonicClock};
use modbot_runtime::grid::component::Registry;

/// Steps the components the system description puts on `--host`, whenever the coordinator
/// releases them. The supervisor starts one per host name of the grid.
#[derive(Debug, Parser)]
#[command(name = "modbot-host", version)]
struct Cli {
    #[command(flatten)]
    host: HostArgs,
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::finish("modbot-host", run())
}

fn run() -> anyhow::Result<()> {
    init_logging();
    let mut p = HostProcess::start(Cli::parse().host, |_| Ok(Registry::builtin()))?;
    let name = p.grid.host_module(p.host_name());
    let service = p.serve(name, 200, |module| module, ())?;
    let now = || MonotonicClock.now_ns();
    while HostProcess::running(&service) {
        // Wakes up for its releases; every 5 ms also to look at the termination flag.
        p.host
            .wait_and_serve(Some(Duration::from_millis(5)), &now)?;
        p.host.prepare_step(&p.node, load_assembly)?;
    }
    p.finish(service)
}
