//! The simulated drives' own faults: a lasting following error and a torque held at its limit
//! are detected after their time and not before, each fault disables the drive at once with
//! its error code, and a lost encoder freezes the motor's measurements and keeps the drive in
//! fault until it is back.

use crate::backend::BlockError;
use crate::cia402::{sw, DriveState};
use crate::{AxisActual, Backend, DriveFault, DriveParams, PlantParams, SimBackend};

use super::drives::*;
use DriveState as S;

/// Whole cycles of `DT` in `seconds`.
fn cycles_in(seconds: f64) -> usize {
    (seconds / DT).round() as usize
}

/// A drive that faulted: in fault, its code in 0x603F, no torque.
fn assert_faulted(actual: &AxisActual, code: u16) {
    assert_eq!(actual.state, S::Fault, "{actual:?}");
    assert!(actual.statusword & sw::FAULT != 0, "{actual:?}");
    assert_eq!(actual.error_code, code, "{actual:?}");
    assert_eq!(actual.motor_torque, 0.0, "{actual:?}");
}

#[test]
fn a_following_error_beyond_its_limit_faults_csp_after_its_timeout_and_not_before() {
    let mut sut = backend(2);
    let p = *sut.drive_params();
    enable(&mut sut, CSP);
    sut.block_axis(0, true);
    let mut far = command(0x0F, CSP);
    far.target_position = p.following_error_limit + 0.5;
    let still = command(0x0F, CSP);
    for n in 1..=cycles_in(p.following_error_timeout) {
        let actual = cycle(&mut sut, &[far, still]);
        assert_eq!(actual[0].state, S::OperationEnabled, "cycle {n}");
        assert_eq!(actual[0].error_code, 0, "cycle {n}");
    }
    let actual = cycle(&mut sut, &[far, still]);
    assert_faulted(&actual[0], 0x8611);
    assert_eq!(
        actual[1].state,
        S::OperationEnabled,
        "the other axis runs on"
    );
    let later = cycle(&mut sut, &[far, still]);
    assert_faulted(&later[0], 0x8611);
}

#[test]
fn a_torque_held_at_its_limit_faults_after_its_time_and_a_break_starts_the_time_again() {
    let mut sut = backend(1);
    let limit_time = sut.drive_params().torque_limit_time;
    enable(&mut sut, CST);
    sut.block_axis(0, true);
    let mut push = command(0x0F, CST);
    push.target_torque = 2.0 * PlantParams::default().torque_limit;
    let rest = command(0x0F, CST);
    let cycles = cycles_in(limit_time);
    for _ in 1..cycles {
        cycle(&mut sut, &[push]);
    }
    let actual = cycle(&mut sut, &[rest])[0];
    assert_eq!(actual.state, S::OperationEnabled, "a break below the limit");
    for n in 1..=cycles {
        let actual = cycle(&mut sut, &[push])[0];
        assert_eq!(actual.state, S::OperationEnabled, "cycle {n}");
        assert!(actual.statusword & sw::INTERNAL_LIMIT_ACTIVE != 0);
    }
    let actual = cycle(&mut sut, &[push])[0];
    assert_faulted(&actual, 0x8311);
}

#[test]
fn an_injected_following_or_torque_fault_disables_the_drive_at_once_and_the_joint_coasts() {
    for fault in [DriveFault::Following, DriveFault::Torque] {
        let mut sut = backend(1);
        enable(&mut sut, CSV);
        let mut spin = command(0x0F, CSV);
        spin.target_velocity = 1.0;
        for _ in 0..300 {
            cycle(&mut sut, &[spin]);
        }
        sut.inject(0, fault, false).unwrap();
        let before = cycle(&mut sut, &[spin])[0];
        assert_eq!(
            before.state,
            S::OperationEnabled,
            "{fault:?} off does nothing"
        );
        sut.inject(0, fault, true).unwrap();
        let actual = cycle(&mut sut, &[spin])[0];
        assert_faulted(&actual, fault.error_code());
        assert!(
            actual.motor_velocity > 0.9 && actual.link_position > before.link_position,
            "no braking: the joint moves on, {actual:?}"
        );
        assert_eq!(sut.fault_cause(0), None, "a reset can clear it");
    }
}

