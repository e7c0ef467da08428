//! The command line every module program takes — `--domain`, `--name`, `--addr`, `--mode`,
//! what a supervisor passes the processes it starts (the rest of what it tells them is in the
//! environment: [`crate::transport::launch`]). Flatten [`ModuleArgs`] into a program's own
//! `clap` parser.

use clap::Args;

use crate::domain::Domain;
use crate::error::ModuleError;
use crate::module::ModuleBuilder;
use crate::transport::ipc::IpcTransport;
use crate::transport::ReceiveMode;

/// The environment variable a module program reads its `--linger-us` from (a system
/// description's `linger_us` sets it).
pub const LINGER_ENV: &str = "MODBOT_LINGER_US";

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
    /// Blocking mode: how long, in µs, the module looks for the next frame after serving one
    /// before it sleeps again (0: sleeps at once; see `ModuleBuilder::linger`).
    #[arg(long, env = LINGER_ENV, value_name = "US",
          default_value_t = crate::module::DEFAULT_LINGER.as_micros() as u64)]
    pub linger_us: u64,
}

impl ModuleArgs {
    /// The receive mode asked for.
    pub fn receive_mode(&self) -> ReceiveMode {
        if self.mode == "busy" {
            ReceiveMode::BusyPoll
        } else {
            ReceiveMode::Blocking
        }
    }

    /// The iceoryx2 transport of the domain.
    pub fn transport(&self) -> Result<IpcTransport, ModuleError> {
        Ok(IpcTransport::new(&Domain::new(&self.domain)?)?)
    }

    /// The name given, else `default`.
    pub fn name_or(&self, default: &str) -> String {
        self.name.clone().unwrap_or_else(|| default.to_owned())
    }

    /// The address given, else `default`.
    pub fn addr_or(&self, default: u8) -> u8 {
        self.addr.unwrap_or(default)
    }

    /// A builder for the module these options name: `--name` else `name`, `--addr` else
    /// `addr`, waiting for frames as `--mode` and `--linger-us` say.
    pub fn module<S>(&self, name: &str, addr: u8) -> ModuleBuilder<S> {
        ModuleBuilder::new(&self.name_or(name), self.addr_or(addr))
            .mode(self.receive_mode())
            .linger(core::time::Duration::from_micros(self.linger_us))
    }

    /// Opens the module `builder` describes in the domain, with `state`, and serves until it
    /// is stopped (see [`crate::Module::run`]).
    pub fn serve<S>(&self, builder: ModuleBuilder<S>, state: S) -> Result<(), ModuleError> {
        builder.open(self.transport()?, state)?.run()
    }
}

/// Ends a module program: `Ok` exits 0; an error is one line on stderr — `PROGRAM: what went
/// wrong: its causes` — and exit status 1, never a backtrace (a panic keeps its backtrace:
/// that is a bug, not a refusal).
pub fn exit(
    program: &str,
    result: Result<(), Box<dyn std::error::Error>>,
) -> std::process::ExitCode {
    let Err(e) = result else {
        return std::process::ExitCode::SUCCESS;
    };
    let mut line = format!("{program}: {e}");
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        // thiserror's transparent errors repeat their source's text: say it once.
        if !line.ends_with(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        cause = c.source();
    }
    eprintln!("{line}");
    std::process::ExitCode::from(1)
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Debug, Parser)]
    struct Program {
        #[command(flatten)]
        module: ModuleArgs,
    }

    #[test]
    fn a_module_program_lingers_fifty_microseconds_unless_told_otherwise() {
        let default = Program::try_parse_from(["m"]).unwrap();
        assert_eq!(default.module.linger_us, 50);
        let none = Program::try_parse_from(["m", "--linger-us", "0"]).unwrap();
        assert_eq!(none.module.linger_us, 0);
        let err = Program::try_parse_from(["m", "--linger-us", "soon"]).unwrap_err();
        assert!(err.to_string().contains("--linger-us"), "{err}");
    }
}
