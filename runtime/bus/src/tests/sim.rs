//! The simulated drives in closed loop: enabling, CSP tracking, quick stop and safe stop,
//! faults, a blocked link, determinism.

use crate::cia402::{sw, DriveState, ModeOfOperation};
use crate::{AxisActual, AxisCommand, Backend, PlantParams};

use super::drives::*;
use DriveState as S;

fn has(actual: &AxisActual, bit: u16) -> bool {
    actual.statusword & bit != 0
}

#[test]
fn six_drives_in_csp_follow_steps_and_ramps_after_settling() {
    let mut sut = backend(6);
    let actuals = enable(&mut sut, CSP);
    assert!(actuals
        .iter()
        .all(|a| a.mode == CSP && has(a, sw::MODE_SPECIFIC_12)));
    let mut worst = [0.0f64; 6];
    for n in 0..2000 {
        let t = n as f64 * DT;
        let commands: Vec<_> = (0..6)
            .map(|axis| {
                let mut c = command(0x0F, CSP);
                let size = 0.1 * (axis + 1) as f64;
                if axis % 2 == 0 {
                    c.target_position = if t >= 0.1 { size } else { 0.0 };
                } else if t >= 0.1 {
                    c.target_position = size * (t - 0.1);
                    c.target_velocity = size;
                }
                c
            })
            .collect();
        let actuals = cycle(&mut sut, &commands);
        if t >= 1.0 {
            for (axis, (c, a)) in commands.iter().zip(&actuals).enumerate() {
                // The actuals are measured a cycle later than the target was valid.
                let target = c.target_position + c.target_velocity * DT;
                let error = (target - a.motor_position).abs();
                let link_error = (target - a.link_position).abs();
                worst[axis] = worst[axis].max(error).max(link_error);
                assert!(!has(a, sw::MODE_SPECIFIC_13), "no following error");
            }
        }
    }
    assert!(
        worst.iter().all(|&e| e < 1e-4),
        "errors after 1 s: {worst:?}"
    );
}

#[test]
fn a_quick_stop_decelerates_to_standstill_holds_and_recovers_through_switch_on_disabled() {
    let mut sut = backend(1);
    enable(&mut sut, CSV);
    let mut moving = command(0x0F, CSV);
    moving.target_velocity = 2.0;
    for _ in 0..500 {
        cycle(&mut sut, &[moving]);
    }
    let stop = AxisCommand {
        controlword: 0x02,
        ..moving
    };
    let first = cycle(&mut sut, &[stop])[0];
    assert_eq!(first.state, S::QuickStopActive);
    assert!(
        !has(&first, sw::QUICK_STOP),
        "bit 5 is low: {:#06x}",
        first.statusword
    );
    let mut speeds = Vec::new();
    let mut last = first;
    for _ in 0..600 {
        last = cycle(&mut sut, &[stop])[0];
        speeds.push(last.motor_velocity);
    }
    let deceleration = (speeds[49] - speeds[149]) / 0.1;
    assert!(
        (deceleration - 10.0).abs() < 0.5,
        "the ramp: {deceleration} rad/s²"
    );
    assert!(speeds[400..].iter().all(|v| v.abs() < 1e-3), "standstill");
    assert_eq!(last.state, S::QuickStopActive, "hold after stop");
    assert!(has(&last, sw::TARGET_REACHED) && !has(&last, sw::QUICK_STOP));
    let held = cycle(&mut sut, &[stop])[0].motor_position;
    assert!((held - last.motor_position).abs() < 1e-6, "holds position");
    let reset = cycle(&mut sut, &[command(0x82, CSV)])[0];
    assert_eq!(
        reset.state,
        S::QuickStopActive,
        "fault reset is not a way out"
    );
    assert_eq!(sut.rejected(0).0, 1);
    for (controlword, state) in [
        (0x00, S::SwitchOnDisabled),
        (0x06, S::ReadyToSwitchOn),
        (0x07, S::SwitchedOn),
        (0x0F, S::OperationEnabled),
    ] {
        let actual = cycle(&mut sut, &[command(controlword, CSV)])[0];
        assert_eq!(actual.state, state, "after {controlword:#06x}");
        assert_eq!(S::from_statusword(actual.statusword), Some(state));
    }
}

