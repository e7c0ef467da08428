//! What the supervisor knows of each module, as rows for the terminal and for `modbot ls`.
//!
//! The supervisor answers the method `status` with one bytes value, its rows in the format of
//! `modbot_ipc_schema::status` (rows, encode, decode), re-exported here. This file keeps the
//! states a module goes through and renders the rows as a table.

pub use modbot_ipc_schema::status::{decode, encode, Row, StatusError, FIELDS};

/// Where a supervised module is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunState {
    /// Started, not announced yet.
    Starting,
    /// Announced, heartbeat arriving.
    Running,
    /// Ended; starts again after its backoff.
    Restarting,
    /// Ended and stays down (its restart policy says so).
    Down,
    /// Ended too often: the supervisor gave up on it.
    Failed,
    /// Stopped by the supervisor at shutdown.
    Stopped,
    /// A host of an assembly that was replaced: stopped, and no longer listed.
    Retired,
}

impl RunState {
    pub fn name(self) -> &'static str {
        match self {
            RunState::Starting => "starting",
            RunState::Running => "running",
            RunState::Restarting => "restarting",
            RunState::Down => "down",
            RunState::Failed => "failed",
            RunState::Stopped => "stopped",
            RunState::Retired => "retired",
        }
    }
}

/// The status table, one line per module.
pub fn table(rows: &[Row]) -> String {
    let width = rows.iter().map(|r| r.name.len()).max().unwrap_or(4).max(4);
    let mut out = format!(
        "{:>4}  {:<width$}  {:<10} {:>8} {:>8}  {:<28} {:>7} {:>7} {:>7}\n",
        "ADDR", "NAME", "STATE", "PID", "RESTARTS", "LAST EXIT", "DROPPED", "REJECT", "REPLAY"
    );
    for r in rows {
        let pid = if r.pid == 0 {
            "-".to_owned()
        } else {
            r.pid.to_string()
        };
        let last = if r.last_exit.is_empty() {
            "-"
        } else {
            r.last_exit.as_str()
        };
        out.push_str(&format!(
            "{:>4}  {:<width$}  {:<10} {:>8} {:>8}  {:<28} {:>7} {:>7} {:>7}\n",
            r.addr,
            r.name,
            r.state,
            pid,
            r.restarts,
            last,
            r.counters.dropped,
            r.counters.rejected,
            r.counters.replayed
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_ipc_schema::heartbeat::Counters;

    #[test]
    fn the_table_has_a_line_per_row_with_its_last_exit() {
        let row = |name: &str, addr, pid, last_exit: &str| Row {
            name: name.into(),
            addr,
            state: "running".into(),
            pid,
            restarts: 0,
            last_exit: last_exit.into(),
            counters: Counters::default(),
            heartbeat_age_ms: None,
            upgrades: 0,
        };
        let rows = vec![
            row("sonar", 2, 42, "killed by SIGKILL"),
            row("mobility", 3, 0, ""),
        ];
        let table = table(&rows);
        assert!(
            table.lines().nth(1).unwrap().contains("killed by SIGKILL"),
            "{table}"
        );
        let down = table.lines().nth(2).unwrap();
        assert!(down.contains("mobility") && down.contains(" - "), "{table}");
    }
}
