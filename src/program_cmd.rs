//! `modbot program run FILE` and `modbot program repl`: robot programs (`modbot-program`),
//! against the system running in the domain, with its assembly data.

use std::io::{BufRead, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Subcommand;
use modbot_program::{interrupt, Interpreter, Interrupt, Left, Options, ProgramError, SystemRobot};

/// What `modbot program` does.
#[derive(Debug, Subcommand)]
pub enum ProgramCommand {
    /// Runs a robot program (a Lua file) to its end: each command switches to its assembly,
    /// waits until it is done and keeps its results in assembly data; one line per command
    /// run. A failure (or Ctrl-C) stops it with `file:line: why`, leaves the robot holding and
    /// exits 1.
    Run {
        /// The program.
        file: PathBuf,
    },
    /// Reads commands and Lua lines one at a time (line editing and history on a terminal,
    /// plain lines from a pipe), prints results; `help` lists the commands with their
    /// parameters, `quit` or Ctrl-D ends.
    Repl,
}

pub fn run(domain: &str, command: ProgramCommand) -> anyhow::Result<ExitCode> {
    interrupt::install()?;
    match command {
        ProgramCommand::Run { file } => run_file(domain, &file),
        ProgramCommand::Repl => repl(domain),
    }
}

/// An interpreter for the system in `domain`; `require` looks in `dir`.
fn interpreter(domain: &str, dir: &Path) -> anyhow::Result<Interpreter> {
    let robot = SystemRobot::open(domain)?;
    let store = crate::data_cmd::open_store(domain)?;
    let options = Options {
        dir: dir.to_owned(),
        interrupt: Interrupt::Signals,
        report: Box::new(|line| println!("{line}")),
    };
    Ok(Interpreter::new(Box::new(robot), store, options)?)
}

fn run_file(domain: &str, file: &Path) -> anyhow::Result<ExitCode> {
    let dir = file.parent().filter(|d| !d.as_os_str().is_empty());
    let mut sut = interpreter(domain, dir.unwrap_or(Path::new(".")))?;
    match sut.run_file(file) {
        Ok(()) => Ok(ExitCode::SUCCESS),
        Err(e) => {
            fail(&mut sut, &e);
            Ok(ExitCode::from(1))
        }
    }
}

/// Says why the program stopped, and how it left the robot.
fn fail(sut: &mut Interpreter, e: &ProgramError) {
    eprintln!("{e}");
    match sut.left() {
        Left::Untouched => {}
        Left::Holding(tick) => eprintln!("the robot holds (assembly hold from tick {tick})"),
        Left::NotHolding(why) => eprintln!("the robot could not be left holding: {why}"),
    }
}

fn repl(domain: &str) -> anyhow::Result<ExitCode> {
    let mut sut = interpreter(domain, Path::new("."))?;
    let one = |sut: &mut Interpreter, line: &str| -> bool {
        match line.trim() {
            "" => {}
            "quit" | "exit" => return false,
            "help" => print!("{}", sut.help()),
            line => match sut.run_line(line) {
                Ok(Some(shown)) => println!("{shown}"),
                Ok(None) => {}
                Err(e) => fail(sut, &e),
            },
        }
        let _ = std::io::stdout().flush();
        true
    };
    if !std::io::stdin().is_terminal() {
        for line in std::io::stdin().lock().lines() {
            if !one(&mut sut, &line?) {
                break;
            }
        }
        return Ok(ExitCode::SUCCESS);
    }
    let mut editor = rustyline::DefaultEditor::new()?;
    let history = modbot_data::path_for(domain).with_extension("history");
    let _ = editor.load_history(&history);
    println!("modbot program repl, domain '{domain}': `help` lists the commands, `quit` ends");
    loop {
        match editor.readline("modbot> ") {
            Ok(line) => {
                let _ = editor.add_history_entry(line.as_str());
                if !one(&mut sut, &line) {
                    break;
                }
            }
            Err(rustyline::error::ReadlineError::Interrupted) => continue,
            Err(rustyline::error::ReadlineError::Eof) => break,
            Err(e) => return Err(e.into()),
        }
    }
    let _ = editor.save_history(&history);
    Ok(ExitCode::SUCCESS)
}
