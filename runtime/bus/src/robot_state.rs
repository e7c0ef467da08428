//! The robot's state, owned by the bus bridge and the same for every backend: whether the
//! drives follow the running assembly, and if not, why and since when.
//!
//! - `operational`: every drive in operation enabled, following the running assembly;
//! - `safe_stop`: the bridge stopped the drives (quick stop) and holds them: the coordinator
//!   was lost, the assembly faulted, the bus failed. Only an operator's reset ends it;
//! - `fault`: a drive reported a fault (its error code, 0x603F): it disabled itself and the
//!   bridge quick-stopped the others. Only an operator's reset ends it;
//! - `disabled`: no stop and no fault, but not every drive is enabled (before the assembly has
//!   enabled them, or while a reset brings them back).
//!
//! The state travels as a method's answer, a blackboard item and a program's
//! `robot_state()` in one form, [`RobotState::to_values`]: the kind as text, the tick since
//! which it holds, the faulted drive (−1: none), its error code, and the cause in words.

use std::fmt;

use modbot_ipc_schema::OwnedValue;

use super::backend::error_text;

/// The robot's state (see the module doc).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RobotState {
    Disabled {
        since_tick: u64,
    },
    Operational {
        since_tick: u64,
    },
    SafeStop {
        since_tick: u64,
        cause: String,
    },
    Fault {
        since_tick: u64,
        drive: usize,
        error_code: u16,
        cause: String,
    },
}

/// The kinds, as [`RobotState::kind`] names them and the `state` output of `bus` numbers
/// them (0 to 3).
pub const KINDS: [&str; 4] = ["disabled", "operational", "safe_stop", "fault"];

impl RobotState {
    /// `disabled`, `operational`, `safe_stop` or `fault`.
    pub fn kind(&self) -> &'static str {
        KINDS[self.code()]
    }

    /// The kind's number: 0 disabled, 1 operational, 2 safe stop, 3 fault.
    pub fn code(&self) -> usize {
        match self {
            RobotState::Disabled { .. } => 0,
            RobotState::Operational { .. } => 1,
            RobotState::SafeStop { .. } => 2,
            RobotState::Fault { .. } => 3,
        }
    }

    /// The tick since which the state holds.
    pub fn since_tick(&self) -> u64 {
        match self {
            RobotState::Disabled { since_tick }
            | RobotState::Operational { since_tick }
            | RobotState::SafeStop { since_tick, .. }
            | RobotState::Fault { since_tick, .. } => *since_tick,
        }
    }

    pub fn is_operational(&self) -> bool {
        matches!(self, RobotState::Operational { .. })
    }

    /// Why the robot does not follow, in words (empty when operational or disabled).
    pub fn cause(&self) -> &str {
        match self {
            RobotState::SafeStop { cause, .. } | RobotState::Fault { cause, .. } => cause,
            _ => "",
        }
    }

    /// The state as values: kind, since tick, drive (−1: none), error code, cause.
    pub fn to_values(&self) -> [OwnedValue; 5] {
        let (drive, code) = match self {
            RobotState::Fault {
                drive, error_code, ..
            } => (*drive as i64, i64::from(*error_code)),
            _ => (-1, 0),
        };
        [
            OwnedValue::Text(self.kind().to_owned()),
            OwnedValue::I64(self.since_tick() as i64),
            OwnedValue::I64(drive),
            OwnedValue::I64(code),
            OwnedValue::Text(self.cause().to_owned()),
        ]
    }

    /// The state from [`RobotState::to_values`]'s values.
    pub fn from_values(values: &[OwnedValue]) -> Result<RobotState, RobotStateError> {
        let bad = |why: &str| RobotStateError(why.to_owned());
        let [OwnedValue::Text(kind), OwnedValue::I64(since), OwnedValue::I64(drive), OwnedValue::I64(code), OwnedValue::Text(cause)] =
            values
        else {
            return Err(bad(
                "expected text kind, i64 since tick, i64 drive, i64 error code, text cause",
            ));
        };
        let since_tick = u64::try_from(*since).map_err(|_| bad("a negative tick"))?;
        Ok(match kind.as_str() {
            "disabled" => RobotState::Disabled { since_tick },
            "operational" => RobotState::Operational { since_tick },
            "safe_stop" => RobotState::SafeStop {
                since_tick,
                cause: cause.clone(),
            },
            "fault" => RobotState::Fault {
                since_tick,
                drive: usize::try_from(*drive).map_err(|_| bad("a fault without its drive"))?,
                error_code: u16::try_from(*code)
                    .map_err(|_| bad("an error code beyond 16 bits"))?,
                cause: cause.clone(),
            },
            other => return Err(RobotStateError(format!("an unknown kind '{other}'"))),
        })
    }
}

/// The cause of drive `drive`'s fault with `error_code`, in words.
pub fn fault_cause(drive: usize, error_code: u16) -> String {
    format!(
        "drive {drive} fault {error_code:#06x}: {}",
        error_text(error_code)
    )
}

impl fmt::Display for RobotState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RobotState::Disabled { since_tick } | RobotState::Operational { since_tick } => {
                write!(f, "{} since tick {since_tick}", self.kind())
            }
            RobotState::SafeStop { since_tick, cause } => {
                write!(f, "safe stop since tick {since_tick} ({cause})")
            }
            RobotState::Fault {
                since_tick, cause, ..
            } => write!(f, "fault since tick {since_tick} ({cause})"),
        }
    }
}

/// Values that are not a robot state.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("not a robot state: {0}")]
pub struct RobotStateError(pub String);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_state_reads_back_from_its_values() {
        for state in [
            RobotState::Disabled { since_tick: 0 },
            RobotState::Operational { since_tick: 12 },
            RobotState::SafeStop {
                since_tick: 4012,
                cause: "coordinator lost: no tick for 3 base periods".into(),
            },
            RobotState::Fault {
                since_tick: 7,
                drive: 2,
                error_code: 0x8611,
                cause: fault_cause(2, 0x8611),
            },
        ] {
            assert_eq!(RobotState::from_values(&state.to_values()), Ok(state));
        }
    }

    #[test]
    fn a_state_says_why_and_since_when() {
        let s = RobotState::Fault {
            since_tick: 7,
            drive: 2,
            error_code: 0x8611,
            cause: fault_cause(2, 0x8611),
        };
        assert_eq!(
            s.to_string(),
            "fault since tick 7 (drive 2 fault 0x8611: following error: beyond the window for longer than its time-out)"
        );
        assert!(RobotState::from_values(&[OwnedValue::I64(1)]).is_err());
        let mut v = s.to_values();
        v[0] = OwnedValue::Text("dancing".into());
        assert_eq!(
            RobotState::from_values(&v).unwrap_err().to_string(),
            "not a robot state: an unknown kind 'dancing'"
        );
    }
}
