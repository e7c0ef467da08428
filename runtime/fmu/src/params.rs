//! A description's parameters for an FMU component, checked against the FMU's before any
//! process starts (`modbot check` names the file and line): each is one of the FMU's, of its
//! type, of its shape (an array's or a matrix's number of elements, row-major), and within
//! its declared range (`min`, `max`) and what its FMI type holds (Int32, UInt64).

use modbot_grid::component::{intern, ParamError, ParamValue, Params, AUTOMATIC_PARAMS};

use super::interface::{shape_text, Extent, Interface, Kind, Param};

/// The param (and component field) that names the FMU.
pub const FMU: &str = "fmu";

/// Which of the description's parameters to check.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// The structural parameters only, before they size the interface's arrays (others, even
    /// unknown ones, wait for [`Which::All`]).
    Structural,
    /// Every parameter, against the interface sized by the structural ones.
    All,
}

/// Every param of `p` (of those `which` names) is the FMU's, of its type, shape and range (or
/// `fmu`, or an automatic one).
pub fn check(p: &Params, interface: &Interface, which: Which) -> Result<(), ParamError> {
    for (name, value) in p.iter() {
        if name == FMU || AUTOMATIC_PARAMS.contains(&name) {
            continue;
        }
        let Some(q) = interface.params.iter().find(|q| q.name == name) else {
            if which == Which::Structural {
                continue;
            }
            return Err(ParamError::Unknown {
                name: name.to_owned(),
                type_name: format!("fmu ({})", interface.model_name),
                known: interface.params.iter().map(|q| intern(&q.name)).collect(),
            });
        };
        if which == Which::Structural && !q.structural {
            continue;
        }
        check_one(q, value, interface)?;
    }
    Ok(())
}

/// `value` fits parameter `q`.
fn check_one(q: &Param, value: &ParamValue, interface: &Interface) -> Result<(), ParamError> {
    let invalid = |why: String| ParamError::invalid(&q.name, why);
    let numbers: Vec<f64> = match value.coerce(q.ty) {
        Some(ParamValue::F64(x)) => vec![x],
        Some(ParamValue::F64s(xs)) => {
            let n: u64 = q.dims.iter().product();
            if xs.len() as u64 != n {
                return Err(invalid(shape_wanted(q, interface, xs.len())));
            }
            xs
        }
        Some(ParamValue::I64(i)) => {
            let (lowest, highest, fmi) = match q.kind {
                Kind::Int32 => (i64::from(i32::MIN), i64::from(i32::MAX), "Int32"),
                Kind::UInt64 => (0, i64::MAX, "UInt64"),
                _ => (i64::MIN, i64::MAX, "Int64"),
            };
            if !(lowest..=highest).contains(&i) {
                return Err(invalid(format!(
                    "must fit the FMU's {fmi} (from {lowest} to {highest}), not {i}"
                )));
            }
            vec![i as f64]
        }
        Some(_) => Vec::new(),
        None => {
            return Err(ParamError::WrongType {
                name: q.name.clone(),
                expected: q.ty,
                got: value.clone(),
            })
        }
    };
    let array = numbers.len() > 1 || !q.dims.is_empty();
    for (k, &x) in numbers.iter().enumerate() {
        if !q.range.contains(x) {
            let which = if array {
                format!("element {} ", k + 1)
            } else {
                String::new()
            };
            return Err(invalid(format!(
                "{which}must be {} (the FMU's declared range), not {x}",
                q.range.text()
            )));
        }
    }
    Ok(())
}

