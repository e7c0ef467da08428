//! The `bus` component's joint parameters: one value for every axis, or one per axis.

use crate::robot::joints;
use crate::PlantParams;
use modbot_grid::component::{ParamValue, Params};

#[test]
fn joint_parameters_are_given_per_axis_or_once_for_all_and_default_otherwise() {
    let params = Params::new()
        .with("link_inertia", ParamValue::F64s(vec![60.0, 50.0, 18.0]))
        .with("stiffness", ParamValue::F64s(vec![1.0e5]));
    let sut = joints(&params, 3).unwrap();
    assert_eq!(sut.len(), 3);
    assert_eq!(sut[2].link_inertia, 18.0);
    assert!(sut.iter().all(|j| j.stiffness == 1.0e5));
    assert_eq!(sut[0].motor_inertia, PlantParams::default().motor_inertia);
}

#[test]
fn a_joint_its_checks_refuse_is_refused_naming_the_axis() {
    let params = Params::new().with("motor_inertia", ParamValue::F64s(vec![0.5, 0.0]));
    let e = joints(&params, 2).unwrap_err().to_string();
    assert!(e.contains("joint 1"), "{e}");
    let params = Params::new().with("damping", ParamValue::F64s(vec![1.0, 2.0, 3.0]));
    let e = joints(&params, 2).unwrap_err().to_string();
    assert!(e.contains("1 value or 2"), "{e}");
}
