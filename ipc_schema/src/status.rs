//! The supervisor's status rows: its answer to the method `status` (`modbot ls`).
//!
//! One bytes value holding a run of values in the payload encoding, [`FIELDS`] per module:
//! name (text, a module name), address (i64, 1..=254), state (text, one of [`STATES`]), pid
//! (i64, u32; 0 when not running), restarts (i64, u32), last exit (text, empty if none), then
//! the frames the module dropped, rejected and replayed (i64 ≥ 0, from its heartbeats), then
//! the age of its last heartbeat in milliseconds when the rows were built (i64 ≥ 0; −1 when it
//! does not run or has not beaten since it started), then how often a live upgrade replaced its
//! process (i64, u16). A run
//! whose last row is incomplete, a value of another kind or out of range, a name that is not
//! a module name or an unknown state is malformed.

use thiserror::Error;

use crate::addr::Addr;
use crate::fields::{push, push_u64, FieldError, Fields};
use crate::heartbeat::Counters;
use crate::names::is_module_name;
use crate::value::Value;

/// Values per module.
pub const FIELDS: usize = 11;

/// One module as the supervisor reports it.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Row {
    pub name: String,
    pub addr: u8,
    /// What the supervisor makes of the module (`running`, `restarting`, ...).
    pub state: String,
    /// 0 when it does not run.
    pub pid: u32,
    pub restarts: u32,
    /// Why it last ended (`killed by SIGKILL`, ...); empty if it never did.
    pub last_exit: String,
    /// Its transport counters, from its heartbeats.
    pub counters: Counters,
    /// How old its last heartbeat was when the supervisor built the rows (it does so at least
    /// four times a second); `None` when it does not run or has not beaten yet.
    pub heartbeat_age_ms: Option<u64>,
    /// How often a live upgrade replaced its process (`modbot upgrade`).
    pub upgrades: u16,
}

/// The states a row names.
pub const STATES: [&str; 6] = [
    "starting",
    "running",
    "restarting",
    "down",
    "failed",
    "stopped",
];

/// Why bytes are not status rows.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum StatusError {
    #[error("status row {row}: {why}")]
    Row { row: usize, why: FieldError },
    #[error("status row {row}: '{name}' is not a module name (1 to 48 of a-z A-Z 0-9 _ -)")]
    Name { row: usize, name: String },
    #[error("status row {row}: address {addr} is not a module address (1..=254)")]
    Address { row: usize, addr: u8 },
    #[error("status row {row}: unknown state '{state}'")]
    State { row: usize, state: String },
}

impl Row {
    /// Appends this row's values to `out`.
    pub fn encode(&self, out: &mut Vec<u8>) {
        push(out, Value::Text(&self.name));
        push_u64(out, u64::from(self.addr));
        push(out, Value::Text(&self.state));
        push_u64(out, u64::from(self.pid));
        push_u64(out, u64::from(self.restarts));
        push(out, Value::Text(&self.last_exit));
        push_u64(out, self.counters.dropped);
        push_u64(out, self.counters.rejected);
        push_u64(out, self.counters.replayed);
        match self.heartbeat_age_ms {
            Some(ms) => push_u64(out, ms),
            None => push(out, Value::I64(-1)),
        }
        push_u64(out, u64::from(self.upgrades));
    }

    fn decode(fields: &mut Fields<'_>) -> Result<Row, FieldError> {
        Ok(Row {
            name: fields.text("the name")?.to_owned(),
            addr: fields.int("the address")?,
            state: fields.text("the state")?.to_owned(),
            pid: fields.int("the pid")?,
            restarts: fields.int("the restarts")?,
            last_exit: fields.text("the last exit")?.to_owned(),
            counters: Counters {
                dropped: fields.int("the dropped frames")?,
                rejected: fields.int("the rejected frames")?,
                replayed: fields.int("the replayed requests")?,
            },
            heartbeat_age_ms: match fields.int::<i64>("the heartbeat age")? {
                -1 => None,
                ms => Some(u64::try_from(ms).map_err(|_| FieldError::Range {
                    what: "the heartbeat age",
                    value: ms,
                    ty: "milliseconds (≥ 0, or −1 for none)",
                })?),
            },
            upgrades: fields.int("the upgrades")?,
        })
    }
}

