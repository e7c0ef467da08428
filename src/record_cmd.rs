//! `modbot record compare A.h5 B.h5`: two recordings compared tick by tick, to the last bit.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Subcommand;

/// What `modbot record` does.
#[derive(Debug, Subcommand)]
pub enum RecordCommand {
    /// Compare two recordings of the same signals row by row, bit for bit: "identical through
    /// tick N" (exit 0), or the first tick, signal and values that differ (exit 1).
    Compare { a: PathBuf, b: PathBuf },
}

pub fn run(command: RecordCommand) -> anyhow::Result<ExitCode> {
    match command {
        RecordCommand::Compare { a, b } => match modbot_record::compare::compare(&a, &b) {
            Ok(c) => {
                println!("{c}");
                Ok(match c {
                    modbot_record::compare::Comparison::Identical { .. } => ExitCode::SUCCESS,
                    modbot_record::compare::Comparison::Differs { .. } => ExitCode::from(1),
                })
            }
            Err(e) => {
                eprintln!("modbot record compare: {e}");
                Ok(ExitCode::from(2))
            }
        },
    }
}