#[test]
fn a_safe_stop_holds_every_drive_until_the_master_disables_voltage() {
    let mut sut = backend(3);
    enable(&mut sut, CSV);
    let stale = [
        AxisCommand {
            target_velocity: 1.0,
            ..command(0x0F, CSV)
        },
        command(0x07, CSV),
        command(0x00, CSV),
    ];
    for _ in 0..300 {
        cycle(&mut sut, &stale);
    }
    let before = cycle(&mut sut, &stale);
    assert_eq!(
        before.iter().map(|a| a.state).collect::<Vec<_>>(),
        [S::OperationEnabled, S::SwitchedOn, S::SwitchOnDisabled]
    );
    sut.quick_stop_all();
    sut.quick_stop_all();
    // The master lost control and repeats what it would send to enable every axis.
    let stale = [command(0x0F, CSV), command(0x0F, CSV), command(0x06, CSV)];
    let mut actuals = Vec::new();
    for _ in 0..400 {
        actuals = cycle(&mut sut, &stale);
    }
    let states: Vec<_> = actuals.iter().map(|a| a.state).collect();
    assert_eq!(
        states,
        [S::QuickStopActive, S::SwitchedOn, S::SwitchOnDisabled]
    );
    let stopped = &actuals[0];
    assert!(
        !has(stopped, sw::QUICK_STOP) && has(stopped, sw::TARGET_REACHED),
        "{stopped:?}"
    );
    assert!(actuals.iter().skip(1).all(|a| a.motor_torque == 0.0));
    assert!((0..3).all(|axis| sut.held(axis)));
    assert_eq!(sut.rejected(0).0, 0, "inhibited commands are not errors");
    let released = cycle(&mut sut, &[command(0x00, CSV); 3]);
    assert!(released.iter().all(|a| a.state == S::SwitchOnDisabled));
    assert!((0..3).all(|axis| !sut.held(axis)));
    enable(&mut sut, CSV);
}

#[test]
fn a_blocked_link_makes_the_following_error_grow_under_a_csp_ramp() {
    let mut sut = backend(2);
    enable(&mut sut, CSP);
    sut.block_axis(0, true);
    let mut errors = Vec::new();
    let mut actuals = Vec::new();
    for n in 1..=2000 {
        let mut c = command(0x0F, CSP);
        c.target_position = 0.5 * n as f64 * DT;
        c.target_velocity = 0.5;
        actuals = cycle(&mut sut, &[c, c]);
        if n % 500 == 0 {
            errors.push((c.target_position - actuals[0].motor_position, actuals[1]));
        }
    }
    let blocked: Vec<f64> = errors.iter().map(|(e, _)| *e).collect();
    assert!(blocked.windows(2).all(|w| w[1] > w[0] + 0.2), "{blocked:?}");
    assert!(
        blocked[3] > 0.98,
        "the motor only twists the gear: {blocked:?}"
    );
    let free = &actuals[1];
    assert!(
        (1.0 + 0.5 * DT - free.motor_position).abs() < 1e-4,
        "{free:?}"
    );
    let stuck = &actuals[0];
    assert_eq!(stuck.link_position, 0.0);
    assert_eq!(
        stuck.state,
        S::OperationEnabled,
        "monitoring is upstream: no fault"
    );
    assert!(has(stuck, sw::MODE_SPECIFIC_13) && has(stuck, sw::INTERNAL_LIMIT_ACTIVE));
    assert_eq!(
        stuck.motor_torque.abs(),
        PlantParams::default().torque_limit
    );
}

