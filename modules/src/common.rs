//! What every module program shares: `--domain`, `--name`, `--addr`, `--mode`, and logging.

pub use modbot_core::cli::ModuleArgs;

/// Ends a module program as [`modbot_core::cli::exit`] does: an error is one line on stderr,
/// `PROGRAM: what went wrong: its causes`, exit status 1, never a backtrace.
pub fn finish(program: &str, result: anyhow::Result<()>) -> std::process::ExitCode {
    let boxed: Box<dyn std::error::Error + Send + Sync> = match result {
        Ok(()) => return modbot_core::cli::exit(program, Ok(())),
        Err(e) => e.into(),
    };
    modbot_core::cli::exit(program, Err(boxed))
}

/// The `main` of a module program: logging (see [`init_logging`]), the command line `C`,
/// then `run`; ends as [`finish`] does.
pub fn main<C: clap::Parser>(
    program: &str,
    run: impl FnOnce(C) -> anyhow::Result<()>,
) -> std::process::ExitCode {
    init_logging();
    finish(program, run(C::parse()))
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
