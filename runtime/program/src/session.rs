//! What the interpreter's Lua functions share: the robot, assembly data, the commands
//! defined, the first failure, the instruction budget and where reports go.
//!
//! Borrows of it are short and never span a call into Lua: a command calls its hooks, and
//! they call `read`, `data` and other commands' functions, which borrow it again.

use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;

use modbot_data::Store;

use super::interrupt::Interrupt;
use super::{ProgramError, Robot};

/// What the sandbox calls a program in refusals.
pub(crate) const WHAT: &str = "a robot program";
/// The chunk name of the command library (`library.lua`).
pub(crate) const LIBRARY_NAME: &str = "modbot library";

/// A command as `help` lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CommandInfo {
    pub name: String,
    pub doc: String,
    /// (parameter, what it is), sorted by name.
    pub params: Vec<(String, String)>,
    /// Where it was defined (`modbot library`, or `file:line` of a program's library).
    pub origin: String,
}

pub(crate) struct Session {
    pub robot: Box<dyn Robot>,
    pub store: Store,
    pub commands: Vec<CommandInfo>,
    /// The first failure of the script running; it stops the script.
    pub failure: Option<ProgramError>,
    /// Instructions since the running command (or REPL line) began.
    pub spent: u64,
    pub interrupt: Interrupt,
    /// Reports of command runs (one line each).
    pub report: Box<dyn FnMut(&str)>,
    /// The program's directory: `require "name"` loads `<dir>/name.lua`.
    pub dir: PathBuf,
    /// The libraries required so far, by name, with what they returned (in the Lua registry).
    pub required: Vec<String>,
    /// Whether a command switched the robot's assembly (a failure then leaves it holding).
    pub moved: bool,
}

pub(crate) type Shared = Rc<RefCell<Session>>;

/// Records `error` as the failure (unless there is one already) and returns the Lua error that
/// stops the script.
pub(crate) fn fail(shared: &Shared, error: ProgramError) -> mlua::Error {
    let mut s = shared.borrow_mut();
    if s.failure.is_none() {
        s.failure = Some(error);
    }
    modbot_system::sandbox::stop()
}

/// The failure, at the Lua line that called the running Rust function.
pub(crate) fn fail_here(
    lua: &mlua::Lua,
    shared: &Shared,
    message: impl std::fmt::Display,
) -> mlua::Error {
    let (file, line) = modbot_system::sandbox::caller(lua).unwrap_or_default();
    fail(
        shared,
        ProgramError::new(&file, Some(line), message.to_string()),
    )
}
