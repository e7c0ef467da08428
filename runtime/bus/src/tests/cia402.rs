//! The state machine against IEC 61800-7-201's state table, written out here independently
//! of the implementation's.

use crate::cia402::{
    Command, DriveState, DriveStateMachine, FaultReason, IllegalCommand, ModeOfOperation,
    QuickStopOption, Transition, UnsupportedMode,
};

use Command as C;
use DriveState as S;

const SHUTDOWN: u16 = 0x0006;
const SWITCH_ON: u16 = 0x0007;
const ENABLE_OPERATION: u16 = 0x000F;
const DISABLE_VOLTAGE: u16 = 0x0000;
const QUICK_STOP: u16 = 0x0002;
const FAULT_RESET: u16 = 0x0080;

/// A state machine brought to `state` through the public API only.
fn reach(state: DriveState) -> DriveStateMachine {
    reach_with_bit_7(state, 0)
}

/// As [`reach`], with bit 7 (`bit_7` = 0 or 0x80) in every controlword: with 0x80 the last
/// controlword has bit 7 high, so the next cannot make an edge.
fn reach_with_bit_7(state: DriveState, bit_7: u16) -> DriveStateMachine {
    let mut sut = DriveStateMachine::new();
    let path: &[u16] = match state {
        S::NotReadyToSwitchOn | S::SwitchOnDisabled | S::FaultReactionActive | S::Fault => &[],
        S::ReadyToSwitchOn => &[SHUTDOWN],
        S::SwitchedOn => &[SHUTDOWN, SWITCH_ON],
        S::OperationEnabled => &[SHUTDOWN, SWITCH_ON, ENABLE_OPERATION],
        S::QuickStopActive => &[SHUTDOWN, SWITCH_ON, ENABLE_OPERATION, QUICK_STOP],
    };
    if state != S::NotReadyToSwitchOn {
        sut.complete_initialisation();
    }
    if bit_7 != 0 {
        // A fault reset edge: rejected outside fault, and leaves bit 7 high.
        assert!(sut.apply(bit_7).is_err());
    }
    for &controlword in path {
        sut.apply(controlword | bit_7).expect("a legal path");
    }
    if matches!(state, S::FaultReactionActive | S::Fault) {
        sut.fault(FaultReason::Injected);
    }
    if state == S::Fault {
        sut.motion_stopped();
    }
    assert_eq!(sut.state(), state);
    assert_eq!(sut.last_controlword() & 0x80, bit_7);
    sut
}

fn t(number: u8, from: DriveState, to: DriveState) -> Option<Transition> {
    Some(Transition { number, from, to })
}

/// Applies `controlword` in `from` and checks the transition and the statusword.
fn assert_transition(from: DriveState, controlword: u16, number: u8, to: DriveState, sw: u16) {
    let mut sut = reach(from);
    assert_eq!(
        sut.apply(controlword),
        Ok(t(number, from, to)),
        "{from} + {controlword:#06x}"
    );
    assert_eq!(sut.state(), to);
    assert_eq!(sut.statusword(), sw, "statusword after transition {number}");
}

