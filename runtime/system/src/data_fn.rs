//! `data(key)` in assembly files: the value of `key` in the domain's assembly data
//! (`modbot-data`), or nil when it has none — how a robot program's command gives its
//! assembly parameters (a goal, a speed). The store is opened at the first call, read-only in
//! effect, and only if it exists (looking makes no file). A system description has no
//! `data`: its parameters are `vars`.

use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use mlua::{Lua, MultiValue, Value};

use super::record::{caller_line, fail, one_arg, Shared};
use super::DeclError;
use modbot_data::Store;

/// The `data` function of an evaluation; `data`: the assembly data file, `None` for a system
/// description.
pub(super) fn data_fn(
    lua: &Lua,
    record: &Shared,
    data: Option<&Path>,
) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    let path: Option<PathBuf> = data.map(Path::to_owned);
    let store: Rc<RefCell<Option<Option<Store>>>> = Rc::default();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let what = "data";
        let key = one_arg(&args, "data(\"goto.q\")").and_then(|v| match v {
            Value::String(s) => Ok(s.to_string_lossy()),
            other => Err(DeclError::Argument {
                what: what.into(),
                expected: "a key, as in data(\"goto.q\")".into(),
                got: other.type_name().into(),
            }),
        });
        let key = key.map_err(|e| fail(&record, line, e))?;
        let Some(path) = &path else {
            let why = "assembly data is read by assembly files and robot programs; a system \
                       description takes its parameters from vars";
            return Err(fail(&record, line, DeclError::invalid(what, why)));
        };
        let value = {
            let mut store = store.borrow_mut();
            if store.is_none() {
                let opened = Store::open_existing(path)
                    .map_err(|e| fail(&record, line, DeclError::invalid(what, e.to_string())))?;
                *store = Some(opened);
            }
            match store.as_ref().and_then(Option::as_ref) {
                None => None,
                Some(s) => s
                    .get(&key)
                    .map_err(|e| fail(&record, line, DeclError::invalid(what, e.to_string())))?,
            }
        };
        match value {
            Some(v) => super::sandbox::to_lua(lua, &v),
            None => Ok(Value::Nil),
        }
    })
}
