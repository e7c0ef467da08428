//! `modbot`: the command line of the modbot runtime.
//!
//! - `rvmf encode|decode`: build and read RVMF* frames (see `rvmf_cmd`).
//! - `ls`, `call`, `bb`: look at and talk to a running system (see `tool`).

mod rvmf_cmd;
mod tool;

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
    /// List the modules of the domain: address, name, pid, state, methods.
    Ls,
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
        Command::Ls => tool::ls(&cli.domain),
        Command::Call {
            target,
            args,
            timeout_ms,
        } => tool::call(&cli.domain, &target, &args, timeout_ms),
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