#[test]
fn every_transition_of_the_standard_lands_in_its_state_with_its_statusword() {
    let sut = DriveStateMachine::new();
    assert_eq!(
        (sut.state(), sut.statusword()),
        (S::NotReadyToSwitchOn, 0x0020),
        "0"
    );
    let mut sut = DriveStateMachine::new();
    let one = sut.complete_initialisation();
    assert_eq!(one, t(1, S::NotReadyToSwitchOn, S::SwitchOnDisabled));
    assert_eq!(sut.statusword(), 0x0260, "1");
    assert_transition(S::SwitchOnDisabled, SHUTDOWN, 2, S::ReadyToSwitchOn, 0x0231);
    assert_transition(S::ReadyToSwitchOn, SWITCH_ON, 3, S::SwitchedOn, 0x0233);
    assert_transition(
        S::ReadyToSwitchOn,
        ENABLE_OPERATION,
        3,
        S::SwitchedOn,
        0x0233,
    );
    assert_transition(
        S::SwitchedOn,
        ENABLE_OPERATION,
        4,
        S::OperationEnabled,
        0x0237,
    );
    assert_transition(S::OperationEnabled, SWITCH_ON, 5, S::SwitchedOn, 0x0233);
    assert_transition(S::SwitchedOn, SHUTDOWN, 6, S::ReadyToSwitchOn, 0x0231);
    assert_transition(
        S::ReadyToSwitchOn,
        QUICK_STOP,
        7,
        S::SwitchOnDisabled,
        0x0260,
    );
    assert_transition(
        S::ReadyToSwitchOn,
        DISABLE_VOLTAGE,
        7,
        S::SwitchOnDisabled,
        0x0260,
    );
    assert_transition(S::OperationEnabled, SHUTDOWN, 8, S::ReadyToSwitchOn, 0x0231);
    assert_transition(
        S::OperationEnabled,
        DISABLE_VOLTAGE,
        9,
        S::SwitchOnDisabled,
        0x0260,
    );
    assert_transition(
        S::SwitchedOn,
        DISABLE_VOLTAGE,
        10,
        S::SwitchOnDisabled,
        0x0260,
    );
    assert_transition(S::SwitchedOn, QUICK_STOP, 10, S::SwitchOnDisabled, 0x0260);
    assert_transition(
        S::OperationEnabled,
        QUICK_STOP,
        11,
        S::QuickStopActive,
        0x0217,
    );
    assert_transition(
        S::QuickStopActive,
        DISABLE_VOLTAGE,
        12,
        S::SwitchOnDisabled,
        0x0260,
    );
    for from in S::ALL
        .into_iter()
        .filter(|s| !matches!(s, S::FaultReactionActive | S::Fault))
    {
        let mut sut = reach(from);
        let thirteen = sut.fault(FaultReason::ErrorCode(0x7500));
        assert_eq!(thirteen, t(13, from, S::FaultReactionActive));
        assert_eq!(sut.statusword(), 0x023F, "13 from {from}");
        assert_eq!(sut.fault_reason(), Some(FaultReason::ErrorCode(0x7500)));
    }
    let mut sut = reach(S::FaultReactionActive);
    assert_eq!(
        sut.motion_stopped(),
        t(14, S::FaultReactionActive, S::Fault)
    );
    assert_eq!(sut.statusword(), 0x0228, "14");
    assert_transition(S::Fault, FAULT_RESET, 15, S::SwitchOnDisabled, 0x0260);
    assert_transition(
        S::QuickStopActive,
        ENABLE_OPERATION,
        16,
        S::OperationEnabled,
        0x0237,
    );
}

#[test]
fn with_disable_after_stop_a_quick_stop_ends_in_switch_on_disabled_and_cannot_resume() {
    let mut sut =
        reach(S::OperationEnabled).with_quick_stop_option(QuickStopOption::DisableAfterStop);
    sut.apply(QUICK_STOP).unwrap();
    assert!(
        sut.apply(ENABLE_OPERATION).is_err(),
        "16 needs option codes 5-8"
    );
    assert_eq!(
        sut.motion_stopped(),
        t(12, S::QuickStopActive, S::SwitchOnDisabled)
    );
    let mut hold = reach(S::QuickStopActive);
    assert_eq!(
        hold.motion_stopped(),
        None,
        "hold after stop stays in quick stop active"
    );
    assert_eq!(hold.state(), S::QuickStopActive);
}

/// The standard's table plus the commands that keep a state (what a master repeats every
/// cycle). `None` = stay. Every pair not listed is illegal.
/// (state, command, `Some((transition, next state))` or `None` for stay).
type Row = (DriveState, Command, Option<(u8, DriveState)>);

