//! The record of one evaluation of a description, shared by its declaration functions (in
//! `lua` and `grid_decl`) and the instruction hook: what was declared, which `kind "name"`
//! calls still wait for their table, the first failure; and what every declaration function
//! does with it (its argument, its line, failing).

use std::cell::RefCell;
use std::rc::Rc;

use mlua::{MultiValue, Value};

use super::decl::Declarations;
use super::DeclError;

/// The evaluation's record, shared by the declaration functions and the hook.
///
/// Borrows of it are short and never span a call into Lua: Lua may run user code (finalizers)
/// during any allocation, and that code may call a declaration function.
#[derive(Default)]
pub(super) struct Record {
    pub(super) decls: Declarations,
    /// `module "x"`, `group "x"` and `component "x"` calls, and whether their table was given.
    pub(super) bodies: Vec<Body>,
    /// How many `bodies` there are of each kind (a declaration loop must not count them all
    /// at every call).
    pub(super) counts: Vec<(&'static str, usize)>,
    /// The first failure: its line (if any) and what it is.
    pub(super) failure: Option<(Option<u32>, DeclError)>,
    /// Instructions executed so far, counted by the hook.
    pub(super) instructions: u64,
}

pub(super) struct Body {
    pub(super) kind: &'static str,
    pub(super) name: String,
    pub(super) line: u32,
    pub(super) given: bool,
}

pub(super) type Shared = Rc<RefCell<Record>>;

/// Notes a `kind "name"` call whose table is still to come; returns its index.
pub(super) fn open_body(
    record: &Shared,
    kind: &'static str,
    name: &str,
    line: u32,
    max: usize,
) -> mlua::Result<usize> {
    let count = record
        .borrow()
        .counts
        .iter()
        .find(|(k, _)| *k == kind)
        .map_or(0, |(_, n)| *n);
    if count >= max {
        return Err(fail(record, line, DeclError::TooMany { kind, max }));
    }
    let mut record = record.borrow_mut();
    match record.counts.iter_mut().find(|(k, _)| *k == kind) {
        Some((_, n)) => *n += 1,
        None => record.counts.push((kind, 1)),
    }
    record.bodies.push(Body {
        kind,
        name: name.to_owned(),
        line,
        given: false,
    });
    Ok(record.bodies.len() - 1)
}

pub(super) fn given(record: &Shared, index: usize) {
    if let Some(body) = record.borrow_mut().bodies.get_mut(index) {
        body.given = true;
    }
}

/// The single argument of a declaration; `usage` shows how it is written.
pub(super) fn one_arg<'a>(
    args: &'a MultiValue,
    usage: &'static str,
) -> Result<&'a Value, DeclError> {
    let arguments = DeclError::Arguments {
        got: args.len(),
        usage,
    };
    match args.len() {
        1 => args.front().ok_or(arguments),
        _ => Err(arguments),
    }
}

/// Records `error` as the failure (unless there is one already) and returns the Lua error
/// that stops the script.
pub(super) fn fail(record: &Shared, line: u32, error: DeclError) -> mlua::Error {
    let mut record = record.borrow_mut();
    if record.failure.is_none() {
        record.failure = Some((Some(line), error));
    }
    stop()
}

pub(super) use super::sandbox::{caller_line, stop};
