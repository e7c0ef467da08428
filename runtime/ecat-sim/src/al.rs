//! The application layer state machine (INIT, PRE-OP, SAFE-OP, OP) and its status codes.

/// An AL state, as in AL control/status bits 0–3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum AlState {
    /// INIT: no mailbox, no process data.
    Init,
    /// PRE-OP: mailbox.
    PreOp,
    /// BOOTSTRAP: firmware update (not supported by the emulator).
    Bootstrap,
    /// SAFE-OP: mailbox, inputs.
    SafeOp,
    /// OP: mailbox, inputs, outputs.
    Op,
}

impl AlState {
    /// The state of a 4-bit code.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            1 => Self::Init,
            2 => Self::PreOp,
            3 => Self::Bootstrap,
            4 => Self::SafeOp,
            8 => Self::Op,
            _ => return None,
        })
    }

    /// The 4-bit code.
    pub fn code(self) -> u8 {
        match self {
            Self::Init => 1,
            Self::PreOp => 2,
            Self::Bootstrap => 3,
            Self::SafeOp => 4,
            Self::Op => 8,
        }
    }

    fn rank(self) -> u8 {
        match self {
            Self::Init => 0,
            Self::PreOp | Self::Bootstrap => 1,
            Self::SafeOp => 2,
            Self::Op => 3,
        }
    }

    /// True if going from `self` to `to` is one step up (INIT→PRE-OP→SAFE-OP→OP).
    pub fn is_next_step_up(self, to: Self) -> bool {
        matches!(
            (self, to),
            (Self::Init, Self::PreOp) | (Self::PreOp, Self::SafeOp) | (Self::SafeOp, Self::Op)
        )
    }

    /// True if `to` is lower than `self`.
    pub fn is_down_to(self, to: Self) -> bool {
        to.rank() < self.rank()
    }
}

/// AL status codes (ETG.1000.6 Table 11) the emulator reports.
pub mod status_code {
    /// No error.
    pub const NO_ERROR: u16 = 0x0000;
    /// Invalid requested state change.
    pub const INVALID_STATE_CHANGE: u16 = 0x0011;
    /// Unknown requested state.
    pub const UNKNOWN_STATE: u16 = 0x0012;
    /// Bootstrap not supported.
    pub const BOOTSTRAP_NOT_SUPPORTED: u16 = 0x0013;
    /// Invalid mailbox configuration (PRE-OP).
    pub const INVALID_MAILBOX_CONFIG: u16 = 0x0016;
    /// Sync manager watchdog.
    pub const SM_WATCHDOG: u16 = 0x001B;
    /// Invalid output configuration.
    pub const INVALID_OUTPUT_CONFIG: u16 = 0x001D;
    /// Invalid input configuration.
    pub const INVALID_INPUT_CONFIG: u16 = 0x001E;
    /// Invalid output mapping.
    pub const INVALID_OUTPUT_MAPPING: u16 = 0x0025;
    /// Invalid input mapping.
    pub const INVALID_INPUT_MAPPING: u16 = 0x0024;
    /// Invalid DC SYNC configuration.
    pub const INVALID_DC_SYNC_CONFIG: u16 = 0x0030;
    /// DC invalid sync cycle time.
    pub const DC_INVALID_CYCLE_TIME: u16 = 0x0035;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn state_codes_round_trip() {
        for state in [
            AlState::Init,
            AlState::PreOp,
            AlState::Bootstrap,
            AlState::SafeOp,
            AlState::Op,
        ] {
            assert_eq!(AlState::from_code(state.code()), Some(state));
        }
        assert_eq!(AlState::from_code(5), None);
    }

    #[test]
    fn only_single_steps_go_up() {
        assert!(AlState::Init.is_next_step_up(AlState::PreOp));
        assert!(!AlState::Init.is_next_step_up(AlState::SafeOp));
        assert!(!AlState::PreOp.is_next_step_up(AlState::Op));
        assert!(AlState::Op.is_down_to(AlState::Init));
    }
}
