//! Robot programs: MoRC's *Program Interpreter*. A robot program is a Lua file, run outside
//! real time in the sandbox of system descriptions, whose robot commands are *skills*: a
//! precondition check, an execution and an evaluation. A command's execution names an
//! assembly and its parameters: the interpreter writes the parameters to assembly data
//! (`modbot-data`, where the assembly file reads them when it is loaded), switches to the
//! assembly as `modbot assembly switch` does, waits until its finish condition holds (read
//! from what the grid's components publish) or its timeout, evaluates, keeps the run and its
//! results in assembly data, and goes on. A failed precondition or evaluation, an error, or
//! Ctrl-C stops the program with `file:line: why` and leaves the robot holding.
//!
//! ```lua
//! require "moves"                                    -- a library next to the program
//! ptp { q = { 0.3, -0.2, 0.1, 0, 0, 0 }, v = 0.5 }   -- assembly goto, until settled
//! hold {}                                            -- assembly hold
//! print(data("ptp.peak_following"))                  -- the last ptp's result
//! ```
//!
//! `modbot program run FILE` and `modbot program repl` (the CLI) drive a [`SystemRobot`].
//!
//! # Layout
//! - [`interpreter`]: [`Interpreter`] — a file, or a REPL line; what a failure leaves.
//! - `command`: `command "name" { doc, params, pre, run, done, eval }` and a command's run.
//! - `lua_env`: the sandbox with the program's functions (`read`, `call`, `data`, `require`).
//! - `recordings`: `absolute`, `recorded` (a signal read back from a recording) and `plot`
//!   (an SVG, drawn by `plot`).
//! - `library.lua`: the command library (`ptp`, `hold`, `wait`, `record`, `stop_record`),
//!   written as a program's own.
//! - `session`: what the Lua functions share (robot, store, commands, the first failure).
//! - [`robot`]: [`Robot`], what a program needs of a running system; [`system_robot`]: the
//!   real one, a tool endpoint in the system's domain.
//! - [`interrupt`]: Ctrl-C as a flag the interpreter looks at.
//! - `error`: [`ProgramError`] (`file:line: why`) and [`RobotError`].

mod command;
mod error;
pub mod interpreter;
pub mod interrupt;
mod lua_env;
mod plot;
mod recordings;
pub mod robot;
mod script_error;
mod session;
pub mod system_robot;

#[cfg(test)]
mod tests;

pub use error::{ProgramError, RobotError};
pub use interpreter::{Interpreter, Left, Options, HOLD};
pub use interrupt::Interrupt;
pub use robot::Robot;
pub use script_error::ScriptError;
pub use session::CommandInfo;
pub use system_robot::SystemRobot;
