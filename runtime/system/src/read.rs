//! Reading typed values out of Lua values, for the declarations in `decl`.
//!
//! Every reader returns the value or a [`DeclError`] that names the declaration (`what`, such
//! as "module 'sonar'") and the field, and shows the value that was refused. Tables are read
//! with raw access: no metamethod runs.

use std::time::Duration;

use mlua::{Lua, Value};

use super::DeclError;

/// Lua's failure while reading a table of `what`.
pub(super) fn lua_failed(what: &str, e: &mlua::Error) -> DeclError {
    DeclError::Lua {
        what: what.to_owned(),
        detail: e.to_string(),
    }
}

/// A list of strings; numbers are converted as Lua's `tostring` does.
pub(super) fn string_list(
    lua: &Lua,
    what: &str,
    field: &str,
    v: &Value,
) -> Result<Vec<String>, DeclError> {
    let bad = || DeclError::Field {
        what: what.to_owned(),
        field: field.to_owned(),
        expected: "a list of strings".into(),
        got: None,
    };
    let mut strings = Vec::new();
    for item in list(what, field, v).map_err(|_| bad())? {
        let s = coerce(lua, &item).ok_or_else(bad)?;
        if s.contains('\0') {
            let why = format!(
                "field '{field}': item {} contains a NUL character",
                strings.len() + 1
            );
            return Err(DeclError::invalid(what, why));
        }
        strings.push(s);
    }
    Ok(strings)
}

/// The items of a Lua sequence (a table whose keys are exactly 1..n).
pub(super) fn list(what: &str, field: &str, v: &Value) -> Result<Vec<Value>, DeclError> {
    let not_a_list = || DeclError::Field {
        what: what.to_owned(),
        field: field.to_owned(),
        expected: "a list".into(),
        got: None,
    };
    let Value::Table(table) = v else {
        return Err(not_a_list());
    };
    // Collect first: `raw_len` is a border, which a sparse table can make huge.
    let len = table.raw_len();
    let mut items = Vec::new();
    for pair in table.pairs::<Value, Value>() {
        let (key, value) = pair.map_err(|e| lua_failed(what, &e))?;
        let index = integer(&key)
            .and_then(|i| usize::try_from(i).ok())
            .filter(|i| (1..=len).contains(i))
            .ok_or_else(not_a_list)?;
        items.push((index, value));
    }
    if items.len() != len {
        return Err(not_a_list());
    }
    items.sort_unstable_by_key(|(index, _)| *index);
    Ok(items.into_iter().map(|(_, value)| value).collect())
}

/// A table's fields, checked against the names a declaration knows.
pub(super) struct Fields(Vec<(String, Value)>);

impl Fields {
    /// Reads the fields of table `v`; any other key is an error naming `what`.
    pub(super) fn read(
        what: &str,
        v: &Value,
        expected: &'static [&'static str],
    ) -> Result<Fields, DeclError> {
        let Value::Table(table) = v else {
            let first = expected.first().copied().unwrap_or("name");
            return Err(DeclError::Argument {
                what: what.to_owned(),
                expected: format!("a table of fields ({first} = ...)"),
                got: show(v),
            });
        };
        let mut fields = Vec::new();
        // Lua's iteration order is not stable across runs: sort, so the message is.
        let mut problems = Vec::new();
        for pair in table.pairs::<Value, Value>() {
            let (key, value) = pair.map_err(|e| lua_failed(what, &e))?;
            match text(&key) {
                Some(name) if expected.contains(&name.as_str()) => fields.push((name, value)),
                Some(field) => problems.push(DeclError::UnknownField {
                    what: what.to_owned(),
                    field,
                    expected,
                }),
                None => problems.push(DeclError::Unnamed {
                    what: what.to_owned(),
                    kind: "fields",
                    key: show(&key),
                    value: show(&value),
                }),
            }
        }
        // The first by its message, as before the errors had types.
        problems.sort_by_cached_key(|p| p.to_string());
        match problems.into_iter().next() {
            Some(problem) => Err(problem),
            None => Ok(Fields(fields)),
        }
    }

    /// The value of field `name`, if the table has it.
    pub(super) fn take(&mut self, name: &str) -> Option<Value> {
        let at = self.0.iter().position(|(n, _)| n == name)?;
        Some(self.0.swap_remove(at).1)
    }
}

pub(super) fn string(what: &str, field: &str, v: &Value) -> Result<String, DeclError> {
    text(v).ok_or_else(|| DeclError::field(what, field, "a string", show(v)))
}

pub(super) fn integer_in(
    what: &str,
    field: &str,
    v: &Value,
    lo: i64,
    hi: i64,
) -> Result<i64, DeclError> {
    match integer(v) {
        Some(i) if (lo..=hi).contains(&i) => Ok(i),
        _ => {
            let expected = format!("an integer from {lo} to {hi}");
            Err(DeclError::field(what, field, expected, show(v)))
        }
    }
}

/// A duration in seconds; zero only if `zero_ok`.
pub(super) fn seconds(
    what: &str,
    field: &str,
    v: &Value,
    zero_ok: bool,
) -> Result<Duration, DeclError> {
    let secs = match v {
        Value::Integer(i) => *i as f64,
        Value::Number(n) => *n,
        _ => f64::NAN,
    };
    let ok = secs.is_finite() && (secs > 0.0 || (zero_ok && secs == 0.0));
    let expected = if zero_ok {
        "a number of seconds, 0 or more"
    } else {
        "a positive number of seconds"
    };
    if !ok {
        return Err(DeclError::field(what, field, expected, show(v)));
    }
    Duration::try_from_secs_f64(secs)
        .map_err(|_| DeclError::invalid(what, format!("field '{field}' is too large ({secs} s)")))
}

/// An integer, or a float with an integer value.
pub(super) fn integer(v: &Value) -> Option<i64> {
    match v {
        Value::Integer(i) => Some(*i),
        Value::Number(n) if n.fract() == 0.0 && n.abs() < 9.0e15 => Some(*n as i64),
        _ => None,
    }
}

/// A Lua string as UTF-8 text.
pub(super) fn text(v: &Value) -> Option<String> {
    match v {
        Value::String(s) => s.to_str().ok().map(|s| s.to_owned()),
        _ => None,
    }
}

/// A string, or a number as Lua's `tostring` writes it.
pub(super) fn coerce(lua: &Lua, v: &Value) -> Option<String> {
    match v {
        Value::String(_) => text(v),
        Value::Integer(_) | Value::Number(_) => lua
            .coerce_string(v.clone())
            .ok()
            .flatten()
            .and_then(|s| s.to_str().ok().map(|s| s.to_owned())),
        _ => None,
    }
}

/// A value as a message shows it: `3`, `'text'`, `a table`.
pub(super) fn show(v: &Value) -> String {
    match v {
        Value::Nil => "nil".to_owned(),
        Value::Boolean(b) => b.to_string(),
        Value::Integer(i) => i.to_string(),
        Value::Number(n) => n.to_string(),
        Value::String(s) => {
            let s = s.to_string_lossy();
            match s.char_indices().nth(40) {
                Some((cut, _)) => format!("'{}...'", &s[..cut]),
                None => format!("'{s}'"),
            }
        }
        other => format!("a {}", other.type_name()),
    }
}
