//! The overrun ledger: per component, its releases, overruns, execution times and release
//! latency; for the grid, its ticks, the measured tick rate and the tick error.
//!
//! The coordinator answers the method `ledger` with one bytes value: a header row and one row
//! per component, as a sequence of values (the frame payload encoding):
//! - grid: state (text: running, faulted, done), fault (text), ticks, missed ticks, tick rate
//!   (f64, Hz over the last second), tick error p50, p99, max (ns);
//! - per component ([`FIELDS`] values): name, host, period (ticks), policy, releases, overruns,
//!   late completions, failed steps, stale releases (not executed: an input's version was
//!   gone), exec min, p50, p99, max (ns), release latency p50, p99
//!   (ns).

use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::Value;

use modbot_core::stats::Histogram;

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

/// Percentiles of a histogram as the ledger shows them.
pub fn p50_p99_max(h: &Histogram) -> (u64, u64, u64) {
    if h.count() == 0 {
        return (0, 0, 0);
    }
    (h.percentile(50.0), h.percentile(99.0), h.max())
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

/// The `modbot top` table, one line per component under a line for the grid.
pub fn render(grid: &GridRow, rows: &[ComponentRow]) -> String {
    let us = |ns: u64| format!("{:.1}", ns as f64 / 1000.0);
    let mut out = format!(
        "grid {}{}  ticks {}  missed {}  rate {:.1} Hz  tick error p50 {} us p99 {} us max {} us\n",
        grid.state,
        if grid.fault.is_empty() {
            String::new()
        } else {
            format!(" ({})", grid.fault)
        },
        grid.ticks,
        grid.missed,
        grid.rate_hz,
        us(grid.tick_err_p50),
        us(grid.tick_err_p99),
        us(grid.tick_err_max),
    );
    out.push_str(&format!(
        "{:<16} {:<10} {:>6} {:<6} {:>9} {:>8} {:>6} {:>10} {:>10} {:>10} {:>11}\n",
        "COMPONENT",
        "HOST",
        "PERIOD",
        "POLICY",
        "RELEASES",
        "OVERRUN",
        "STALE",
        "EXEC p50",
        "EXEC p99",
        "EXEC max",
        "JITTER p99"
    ));
    for r in rows {
        out.push_str(&format!(
            "{:<16} {:<10} {:>6} {:<6} {:>9} {:>8} {:>6} {:>10} {:>10} {:>10} {:>11}\n",
            r.name,
            r.host,
            r.period,
            r.policy,
            r.releases,
            r.overruns,
            r.stale,
            us(r.exec_p50),
            us(r.exec_p99),
            us(r.exec_max),
            us(r.latency_p99),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ledger_survives_its_encoding_and_renders_one_line_per_component() {
        let grid = GridRow {
            state: "running".into(),
            ticks: 5000,
            rate_hz: 1000.0,
            tick_err_p99: 40_000,
            ..Default::default()
        };
        let rows = vec![ComponentRow {
            name: "A".into(),
            host: "h1".into(),
            period: 1,
            policy: "hold".into(),
            releases: 5000,
            overruns: 1,
            exec_p50: 2_000,
            ..Default::default()
        }];
        let mut bytes = Vec::new();
        encode(&grid, &rows, &mut bytes);
        assert_eq!(decode(&bytes).unwrap(), (grid.clone(), rows.clone()));
        let table = render(&grid, &rows);
        assert_eq!(table.lines().count(), 3, "{table}");
        assert!(table.contains("rate 1000.0 Hz"), "{table}");
        assert!(decode(&bytes[..bytes.len() - 1]).is_err());
    }
}
