//! The time grid's overrun ledger, the answer to the coordinator's method `ledger`: one bytes
//! value holding a sequence of values (the frame payload encoding) — a grid row, then one row
//! per component.
//! - grid ([`GRID_FIELDS`] values): state (text: running, faulted, done), fault (text), ticks,
//!   missed ticks, tick rate (f64, Hz over the last second), tick error p50, p99, max (ns);
//! - per component ([`FIELDS`] values): name, host, period (ticks), policy, releases, overruns,
//!   late completions, failed steps, stale releases (not executed: an input's version was
//!   gone), exec min, p50, p99, max (ns), release latency p50, p99 (ns).

use crate::value::Values;
use crate::Value;

/// Values per component row.
pub const FIELDS: usize = 15;
/// Values in the grid row.
pub const GRID_FIELDS: usize = 8;

/// One component's line of the ledger.
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

fn push(out: &mut Vec<u8>, v: Value<'_>) {
    // Names and counts are small: far below any encoding limit.
    let _ = v.encode_to_vec(out);
}

/// Encodes the ledger.
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
        push(out, Value::I64(n as i64));
    }
    push(out, Value::F64(rate_hz));
    for n in tick_error {
        push(out, Value::I64(n as i64));
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
    push(out, Value::I64(period as i64));
    push(out, Value::Text(policy));
    for n in numbers {
        push(out, Value::I64(n as i64));
    }
}

/// Decodes a ledger.
pub fn decode(bytes: &[u8]) -> Result<(GridRow, Vec<ComponentRow>), String> {
    let values = Values::new(bytes, 0)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())?;
    if values.len() < GRID_FIELDS || !(values.len() - GRID_FIELDS).is_multiple_of(FIELDS) {
        return Err(format!("ledger of {} values is malformed", values.len()));
    }
    let text = |v: &Value<'_>| match v {
        Value::Text(t) => Ok((*t).to_owned()),
        other => Err(format!("expected text, found {other}")),
    };
    let num = |v: &Value<'_>| match v {
        Value::I64(n) => Ok((*n).max(0) as u64),
        other => Err(format!("expected an integer, found {other}")),
    };
    let grid = GridRow {
        state: text(&values[0])?,
        fault: text(&values[1])?,
        ticks: num(&values[2])?,
        missed: num(&values[3])?,
        rate_hz: match values[4] {
            Value::F64(x) => x,
            ref other => return Err(format!("expected f64, found {other}")),
        },
        tick_err_p50: num(&values[5])?,
        tick_err_p99: num(&values[6])?,
        tick_err_max: num(&values[7])?,
    };
    let rows = values[GRID_FIELDS..]
        .chunks(FIELDS)
        .map(|r| {
            Ok(ComponentRow {
                name: text(&r[0])?,
                host: text(&r[1])?,
                period: num(&r[2])?,
                policy: text(&r[3])?,
                releases: num(&r[4])?,
                overruns: num(&r[5])?,
                late: num(&r[6])?,
                failed: num(&r[7])?,
                stale: num(&r[8])?,
                exec_min: num(&r[9])?,
                exec_p50: num(&r[10])?,
                exec_p99: num(&r[11])?,
                exec_max: num(&r[12])?,
                latency_p50: num(&r[13])?,
                latency_p99: num(&r[14])?,
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok((grid, rows))
}
