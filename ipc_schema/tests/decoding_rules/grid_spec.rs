//! The checked grid. The golden image's values: magic, version (0, 1); the grid: base period,
//! priority, mlock, CPU count, line, clock, track_ticks, spin_us (2..=9); the assembly's tag
//! (10); the declared types' count (11); the components' count (12), then component A: name,
//! type, program, host, period, policy, line (13..=19), its parameter count, name and value
//! (20..=22), its interface: type, doc, inputs' count, outputs' count, `y`, `f64` (23..=28),
//! its declared parameters' count, name, type, has_default, default (29..=33); the
//! connections' count (34). Rules about connections break an image built from the golden one:
//! a component `B` that reads `A.y`.

use modbot_ipc_schema::fields::FieldError;
use modbot_ipc_schema::grid::{OverrunPolicy, PortType};
use modbot_ipc_schema::grid_spec::{
    decode, encode, ComponentImage, ConnectionImage, End, GridImage, GridSpecError, InfoImage,
    Place, PortAt, PortImage,
};
use modbot_ipc_schema::{OwnedValue, Value, ValueKind};

use crate::{run_bytes, run_values, run_with};

const GOLDEN: &str = "grid_spec base_period_ns=";

fn with(index: usize, value: Value<'_>) -> Option<GridSpecError> {
    decode(&run_with(GOLDEN, index, value)).err()
}

fn refused(image: &GridImage) -> Option<GridSpecError> {
    let mut bytes = Vec::new();
    encode(image, &mut bytes);
    decode(&bytes).err()
}

/// The golden image with `B` (inputs `inputs`, no outputs) and a connection from `A.y` to
/// `B`'s first input.
fn with_reader(inputs: &[(&str, PortType)]) -> GridImage {
    let mut image = decode(&crate::support::golden(GOLDEN)).unwrap();
    image.components.push(ComponentImage {
        name: "B".into(),
        type_name: "sink".into(),
        program: None,
        host: "h".into(),
        period: 1,
        policy: OverrunPolicy::Hold,
        line: 3,
        params: vec![],
        info: InfoImage {
            type_name: "sink".into(),
            doc: String::new(),
            inputs: inputs
                .iter()
                .map(|&(name, ty)| PortImage {
                    name: name.into(),
                    ty,
                })
                .collect(),
            outputs: vec![],
            params: vec![],
        },
    });
    image.connections.push(connection((0, 0), (1, 0)));
    image
}

fn connection(from: (usize, usize), to: (usize, usize)) -> ConnectionImage {
    ConnectionImage {
        from: PortAt {
            component: from.0,
            port: from.1,
        },
        to: PortAt {
            component: to.0,
            port: to.1,
        },
        line: 4,
    }
}

#[test]
fn an_image_that_ends_inside_a_field_is_refused() {
    let mut values = run_values(&crate::support::golden(GOLDEN));
    values.pop();
    assert_eq!(
        decode(&run_bytes(&values)),
        Err(GridSpecError::Field(FieldError::Missing {
            what: "the connections"
        }))
    );
    let bytes = crate::support::golden(GOLDEN);
    assert!(matches!(
        decode(&bytes[..bytes.len() - 2]),
        Err(GridSpecError::Field(FieldError::Malformed(_)))
    ));
}

#[test]
fn another_magic_is_refused() {
    assert_eq!(
        with(0, Value::Text("MBGX")),
        Some(GridSpecError::Magic {
            found: "MBGX".into()
        })
    );
}

#[test]
fn another_version_is_refused() {
    assert_eq!(
        with(1, Value::I64(2)),
        Some(GridSpecError::Version { found: 2 })
    );
}

#[test]
fn a_value_of_another_kind_than_its_field_is_refused() {
    assert_eq!(
        with(4, Value::I64(0)),
        Some(GridSpecError::Field(FieldError::Kind {
            what: "mlock",
            expected: ValueKind::Bool,
            found: ValueKind::I64
        }))
    );
}

