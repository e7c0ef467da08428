//! `modbot-faulty`: a module that misbehaves on request, for fault-injection tests.

use std::time::Duration;

use clap::Parser;
use modbot_core::ModuleBuilder;
use modbot_modules::common::{init_logging, ModuleArgs};
use modbot_modules::faulty::{self, Faulty};

/// A module that panics, exits, hangs, floods or spams when called to; see `modbot_modules::faulty`.
///
/// Methods: `ping()`, `panic()`, `exit(code)`, `hang()`, `flood(module, n)`, `spam(module, n)`.
#[derive(Debug, Parser)]
#[command(name = "modbot-faulty", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// Milliseconds spent on every REPORT received (a slow consumer).
    #[arg(long, default_value_t = 0)]
    slow_ms: u64,
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::finish("modbot-faulty", run())
}

fn run() -> anyhow::Result<()> {
    init_logging();
    let cli = Cli::parse();
    let state = Faulty {
        slow_ms: cli.slow_ms,
        ..Default::default()
    };
    let module = ModuleBuilder::new(
        cli.module.name.as_deref().unwrap_or("faulty"),
        cli.module.addr.unwrap_or(10),
    )
    .mode(cli.module.receive_mode())
    .method("ping", faulty::ping)
    .method("panic", faulty::panic)
    .method("exit", faulty::exit)
    .method("hang", faulty::hang)
    .method("flood", faulty::flood)
    .method("spam", faulty::spam)
    .on_report(faulty::on_report)
    .every(Duration::from_millis(10), faulty::tick)
    .open(cli.module.transport()?, state)?;
    module.run()?;
    Ok(())
}
