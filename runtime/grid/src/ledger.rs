//! The overrun ledger: per component, its releases, overruns, execution times and release
//! latency; for the grid, its ticks, the measured tick rate and the tick error.
//!
//! The coordinator answers the method `ledger` with one bytes value; its format (rows, encode,
//! decode) is `modbot_ipc_schema::ledger`'s, re-exported here. This file renders it as
//! `modbot top` shows it.

use modbot_core::stats::Histogram;

pub use modbot_ipc_schema::ledger::{
    decode, encode, encode_component, encode_grid, ComponentRow, GridRow, FIELDS, GRID_FIELDS,
};

/// Percentiles of a histogram as the ledger shows them.
pub fn p50_p99_max(h: &Histogram) -> (u64, u64, u64) {
    if h.count() == 0 {
        return (0, 0, 0);
    }
    (h.percentile(50.0), h.percentile(99.0), h.max())
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
