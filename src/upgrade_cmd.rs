//! `modbot upgrade MODULE [--program PATH] [--force]`: asks the supervisor for a live upgrade
//! of a running module and waits for its outcome (see `modbot_core::upgrade`).

use std::path::Path;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context;
use modbot_core::tool::Calls;
use modbot_core::CallOptions;
use modbot_ipc_schema::{OwnedValue, Value};

use crate::tool;

/// What `modbot upgrade` was given.
pub struct UpgradeArgs<'a> {
    pub module: &'a str,
    /// The new program; the module's own (rebuilt in place) when `None`.
    pub program: Option<&'a Path>,
    pub force: bool,
    /// How long to wait for the outcome.
    pub timeout: Duration,
}

pub fn run(domain: &str, a: &UpgradeArgs<'_>) -> anyhow::Result<ExitCode> {
    // The supervisor may run elsewhere in the file system: it gets an absolute path.
    let program = match a.program {
        Some(p) => std::fs::canonicalize(p)
            .with_context(|| format!("the program {}", p.display()))?
            .display()
            .to_string(),
        None => String::new(),
    };
    let mut tool = tool::open(domain)?;
    let opts = CallOptions::timeout(Duration::from_secs(2));
    let args = [
        Value::Text(a.module),
        Value::Text(&program),
        Value::Bool(a.force),
    ];
    if let Err(e) = tool.call_owned("supervisor", "upgrade", &args, opts) {
        eprintln!("modbot upgrade: {e}");
        return Ok(ExitCode::from(1));
    }
    let deadline = Instant::now() + a.timeout;
    loop {
        let status = tool.call_owned(
            "supervisor",
            "upgrade_status",
            &[Value::Text(a.module)],
            opts,
        );
        let (state, detail) = match status.as_deref() {
            Ok([OwnedValue::Text(state), OwnedValue::Text(detail)]) => {
                (state.clone(), detail.clone())
            }
            Ok(other) => anyhow::bail!("upgrade_status answered {other:?}"),
            Err(e) => {
                eprintln!("modbot upgrade: {e}");
                return Ok(ExitCode::from(1));
            }
        };
        match state.as_str() {
            "done" => {
                println!("{} upgraded: {}", a.module, detail);
                return Ok(ExitCode::SUCCESS);
            }
            "refused" => {
                eprintln!("modbot upgrade: {} not upgraded: {}", a.module, detail);
                return Ok(ExitCode::from(1));
            }
            _ => {}
        }
        if Instant::now() > deadline {
            eprintln!(
                "modbot upgrade: {} still upgrading after {} s ({})",
                a.module,
                a.timeout.as_secs(),
                detail
            );
            return Ok(ExitCode::from(1));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}
