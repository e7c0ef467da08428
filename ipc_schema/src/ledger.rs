//! The time grid's overrun ledger, the answer to the coordinator's method `ledger`: one bytes
//! value holding a sequence of values (the frame payload encoding) — a grid row, then one row
//! per component.
//! - grid ([`GRID_FIELDS`] values): state (text: `running`, `faulted` or `done`, then perhaps
//!   a description such as ` in lockstep (assembly ptp, generation 3)`), fault (text), ticks,
//!   missed ticks, tick rate (f64, Hz over the last second), tick error p50, p99, max (ns);
//! - per component ([`FIELDS`] values): name, host, period (ticks, ≥ 1), policy (`hold` or
//!   `fault`), releases, overruns, late completions, failed steps, stale releases (not
//!   executed: an input's version was gone), exec min, p50, p99, max (ns), release latency
//!   p50, p99 (ns).
//!
//! Numbers are i64 ≥ 0 (an encoder writes a count past `i64::MAX` as `i64::MAX`). The
//! percentiles are bucket estimates and are not checked against each other or the max.

use thiserror::Error;

use crate::fields::{push, push_u64, FieldError, Fields};
use crate::value::{ValueError, Values};
use crate::Value;

/// Values per component row.
pub const FIELDS: usize = 15;
/// Values in the grid row.
pub const GRID_FIELDS: usize = 8;

/// One component's line of the ledger.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ComponentRow {
    pub name: String,
    pub host: String,
    pub period: u64,
    pub policy: String,
    pub releases: u64,
    pub overruns: u64,
    pub late: u64,
    pub failed: u64,
    pub stale: u64,
    pub exec_min: u64,
    pub exec_p50: u64,
    pub exec_p99: u64,
    pub exec_max: u64,
    pub latency_p50: u64,
    pub latency_p99: u64,
}

/// The grid's line of the ledger.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GridRow {
    pub state: String,
    pub fault: String,
    pub ticks: u64,
    pub missed: u64,
    pub rate_hz: f64,
    pub tick_err_p50: u64,
    pub tick_err_p99: u64,
    pub tick_err_max: u64,
}

/// Encodes the ledger, as given: a state, policy, rate or period that breaks the rules of
/// [`decode`] is refused there.
pub fn encode(grid: &GridRow, rows: &[ComponentRow], out: &mut Vec<u8>) {
    encode_grid(
        out,
        &grid.state,
        &grid.fault,
        [grid.ticks, grid.missed],
        grid.rate_hz,
        [grid.tick_err_p50, grid.tick_err_p99, grid.tick_err_max],
    );
    for r in rows {
        encode_component(
            out,
            [&r.name, &r.host],
            r.period,
            &r.policy,
            [
                r.releases,
                r.overruns,
                r.late,
                r.failed,
                r.stale,
                r.exec_min,
                r.exec_p50,
                r.exec_p99,
                r.exec_max,
                r.latency_p50,
                r.latency_p99,
            ],
        );
    }
}

/// Appends the grid's row: state, fault, [ticks, missed], rate, [tick error p50, p99, max].
/// No allocation once `out` has the room.
pub fn encode_grid(
    out: &mut Vec<u8>,
    state: &str,
    fault: &str,
    counts: [u64; 2],
    rate_hz: f64,
    tick_error: [u64; 3],
) {
    push(out, Value::Text(state));
    push(out, Value::Text(fault));
    for n in counts {
        push_u64(out, n);
    }
    push(out, Value::F64(rate_hz));
    for n in tick_error {
        push_u64(out, n);
    }
}

/// Appends a component's row: [name, host], period, policy, then releases, overruns, late,
/// failed, stale, exec min, p50, p99, max, latency p50, p99. No allocation once `out` has the
/// room.
pub fn encode_component(
    out: &mut Vec<u8>,
    names: [&str; 2],
    period: u64,
    policy: &str,
    numbers: [u64; FIELDS - 4],
) {
    push(out, Value::Text(names[0]));
    push(out, Value::Text(names[1]));
    push_u64(out, period);
    push(out, Value::Text(policy));
    for n in numbers {
        push_u64(out, n);
    }
}

/// The states the grid row's state text starts with.
pub const STATES: [&str; 3] = ["running", "faulted", "done"];
/// A component's policy on an overrun.
pub const POLICIES: [&str; 2] = ["hold", "fault"];

