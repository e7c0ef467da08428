//! A method's arguments: decoded once, without allocating, with typed accessors.

use thiserror::Error;

use crate::value::{F64s, Value, ValueError, ValueKind, Values};

/// The most arguments a method call carries.
pub const MAX_ARGS: usize = 16;

/// Why arguments do not fit what a method expects.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ArgError {
    #[error("argument {index} is missing: expected {expected}")]
    Missing { index: usize, expected: ValueKind },
    #[error("argument {index} is {got}, expected {expected}")]
    WrongKind {
        index: usize,
        expected: ValueKind,
        got: ValueKind,
    },
    #[error("too many arguments: at most {MAX_ARGS}")]
    TooMany,
    #[error("{0}")]
    Malformed(#[from] ValueError),
    #[error("argument {index}: {reason}")]
    Invalid { index: usize, reason: &'static str },
}

/// The decoded arguments of one call, borrowing the frame.
#[derive(Debug, Clone, Copy)]
pub struct Args<'a> {
    values: [Value<'a>; MAX_ARGS],
    len: usize,
}

impl<'a> Args<'a> {
    /// No arguments.
    pub const EMPTY: Args<'static> = Args {
        values: [Value::Bool(false); MAX_ARGS],
        len: 0,
    };

    /// Decodes every value of `values`.
    pub fn decode(values: Values<'a>) -> Result<Args<'a>, ArgError> {
        let mut args = Args::EMPTY;
        args.decode_from(values)?;
        Ok(args)
    }

    /// Decodes every value of `values` into these arguments, in place (the message path: an
    /// `Args` is a few hundred bytes, and returning one by value copies it).
    pub fn decode_from(&mut self, values: Values<'a>) -> Result<(), ArgError> {
        self.len = 0;
        for v in values {
            let v = v?;
            if self.len == MAX_ARGS {
                return Err(ArgError::TooMany);
            }
            self.values[self.len] = v;
            self.len += 1;
        }
        Ok(())
    }

    /// Builds arguments from values already in hand (for in-process calls and tests).
    pub fn from_values(values: &[Value<'a>]) -> Result<Args<'a>, ArgError> {
        if values.len() > MAX_ARGS {
            return Err(ArgError::TooMany);
        }
        let mut args = Args {
            values: [Value::Bool(false); MAX_ARGS],
            len: values.len(),
        };
        args.values[..values.len()].copy_from_slice(values);
        Ok(args)
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn as_slice(&self) -> &[Value<'a>] {
        &self.values[..self.len]
    }

    pub fn get(&self, index: usize) -> Option<Value<'a>> {
        self.as_slice().get(index).copied()
    }

    fn typed<T>(
        &self,
        index: usize,
        expected: ValueKind,
        pick: impl Fn(Value<'a>) -> Option<T>,
    ) -> Result<T, ArgError> {
        let v = self
            .get(index)
            .ok_or(ArgError::Missing { index, expected })?;
        pick(v).ok_or(ArgError::WrongKind {
            index,
            expected,
            got: v.kind(),
        })
    }

    /// Argument `index` as an f64; integers are accepted.
    pub fn f64(&self, index: usize) -> Result<f64, ArgError> {
        self.typed(index, ValueKind::F64, |v| v.as_f64())
    }

    pub fn i64(&self, index: usize) -> Result<i64, ArgError> {
        self.typed(index, ValueKind::I64, |v| match v {
            Value::I64(x) => Some(x),
            _ => None,
        })
    }

    pub fn bool(&self, index: usize) -> Result<bool, ArgError> {
        self.typed(index, ValueKind::Bool, |v| match v {
            Value::Bool(x) => Some(x),
            _ => None,
        })
    }

    pub fn text(&self, index: usize) -> Result<&'a str, ArgError> {
        self.typed(index, ValueKind::Text, |v| match v {
            Value::Text(x) => Some(x),
            _ => None,
        })
    }

    pub fn bytes(&self, index: usize) -> Result<&'a [u8], ArgError> {
        self.typed(index, ValueKind::Bytes, |v| match v {
            Value::Bytes(x) => Some(x),
            _ => None,
        })
    }

    pub fn f64s(&self, index: usize) -> Result<F64s<'a>, ArgError> {
        self.typed(index, ValueKind::F64s, |v| match v {
            Value::F64s(x) => Some(x),
            _ => None,
        })
    }

    /// Argument `index` as an f64 if present, else `default`.
    pub fn f64_or(&self, index: usize, default: f64) -> Result<f64, ArgError> {
        if index >= self.len {
            return Ok(default);
        }
        self.f64(index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_accessors_name_the_argument_and_the_expected_kind() {
        let sut = Args::from_values(&[Value::I64(10), Value::Text("x")]).unwrap();
        assert_eq!(sut.f64(0).unwrap(), 10.0);
        assert_eq!(sut.text(1).unwrap(), "x");
        assert_eq!(
            sut.bool(1).unwrap_err().to_string(),
            "argument 1 is text, expected bool"
        );
        assert_eq!(
            sut.f64(2).unwrap_err().to_string(),
            "argument 2 is missing: expected f64"
        );
        assert_eq!(sut.f64_or(2, 0.61).unwrap(), 0.61);
    }
}
