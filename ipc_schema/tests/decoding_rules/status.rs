//! The supervisor's status rows. The golden row's values: name, address, state, pid,
//! restarts, last exit, dropped, rejected, replayed, heartbeat age, upgrades.

use modbot_ipc_schema::fields::FieldError;
use modbot_ipc_schema::status::{decode, StatusError};
use modbot_ipc_schema::Value;

use crate::{run_bytes, run_values, run_with};

const GOLDEN: &str = "status name=sonar";

fn with(index: usize, value: Value<'_>) -> Option<StatusError> {
    decode(&run_with(GOLDEN, index, value)).err()
}

#[test]
fn a_last_row_with_fewer_than_11_values_is_refused() {
    let mut values = run_values(&crate::support::golden(GOLDEN));
    values.pop();
    assert_eq!(
        decode(&run_bytes(&values)).err(),
        Some(StatusError::Row {
            row: 0,
            why: FieldError::Missing {
                what: "the upgrades"
            }
        })
    );
}

#[test]
fn a_value_of_another_kind_than_its_field_is_refused() {
    assert!(matches!(
        with(0, Value::I64(1)),
        Some(StatusError::Row {
            why: FieldError::Kind { .. },
            ..
        })
    ));
}

#[test]
fn a_name_that_is_not_a_module_name_is_refused() {
    assert_eq!(
        with(0, Value::Text("so nar")),
        Some(StatusError::Name {
            row: 0,
            name: "so nar".into()
        })
    );
}

#[test]
fn an_address_that_is_not_a_module_address_is_refused() {
    assert_eq!(
        with(1, Value::I64(0)),
        Some(StatusError::Address { row: 0, addr: 0 })
    );
}

#[test]
fn an_address_past_a_byte_is_refused() {
    assert!(matches!(
        with(1, Value::I64(256)),
        Some(StatusError::Row {
            why: FieldError::Range { value: 256, .. },
            ..
        })
    ));
}

#[test]
fn an_unknown_state_is_refused() {
    assert_eq!(
        with(2, Value::Text("retired")),
        Some(StatusError::State {
            row: 0,
            state: "retired".into()
        })
    );
}

#[test]
fn a_pid_past_u32_is_refused() {
    assert!(matches!(
        with(3, Value::I64(1 << 32)),
        Some(StatusError::Row {
            why: FieldError::Range { .. },
            ..
        })
    ));
}

#[test]
fn a_negative_counter_is_refused() {
    assert!(matches!(
        with(8, Value::I64(-1)),
        Some(StatusError::Row {
            why: FieldError::Range { value: -1, .. },
            ..
        })
    ));
}

#[test]
fn a_heartbeat_age_below_minus_one_is_refused_and_minus_one_is_none() {
    assert!(matches!(
        with(9, Value::I64(-2)),
        Some(StatusError::Row {
            why: FieldError::Range { value: -2, .. },
            ..
        })
    ));
    let rows = decode(&run_with(GOLDEN, 9, Value::I64(-1))).unwrap();
    assert_eq!(rows[0].heartbeat_age_ms, None);
}

#[test]
fn no_bytes_are_no_rows() {
    assert_eq!(decode(&[]), Ok(Vec::new()));
}