/// Encodes the answer to `status`. The rows are written as given: a row whose name, address
/// or state breaks the rules above is refused by [`decode`] (the supervisor's rows follow them:
/// its modules' names and addresses are checked when the system is read).
pub fn encode(rows: &[Row], out: &mut Vec<u8>) {
    for r in rows {
        r.encode(out);
    }
}

/// Reads the answer to `status`.
pub fn decode(bytes: &[u8]) -> Result<Vec<Row>, StatusError> {
    let mut fields = Fields::new(bytes);
    let mut rows = Vec::new();
    while !fields.is_done() {
        let row = rows.len();
        let r = Row::decode(&mut fields).map_err(|why| StatusError::Row { row, why })?;
        if !is_module_name(r.name.as_bytes()) {
            return Err(StatusError::Name { row, name: r.name });
        }
        if !Addr(r.addr).is_module() {
            return Err(StatusError::Address { row, addr: r.addr });
        }
        if !STATES.contains(&r.state.as_str()) {
            return Err(StatusError::State {
                row,
                state: r.state,
            });
        }
        rows.push(r);
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    fn rows() -> Vec<Row> {
        vec![
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
                heartbeat_age_ms: Some(120),
                upgrades: 2,
            },
            Row {
                name: "mobility".into(),
                addr: 3,
                state: "down".into(),
                pid: 0,
                restarts: 0,
                last_exit: String::new(),
                counters: Counters::default(),
                heartbeat_age_ms: None,
                upgrades: 0,
            },
        ]
    }

    #[test]
    fn a_row_has_the_documented_layout() {
        let mut bytes = Vec::new();
        rows()[1].encode(&mut bytes);
        assert_eq!(
            hex::encode(&bytes),
            "a86d6f62696c697479 03 a4646f776e 00 00 a0 00 00 00 ff 00".replace(' ', "")
        );
    }

    #[test]
    fn rows_survive_the_status_answer() {
        let mut bytes = Vec::new();
        encode(&rows(), &mut bytes);
        assert_eq!(decode(&bytes), Ok(rows()));
        assert_eq!(decode(&[]), Ok(Vec::new()));
    }

    #[test]
    fn malformed_rows_are_refused_with_the_row_and_the_field() {
        let mut bytes = Vec::new();
        encode(&rows(), &mut bytes);
        assert!(matches!(
            decode(&bytes[..bytes.len() - 1]),
            Err(StatusError::Row {
                row: 1,
                why: FieldError::Missing {
                    what: "the upgrades"
                }
            })
        ));
        let mut wide = Vec::new();
        push(&mut wide, Value::Text("x"));
        push(&mut wide, Value::I64(256));
        assert!(matches!(
            decode(&wide),
            Err(StatusError::Row {
                row: 0,
                why: FieldError::Range { value: 256, .. }
            })
        ));
        let mut negative = bytes.clone();
        let replayed = negative.len() - 3;
        negative[replayed] = 0xff; // -1 replayed
        assert!(matches!(
            decode(&negative),
            Err(StatusError::Row {
                row: 1,
                why: FieldError::Range { value: -1, .. }
            })
        ));
        let mut aged = bytes.clone();
        aged.truncate(aged.len() - 2);
        push(&mut aged, Value::I64(-2));
        push(&mut aged, Value::I64(0));
        assert!(matches!(
            decode(&aged),
            Err(StatusError::Row {
                row: 1,
                why: FieldError::Range { value: -2, .. }
            })
        ));
        let mut not_text = bytes;
        not_text[0] = 0x07;
        assert!(matches!(
            decode(&not_text),
            Err(StatusError::Row {
                row: 0,
                why: FieldError::Kind { .. }
            })
        ));
    }
}
