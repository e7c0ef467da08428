//! `modbot data ls` and `modbot data get KEY`: the domain's assembly data (`modbot-data`), read
//! while the system runs or not.

use std::process::ExitCode;

use clap::Subcommand;
use modbot_data::Store;

/// What `modbot data` does.
#[derive(Debug, Subcommand)]
pub enum DataCommand {
    /// Every key with its value, then every command run (`run.N`: command, assembly, where
    /// the program called it, ticks, outcome, results).
    Ls,
    /// One key's value, or a run's (`run.N`) record.
    Get { key: String },
}

/// The domain's store, made if there is none (a program keeps its runs there).
pub fn open_store(domain: &str) -> anyhow::Result<Store> {
    Ok(Store::open(&modbot_data::path_for(domain))?)
}

pub fn run(domain: &str, command: DataCommand) -> anyhow::Result<ExitCode> {
    let path = modbot_data::path_for(domain);
    let Some(store) = Store::open_existing(&path)? else {
        match command {
            DataCommand::Ls => {
                println!("# {}: no assembly data yet", path.display());
                return Ok(ExitCode::SUCCESS);
            }
            DataCommand::Get { key } => {
                eprintln!(
                    "modbot data get: no '{key}': there is no assembly data yet ({})",
                    path.display()
                );
                return Ok(ExitCode::from(1));
            }
        }
    };
    match command {
        DataCommand::Ls => {
            println!("# {}", path.display());
            for (key, value) in store.entries()? {
                println!("{key} = {value}");
            }
            for (n, run) in store.runs()? {
                println!("run.{n}: {run}");
            }
            Ok(ExitCode::SUCCESS)
        }
        DataCommand::Get { key } => {
            let run = key.strip_prefix("run.").and_then(|n| n.parse::<u64>().ok());
            let shown = match run {
                Some(n) => store.run(n)?.map(|r| r.to_string()),
                None => store.get(&key)?.map(|v| v.to_string()),
            };
            match shown {
                Some(text) => {
                    println!("{text}");
                    Ok(ExitCode::SUCCESS)
                }
                None => {
                    eprintln!("modbot data get: no '{key}' in {}", path.display());
                    Ok(ExitCode::from(1))
                }
            }
        }
    }
}
