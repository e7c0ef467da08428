//! What every module program shares: `--domain`, `--name`, `--addr`, `--mode`, and logging.

use clap::Args;
use modbot_core::{Domain, IpcTransport, ReceiveMode};

/// The options every module program takes.
#[derive(Debug, Clone, Args)]
pub struct ModuleArgs {
    /// The system's domain: every module of one robot uses the same.
    #[arg(long, env = "MODBOT_DOMAIN", default_value = "default")]
    pub domain: String,
    /// The module's name in the phone book.
    #[arg(long)]
    pub name: Option<String>,
    /// The module's 8-bit address (1..=254).
    #[arg(long)]
    pub addr: Option<u8>,
    /// How to wait for frames: `blocking` (sleep until woken) or `busy` (spin on a core).
    #[arg(long, default_value = "blocking", value_parser = ["blocking", "busy"])]
    pub mode: String,
}

impl ModuleArgs {
    pub fn receive_mode(&self) -> ReceiveMode {
        if self.mode == "busy" {
            ReceiveMode::BusyPoll
        } else {
            ReceiveMode::Blocking
        }
    }

    pub fn transport(&self) -> anyhow::Result<IpcTransport> {
        Ok(IpcTransport::new(&Domain::new(&self.domain)?)?)
    }
}

/// Ends a module program: an error is one line on stderr, `PROGRAM: what went wrong: its
/// causes`, and exit status 1 — never a backtrace, whatever `RUST_BACKTRACE` says (a panic
/// keeps its backtrace: that is a bug, not a refusal).
pub fn finish(program: &str, result: anyhow::Result<()>) -> std::process::ExitCode {
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{program}: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}

/// Logs to stderr, filtered by `RUST_LOG` (default `info`); colours only on a terminal (under
/// `modbot up` the supervisor reads the lines through a pipe).
pub fn init_logging() {
    use std::io::IsTerminal;
    let filter =
        tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
}
