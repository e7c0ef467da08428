//! The coordinator's answers about assembly switches (`modbot assembly`).
//!
//! - `switch(name)`: the request is one text value, the assembly's name; the answer one i64,
//!   the generation the assembly gets (read with [`decode_generation`]). A switch that cannot
//!   be asked for is answered with a NAK and the reason (a grid without assemblies, a bad
//!   name, a switch already under way: busy).
//! - `assembly()`: one bytes value holding a run of values in the payload encoding
//!   ([`encode`], [`decode`]):
//!
//! ```text
//! the running assembly   name (text; "none" before the first), generation (i64, 0..=65535)
//! the switch under way   tag (i64): 0 idle
//!                                   1 preparing: generation, name
//!                                   2 announced: generation, name, the tick it takes over at
//! then per recent outcome, oldest first (at most 64):
//!                        tag (i64): 1 switched: generation, name, announced tick, tick
//!                                   2 failed: generation, name, reason (text)
//! ```
//!
//! Names are assembly names (1 to 32 of `a-z 0-9 _`; `none` is one), ticks are i64 ≥ 0. A tag
//! other than these, a value of another kind, a generation outside u16, a name that is not an
//! assembly name, more than [`MAX_OUTCOMES`] outcomes or a run that ends inside an entry is
//! malformed. The order of generations and ticks is the coordinator's and is not checked.

use core::fmt;

use thiserror::Error;

use crate::args::ArgError;
use crate::fields::{push, push_u64, FieldError, Fields};
use crate::names::is_assembly_name;
use crate::value::{Value, ValueKind};

const IDLE: i64 = 0;
const PREPARING: i64 = 1;
const ANNOUNCED: i64 = 2;
const SWITCHED: i64 = 1;
const FAILED: i64 = 2;

/// Where the assemblies stand: the coordinator's answer to `assembly()`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Status {
    /// The running assembly (`none` before the first).
    pub assembly: String,
    /// Its generation.
    pub generation: u16,
    /// The switch under way, if any.
    pub state: State,
    /// The outcomes of the last switches, oldest first.
    pub outcomes: Vec<Outcome>,
}

/// The switch under way.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum State {
    Idle,
    /// Asked for: loaded, its hosts started and made ready.
    Preparing {
        generation: u16,
        assembly: String,
    },
    /// Prepared: its components track, and it takes over at `tick`.
    Announced {
        generation: u16,
        assembly: String,
        tick: u64,
    },
}

/// How one switch ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// It took over at `tick`; the coordinator had announced it for `announced`.
    Switched {
        generation: u16,
        assembly: String,
        announced: u64,
        tick: u64,
    },
    /// It was not switched to, and why; the running assembly stayed.
    Failed {
        generation: u16,
        assembly: String,
        reason: String,
    },
}

/// Why an answer about switches is malformed.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SwitchAnswerError {
    #[error("{0}")]
    Field(#[from] FieldError),
    #[error("unknown {what} tag {tag}")]
    Tag { what: &'static str, tag: i64 },
    #[error("the answer's values: {0}")]
    Args(#[from] ArgError),
    #[error("{count} values after the generation")]
    Trailing { count: usize },
    #[error("{what} '{name}' is not an assembly name (1 to 32 of a-z 0-9 _)")]
    Name { what: &'static str, name: String },
    #[error("more than {MAX_OUTCOMES} outcomes")]
    TooManyOutcomes,
}

/// The most outcomes an answer lists.
pub const MAX_OUTCOMES: usize = 64;

/// Reads an assembly name.
fn assembly_name(fields: &mut Fields<'_>, what: &'static str) -> Result<String, SwitchAnswerError> {
    let name = fields.text(what)?;
    if !is_assembly_name(name.as_bytes()) {
        return Err(SwitchAnswerError::Name {
            what,
            name: name.to_owned(),
        });
    }
    Ok(name.to_owned())
}

impl Default for Status {
    /// What the coordinator answers before its first assembly runs.
    fn default() -> Status {
        Status {
            assembly: "none".into(),
            generation: 0,
            state: State::Idle,
            outcomes: Vec::new(),
        }
    }
}

impl Outcome {
    pub fn generation(&self) -> u16 {
        match self {
            Outcome::Switched { generation, .. } | Outcome::Failed { generation, .. } => {
                *generation
            }
        }
    }

    pub fn assembly(&self) -> &str {
        match self {
            Outcome::Switched { assembly, .. } | Outcome::Failed { assembly, .. } => assembly,
        }
    }
}

/// `generation G NAME: switched at tick T (announced A)` or `generation G NAME: not switched:
/// REASON`, as `modbot assembly` and the control station show it.
impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (g, name) = (self.generation(), self.assembly());
        match self {
            Outcome::Switched {
                announced, tick, ..
            } => write!(
                f,
                "generation {g} {name}: switched at tick {tick} (announced {announced})"
            ),
            Outcome::Failed { reason, .. } => {
                write!(f, "generation {g} {name}: not switched: {reason}")
            }
        }
    }
}

/// `idle`, `preparing GEN NAME` or `announced GEN NAME TICK`, as `modbot assembly` shows it.
impl fmt::Display for State {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            State::Idle => f.write_str("idle"),
            State::Preparing {
                generation,
                assembly,
            } => write!(f, "preparing {generation} {assembly}"),
            State::Announced {
                generation,
                assembly,
                tick,
            } => write!(f, "announced {generation} {assembly} {tick}"),
        }
    }
}

