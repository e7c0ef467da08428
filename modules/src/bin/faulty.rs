//! `modbot-faulty`: a module that misbehaves on request, for fault-injection tests.

use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use modbot_core::module::MethodFn;
use modbot_core::Blackboard;
use modbot_ipc_schema::OwnedValue;
use modbot_modules::common::ModuleArgs;
use modbot_modules::faulty::{self, Faulty};

/// A module that panics, exits, hangs, floods or spams when called to; see `modbot_modules::faulty`.
///
/// Methods: `ping()`, `panic()`, `exit(code)`, `hang()`, `work(ms)`, `flood(module, n)`, `spam(module, n)`,
/// `record(seq)`. Blackboard: `recorded`, the last `seq` recorded (0: none yet),
/// `reports`, the SPAM reports received (as of the last 10 ms tick), and `upgrades`, the live
/// upgrades its state went through (carried by its upgrade hooks).
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
    /// Serve without the method NAME: a program of another method table (for tests of
    /// `modbot upgrade`'s refusal).
    #[arg(long, value_name = "NAME")]
    without_method: Option<String>,
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
    let methods: [(&str, MethodFn<Faulty>); 8] = [
        ("ping", faulty::ping),
        ("panic", faulty::panic),
        ("exit", faulty::exit),
        ("hang", faulty::hang),
        ("work", faulty::work),
        ("flood", faulty::flood),
        ("spam", faulty::spam),
        ("record", faulty::record),
    ];
    let mut module = cli.module.module("faulty", 10);
    for (name, f) in methods {
        if cli.without_method.as_deref() != Some(name) {
            module = module.method(name, f);
        }
    }
    let module = module
        .blackboard(
            Blackboard::builder()
                .item("recorded", OwnedValue::I64(0))
                .item("reports", OwnedValue::I64(0))
                .item("upgrades", OwnedValue::I64(0))
                .build()?,
        )
        .on_report(faulty::on_report)
        .on_upgrade_out(faulty::STATE_VERSION, faulty::upgrade_out)
        .on_upgrade_in(faulty::upgrade_in)
        .every(Duration::from_millis(10), faulty::tick);
    Ok(cli.module.serve(module, state)?)
}