#[test]
fn a_count_larger_than_the_bytes_left_could_hold_is_refused() {
    assert!(matches!(
        with(25, Value::I64(1 << 40)),
        Some(GridSpecError::Count {
            what: "a type's inputs",
            count,
            ..
        }) if count == 1 << 40
    ));
}

#[test]
fn a_base_period_of_zero_is_refused() {
    assert_eq!(with(2, Value::I64(0)), Some(GridSpecError::BasePeriod));
}

#[test]
fn a_priority_past_99_is_refused() {
    assert_eq!(
        with(3, Value::I64(100)),
        Some(GridSpecError::Priority { priority: 100 })
    );
}

#[test]
fn an_unknown_clock_is_refused() {
    assert_eq!(
        with(7, Value::Text("wall")),
        Some(GridSpecError::Clock {
            name: "wall".into()
        })
    );
}

#[test]
fn an_assembly_tag_other_than_0_or_1_is_refused() {
    assert_eq!(
        with(10, Value::I64(2)),
        Some(GridSpecError::AssemblyTag { tag: 2 })
    );
}

#[test]
fn an_assembly_generation_of_zero_or_a_base_past_the_components_is_refused() {
    let mut values = run_values(&crate::support::golden(GOLDEN));
    let assembly = |generation, base| {
        vec![
            OwnedValue::I64(1),
            OwnedValue::Text("ptp".into()),
            OwnedValue::I64(generation),
            OwnedValue::I64(base),
        ]
    };
    values.splice(10..11, assembly(0, 0));
    assert_eq!(decode(&run_bytes(&values)), Err(GridSpecError::Generation));
    values.splice(10..14, assembly(1, 2));
    assert_eq!(
        decode(&run_bytes(&values)),
        Err(GridSpecError::Base {
            base: 2,
            components: 1
        })
    );
    values.splice(10..14, assembly(1, 1));
    assert!(
        decode(&run_bytes(&values)).is_ok(),
        "a base of n: no own components"
    );
}

#[test]
fn an_empty_component_name_is_refused() {
    assert_eq!(
        with(13, Value::Text("")),
        Some(GridSpecError::Name {
            at: Place::Component(0),
            what: "the name",
            name: String::new(),
            rule: "a text that is not empty"
        })
    );
}

#[test]
fn a_host_that_is_not_a_module_name_is_refused() {
    assert!(matches!(
        with(16, Value::Text("h/2")),
        Some(GridSpecError::Name {
            at: Place::Component(0),
            what: "the host",
            ..
        })
    ));
}

#[test]
fn a_period_of_zero_or_past_u32_is_refused() {
    for period in [0, 1 << 32] {
        assert_eq!(
            with(17, Value::I64(period)),
            Some(GridSpecError::Period {
                component: 0,
                period: period as u64
            })
        );
    }
}

#[test]
fn an_unknown_policy_is_refused() {
    assert_eq!(
        with(18, Value::Text("skip")),
        Some(GridSpecError::Policy {
            component: 0,
            name: "skip".into()
        })
    );
}

#[test]
fn bytes_as_a_parameter_value_are_refused() {
    assert_eq!(
        with(22, Value::Bytes(&[1])),
        Some(GridSpecError::ParamKind {
            at: Place::Component(0),
            param: "slope".into(),
            found: ValueKind::Bytes
        })
    );
    assert!(matches!(
        with(33, Value::Bytes(&[1])),
        Some(GridSpecError::ParamKind {
            found: ValueKind::Bytes,
            ..
        })
    ));
}

#[test]
fn a_parameter_value_of_every_other_kind_is_taken() {
    for value in [Value::Bool(true), Value::I64(-1), Value::Text("x")] {
        assert_eq!(with(22, value), None, "{value:?}");
    }
}

#[test]
fn an_unknown_port_type_is_refused() {
    assert_eq!(
        with(28, Value::Text("f64[0]")),
        Some(GridSpecError::PortType {
            at: Place::Component(0),
            port: "y".into(),
            ty: "f64[0]".into()
        })
    );
}