const TABLE: &[Row] = &[
    (S::NotReadyToSwitchOn, C::DisableVoltage, None),
    (S::NotReadyToSwitchOn, C::QuickStop, None),
    (
        S::SwitchOnDisabled,
        C::Shutdown,
        Some((2, S::ReadyToSwitchOn)),
    ),
    (S::SwitchOnDisabled, C::DisableVoltage, None),
    (S::SwitchOnDisabled, C::QuickStop, None),
    (S::ReadyToSwitchOn, C::Shutdown, None),
    (S::ReadyToSwitchOn, C::SwitchOn, Some((3, S::SwitchedOn))),
    (
        S::ReadyToSwitchOn,
        C::EnableOperation,
        Some((3, S::SwitchedOn)),
    ),
    (
        S::ReadyToSwitchOn,
        C::DisableVoltage,
        Some((7, S::SwitchOnDisabled)),
    ),
    (
        S::ReadyToSwitchOn,
        C::QuickStop,
        Some((7, S::SwitchOnDisabled)),
    ),
    (S::SwitchedOn, C::Shutdown, Some((6, S::ReadyToSwitchOn))),
    (S::SwitchedOn, C::SwitchOn, None),
    (
        S::SwitchedOn,
        C::EnableOperation,
        Some((4, S::OperationEnabled)),
    ),
    (
        S::SwitchedOn,
        C::DisableVoltage,
        Some((10, S::SwitchOnDisabled)),
    ),
    (S::SwitchedOn, C::QuickStop, Some((10, S::SwitchOnDisabled))),
    (
        S::OperationEnabled,
        C::Shutdown,
        Some((8, S::ReadyToSwitchOn)),
    ),
    (S::OperationEnabled, C::SwitchOn, Some((5, S::SwitchedOn))),
    (S::OperationEnabled, C::EnableOperation, None),
    (
        S::OperationEnabled,
        C::DisableVoltage,
        Some((9, S::SwitchOnDisabled)),
    ),
    (
        S::OperationEnabled,
        C::QuickStop,
        Some((11, S::QuickStopActive)),
    ),
    (
        S::QuickStopActive,
        C::EnableOperation,
        Some((16, S::OperationEnabled)),
    ),
    (
        S::QuickStopActive,
        C::DisableVoltage,
        Some((12, S::SwitchOnDisabled)),
    ),
    (S::QuickStopActive, C::QuickStop, None),
    (S::FaultReactionActive, C::DisableVoltage, None),
    (S::FaultReactionActive, C::QuickStop, None),
    (S::Fault, C::DisableVoltage, None),
    (S::Fault, C::QuickStop, None),
    (S::Fault, C::FaultReset, Some((15, S::SwitchOnDisabled))),
];

#[test]
fn every_state_and_command_pair_not_in_the_table_is_rejected_and_keeps_the_state() {
    let (mut transitions, mut stays, mut rejected) = (0, 0, 0);
    for state in S::ALL {
        for bit_7 in [0x0000, 0x0080] {
            for controlword in 0..=0xFFu16 {
                let mut sut = reach_with_bit_7(state, bit_7);
                let command = Command::decode(controlword, sut.last_controlword());
                let expected = TABLE.iter().find(|(s, c, _)| (*s, *c) == (state, command));
                let result = sut.apply(controlword);
                match expected {
                    Some((_, _, Some((number, to)))) => {
                        transitions += 1;
                        assert_eq!(result, Ok(t(*number, state, *to)), "{state} + {command}");
                        assert_eq!(sut.state(), *to);
                    }
                    Some((_, _, None)) => {
                        stays += 1;
                        assert_eq!(result, Ok(None), "{state} + {command} stays");
                        assert_eq!(sut.state(), state);
                    }
                    None => {
                        rejected += 1;
                        let error = IllegalCommand {
                            state,
                            command,
                            controlword,
                        };
                        assert_eq!(result, Err(error));
                        assert_eq!(sut.state(), state, "a rejected command changes nothing");
                    }
                }
            }
        }
    }
    assert_eq!(transitions + stays + rejected, 8 * 2 * 256);
    assert!(transitions > 0 && stays > 0 && rejected > 0);
}

#[test]
fn the_decoder_follows_the_standards_bit_patterns() {
    for controlword in 0..=0x7Fu16 {
        let by_pattern = [
            (0x87, 0x06, C::Shutdown),
            (0x8F, 0x07, C::SwitchOn),
            (0x8F, 0x0F, C::EnableOperation),
            (0x82, 0x00, C::DisableVoltage),
            (0x86, 0x02, C::QuickStop),
        ];
        let matching: Vec<_> = by_pattern
            .iter()
            .filter(|(mask, value, _)| controlword & mask == *value)
            .map(|(_, _, c)| *c)
            .collect();
        assert_eq!(matching.len(), 1, "{controlword:#06x} matches one pattern");
        assert_eq!(Command::decode(controlword, 0), matching[0]);
        assert_eq!(Command::decode(controlword | 0x80, 0), C::FaultReset);
        assert_eq!(
            Command::decode(controlword | 0x80, 0x80),
            matching[0],
            "bit 7 held"
        );
    }
    for command in Command::ALL {
        assert_eq!(Command::decode(command.controlword(), 0), command);
    }
}

