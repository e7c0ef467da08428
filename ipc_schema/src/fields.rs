//! Answers laid out as a run of values in the payload encoding (the supervisor's status rows,
//! the coordinator's switch status and ledger): written field by field, and read field by field with
//! each field named in the error when it is missing, of another kind or out of range.

use thiserror::Error;

use crate::value::{Value, ValueError, ValueKind, Values};

/// Why a field of a run of values cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FieldError {
    #[error("{0}")]
    Malformed(#[from] ValueError),
    #[error("{what} is missing: the values end before it")]
    Missing { what: &'static str },
    #[error("{what} is {found}, expected {expected}")]
    Kind {
        what: &'static str,
        expected: ValueKind,
        found: ValueKind,
    },
    #[error("{what} {value} does not fit in {ty}")]
    Range {
        what: &'static str,
        value: i64,
        ty: &'static str,
    },
}

/// Appends a value. Texts in these answers are names and short reasons, far below the
/// encoding's limit of 4 GiB, so appending to a `Vec` does not fail.
pub(crate) fn push(out: &mut Vec<u8>, value: Value<'_>) {
    let _ = value.encode_to_vec(out);
}

/// Appends an unsigned number as an i64 (numbers past `i64::MAX` are written as `i64::MAX`).
pub(crate) fn push_u64(out: &mut Vec<u8>, n: u64) {
    push(out, Value::I64(i64::try_from(n).unwrap_or(i64::MAX)));
}

/// Reads a run of values one named field at a time.
#[derive(Debug, Clone)]
pub(crate) struct Fields<'a> {
    values: Values<'a>,
}

impl<'a> Fields<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Fields<'a> {
        Fields {
            values: Values::new(bytes, 0),
        }
    }

    /// Whether every value has been read.
    pub(crate) fn is_done(&mut self) -> bool {
        self.values.rest().is_empty()
    }

    /// The bytes not read yet: a bound on how many values can follow (each takes one byte or
    /// more), for counts that must not be trusted further.
    pub(crate) fn remaining(&self) -> usize {
        self.values.rest().len()
    }

    /// Where the next value starts, in bytes from the start of the run.
    pub(crate) fn offset(&self) -> usize {
        self.values.offset()
    }

    fn next(&mut self, what: &'static str) -> Result<Value<'a>, FieldError> {
        Ok(self.values.next().ok_or(FieldError::Missing { what })??)
    }

    /// The next value, whatever its kind.
    pub(crate) fn value(&mut self, what: &'static str) -> Result<Value<'a>, FieldError> {
        self.next(what)
    }

    pub(crate) fn bool(&mut self, what: &'static str) -> Result<bool, FieldError> {
        match self.next(what)? {
            Value::Bool(b) => Ok(b),
            other => Err(kind(what, ValueKind::Bool, other)),
        }
    }

    pub(crate) fn text(&mut self, what: &'static str) -> Result<&'a str, FieldError> {
        match self.next(what)? {
            Value::Text(t) => Ok(t),
            other => Err(kind(what, ValueKind::Text, other)),
        }
    }

    pub(crate) fn f64(&mut self, what: &'static str) -> Result<f64, FieldError> {
        match self.next(what)? {
            Value::F64(x) => Ok(x),
            other => Err(kind(what, ValueKind::F64, other)),
        }
    }

    /// An integer that must fit in `T` (a `u8`, `u16`, `u32` or `u64`: no negative numbers).
    pub(crate) fn int<T: TryFrom<i64>>(&mut self, what: &'static str) -> Result<T, FieldError> {
        match self.next(what)? {
            Value::I64(n) => T::try_from(n).map_err(|_| FieldError::Range {
                what,
                value: n,
                ty: core::any::type_name::<T>(),
            }),
            other => Err(kind(what, ValueKind::I64, other)),
        }
    }
}

fn kind(what: &'static str, expected: ValueKind, found: Value<'_>) -> FieldError {
    FieldError::Kind {
        what,
        expected,
        found: found.kind(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_read_in_order_and_named_in_errors() {
        let mut bytes = Vec::new();
        push(&mut bytes, Value::Text("a"));
        push_u64(&mut bytes, 300);
        push(&mut bytes, Value::I64(-1));
        push(&mut bytes, Value::Bool(true));
        let mut sut = Fields::new(&bytes);
        assert_eq!(sut.text("name"), Ok("a"));
        assert_eq!(
            sut.int::<u8>("address"),
            Err(FieldError::Range {
                what: "address",
                value: 300,
                ty: "u8"
            })
        );
        assert!(matches!(
            sut.int::<u64>("count"),
            Err(FieldError::Range { value: -1, .. })
        ));
        assert_eq!(
            sut.text("reason"),
            Err(FieldError::Kind {
                what: "reason",
                expected: ValueKind::Text,
                found: ValueKind::Bool
            })
        );
        assert!(sut.is_done());
        assert_eq!(sut.text("more"), Err(FieldError::Missing { what: "more" }));
    }

    #[test]
    fn a_bool_a_value_of_any_kind_and_the_bytes_left_are_read() {
        let mut bytes = Vec::new();
        push(&mut bytes, Value::Bool(true));
        push(&mut bytes, Value::Bytes(&[1, 2]));
        push(&mut bytes, Value::I64(1));
        let mut sut = Fields::new(&bytes);
        assert_eq!((sut.remaining(), sut.offset()), (6, 0));
        assert_eq!(sut.bool("mlock"), Ok(true));
        assert_eq!(sut.value("a value"), Ok(Value::Bytes(&[1, 2])));
        assert_eq!((sut.remaining(), sut.offset()), (1, 5));
        assert_eq!(
            sut.bool("mlock"),
            Err(FieldError::Kind {
                what: "mlock",
                expected: ValueKind::Bool,
                found: ValueKind::I64
            })
        );
        assert!(sut.is_done());
        assert_eq!(sut.value("more"), Err(FieldError::Missing { what: "more" }));
    }

    #[test]
    fn numbers_past_i64_are_written_as_its_largest() {
        let mut bytes = Vec::new();
        push_u64(&mut bytes, u64::MAX);
        assert_eq!(Fields::new(&bytes).int::<u64>("n"), Ok(i64::MAX as u64));
    }

    #[test]
    fn a_malformed_value_is_refused_with_its_offset() {
        // A text of 2 bytes with one byte present.
        assert!(matches!(
            Fields::new(&[0xa2, b'a']).text("name"),
            Err(FieldError::Malformed(ValueError::Truncated { .. }))
        ));
    }
}
