//! The FMU component with the project's FMUs: its time, its initial outputs, its structural
//! parameters, a refused parameter, a discarded step and a clamped input.

use modbot_grid::component::Component as _;
use modbot_grid::component::{ParamValue, PortType};

use super::*;

/// What a host's logging does with `log` records (tracing events), so that what an FMU logs
/// reaches its component.
fn logging_as_a_host() {
    let _ = tracing_log::LogTracer::init();
}

/// The params of the FMU at `path` at 1 ms, with `params`.
fn fmu(path: &str, params: &[(&str, ParamValue)]) -> Params {
    let mut p = Params::new().with(FMU, ParamValue::Text(path.into()));
    for (name, value) in params {
        p.set(*name, value.clone());
    }
    p.set_timing(0.001, 1);
    p
}

/// The params of the FMI 2 feed-forward at 1 ms, with `Jm`.
fn ff2(jm: f64) -> Params {
    let mut p = Params::new()
        .with(FMU, ParamValue::Text(modbot_fmus::FF2.into()))
        .with("Jm", ParamValue::F64(jm));
    p.set_timing(0.001, 1);
    p
}

#[test]
fn an_fmu_first_released_at_tick_500_starts_its_co_simulation_at_0_5_s() {
    let mut sut = build(&ff2(0.5)).unwrap();
    assert_eq!(sut.time, None, "initialised at its first release");
    let inputs = vec![PortValue::F64s(vec![0.1; 6]); 3];
    let mut outputs = vec![PortType::F64s(6).zero(); 2];
    for tick in 500..503 {
        sut.step(&Released::at(tick), &inputs, &mut outputs);
        assert!(!sut.unsafe_state(), "the FMU took the step at tick {tick}");
    }
    let time = sut.time.expect("initialised");
    assert!(
        (time - 0.503).abs() < 1e-12,
        "its next step starts at {time}"
    );
    let PortValue::F64s(qm) = &outputs[1] else {
        panic!("qm is f64[6]");
    };
    // qm = q + Jl/k q'' with Jl = 2, k = 2e4 (the FMU's start values).
    assert!((qm[0] - 0.10001).abs() < 1e-12, "qm {qm:?}");
    sut.terminate();
}

#[test]
fn a_parameter_the_fmu_refuses_at_initialisation_refuses_the_component_when_it_is_made() {
    logging_as_a_host();
    let err = build(&ff2(-1.0)).err().expect("Jm = -1 is refused");
    let text = err.to_string();
    assert!(
        text.contains("fmi2EnterInitializationMode failed with fmi2Error")
            && text.contains("the FMU logged: \"parameters must be finite"),
        "{text}"
    );
}

#[test]
fn an_fmus_initial_outputs_are_its_outputs_after_initialisation() {
    let mut sut = build(&fmu(modbot_fmus::SS3, &[])).unwrap();
    let mut outputs = vec![PortType::F64s(1).zero()];
    sut.initial_outputs(&mut outputs);
    assert_eq!(
        outputs,
        [PortValue::F64s(vec![2.0])],
        "y = C x0 = [2 0]·[1 0]"
    );
    let mut sut = build(&fmu(modbot_fmus::STAIR2, &[("start", ParamValue::I64(7))])).unwrap();
    let mut outputs = vec![PortType::I64.zero()];
    sut.initial_outputs(&mut outputs);
    assert_eq!(outputs, [PortValue::I64(7)], "the counter starts at start");
    sut.terminate();
}

#[test]
fn structural_parameters_the_description_sets_size_the_fmu_in_configuration_mode() {
    let params = [
        ("nx", ParamValue::I64(3)),
        ("ny", ParamValue::I64(2)),
        (
            "A",
            ParamValue::F64s(vec![0.0, 1.0, 0.0, 0.0, 0.0, 1.0, -1.0, -3.0, -3.0]),
        ),
        ("B", ParamValue::F64s(vec![0.0, 0.0, 1.0])),
        ("C", ParamValue::F64s(vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0])),
        ("x0", ParamValue::F64s(vec![0.5, 0.0, 0.25])),
    ];
    let mut sut = build(&fmu(modbot_fmus::SS3, &params)).unwrap();
    let mut outputs = vec![PortType::F64s(2).zero()];
    sut.initial_outputs(&mut outputs);
    assert_eq!(outputs, [PortValue::F64s(vec![0.5, 0.25])]);
    let inputs = [PortValue::F64s(vec![1.0])];
    for tick in 0..10 {
        sut.step(&Released::at(tick), &inputs, &mut outputs);
    }
    assert!(!sut.unsafe_state(), "{:?}", sut.failed);
    let PortValue::F64s(y) = &outputs[0] else {
        panic!("y is f64[2]");
    };
    assert_eq!(y.len(), 2);
    assert!(y[0] > 0.5, "the first state rose with the third: {y:?}");
    sut.terminate();
}

#[test]
fn a_step_the_fmu_discards_says_its_status_the_time_and_what_the_fmu_logged() {
    logging_as_a_host();
    let params = [("t_stop", ParamValue::F64(0.003))];
    let mut sut = build(&fmu(modbot_fmus::STAIR2, &params)).unwrap();
    let inputs = [PortValue::I64(1)];
    let mut outputs = vec![PortType::I64.zero()];
    for tick in 0..3 {
        sut.step(&Released::at(tick), &inputs, &mut outputs);
        assert!(!sut.unsafe_state(), "tick {tick}: {:?}", sut.failed);
    }
    sut.step(&Released::at(3), &inputs, &mut outputs);
    assert!(
        sut.unsafe_state(),
        "the step from 0.003 s ends after t_stop"
    );
    let why = sut.failed.clone().unwrap();
    assert!(
        why.starts_with(
            "fmi2DoStep failed with fmi2Discard: the FMU asks to terminate (fmi2Terminated) \
             at t = 0.003 s; the FMU logged: \"the stair ends at t_stop = 0.003 s"
        ),
        "{why}"
    );
    assert_eq!(
        outputs,
        [PortValue::I64(6)],
        "its last outputs: 3 + 3 steps"
    );
    sut.step(&Released::at(4), &inputs, &mut outputs);
    assert_eq!(
        sut.failed.as_deref(),
        Some(why.as_str()),
        "not stepped again"
    );
    sut.terminate();
}

#[test]
fn an_i64_beyond_an_fmi_int32_input_is_clamped_to_the_nearest_int32() {
    let mut sut = build(&fmu(modbot_fmus::STAIR2, &[])).unwrap();
    let inputs = [PortValue::I64(-(1 << 40))];
    let mut outputs = vec![PortType::I64.zero()];
    sut.step(&Released::at(0), &inputs, &mut outputs);
    assert_eq!(outputs, [PortValue::I64(3 + i64::from(i32::MIN))]);
    sut.terminate();
}
