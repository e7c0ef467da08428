//! `modbot-coordinator`: the time grid's clock. All of it is in the library's
//! [`modbot_grid_processes::coordinator`]: the grid its tick thread runs, and the service
//! thread this program's main thread becomes.

use clap::Parser;
use modbot_grid_processes::coordinator::service::{self, Cli};

fn main() -> std::process::ExitCode {
    modbot_modules::common::finish("modbot-coordinator", service::run(Cli::parse()))
}
