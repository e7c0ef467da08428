//! The grid's ledger. The golden ledger is a grid row (values 0..8: state, fault, ticks,
//! missed, rate, tick error p50, p99, max) and one component row (values 8..23: name, host,
//! period, policy, then 11 numbers).

use modbot_ipc_schema::fields::FieldError;
use modbot_ipc_schema::ledger::{decode, LedgerError};
use modbot_ipc_schema::{Value, ValueKind};

use crate::{run_bytes, run_values, run_with};

const GOLDEN: &str = "ledger state=running";

fn refused(bytes: &[u8]) -> Option<LedgerError> {
    decode(bytes).err()
}

fn with(index: usize, value: Value<'_>) -> Option<LedgerError> {
    refused(&run_with(GOLDEN, index, value))
}

#[test]
fn a_ledger_with_a_malformed_value_is_refused() {
    let mut bytes = crate::support::golden(GOLDEN);
    bytes.push(0xc1);
    assert!(matches!(refused(&bytes), Some(LedgerError::Values(_))));
}

#[test]
fn a_ledger_whose_value_count_is_not_8_plus_15_per_component_is_refused() {
    let mut values = run_values(&crate::support::golden(GOLDEN));
    values.pop();
    assert_eq!(refused(&run_bytes(&values)), Some(LedgerError::Count(22)));
}

#[test]
fn a_value_of_another_kind_than_its_field_is_refused() {
    assert!(matches!(
        with(4, Value::I64(1000)),
        Some(LedgerError::Grid(FieldError::Kind {
            expected: ValueKind::F64,
            ..
        }))
    ));
}

#[test]
fn a_negative_count_is_refused() {
    assert!(matches!(
        with(13, Value::I64(-1)),
        Some(LedgerError::Row {
            row: 0,
            why: FieldError::Range { value: -1, .. }
        })
    ));
}

#[test]
fn a_state_that_does_not_start_with_running_faulted_or_done_is_refused() {
    assert_eq!(
        with(0, Value::Text("stopped")),
        Some(LedgerError::State("stopped".into()))
    );
}

#[test]
fn a_state_may_describe_the_run_after_its_first_word() {
    let bytes = run_with(
        GOLDEN,
        0,
        Value::Text("faulted in lockstep (assembly ptp, generation 3)"),
    );
    assert!(decode(&bytes).is_ok());
}

#[test]
fn a_tick_rate_that_is_nan_is_refused() {
    assert!(matches!(
        with(4, Value::F64(f64::NAN)),
        Some(LedgerError::Rate(_))
    ));
}

#[test]
fn an_infinite_tick_rate_is_refused() {
    assert_eq!(
        with(4, Value::F64(f64::INFINITY)),
        Some(LedgerError::Rate(f64::INFINITY))
    );
}

#[test]
fn a_negative_tick_rate_is_refused() {
    assert_eq!(with(4, Value::F64(-1.0)), Some(LedgerError::Rate(-1.0)));
}

#[test]
fn a_policy_other_than_hold_or_fault_is_refused() {
    assert_eq!(
        with(11, Value::Text("skip")),
        Some(LedgerError::Policy {
            row: 0,
            policy: "skip".into()
        })
    );
}

#[test]
fn a_period_of_0_ticks_is_refused() {
    assert_eq!(
        with(10, Value::I64(0)),
        Some(LedgerError::Period { row: 0 })
    );
}