/// What an array parameter given `got` numbers should have been: `is a 3×3 matrix (nx×nx):
/// give its 9 numbers, row by row, not 4`.
fn shape_wanted(q: &Param, interface: &Interface, got: usize) -> String {
    let n: u64 = q.dims.iter().product();
    let named: Vec<String> = q
        .shape
        .iter()
        .map(|e| match e {
            Extent::Fixed(n) => n.to_string(),
            Extent::Of(r) => interface
                .params
                .iter()
                .find(|s| s.structural && s.refs.first() == Some(r))
                .map_or_else(|| format!("#{r}"), |s| s.name.clone()),
        })
        .collect();
    let sizes = if q.shape.iter().any(|e| matches!(e, Extent::Of(_))) {
        format!(" ({})", named.join("×"))
    } else {
        String::new()
    };
    match q.dims.len() {
        0 | 1 => format!("is an array of {n}{sizes}: give its {n} numbers, not {got}"),
        _ => format!(
            "is a {} matrix{sizes}: give its {n} numbers, row by row, not {got}",
            shape_text(&q.dims)
        ),
    }
}

#[cfg(test)]
mod tests {
    use modbot_grid::component::ParamType;

    use super::super::component_type::info;
    use super::*;

    /// The params of the FMU at `path` with `params`.
    fn fmu(path: &str, params: &[(&str, ParamValue)]) -> Params {
        let mut p = Params::new().with(FMU, ParamValue::Text(path.into()));
        for (name, value) in params {
            p.set(*name, value.clone());
        }
        p
    }

    /// Why `info` refuses these params.
    fn refused(path: &str, params: &[(&str, ParamValue)]) -> String {
        info(&fmu(path, params)).expect_err("refused").to_string()
    }

    #[test]
    fn a_matrix_parameter_takes_its_elements_row_by_row_and_refuses_another_count() {
        let a = ParamValue::F64s(vec![0.0, 1.0, -4.0, -0.4]);
        let sut = info(&fmu(modbot_fmus::SS3, &[("A", a)])).unwrap();
        let decl = sut.params.iter().find(|d| d.name == "A").unwrap();
        assert_eq!(decl.ty, ParamType::F64s);
        let three = ParamValue::F64s(vec![1.0, 2.0, 3.0]);
        assert_eq!(
            refused(modbot_fmus::SS3, &[("A", three)]),
            "param 'A' is a 2×2 matrix (nx×nx): give its 4 numbers, row by row, not 3"
        );
        let nine = ParamValue::F64s(vec![0.0; 9]);
        let sized = [("nx", ParamValue::I64(3)), ("A", nine)];
        let sut = info(&fmu(modbot_fmus::SS3, &sized)).unwrap();
        assert_eq!(sut.outputs[0].ty.to_string(), "f64[1]");
    }

    #[test]
    fn structural_parameters_size_the_ports_a_description_connects() {
        let sut = info(&fmu(
            modbot_fmus::SS3,
            &[("nu", ParamValue::I64(2)), ("ny", ParamValue::I64(3))],
        ))
        .unwrap();
        let ports: Vec<String> = sut
            .inputs
            .iter()
            .chain(&sut.outputs)
            .map(|p| format!("{}:{}", p.name, p.ty))
            .collect();
        assert_eq!(ports, ["u:f64[2]", "y:f64[3]"]);
    }

    #[test]
    fn a_parameter_outside_its_declared_range_is_refused_naming_the_range() {
        assert_eq!(
            refused(modbot_fmus::STAIR2, &[("start", ParamValue::I64(1001))]),
            "param 'start' must be from -1000 to 1000 (the FMU's declared range), not 1001"
        );
        assert_eq!(
            refused(modbot_fmus::STAIR2, &[("t_stop", ParamValue::F64(-0.5))]),
            "param 't_stop' must be 0 or more (the FMU's declared range), not -0.5"
        );
        assert_eq!(
            refused(modbot_fmus::SS3, &[("nx", ParamValue::I64(9))]),
            "param 'nx' must be from 1 to 8 (the FMU's declared range), not 9"
        );
        assert_eq!(
            refused(modbot_fmus::SS3, &[("ny", ParamValue::I64(-1))]),
            "param 'ny' must fit the FMU's UInt64 (from 0 to 9223372036854775807), not -1"
        );
        assert!(info(&fmu(
            modbot_fmus::STAIR2,
            &[("start", ParamValue::I64(-1000))]
        ))
        .is_ok());
    }
}
