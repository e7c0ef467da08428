//! `modbot-faulty`: a module that misbehaves on request, for fault-injection tests.

use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use modbot_core::Blackboard;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::ModuleArgs;
use modbot_modules::faulty::{self, Faulty};

/// A module that panics, exits, hangs, floods or spams when called to; see `modbot_modules::faulty`.
///
/// Methods: `ping()`, `panic()`, `exit(code)`, `hang()`, `work(ms)`, `flood(module, n)`, `spam(module, n)`,
/// `record(seq)`. Blackboard: `recorded`, the last `seq` recorded (0: none yet), and
/// `reports`, the SPAM reports received (as of the last 10 ms tick).
#[derive(Debug, Parser)]
#[command(name = "modbot-faulty", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// Milliseconds spent on every REPORT received (a slow consumer).
    #[arg(long, default_value_t = 0)]
    slow_ms: u64,
    /// The file `record(seq)` appends to (created if missing; every restart appends to it).
    #[arg(long, value_name = "PATH")]
    journal: Option<std::path::PathBuf>,
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::main("modbot-faulty", run)
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let journal = match &cli.journal {
        Some(path) => Some(
            std::fs::OpenOptions::new()
                .append(true)
                .create(true)
                .open(path)
                .with_context(|| format!("cannot open the journal {}", path.display()))?,
        ),
        None => None,
    };
    let state = Faulty {
        slow_ms: cli.slow_ms,
        journal,
        ..Default::default()
    };
    let module = cli
        .module
        .module("faulty", 10)
        .method("ping", faulty::ping)
        .method("panic", faulty::panic)
        .method("exit", faulty::exit)
        .method("hang", faulty::hang)
        .method("work", faulty::work)
        .method("flood", faulty::flood)
        .method("spam", faulty::spam)
        .method("record", faulty::record)
        .blackboard(
            Blackboard::builder()
                .item("recorded", OwnedValue::I64(0))
                .item("reports", OwnedValue::I64(0))
                .build()?,
        )
        .on_report(faulty::on_report)
        .every(Duration::from_millis(10), faulty::tick);
    Ok(cli.module.serve(module, state)?)
}