/// Appends an entry's tag, generation and assembly.
fn push_entry(out: &mut Vec<u8>, tag: i64, generation: u16, assembly: &str) {
    push(out, Value::I64(tag));
    push_u64(out, u64::from(generation));
    push(out, Value::Text(assembly));
}

impl Status {
    /// Appends the answer to `assembly()` to `out`, as given: names that are not assembly
    /// names or more than [`MAX_OUTCOMES`] outcomes are refused by [`decode`] (the coordinator
    /// checks a name before it switches, and keeps the last 64 outcomes).
    pub fn encode(&self, out: &mut Vec<u8>) {
        push(out, Value::Text(&self.assembly));
        push_u64(out, u64::from(self.generation));
        match &self.state {
            State::Idle => push(out, Value::I64(IDLE)),
            State::Preparing {
                generation,
                assembly,
            } => push_entry(out, PREPARING, *generation, assembly),
            State::Announced {
                generation,
                assembly,
                tick,
            } => {
                push_entry(out, ANNOUNCED, *generation, assembly);
                push_u64(out, *tick);
            }
        }
        for outcome in &self.outcomes {
            push_entry(
                out,
                match outcome {
                    Outcome::Switched { .. } => SWITCHED,
                    Outcome::Failed { .. } => FAILED,
                },
                outcome.generation(),
                outcome.assembly(),
            );
            match outcome {
                Outcome::Switched {
                    announced, tick, ..
                } => {
                    push_u64(out, *announced);
                    push_u64(out, *tick);
                }
                Outcome::Failed { reason, .. } => push(out, Value::Text(reason)),
            }
        }
    }
}

/// Reads the answer to `assembly()`.
pub fn decode(bytes: &[u8]) -> Result<Status, SwitchAnswerError> {
    let mut fields = Fields::new(bytes);
    let assembly = assembly_name(&mut fields, "the running assembly")?;
    let generation = fields.int("the running generation")?;
    let state = match fields.int::<i64>("the state's tag")? {
        IDLE => State::Idle,
        PREPARING => State::Preparing {
            generation: fields.int("the preparing generation")?,
            assembly: assembly_name(&mut fields, "the preparing assembly")?,
        },
        ANNOUNCED => State::Announced {
            generation: fields.int("the announced generation")?,
            assembly: assembly_name(&mut fields, "the announced assembly")?,
            tick: fields.int("the announced tick")?,
        },
        tag => return Err(SwitchAnswerError::Tag { what: "state", tag }),
    };
    let mut outcomes = Vec::new();
    while !fields.is_done() {
        if outcomes.len() == MAX_OUTCOMES {
            return Err(SwitchAnswerError::TooManyOutcomes);
        }
        let tag = fields.int::<i64>("an outcome's tag")?;
        let generation = fields.int("an outcome's generation")?;
        let assembly = assembly_name(&mut fields, "an outcome's assembly")?;
        outcomes.push(match tag {
            SWITCHED => Outcome::Switched {
                generation,
                assembly,
                announced: fields.int("the announced tick of a switch")?,
                tick: fields.int("the tick of a switch")?,
            },
            FAILED => Outcome::Failed {
                generation,
                assembly,
                reason: fields.text("the reason of a failed switch")?.to_owned(),
            },
            tag => {
                return Err(SwitchAnswerError::Tag {
                    what: "outcome",
                    tag,
                })
            }
        });
    }
    Ok(Status {
        assembly,
        generation,
        state,
        outcomes,
    })
}

/// The answer to `switch(name)`: the generation.
pub fn generation_value(generation: u16) -> Value<'static> {
    Value::I64(i64::from(generation))
}

