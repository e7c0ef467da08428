//! What the supervisor knows of each module, as rows for the terminal and for `modbot ls`.
//!
//! The supervisor answers the method `status` with one bytes value: the rows as a sequence
//! of values (the same encoding as a frame's payload), 9 per module, in this order: name
//! (text), address (i64), state (text), pid (i64, 0 when not running), restarts (i64), last exit
//! (text, empty if none), dropped, rejected, replayed (i64, from its heartbeats).

use modbot_ipc_schema::heartbeat::Counters;
use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::Value;

/// Values per module in the answer to `status`.
pub const FIELDS: usize = 9;

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

/// One module as the supervisor reports it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Row {
    pub name: String,
    pub addr: u8,
    pub state: String,
    pub pid: u32,
    pub restarts: u32,
    pub last_exit: String,
    pub counters: Counters,
}

impl Row {
    /// Appends this row's values to `out`.
    pub fn encode(&self, out: &mut Vec<u8>) {
        for v in [
            Value::Text(&self.name),
            Value::I64(i64::from(self.addr)),
            Value::Text(&self.state),
            Value::I64(i64::from(self.pid)),
            Value::I64(i64::from(self.restarts)),
            Value::Text(&self.last_exit),
            Value::I64(self.counters.dropped as i64),
            Value::I64(self.counters.rejected as i64),
            Value::I64(self.counters.replayed as i64),
        ] {
            // Texts here are module names and short reasons: far below any encoding limit.
            let _ = v.encode_to_vec(out);
        }
    }

    /// Reads the rows of an answer to `status`.
    pub fn parse_all(bytes: &[u8]) -> Result<Vec<Row>, String> {
        let values = Values::new(bytes, 0)
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| e.to_string())?;
        if values.len() % FIELDS != 0 {
            return Err(format!(
                "status answer has {} values, not a multiple of {FIELDS}",
                values.len()
            ));
        }
        let text = |v: &Value<'_>| match v {
            Value::Text(t) => Ok((*t).to_owned()),
            other => Err(format!("expected text, found {other}")),
        };
        let count = |v: &Value<'_>| match v {
            Value::I64(n) => Ok((*n).max(0) as u64),
            other => Err(format!("expected an integer, found {other}")),
        };
        values
            .chunks(FIELDS)
            .map(|r| {
                Ok(Row {
                    name: text(&r[0])?,
                    addr: count(&r[1])?.min(255) as u8,
                    state: text(&r[2])?,
                    pid: count(&r[3])?.min(u64::from(u32::MAX)) as u32,
                    restarts: count(&r[4])?.min(u64::from(u32::MAX)) as u32,
                    last_exit: text(&r[5])?,
                    counters: Counters {
                        dropped: count(&r[6])?,
                        rejected: count(&r[7])?,
                        replayed: count(&r[8])?,
                    },
                })
            })
            .collect()
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

    #[test]
    fn rows_survive_the_status_answer() {
        let rows = vec![
            Row {
                name: "sonar".into(),
                addr: 2,
                state: "running".into(),
                pid: 42,
                restarts: 1,
                last_exit: "killed by SIGKILL".into(),
                counters: Counters {
                    dropped: 3,
                    rejected: 4,
                    replayed: 5,
                },
            },
            Row {
                name: "mobility".into(),
                addr: 3,
                state: "down".into(),
                pid: 0,
                restarts: 0,
                last_exit: String::new(),
                counters: Counters::default(),
            },
        ];
        let mut bytes = Vec::new();
        for r in &rows {
            r.encode(&mut bytes);
        }
        assert_eq!(Row::parse_all(&bytes).unwrap(), rows);
        assert!(Row::parse_all(&bytes[..bytes.len() - 1]).is_err());
        let table = table(&rows);
        assert!(
            table.lines().nth(1).unwrap().contains("killed by SIGKILL"),
            "{table}"
        );
    }
}
