//! `modbot assembly`: where the assemblies stand, and `modbot assembly switch NAME`.

use std::process::ExitCode;
use std::time::Duration;

use clap::Subcommand;
use modbot_grid::switch;

/// What `modbot assembly` does.
#[derive(Debug, Subcommand)]
pub enum AssemblyCommand {
    /// The running assembly, a switch under way, and the recent switches.
    Status,
    /// Prepare assembly NAME while the running one goes on, then switch at an announced tick;
    /// prints the tick. Exits 1 with the reason when it cannot be switched to (the running
    /// assembly then stays).
    Switch {
        name: String,
        /// How long to wait for the switch, in seconds.
        #[arg(long, default_value_t = 30.0)]
        timeout: f64,
    },
}

pub fn run(domain: &str, command: Option<AssemblyCommand>) -> anyhow::Result<ExitCode> {
    let mut tool = crate::tool::open(domain)?;
    match command.unwrap_or(AssemblyCommand::Status) {
        AssemblyCommand::Status => match switch::status(&mut tool) {
            Ok(s) => {
                println!("assembly {} (generation {})", s.assembly, s.generation);
                println!("switch: {}", s.state);
                for outcome in &s.outcomes {
                    println!("  {outcome}");
                }
                Ok(ExitCode::SUCCESS)
            }
            Err(e) => {
                eprintln!("modbot assembly: {e}");
                Ok(ExitCode::from(1))
            }
        },
        AssemblyCommand::Switch { name, timeout } => {
            if !(timeout.is_finite() && timeout > 0.0) {
                anyhow::bail!("--timeout {timeout}: expected a positive number of seconds");
            }
            match switch::switch(&mut tool, &name, Duration::from_secs_f64(timeout)) {
                Ok(s) => {
                    println!(
                        "switched to {} (generation {}) at tick {}, announced for tick {}, {} ms after the request",
                        s.assembly,
                        s.generation,
                        s.tick,
                        s.announced,
                        s.took.as_millis()
                    );
                    Ok(ExitCode::SUCCESS)
                }
                Err(e) => {
                    eprintln!("modbot assembly switch: {e}");
                    Ok(ExitCode::from(1))
                }
            }
        }
    }
}
