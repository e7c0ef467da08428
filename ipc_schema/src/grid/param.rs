//! A component parameter's type and value, as a system description gives them and as the
//! checked grid carries them to the grid's processes (`grid_spec`).

use core::fmt;

/// A parameter's type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamType {
    Bool,
    I64,
    F64,
    /// A list of f64 of any length.
    F64s,
    Text,
}

impl fmt::Display for ParamType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ParamType::Bool => "bool",
            ParamType::I64 => "i64",
            ParamType::F64 => "f64",
            ParamType::F64s => "f64 list",
            ParamType::Text => "text",
        })
    }
}

/// A parameter's value.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    Bool(bool),
    I64(i64),
    F64(f64),
    F64s(Vec<f64>),
    Text(String),
}

impl ParamValue {
    pub fn param_type(&self) -> ParamType {
        match self {
            ParamValue::Bool(_) => ParamType::Bool,
            ParamValue::I64(_) => ParamType::I64,
            ParamValue::F64(_) => ParamType::F64,
            ParamValue::F64s(_) => ParamType::F64s,
            ParamValue::Text(_) => ParamType::Text,
        }
    }

    /// This value as type `ty`, where that loses nothing: an integer is an f64 (when exactly
    /// representable), an f64 with an integer value is an i64, a number is an f64 list of one;
    /// otherwise only the same type.
    pub fn coerce(&self, ty: ParamType) -> Option<ParamValue> {
        const EXACT: i64 = 1 << 53;
        match (self, ty) {
            (ParamValue::I64(_) | ParamValue::F64(_), ParamType::F64s) => {
                match self.coerce(ParamType::F64)? {
                    ParamValue::F64(x) => Some(ParamValue::F64s(vec![x])),
                    _ => None,
                }
            }
            (ParamValue::I64(i), ParamType::F64) if (-EXACT..=EXACT).contains(i) => {
                Some(ParamValue::F64(*i as f64))
            }
            (ParamValue::F64(x), ParamType::I64) if x.fract() == 0.0 && x.abs() <= 9.0e15 => {
                Some(ParamValue::I64(*x as i64))
            }
            (v, ty) if v.param_type() == ty => Some(v.clone()),
            _ => None,
        }
    }
}

impl fmt::Display for ParamValue {
    /// As a description writes it: `true`, `3`, `0.5`, `{1.0, 2.0}`, `"text"`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamValue::Bool(b) => write!(f, "{b}"),
            ParamValue::I64(i) => write!(f, "{i}"),
            ParamValue::F64(x) => write!(f, "{x:?}"),
            ParamValue::F64s(xs) => {
                f.write_str("{")?;
                for (i, x) in xs.iter().enumerate() {
                    let sep = if i > 0 { ", " } else { "" };
                    write!(f, "{sep}{x:?}")?;
                }
                f.write_str("}")
            }
            ParamValue::Text(s) => write!(f, "{s:?}"),
        }
    }
}