#[test]
fn an_unknown_parameter_type_is_refused() {
    assert_eq!(
        with(31, Value::Text("float")),
        Some(GridSpecError::ParamType {
            at: Place::Component(0),
            param: "slope".into(),
            ty: "float".into()
        })
    );
}

#[test]
fn a_value_after_the_connections_is_refused() {
    let mut bytes = crate::support::golden(GOLDEN);
    let end = bytes.len();
    bytes.push(0x00);
    assert_eq!(decode(&bytes), Err(GridSpecError::Trailing { offset: end }));
}

#[test]
fn a_second_component_of_the_same_name_is_refused() {
    let mut image = with_reader(&[("u", PortType::F64)]);
    image.components[1].name = "A".into();
    assert_eq!(
        refused(&image),
        Some(GridSpecError::DuplicateComponent {
            name: "A".into(),
            first: 0,
            second: 1
        })
    );
}

#[test]
fn a_connection_to_a_component_or_port_that_does_not_exist_is_refused() {
    let mut image = with_reader(&[("u", PortType::F64)]);
    assert_eq!(refused(&image), None, "the reader is a valid image");
    image.connections[0].to.component = 2;
    assert_eq!(
        refused(&image),
        Some(GridSpecError::OutOfRange {
            connection: 0,
            end: End::To,
            what: "component",
            index: 2,
            len: 2
        })
    );
    image.connections[0].to.component = 1;
    image.connections[0].from.port = 1;
    assert_eq!(
        refused(&image),
        Some(GridSpecError::OutOfRange {
            connection: 0,
            end: End::From,
            what: "output",
            index: 1,
            len: 1
        })
    );
    image.connections[0] = connection((0, 0), (1, 1));
    assert!(matches!(
        refused(&image),
        Some(GridSpecError::OutOfRange {
            end: End::To,
            what: "input",
            index: 1,
            ..
        })
    ));
}

#[test]
fn a_connection_between_ports_of_two_types_is_refused() {
    let image = with_reader(&[("u", PortType::F64s(6))]);
    assert_eq!(
        refused(&image),
        Some(GridSpecError::TypeMismatch {
            connection: 0,
            from: "A.y".into(),
            from_ty: PortType::F64,
            to: "B.u".into(),
            to_ty: PortType::F64s(6)
        })
    );
}

#[test]
fn an_input_fed_by_nothing_is_refused() {
    let image = with_reader(&[("u", PortType::F64), ("w", PortType::F64)]);
    assert_eq!(
        refused(&image),
        Some(GridSpecError::Unfed {
            component: "B".into(),
            input: "w".into()
        })
    );
}

#[test]
fn an_input_fed_twice_is_refused() {
    let mut image = with_reader(&[("u", PortType::F64)]);
    image.connections.push(connection((0, 0), (1, 0)));
    assert_eq!(
        refused(&image),
        Some(GridSpecError::FedTwice {
            component: "B".into(),
            input: "u".into(),
            first: 0,
            second: 1
        })
    );
}

#[test]
fn inputs_from_more_than_16_components_are_refused() {
    let inputs: Vec<(String, PortType)> =
        (0..17).map(|i| (format!("u{i}"), PortType::F64)).collect();
    let inputs: Vec<(&str, PortType)> = inputs.iter().map(|(n, t)| (n.as_str(), *t)).collect();
    let mut image = with_reader(&inputs);
    // Sixteen more copies of A, each feeding one more input of B.
    for i in 1..17 {
        let mut source = image.components[0].clone();
        source.name = format!("A{i}");
        image.components.push(source);
        image.connections.push(connection((i + 1, 0), (1, i)));
    }
    assert_eq!(
        refused(&image),
        Some(GridSpecError::TooManySources {
            component: "B".into(),
            sources: 17
        })
    );
    // Sixteen sources are allowed: A feeds two inputs.
    image.connections[16].from.component = 0;
    assert_eq!(refused(&image), None);
}
