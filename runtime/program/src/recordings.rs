//! What a program does with its recordings (`record { }` and `stop_record { }`, in the
//! library, start and stop them):
//!
//! | function | |
//! |---|---|
//! | `absolute("run.h5")` | the path made absolute against the directory the program runs in (the recorder, another process, gets it so) |
//! | `recorded(file, "comp.port", from, to)` | a signal's rows with ticks from `from` to `to`: `{ ticks = { ... }, values = { ... } }`, each value a number, or a table for an `f64[N]` signal |
//! | `plot { file = "x.svg", title, x, y, lines = { { name = "...", x = { ... }, y = { ... } }, ... } }` | writes the lines as an SVG plot; returns the file |

use mlua::{Lua, MultiValue, Table, Value};

use super::plot::{self, Labels, Line};
use super::session::{fail_here, Shared};
use super::ScriptError;

/// Adds the functions to `globals`.
pub(crate) fn register(lua: &Lua, globals: &Table, shared: &Shared) -> mlua::Result<()> {
    globals.raw_set("absolute", absolute_fn(lua, shared)?)?;
    globals.raw_set("recorded", recorded_fn(lua, shared)?)?;
    globals.raw_set("plot", plot_fn(lua, shared)?)
}

fn absolute_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    lua.create_function(move |lua, path: Value| {
        let Value::String(path) = path else {
            return Err(fail_here(
                lua,
                &shared,
                "absolute takes a path, as in absolute(\"run.h5\")",
            ));
        };
        let path = path.to_string_lossy();
        std::path::absolute(&path)
            .map(|p| p.display().to_string())
            .map_err(|e| fail_here(lua, &shared, format!("absolute(\"{path}\"): {e}")))
    })
}

fn recorded_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    lua.create_function(
        move |lua, (file, signal, from, to): (Value, Value, Value, Value)| {
            let usage = "recorded(file, \"comp.port\", from_tick, to_tick)";
            let (Value::String(file), Value::String(signal)) = (file, signal) else {
                return Err(fail_here(lua, &shared, format!("recorded takes {usage}")));
            };
            let tick = |v: &Value| match v {
                Value::Integer(i) => Some(*i),
                Value::Number(x) if x.fract() == 0.0 => Some(*x as i64),
                _ => None,
            };
            let (Some(from), Some(to)) = (tick(&from), tick(&to)) else {
                return Err(fail_here(
                    lua,
                    &shared,
                    format!("recorded takes whole ticks: {usage}"),
                ));
            };
            let path = std::path::PathBuf::from(file.to_string_lossy());
            let series =
                modbot_record::read::read_signal(&path, &signal.to_string_lossy(), from, to)
                    .map_err(|e| fail_here(lua, &shared, format!("recorded: {e}")))?;
            let out = lua.create_table()?;
            out.raw_set(
                "ticks",
                lua.create_sequence_from(series.ticks.iter().copied())?,
            )?;
            let values = lua.create_table_with_capacity(series.ticks.len(), 0)?;
            for i in 0..series.ticks.len() {
                let row = series.row(i);
                if series.width == 1 {
                    values.raw_push(row[0])?;
                } else {
                    values.raw_push(lua.create_sequence_from(row.iter().copied())?)?;
                }
            }
            out.raw_set("values", values)?;
            Ok(out)
        },
    )
}

/// A sequence of numbers, or why not (`what` names it).
fn numbers(t: &Table, what: impl Fn() -> String) -> Result<Vec<f64>, ScriptError> {
    t.sequence_values::<Value>()
        .map(|v| match v {
            Ok(Value::Integer(i)) => Ok(i as f64),
            Ok(Value::Number(x)) => Ok(x),
            _ => Err(ScriptError::NotNumbers { what: what() }),
        })
        .collect()
}

/// The lines of `plot { lines = ... }`.
fn lines(spec: &Table) -> Result<Vec<Line>, ScriptError> {
    let Ok(Value::Table(lines)) = spec.raw_get::<Value>("lines") else {
        return Err(ScriptError::NoLines);
    };
    let mut out = Vec::new();
    for (i, line) in lines.sequence_values::<Value>().enumerate() {
        let Ok(Value::Table(line)) = line else {
            return Err(ScriptError::LineNotATable(i + 1));
        };
        let name = line
            .raw_get::<Option<String>>("name")
            .ok()
            .flatten()
            .unwrap_or_else(|| format!("line {}", i + 1));
        let what = |k: &str| format!("lines[{}].{k}", i + 1);
        let axis = |k: &str| match line.raw_get::<Value>(k) {
            Ok(Value::Table(t)) => numbers(&t, || what(k)),
            _ => Err(ScriptError::NotNumbers { what: what(k) }),
        };
        let (x, y) = (axis("x")?, axis("y")?);
        if x.len() != y.len() {
            return Err(ScriptError::Unequal {
                line: i + 1,
                x: x.len(),
                y: y.len(),
            });
        }
        out.push(Line {
            name,
            points: x.into_iter().zip(y).collect(),
        });
    }
    Ok(out)
}

fn plot_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let Some(Value::Table(spec)) = args.front() else {
            let why = "plot takes a table: plot { file = \"x.svg\", lines = { ... } }";
            return Err(fail_here(lua, &shared, why));
        };
        let text = |k: &str| {
            spec.raw_get::<Option<String>>(k)
                .ok()
                .flatten()
                .unwrap_or_default()
        };
        let file = text("file");
        if file.is_empty() {
            return Err(fail_here(
                lua,
                &shared,
                "plot: file = \"x.svg\" is required",
            ));
        }
        let labels = Labels {
            title: text("title"),
            x: text("x"),
            y: text("y"),
        };
        let lines = lines(spec).map_err(|why| fail_here(lua, &shared, format!("plot: {why}")))?;
        let path = std::path::absolute(&file).unwrap_or_else(|_| file.clone().into());
        plot::svg(&path, &labels, &lines)
            .map_err(|why| fail_here(lua, &shared, format!("plot: {why}")))?;
        Ok(path.display().to_string())
    })
}