/// Why bytes are not a ledger.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LedgerError {
    #[error("{0}")]
    Values(#[from] ValueError),
    #[error("a ledger is {GRID_FIELDS} values and {FIELDS} per component, got {0}")]
    Count(usize),
    #[error("the ledger's grid row: {0}")]
    Grid(FieldError),
    #[error("the ledger's row {row}: {why}")]
    Row { row: usize, why: FieldError },
    #[error("the grid's state '{0}' does not start with running, faulted or done")]
    State(String),
    #[error("the grid's tick rate {0} Hz is not a finite number ≥ 0")]
    Rate(f64),
    #[error("the ledger's row {row}: policy '{policy}' is neither hold nor fault")]
    Policy { row: usize, policy: String },
    #[error("the ledger's row {row}: a period of 0 ticks")]
    Period { row: usize },
}

/// For callers that gather errors as text (`?` in a closure that returns `Result<_, String>`).
impl From<LedgerError> for String {
    fn from(e: LedgerError) -> String {
        e.to_string()
    }
}

impl GridRow {
    fn decode(fields: &mut Fields<'_>) -> Result<GridRow, FieldError> {
        Ok(GridRow {
            state: fields.text("the state")?.to_owned(),
            fault: fields.text("the fault")?.to_owned(),
            ticks: fields.int("the ticks")?,
            missed: fields.int("the missed ticks")?,
            rate_hz: fields.f64("the tick rate")?,
            tick_err_p50: fields.int("the tick error p50")?,
            tick_err_p99: fields.int("the tick error p99")?,
            tick_err_max: fields.int("the tick error max")?,
        })
    }
}

impl ComponentRow {
    fn decode(fields: &mut Fields<'_>) -> Result<ComponentRow, FieldError> {
        Ok(ComponentRow {
            name: fields.text("the name")?.to_owned(),
            host: fields.text("the host")?.to_owned(),
            period: fields.int("the period")?,
            policy: fields.text("the policy")?.to_owned(),
            releases: fields.int("the releases")?,
            overruns: fields.int("the overruns")?,
            late: fields.int("the late completions")?,
            failed: fields.int("the failed steps")?,
            stale: fields.int("the stale releases")?,
            exec_min: fields.int("the exec min")?,
            exec_p50: fields.int("the exec p50")?,
            exec_p99: fields.int("the exec p99")?,
            exec_max: fields.int("the exec max")?,
            latency_p50: fields.int("the latency p50")?,
            latency_p99: fields.int("the latency p99")?,
        })
    }
}

/// Decodes a ledger: 8 + 15·n well-formed values, each of its field's kind; numbers ≥ 0; the
/// state's first word one of [`STATES`]; a finite rate ≥ 0; each policy one of [`POLICIES`];
/// each period ≥ 1.
pub fn decode(bytes: &[u8]) -> Result<(GridRow, Vec<ComponentRow>), LedgerError> {
    let mut count = 0;
    for value in Values::new(bytes, 0) {
        value?;
        count += 1;
    }
    if count < GRID_FIELDS || !(count - GRID_FIELDS).is_multiple_of(FIELDS) {
        return Err(LedgerError::Count(count));
    }
    let mut fields = Fields::new(bytes);
    let grid = GridRow::decode(&mut fields).map_err(LedgerError::Grid)?;
    let first_word = grid.state.split(' ').next().unwrap_or_default();
    if !STATES.contains(&first_word) {
        return Err(LedgerError::State(grid.state));
    }
    if !(grid.rate_hz.is_finite() && grid.rate_hz >= 0.0) {
        return Err(LedgerError::Rate(grid.rate_hz));
    }
    let mut rows = Vec::with_capacity((count - GRID_FIELDS) / FIELDS);
    while !fields.is_done() {
        let row = rows.len();
        let r = ComponentRow::decode(&mut fields).map_err(|why| LedgerError::Row { row, why })?;
        if !POLICIES.contains(&r.policy.as_str()) {
            return Err(LedgerError::Policy {
                row,
                policy: r.policy,
            });
        }
        if r.period == 0 {
            return Err(LedgerError::Period { row });
        }
        rows.push(r);
    }
    Ok((grid, rows))
}