/// Reads the answer to `switch(name)`: exactly one i64, the generation.
pub fn decode_generation(answer: &[Value<'_>]) -> Result<u16, SwitchAnswerError> {
    const WHAT: &str = "the generation";
    match answer {
        [] => Err(FieldError::Missing { what: WHAT }.into()),
        [Value::I64(n), rest @ ..] => {
            let generation = u16::try_from(*n).map_err(|_| FieldError::Range {
                what: WHAT,
                value: *n,
                ty: "u16",
            })?;
            match rest.len() {
                0 => Ok(generation),
                count => Err(SwitchAnswerError::Trailing { count }),
            }
        }
        [other, ..] => Err(FieldError::Kind {
            what: WHAT,
            expected: ValueKind::I64,
            found: other.kind(),
        }
        .into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    fn example() -> Status {
        Status {
            assembly: "ptp".into(),
            generation: 3,
            state: State::Announced {
                generation: 4,
                assembly: "hold".into(),
                tick: 1234,
            },
            outcomes: vec![
                Outcome::Switched {
                    generation: 3,
                    assembly: "ptp".into(),
                    announced: 900,
                    tick: 900,
                },
                Outcome::Failed {
                    generation: 2,
                    assembly: "nope".into(),
                    reason: "no assembly".into(),
                },
            ],
        }
    }

    #[test]
    fn a_status_has_the_documented_layout_and_reads_back() {
        let sut = example();
        let mut bytes = Vec::new();
        sut.encode(&mut bytes);
        assert_eq!(
            hex::encode(&bytes),
            concat!(
                "a3707470 03",                               // running: ptp, generation 3
                "02 04 a4686f6c64 cd04d2",                   // announced 4 hold at 1234
                "01 03 a3707470 cd0384 cd0384",              // switched 3 ptp 900 900
                "02 02 a46e6f7065 ab6e6f20617373656d626c79", // failed 2 nope "no assembly"
            )
            .replace(' ', "")
        );
        assert_eq!(decode(&bytes), Ok(sut));
        assert_eq!(
            example().state.to_string(),
            "announced 4 hold 1234",
            "as modbot assembly shows it"
        );
    }

    #[test]
    fn every_state_and_the_default_read_back() {
        for state in [
            State::Idle,
            State::Preparing {
                generation: 9,
                assembly: "x".into(),
            },
        ] {
            let sut = Status {
                state,
                ..Status::default()
            };
            let mut bytes = Vec::new();
            sut.encode(&mut bytes);
            assert_eq!(decode(&bytes), Ok(sut));
        }
    }

    #[test]
    fn malformed_status_answers_are_refused_with_the_reason() {
        let mut good = Vec::new();
        example().encode(&mut good);
        assert!(matches!(
            decode(&good[..good.len() - 1]),
            Err(SwitchAnswerError::Field(FieldError::Malformed(_)))
        ));
        // The last outcome cut after its assembly: its reason is missing.
        let cut = good.len() - 12;
        assert_eq!(
            decode(&good[..cut]),
            Err(SwitchAnswerError::Field(FieldError::Missing {
                what: "the reason of a failed switch"
            }))
        );
        assert!(matches!(
            decode(&[]),
            Err(SwitchAnswerError::Field(FieldError::Missing { .. }))
        ));
        // State tag 3.
        let unknown = hex::decode("a3707470 03 03").unwrap();
        assert_eq!(
            decode(&unknown),
            Err(SwitchAnswerError::Tag {
                what: "state",
                tag: 3
            })
        );
        // Generation 70000.
        let wide = hex::decode("a3707470 ce00011170 00").unwrap();
        assert!(matches!(
            decode(&wide),
            Err(SwitchAnswerError::Field(FieldError::Range {
                value: 70000,
                ..
            }))
        ));
        // An outcome tag 0.
        let mut bad = good.clone();
        bad[15] = 0;
        assert!(matches!(
            decode(&bad),
            Err(SwitchAnswerError::Tag {
                what: "outcome",
                ..
            })
        ));
    }

    #[test]
    fn the_generation_answer_is_one_integer_that_fits_in_u16() {
        assert_eq!(decode_generation(&[generation_value(7)]), Ok(7));
        assert!(decode_generation(&[]).is_err());
        assert!(decode_generation(&[Value::I64(-1)]).is_err());
        assert!(decode_generation(&[Value::Text("7")]).is_err());
        assert_eq!(
            decode_generation(&[Value::I64(1), Value::I64(2)]),
            Err(SwitchAnswerError::Trailing { count: 1 })
        );
    }
}
