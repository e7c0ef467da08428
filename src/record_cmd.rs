//! `modbot record compare A.h5 B.h5`: two recordings compared tick by tick, to the last bit;
//! `modbot record export FILE.h5 --mcap OUT.mcap`: a recording for Foxglove.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Subcommand;

/// What `modbot record` does.
#[derive(Debug, Subcommand)]
pub enum RecordCommand {
    /// Compare two recordings of the same signals row by row, bit for bit, and the grid's
    /// state hash of each row: "identical through tick N" (exit 0), or the first tick, signal
    /// and values that differ, or the first tick whose state hash differs where no recorded
    /// signal does (exit 1).
    Compare { a: PathBuf, b: PathBuf },
    /// Write the recording as an MCAP file (Foxglove opens it): one channel per signal,
    /// `/modbot/<comp>.<port>`, JSON messages `{"tick": N, "value": ...}` at each tick's time.
    Export {
        file: PathBuf,
        /// The MCAP file to write.
        #[arg(long)]
        mcap: PathBuf,
    },
}

pub fn run(command: RecordCommand) -> anyhow::Result<ExitCode> {
    match command {
        RecordCommand::Compare { a, b } => match modbot_record::compare::compare(&a, &b) {
            Ok(c) => {
                println!("{c}");
                Ok(match c {
                    modbot_record::compare::Comparison::Identical { .. } => ExitCode::SUCCESS,
                    modbot_record::compare::Comparison::Differs { .. }
                    | modbot_record::compare::Comparison::StateDiffers { .. } => ExitCode::from(1),
                })
            }
            Err(e) => {
                eprintln!("modbot record compare: {e}");
                Ok(ExitCode::from(2))
            }
        },
        RecordCommand::Export { file, mcap } => match crate::mcap_export::export(&file, &mcap) {
            Ok(done) => {
                println!(
                    "{}: {} channels, {} messages",
                    mcap.display(),
                    done.channels,
                    done.messages
                );
                Ok(ExitCode::SUCCESS)
            }
            Err(e) => {
                eprintln!("modbot record export: {e:#}");
                Ok(ExitCode::from(2))
            }
        },
    }
}
