//! The elastic joint's numerics: energy, settling, clamping, limits, parameter checks.

use crate::plant::{Plant, PlantParams, PlantState};

const DT: f64 = 1e-3;

fn displaced(params: PlantParams, twist: f64) -> Plant {
    let mut sut = Plant::new(params);
    sut.set_state(PlantState {
        motor_position: twist,
        ..PlantState::default()
    });
    sut
}

fn lossless() -> PlantParams {
    PlantParams {
        damping: 0.0,
        viscous_friction: 0.0,
        coulomb_friction: 0.0,
        ..PlantParams::default()
    }
}

#[test]
fn a_lossless_displaced_spring_oscillates_without_blowing_up_over_100000_steps() {
    let mut sut = displaced(lossless(), 0.01);
    let start = sut.energy();
    let (mut lowest, mut highest) = (start, start);
    let mut late_twist: f64 = 0.0;
    for step in 0..100_000 {
        sut.step(0.0, DT);
        let energy = sut.energy();
        lowest = lowest.min(energy);
        highest = highest.max(energy);
        if step >= 99_000 {
            let s = sut.state();
            late_twist = late_twist.max((s.motor_position - s.link_position).abs());
        }
    }
    assert!(
        highest <= start * 1.05,
        "energy grew to {highest} from {start}"
    );
    assert!(
        lowest >= start * 0.95,
        "energy fell to {lowest} from {start}"
    );
    assert!(late_twist > 0.009, "still oscillating: twist {late_twist}");
    let s = sut.state();
    let momentum = 0.5 * s.motor_velocity + 2.0 * s.link_velocity;
    assert!(momentum.abs() < 1e-9, "momentum is conserved: {momentum}");
}

#[test]
fn a_damped_displaced_spring_settles() {
    let mut sut = displaced(PlantParams::default(), 0.01);
    let start = sut.energy();
    for _ in 0..10_000 {
        sut.step(0.0, DT);
    }
    let s = sut.state();
    assert!(sut.energy() < start * 1e-12, "energy {}", sut.energy());
    assert!(
        s.motor_velocity.abs() < 1e-9 && s.link_velocity.abs() < 1e-9,
        "{s:?}"
    );
    assert!((s.motor_position - s.link_position).abs() < 1e-9, "{s:?}");
}

#[test]
fn a_blocked_link_stays_while_the_motor_twists_the_gear() {
    let params = PlantParams::default();
    let mut sut = Plant::new(params);
    sut.set_blocked(true);
    for _ in 0..5_000 {
        sut.step(100.0, DT);
    }
    let s = sut.state();
    assert_eq!((s.link_position, s.link_velocity), (0.0, 0.0));
    let static_twist = 100.0 / params.stiffness;
    assert!((s.motor_position - static_twist).abs() < 1e-6, "{s:?}");
    sut.set_blocked(false);
    sut.step(100.0, DT);
    assert!(sut.state().link_velocity > 0.0, "released, the link moves");
}

#[test]
fn the_limits_are_reported_for_monitoring() {
    let params = PlantParams::default();
    let mut sut = Plant::new(params);
    assert!(!sut.limits().any());
    sut.step(params.torque_limit, DT);
    assert!(sut.limits().torque);
    sut.set_state(PlantState {
        motor_velocity: 4.0,
        link_position: -3.5,
        ..PlantState::default()
    });
    sut.step(0.0, 0.0);
    let limits = sut.limits();
    assert!(
        limits.position && limits.velocity && !limits.torque,
        "{limits:?}"
    );
}

#[test]
fn one_millisecond_takes_eight_sub_steps_and_no_time_takes_none() {
    let mut sut = displaced(PlantParams::default(), 0.01);
    assert_eq!(sut.substeps(DT), 8);
    assert_eq!(sut.substeps(250e-6), 2);
    let before = sut.state();
    for dt in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert_eq!(sut.substeps(dt), 0);
        sut.step(1.0, dt);
    }
    assert_eq!(sut.state(), before);
}

#[test]
fn parameters_out_of_range_are_named() {
    assert_eq!(PlantParams::default().check(), Ok(()));
    let error = PlantParams {
        link_inertia: -1.0,
        ..PlantParams::default()
    }
    .check()
    .unwrap_err();
    assert_eq!(error.name, "link_inertia");
    let too_coarse = PlantParams {
        max_substep: 1e-2,
        ..PlantParams::default()
    };
    assert_eq!(too_coarse.check().unwrap_err().name, "max_substep");
    let error = PlantParams {
        position_max: f64::NAN,
        ..PlantParams::default()
    }
    .check()
    .unwrap_err();
    assert!(error.to_string().contains("position_max"), "{error}");
}