#[test]
fn a_drive_not_in_operation_enabled_can_be_faulted_and_a_bad_axis_is_refused() {
    let mut sut = backend(2);
    cycle(&mut sut, &[command(0x00, CSV); 2]);
    sut.inject(1, DriveFault::Torque, true).unwrap();
    let actual = cycle(&mut sut, &[command(0x00, CSV); 2]);
    assert_eq!(actual[0].state, S::SwitchOnDisabled);
    assert_faulted(&actual[1], 0x8311);
    sut.inject(1, DriveFault::Following, true).unwrap();
    let actual = cycle(&mut sut, &[command(0x00, CSV); 2]);
    assert_eq!(actual[1].error_code, 0x8311, "the first fault is kept");
    assert_eq!(
        sut.inject(2, DriveFault::Encoder, true),
        Err(BlockError::NoSuchAxis { axis: 2, axes: 2 })
    );
    assert_eq!(sut.fault_cause(2), None);
}

#[test]
fn a_lost_encoder_freezes_the_measurements_and_refuses_the_fault_reset_until_it_is_back() {
    let mut sut = backend(1);
    enable(&mut sut, CSV);
    let mut spin = command(0x0F, CSV);
    spin.target_velocity = 1.0;
    let mut last = AxisActual::default();
    for _ in 0..300 {
        last = cycle(&mut sut, &[spin])[0];
    }
    sut.inject(0, DriveFault::Encoder, true).unwrap();
    let lost = cycle(&mut sut, &[spin])[0];
    assert_faulted(&lost, 0x7305);
    assert_eq!(sut.fault_cause(0), Some("its motor encoder is still lost"));
    let rejected = sut.rejected(0).0;
    for controlword in [0x00, 0x80, 0x00, 0x80] {
        let actual = cycle(&mut sut, &[command(controlword, CSV)])[0];
        assert_faulted(&actual, 0x7305);
        assert_eq!(
            (actual.motor_position, actual.motor_velocity),
            (last.motor_position, last.motor_velocity),
            "frozen at the last measurement"
        );
        assert!(
            actual.link_position > lost.link_position,
            "the joint moves on"
        );
    }
    assert!(
        (sut.plant(0).state().motor_position - last.motor_position).abs() > 1e-3,
        "the motor itself moved"
    );
    assert_eq!(
        sut.rejected(0).0,
        rejected,
        "the refused reset is not illegal"
    );
    sut.inject(0, DriveFault::Encoder, false).unwrap();
    assert_eq!(sut.fault_cause(0), None);
    let back = cycle(&mut sut, &[command(0x00, CSV)])[0];
    assert_faulted(&back, 0x7305);
    assert_eq!(back.motor_position, sut.plant(0).state().motor_position);
    let reset = cycle(&mut sut, &[command(0x80, CSV)])[0];
    assert_eq!(reset.state, S::SwitchOnDisabled);
    assert_eq!(reset.error_code, 0, "a fault reset clears the code");
    for (controlword, state) in [
        (0x06, S::ReadyToSwitchOn),
        (0x07, S::SwitchedOn),
        (0x0F, S::OperationEnabled),
    ] {
        let actual = cycle(&mut sut, &[command(controlword, CSV)])[0];
        assert_eq!(actual.state, state, "after {controlword:#06x}");
    }
}

#[test]
fn a_lost_encoder_ends_a_braking_fault_reaction_at_once() {
    let mut sut = backend(1);
    enable(&mut sut, CSV);
    let mut spin = command(0x0F, CSV);
    spin.target_velocity = 1.0;
    for _ in 0..300 {
        cycle(&mut sut, &[spin]);
    }
    sut.inject_fault(0);
    let braking = cycle(&mut sut, &[spin])[0];
    assert_eq!(braking.state, S::FaultReactionActive);
    assert_eq!(
        braking.error_code, 0xFF00,
        "the braking injected fault's own code"
    );
    sut.inject(0, DriveFault::Encoder, true).unwrap();
    let actual = cycle(&mut sut, &[spin])[0];
    assert_faulted(&actual, 0xFF00);
    assert_eq!(sut.fault_cause(0), Some("its motor encoder is still lost"));
}

/// A parameter's name and what sets it to zero.
type Zeroing = (&'static str, fn(&mut DriveParams));

#[test]
fn the_fault_limits_must_be_positive() {
    let zeroed: [Zeroing; 3] = [
        ("following_error_limit", |p| p.following_error_limit = 0.0),
        ("following_error_timeout", |p| {
            p.following_error_timeout = 0.0
        }),
        ("torque_limit_time", |p| p.torque_limit_time = 0.0),
    ];
    for (name, zero) in zeroed {
        let mut p = DriveParams::default();
        zero(&mut p);
        let e = SimBackend::try_new(1, PlantParams::default(), p)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name), "{e}");
    }
}
