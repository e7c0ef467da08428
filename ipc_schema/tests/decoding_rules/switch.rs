//! The coordinator's answers about assembly switches. The golden `assembly()` answer's values:
//! the running assembly and its generation (0, 1); the switch under way, announced (2: tag,
//! generation, name, tick); a switch (6: tag, generation, name, announced, tick); a failure
//! (11: tag, generation, name, reason).

use modbot_ipc_schema::fields::FieldError;
use modbot_ipc_schema::switch::{decode, decode_generation, Status, SwitchAnswerError};
use modbot_ipc_schema::{OwnedValue, Value};

use crate::{run_bytes, run_values, run_with};

const GOLDEN: &str = "assembly name=ptp";

fn with(index: usize, value: Value<'_>) -> Option<SwitchAnswerError> {
    decode(&run_with(GOLDEN, index, value)).err()
}

#[test]
fn the_generation_answer_is_exactly_one_value() {
    assert_eq!(
        decode_generation(&[Value::I64(1), Value::I64(2)]),
        Err(SwitchAnswerError::Trailing { count: 1 })
    );
}

#[test]
fn a_generation_answer_past_u16_is_refused() {
    assert!(matches!(
        decode_generation(&[Value::I64(65536)]),
        Err(SwitchAnswerError::Field(FieldError::Range { .. }))
    ));
}

#[test]
fn a_name_that_is_not_an_assembly_name_is_refused() {
    assert_eq!(
        with(13, Value::Text("No pe")),
        Some(SwitchAnswerError::Name {
            what: "an outcome's assembly",
            name: "No pe".into()
        })
    );
}

#[test]
fn none_before_the_first_assembly_is_an_assembly_name() {
    let mut bytes = Vec::new();
    Status::default().encode(&mut bytes);
    assert_eq!(decode(&bytes), Ok(Status::default()));
}

#[test]
fn an_unknown_state_tag_is_refused() {
    assert!(matches!(
        with(2, Value::I64(3)),
        Some(SwitchAnswerError::Tag {
            what: "state",
            tag: 3
        })
    ));
}

#[test]
fn an_unknown_outcome_tag_is_refused() {
    assert!(matches!(
        with(6, Value::I64(0)),
        Some(SwitchAnswerError::Tag {
            what: "outcome",
            tag: 0
        })
    ));
}

#[test]
fn a_value_of_another_kind_than_its_field_is_refused() {
    assert!(matches!(
        with(4, Value::I64(1)),
        Some(SwitchAnswerError::Field(FieldError::Kind { .. }))
    ));
}

#[test]
fn a_negative_tick_is_refused() {
    assert!(matches!(
        with(5, Value::I64(-1)),
        Some(SwitchAnswerError::Field(FieldError::Range {
            value: -1,
            ..
        }))
    ));
}

#[test]
fn a_generation_past_u16_is_refused() {
    assert!(matches!(
        with(1, Value::I64(70_000)),
        Some(SwitchAnswerError::Field(FieldError::Range {
            value: 70_000,
            ..
        }))
    ));
}

#[test]
fn more_than_64_outcomes_are_refused() {
    let values = run_values(&crate::support::golden(GOLDEN));
    let failure: Vec<OwnedValue> = values[11..].to_vec();
    let mut many = values[..6].to_vec();
    for _ in 0..65 {
        many.extend(failure.iter().cloned());
    }
    assert_eq!(
        decode(&run_bytes(&many)),
        Err(SwitchAnswerError::TooManyOutcomes)
    );
}

#[test]
fn an_answer_that_ends_inside_an_entry_is_refused() {
    let mut values = run_values(&crate::support::golden(GOLDEN));
    values.pop();
    assert_eq!(
        decode(&run_bytes(&values)),
        Err(SwitchAnswerError::Field(FieldError::Missing {
            what: "the reason of a failed switch"
        }))
    );
}
