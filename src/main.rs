//! `modbot`: the command line of the modbot runtime.
//!
//! - `rvmf encode|decode`: build and read RVMF* frames (see `rvmf_cmd`).
//! - `ls`, `call`, `bb`: look at and talk to a running system (see `tool`).
//! - `check FILE`: load and check a system description (see `check_cmd`).
//! - `up FILE`, `down`: run a system under the supervisor, and stop it (see `up_cmd`).

mod check_cmd;
mod rvmf_cmd;
mod tool;
mod up_cmd;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// modbot: zero-copy shared-memory IPC for modular robot controllers.
#[derive(Debug, Parser)]
#[command(name = "modbot", version, about)]
struct Cli {
    /// The system's domain (its shared-memory namespace).
    #[arg(long, global = true, env = "MODBOT_DOMAIN", default_value = "default")]
    domain: String,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Encode or decode RVMF* frames.
    Rvmf {
        #[command(subcommand)]
        command: rvmf_cmd::RvmfCommand,
    },
    /// Check a system description (a Lua file) and print its modules.
    ///
    /// Exits with 2 and one `file:line: message` line on stderr when it is invalid.
    Check {
        /// The system description.
        file: PathBuf,
    },
    /// Start a system: every module of the description as its own process, supervised.
    ///
    /// Shows the modules' logs, prefixed with their names, and their status; stops on
    /// Ctrl-C, SIGTERM, `modbot down`, or after `--for`. Exits 0 if every module stopped
    /// cleanly, 1 with a summary otherwise, 2 if the description is invalid.
    Up {
        /// The system description (a Lua file).
        file: PathBuf,
        /// Stop after this many seconds.
        #[arg(long = "for", value_name = "SECONDS")]
        run_for: Option<f64>,
    },
    /// Stop the system running in the domain (from another terminal).
    Down,
    /// List the modules of the domain: address, name, pid, state, restarts, last exit,
    /// frame counters and methods.
    Ls {
        /// Tab-separated values with a header line, for scripts.
        #[arg(long)]
        tsv: bool,
    },
    /// Call a method: `modbot call MODULE.METHOD [ARGS...]`.
    ///
    /// Arguments: `1.5` is f64, `3` i64, `true` bool, `[1,2]` f64 array, `0x0a0b` bytes,
    /// anything else text; `f64:3` or `text:true` force a kind.
    Call {
        /// MODULE.METHOD
        target: String,
        /// The method's arguments.
        #[arg(allow_hyphen_values = true)]
        args: Vec<String>,
        /// How long to wait for the answer, in milliseconds.
        #[arg(long, default_value_t = 2000)]
        timeout_ms: u64,
        /// If the module is down (restarting, say), wait for it until the timeout instead of
        /// failing at once with "not available".
        #[arg(long)]
        wait: bool,
    },
    /// Read a module's blackboard (one snapshot), read one item, or write one.
    Bb {
        module: String,
        item: Option<String>,
        #[arg(allow_hyphen_values = true)]
        value: Option<String>,
    },
}

fn main() -> ExitCode {
    let filter =
        tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Rvmf { command } => return rvmf_cmd::run(command),
        Command::Check { file } => return check_cmd::run(&file),
        Command::Up { file, run_for } => up_cmd::up(&file, run_for),
        Command::Down => tool::down(&cli.domain),
        Command::Ls { tsv } => tool::ls(&cli.domain, tsv),
        Command::Call {
            target,
            args,
            timeout_ms,
            wait,
        } => tool::call(&cli.domain, &target, &args, timeout_ms, wait),
        Command::Bb {
            module,
            item,
            value,
        } => tool::bb(&cli.domain, &module, item.as_deref(), value.as_deref()),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("modbot: {e:#}");
            ExitCode::from(1)
        }
    }
}