#[test]
fn an_injected_fault_brakes_to_fault_and_a_reset_edge_clears_it() {
    let mut sut = backend(2);
    enable(&mut sut, CSV);
    let mut moving = command(0x0F, CSV);
    moving.target_velocity = 1.0;
    for _ in 0..300 {
        cycle(&mut sut, &[moving, command(0x00, CSV)]);
    }
    sut.inject_fault(0);
    sut.inject_fault(1);
    let reacting = cycle(&mut sut, &[moving, command(0x00, CSV)]);
    assert_eq!(reacting[0].state, S::FaultReactionActive);
    assert!(has(&reacting[0], sw::FAULT) && reacting[0].motor_velocity > 0.9);
    assert_eq!(
        reacting[1].state,
        S::Fault,
        "no motion, no braking: the reaction ends at once"
    );
    let mut last = reacting;
    for _ in 0..300 {
        last = cycle(&mut sut, &[moving, command(0x00, CSV)]);
    }
    assert_eq!(last[0].state, S::Fault);
    assert!(last[0].motor_velocity.abs() < 1e-3 && last[0].motor_torque == 0.0);
    assert!(
        sut.rejected(0).0 > 0,
        "enable operation is not legal in fault"
    );
    cycle(&mut sut, &[command(0x00, CSV); 2]);
    let reset = cycle(&mut sut, &[command(0x80, CSV); 2]);
    assert!(reset.iter().all(|a| a.state == S::SwitchOnDisabled));
}

#[test]
fn csv_and_cst_run_their_loops_and_no_torque_flows_outside_operation_enabled() {
    let mut sut = backend(2);
    let mut push = command(0x06, CST);
    push.target_torque = 50.0;
    let off = cycle(&mut sut, &[push, push]);
    assert!(off
        .iter()
        .all(|a| a.motor_torque == 0.0 && a.state == S::ReadyToSwitchOn));
    enable(&mut sut, CST);
    let mut pushes = [push, push];
    pushes[0].controlword = 0x0F;
    pushes[1].controlword = 0x0F;
    pushes[1].target_torque = 500.0;
    let actuals = cycle(&mut sut, &pushes);
    assert_eq!(actuals[0].motor_torque, 50.0);
    assert_eq!(actuals[1].motor_torque, 200.0);
    assert!(has(&actuals[1], sw::INTERNAL_LIMIT_ACTIVE));
    let mut spin = command(0x0F, CSV);
    spin.target_velocity = 1.5;
    let mut last = actuals;
    for _ in 0..1000 {
        last = cycle(&mut sut, &[spin, spin]);
    }
    assert!(
        last.iter().all(|a| (a.motor_velocity - 1.5).abs() < 1e-4),
        "{last:?}"
    );
}

#[test]
fn an_unsupported_mode_keeps_the_previous_one_and_sets_the_warning() {
    let mut sut = backend(1);
    enable(&mut sut, CSP);
    let actual = cycle(&mut sut, &[command(0x0F, 1)])[0];
    assert_eq!(actual.mode, i8::from(ModeOfOperation::Csp));
    assert!(has(&actual, sw::WARNING));
    let actual = cycle(&mut sut, &[command(0x0F, CSP)])[0];
    assert!(!has(&actual, sw::WARNING));
}

#[test]
fn an_axis_without_a_command_is_sent_a_quick_stop() {
    let mut sut = backend(2);
    enable(&mut sut, CSV);
    let mut actuals = [AxisActual::default(); 1];
    sut.cycle(DT, &[command(0x0F, CSV)], &mut actuals).unwrap();
    assert_eq!(actuals[0].state, S::OperationEnabled);
    assert_eq!(sut.state_machine(1).state(), S::QuickStopActive);
}

#[test]
fn the_same_commands_give_the_same_actuals_bit_for_bit() {
    let run = || {
        let mut sut = backend(6);
        let mut out = Vec::new();
        for n in 0..3000u32 {
            let t = f64::from(n) * DT;
            let controlword = match n {
                0 => 0x06,
                1 => 0x07,
                2000..=2100 => 0x02,
                _ => 0x0F,
            };
            let commands: Vec<_> = (0..6)
                .map(|axis| AxisCommand {
                    controlword,
                    mode: [CSP, CSV, CST][axis % 3],
                    target_position: (t * (1.0 + axis as f64)).sin(),
                    target_velocity: (t * (1.0 + axis as f64)).cos(),
                    target_torque: 10.0 * (t * 3.0).sin(),
                })
                .collect();
            for a in cycle(&mut sut, &commands) {
                out.push([
                    u64::from(a.statusword),
                    a.mode as u64,
                    a.state as u64,
                    a.motor_position.to_bits(),
                    a.motor_velocity.to_bits(),
                    a.motor_torque.to_bits(),
                    a.link_position.to_bits(),
                ]);
            }
        }
        out
    };
    assert_eq!(run(), run());
}
