//! `modbot-faulty`: a module that misbehaves on request, for fault-injection tests.

use std::time::Duration;

use clap::Parser;
use modbot_modules::common::ModuleArgs;
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
    modbot_modules::common::main("modbot-faulty", run)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let state = Faulty {
        slow_ms: cli.slow_ms,
        ..Default::default()
    };
    let module = cli
        .module
        .module("faulty", 10)
        .method("ping", faulty::ping)
        .method("panic", faulty::panic)
        .method("exit", faulty::exit)
        .method("hang", faulty::hang)
        .method("flood", faulty::flood)
        .method("spam", faulty::spam)
        .on_report(faulty::on_report)
        .every(Duration::from_millis(10), faulty::tick);
    Ok(cli.module.serve(module, state)?)
}
