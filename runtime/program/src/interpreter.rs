//! The interpreter: a program file run to its end ([`Interpreter::run_file`]), or lines typed
//! one at a time ([`Interpreter::run_line`], the REPL). A failure stops the program (or the
//! line) with `file:line: why` and leaves the robot holding: once a command has moved it, the
//! interpreter switches to the assembly `hold`.

use std::path::{Path, PathBuf};

use mlua::{Lua, MultiValue, Table, Value};

use modbot_data::Store;
use modbot_system::sandbox;

use super::command::RESULTS_META;
use super::interrupt::Interrupt;
use super::lua_env;
use super::session::{CommandInfo, Session, Shared, LIBRARY_NAME, WHAT};
use super::{ProgramError, Robot};

/// The command library every program starts with.
const LIBRARY: &str = include_str!("library.lua");
/// The assembly a failed program leaves the robot in.
pub const HOLD: &str = "hold";

/// How an interpreter is set up.
pub struct Options {
    /// Where `require "name"` finds `name.lua` (the program's directory; the current one for
    /// the REPL).
    pub dir: PathBuf,
    /// Where a stop is asked for.
    pub interrupt: Interrupt,
    /// Where each command run is reported (one line).
    pub report: Box<dyn FnMut(&str)>,
}

/// How a failed program left the robot.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Left {
    /// No command had moved it: as it was.
    Untouched,
    /// Switched to `hold` at this tick.
    Holding(u64),
    /// The switch to `hold` failed too: why.
    NotHolding(String),
}

/// A robot program's interpreter.
pub struct Interpreter {
    lua: Lua,
    shared: Shared,
}

impl Interpreter {
    /// An interpreter driving `robot`, keeping results in `store`, with the command library
    /// loaded.
    pub fn new(
        robot: Box<dyn Robot>,
        store: Store,
        options: Options,
    ) -> Result<Interpreter, ProgramError> {
        let shared: Shared = std::rc::Rc::new(std::cell::RefCell::new(Session {
            robot,
            store,
            commands: Vec::new(),
            failure: None,
            spent: 0,
            interrupt: options.interrupt,
            report: options.report,
            dir: options.dir,
            required: Vec::new(),
            moved: false,
        }));
        let lua = lua_env::open(&shared).map_err(|e| {
            ProgramError::new("", None, format!("cannot prepare the Lua sandbox: {e}"))
        })?;
        let mut interpreter = Interpreter { lua, shared };
        interpreter.exec(LIBRARY_NAME, LIBRARY)?;
        Ok(interpreter)
    }

    /// Runs the program in `path` to its end. On a failure, returns it after leaving the robot
    /// holding (see [`Interpreter::left`]).
    pub fn run_file(&mut self, path: &Path) -> Result<(), ProgramError> {
        let name = path.display().to_string();
        let source = std::fs::read_to_string(path)
            .map_err(|e| ProgramError::new(&name, None, format!("cannot read the program: {e}")))?;
        self.exec(&name, &source)
    }

    /// Runs one line typed at the REPL: an expression's values come back as text (not a
    /// command's results: its run was reported), a statement's as nothing.
    /// A failed line leaves the robot holding only if the line itself moved it: a command
    /// done before is done, the robot at rest in its assembly.
    pub fn run_line(&mut self, line: &str) -> Result<Option<String>, ProgramError> {
        self.reset();
        self.shared.borrow_mut().moved = false;
        let chunk = "=stdin";
        // An expression first (as Lua's own REPL does), else a statement.
        let expression = self
            .lua
            .load(format!("return {line}"))
            .set_name(chunk)
            .set_mode(mlua::chunk::ChunkMode::Text)
            .into_function();
        let function = match expression {
            Ok(f) => f,
            Err(_) => self
                .lua
                .load(line)
                .set_name(chunk)
                .set_mode(mlua::chunk::ChunkMode::Text)
                .into_function()
                .map_err(|e| self.error("stdin", &e))?,
        };
        let values = function
            .call::<MultiValue>(())
            .map_err(|e| self.error("stdin", &e))?;
        let results: Table = self
            .lua
            .named_registry_value(RESULTS_META)
            .map_err(|e| self.error("stdin", &e))?;
        let shown: Vec<String> = values
            .iter()
            .filter(|v| !matches!(v, Value::Table(t) if t.metatable().as_ref() == Some(&results)))
            .map(|v| show(v, 0))
            .collect();
        Ok((!shown.is_empty()).then(|| shown.join("\t")))
    }