#[test]
fn fault_reset_needs_a_rising_edge_of_bit_7() {
    let mut sut = reach(S::OperationEnabled);
    sut.apply(ENABLE_OPERATION | FAULT_RESET).ok();
    sut.fault(FaultReason::Injected);
    sut.motion_stopped();
    assert_eq!(
        sut.apply(FAULT_RESET),
        Ok(None),
        "bit 7 was already high: no edge"
    );
    assert_eq!(sut.state(), S::Fault);
    assert_eq!(sut.apply(DISABLE_VOLTAGE), Ok(None));
    assert_eq!(
        sut.apply(FAULT_RESET),
        Ok(t(15, S::Fault, S::SwitchOnDisabled))
    );
    assert_eq!(sut.fault_reason(), None, "the reset clears the fault");
    let mut reacting = reach(S::FaultReactionActive);
    assert!(
        reacting.apply(FAULT_RESET).is_err(),
        "the reaction must finish first"
    );
}

#[test]
fn a_second_fault_keeps_the_first_reason() {
    let mut sut = reach(S::OperationEnabled);
    sut.fault(FaultReason::ErrorCode(0x2310));
    assert_eq!(sut.fault(FaultReason::Injected), None);
    sut.motion_stopped();
    assert_eq!(sut.fault(FaultReason::Injected), None);
    assert_eq!(sut.fault_reason(), Some(FaultReason::ErrorCode(0x2310)));
}

#[test]
fn an_inhibited_drive_accepts_but_does_not_execute_commands_that_raise_power() {
    let mut sut = reach(S::SwitchOnDisabled);
    sut.inhibit_enable(true);
    assert_eq!(sut.apply(SHUTDOWN), Ok(None));
    assert_eq!(sut.state(), S::SwitchOnDisabled);
    let mut sut = reach(S::QuickStopActive);
    sut.inhibit_enable(true);
    assert_eq!(sut.apply(ENABLE_OPERATION), Ok(None), "16 inhibited");
    assert_eq!(sut.state(), S::QuickStopActive);
    let twelve = t(12, S::QuickStopActive, S::SwitchOnDisabled);
    assert_eq!(
        sut.apply(DISABLE_VOLTAGE),
        Ok(twelve),
        "what removes power is executed"
    );
    sut.inhibit_enable(false);
    assert_eq!(
        sut.apply(SHUTDOWN),
        Ok(t(2, S::SwitchOnDisabled, S::ReadyToSwitchOn))
    );
}

#[test]
fn a_drive_whose_fault_persists_accepts_the_reset_and_stays_in_fault() {
    let mut sut = reach(S::SwitchOnDisabled);
    sut.fault(FaultReason::ErrorCode(0x7305));
    sut.motion_stopped();
    sut.inhibit_fault_reset(true);
    assert_eq!(sut.apply(FAULT_RESET), Ok(None), "15 refused, not illegal");
    assert_eq!(sut.state(), S::Fault);
    assert_eq!(sut.fault_reason(), Some(FaultReason::ErrorCode(0x7305)));
    sut.inhibit_fault_reset(false);
    assert_eq!(
        sut.apply(FAULT_RESET),
        Ok(None),
        "bit 7 held high is no edge"
    );
    assert_eq!(sut.apply(DISABLE_VOLTAGE), Ok(None));
    assert_eq!(
        sut.apply(FAULT_RESET),
        Ok(t(15, S::Fault, S::SwitchOnDisabled))
    );
    assert_eq!(sut.fault_reason(), None);
}

#[test]
fn every_state_is_read_back_from_its_statusword_with_the_standards_masks() {
    for state in S::ALL {
        let statusword = state.statusword();
        assert_eq!(S::from_statusword(statusword), Some(state));
        let with_drive_bits = statusword | 0x3C80;
        assert_eq!(
            S::from_statusword(with_drive_bits),
            Some(state),
            "{statusword:#06x}"
        );
    }
    assert_eq!(S::from_statusword(0x0001), None);
}

#[test]
fn modes_of_operation_convert_to_and_from_their_codes() {
    for (code, mode) in [
        (8, ModeOfOperation::Csp),
        (9, ModeOfOperation::Csv),
        (10, ModeOfOperation::Cst),
    ] {
        assert_eq!(ModeOfOperation::try_from(code), Ok(mode));
        assert_eq!(i8::from(mode), code);
    }
    assert_eq!(ModeOfOperation::try_from(1), Err(UnsupportedMode(1)));
    assert_eq!(
        ModeOfOperation::Csp.to_string(),
        "cyclic synchronous position (CSP, 8)"
    );
}

#[test]
fn a_rejected_command_names_the_state_and_the_command() {
    let mut sut = reach(S::SwitchOnDisabled);
    let error = sut.apply(ENABLE_OPERATION).unwrap_err();
    assert_eq!(
        error.to_string(),
        "enable operation (xxxx.1111) is not legal in state 'switch on disabled' (controlword 0x000f)"
    );
}
