//! Why a program stopped ([`ProgramError`]: `file:line: why`) and why the robot did not do
//! what it was asked ([`RobotError`]).

use thiserror::Error;

/// Why a robot program stopped: where (the program's line that called the failing command, or
/// the line of the Lua error) and why.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{}{message}", at(.file, .line))]
pub struct ProgramError {
    /// The file (as the program names it: `prog.lua`, a library `moves.lua`); empty when the
    /// failure is not on a line (a file that cannot be read).
    pub file: String,
    pub line: Option<u32>,
    pub message: String,
}

fn at(file: &str, line: &Option<u32>) -> String {
    match (file, line) {
        ("", _) => String::new(),
        (f, Some(l)) => format!("{f}:{l}: "),
        (f, None) => format!("{f}: "),
    }
}

impl ProgramError {
    pub fn new(file: &str, line: Option<u32>, message: impl Into<String>) -> ProgramError {
        ProgramError {
            file: file.to_owned(),
            line,
            message: message.into(),
        }
    }
}

/// Why the running system did not do what the interpreter asked.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RobotError {
    #[error("assembly '{assembly}' was not switched to: {why}")]
    Switch { assembly: String, why: String },
    #[error("read(\"{what}\"): {why}")]
    Read { what: String, why: String },
    #[error("call(\"{target}\"): {why}")]
    Call { target: String, why: String },
    #[error("the grid: {0}")]
    Grid(String),
    #[error("the robot: {0}")]
    Robot(String),
}