    /// Leaves the robot holding after a failure, if a command had moved it; forgets the
    /// failure and a Ctrl-C, so the interpreter can go on (the REPL).
    pub fn left(&mut self) -> Left {
        let moved = std::mem::take(&mut self.shared.borrow_mut().moved);
        self.reset();
        if !moved {
            return Left::Untouched;
        }
        let switched = self.shared.borrow_mut().robot.switch(HOLD);
        match switched {
            Ok(tick) => Left::Holding(tick),
            Err(e) => Left::NotHolding(e.to_string()),
        }
    }

    /// The commands defined, sorted by name.
    pub fn commands(&self) -> Vec<CommandInfo> {
        self.shared.borrow().commands.clone()
    }

    /// `help`: every command with its parameters, and the program's functions.
    pub fn help(&self) -> String {
        let mut out =
            String::from("commands (call with a table of parameters: ptp { q = { ... } }):\n");
        for c in self.commands() {
            let names: Vec<&str> = c.params.iter().map(|(n, _)| n.as_str()).collect();
            out.push_str(&format!(
                "  {} {{ {} }}  {}\n",
                c.name,
                names.join(", "),
                c.doc
            ));
            for (n, what) in &c.params {
                out.push_str(&format!("      {n}: {what}\n"));
            }
        }
        out.push_str(
            "functions:\n  read(\"module.item\")  a blackboard item, or a component's output (read(\"settle.settled\"))\n  \
             call(\"module.method\", ...)  calls a method, returns its answer\n  \
             data(\"key\"), data(\"key\", value)  reads or writes assembly data\n  \
             require \"name\"  runs the library name.lua next to the program\n  \
             command \"name\" { doc, params, pre, run, done, eval }  defines a command\n",
        );
        out
    }

    /// Runs `source` as chunk `name`.
    fn exec(&mut self, name: &str, source: &str) -> Result<(), ProgramError> {
        self.reset();
        self.lua
            .load(source)
            .set_name(format!("={name}"))
            .set_mode(mlua::chunk::ChunkMode::Text)
            .exec()
            .map_err(|e| self.error(name, &e))
    }

    /// A Lua error as the program's failure: the one recorded, else Lua's own position.
    fn error(&self, chunk: &str, e: &mlua::Error) -> ProgramError {
        if let Some(f) = self.shared.borrow().failure.clone() {
            return f;
        }
        let (file, line, message) = sandbox::position(e, WHAT);
        ProgramError::new(&file.unwrap_or_else(|| chunk.to_owned()), line, message)
    }

    /// Forgets a failure and a stop asked for, and gives the script a fresh budget.
    fn reset(&mut self) {
        {
            let mut s = self.shared.borrow_mut();
            s.failure = None;
            s.spent = 0;
            s.interrupt.clear();
        }
        lua_env::arm_budget(&self.lua, &self.shared);
    }
}

/// A Lua value as the REPL prints it: lists as `{ 1, 2 }`, tables as `{ a = 1 }` (sorted).
fn show(v: &Value, depth: usize) -> String {
    match v {
        Value::Nil => "nil".into(),
        Value::Boolean(b) => b.to_string(),
        Value::Integer(i) => i.to_string(),
        Value::Number(x) => format!("{x:?}"),
        Value::String(s) => s.to_string_lossy(),
        Value::Table(t) if depth < 3 => {
            let len = t.raw_len();
            let mut items: Vec<String> = (1..=len)
                .map(|i| show(&t.raw_get::<Value>(i).unwrap_or(Value::Nil), depth + 1))
                .collect();
            let mut named: Vec<(String, String)> = t
                .pairs::<Value, Value>()
                .filter_map(Result::ok)
                .filter(|(k, _)| !matches!(k, Value::Integer(i) if *i >= 1 && (*i as usize) <= len))
                .map(|(k, v)| (show(&k, depth + 1), show(&v, depth + 1)))
                .collect();
            named.sort();
            items.extend(named.into_iter().map(|(k, v)| format!("{k} = {v}")));
            if items.is_empty() {
                "{}".into()
            } else {
                format!("{{ {} }}", items.join(", "))
            }
        }
        other => format!("<{}>", other.type_name()),
    }
}
