//! One command run of a robot program, as assembly data keeps it.
//!
//! Encoded as a sequence of modbot values (`modbot_ipc_schema::value`, MessagePack): the text
//! `run1` (the format), the command, its assembly, where the program called it, the start and
//! end tick, the outcome, then each result as a text key followed by its value.

use std::fmt;

use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::{OwnedValue, Value};

use super::DataError;

/// A stored run that cannot be read back.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RunDecodeError {
    #[error(transparent)]
    Value(#[from] modbot_ipc_schema::ValueError),
    #[error("value {index} of a run is {found}, not {expected}")]
    Kind {
        index: usize,
        found: String,
        expected: &'static str,
    },
    #[error("a run in format {0:?}, not {FORMAT}")]
    Format(String),
    #[error("a run's results are not key, value pairs")]
    NotPairs,
    #[error("a run's result key is {0}, not text")]
    Key(String),
}

/// The first value of an encoded run: the format.
const FORMAT: &str = "run1";

/// One run of a command.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// The command (`ptp`, `hold`, a program's own).
    pub command: String,
    /// The assembly it switched to, empty when it switched to none (`wait`).
    pub assembly: String,
    /// Where the program called it: `file:line`.
    pub origin: String,
    /// The grid's tick when it began (its assembly took over) and when it ended (its finish
    /// condition held).
    pub start_tick: u64,
    pub end_tick: u64,
    /// `ok`, or why it failed.
    pub outcome: String,
    /// Its results, as its evaluation gave them (`peak_following`, `settling_s`, ...).
    pub values: Vec<(String, OwnedValue)>,
}

impl Run {
    /// Whether it succeeded.
    pub fn ok(&self) -> bool {
        self.outcome == "ok"
    }

    /// The value of result `key`.
    pub fn value(&self, key: &str) -> Option<&OwnedValue> {
        self.values.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }

    pub(super) fn encode(&self) -> Result<Vec<u8>, DataError> {
        let tick = |t: u64| Value::I64(i64::try_from(t).unwrap_or(i64::MAX));
        let mut values = vec![
            Value::Text(FORMAT),
            Value::Text(&self.command),
            Value::Text(&self.assembly),
            Value::Text(&self.origin),
            tick(self.start_tick),
            tick(self.end_tick),
            Value::Text(&self.outcome),
        ];
        for (k, v) in &self.values {
            values.push(Value::Text(k));
            values.push(v.as_value());
        }
        super::encode(&values)
    }

    pub(super) fn decode(bytes: &[u8]) -> Result<Run, RunDecodeError> {
        let values = Values::new(bytes, 0).collect::<Result<Vec<Value<'_>>, _>>()?;
        let found = |i: usize| format!("{:?}", values.get(i));
        let text = |i: usize| match values.get(i) {
            Some(Value::Text(t)) => Ok((*t).to_owned()),
            _ => Err(RunDecodeError::Kind {
                index: i,
                found: found(i),
                expected: "text",
            }),
        };
        let tick = |i: usize| match values.get(i) {
            Some(Value::I64(t)) if *t >= 0 => Ok(*t as u64),
            _ => Err(RunDecodeError::Kind {
                index: i,
                found: found(i),
                expected: "a tick",
            }),
        };
        let format = text(0)?;
        if format != FORMAT {
            return Err(RunDecodeError::Format(format));
        }
        let rest = values.get(7..).unwrap_or_default();
        if rest.len() % 2 != 0 {
            return Err(RunDecodeError::NotPairs);
        }
        let results = rest
            .chunks(2)
            .map(|pair| match pair[0] {
                Value::Text(k) => Ok((k.to_owned(), pair[1].to_owned_value())),
                other => Err(RunDecodeError::Key(format!("{other:?}"))),
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Run {
            command: text(1)?,
            assembly: text(2)?,
            origin: text(3)?,
            start_tick: tick(4)?,
            end_tick: tick(5)?,
            outcome: text(6)?,
            values: results,
        })
    }
}

/// One line: `COMMAND (ASSEMBLY) at ORIGIN, ticks START..END, OUTCOME: key=value ...`.
impl fmt::Display for Run {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.command)?;
        if !self.assembly.is_empty() {
            write!(f, " ({})", self.assembly)?;
        }
        write!(
            f,
            " at {}, ticks {}..{}, {}",
            self.origin, self.start_tick, self.end_tick, self.outcome
        )?;
        for (i, (k, v)) in self.values.iter().enumerate() {
            write!(f, "{}{k}={v}", if i == 0 { ": " } else { " " })?;
        }
        Ok(())
    }
}
