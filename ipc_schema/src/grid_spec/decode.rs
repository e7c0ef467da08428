//! Reading an image: its shape (values of their kinds, counts the bytes can hold, known texts),
//! then the rules of `check.rs`.

use super::{
    AssemblyImage, ComponentImage, ConnectionImage, DeclaredImage, GridImage, GridSpecError,
    InfoImage, ParamDeclImage, Place, PortAt, PortImage, MAGIC, VERSION,
};
use crate::fields::Fields;
use crate::grid::{Generation, GridClock, OverrunPolicy, ParamType, ParamValue, PortType};
use crate::value::Value;

/// Every parameter type, to read one back from its text.
const PARAM_TYPES: [ParamType; 5] = [
    ParamType::Bool,
    ParamType::I64,
    ParamType::F64,
    ParamType::F64s,
    ParamType::Text,
];

/// Reads an image and checks it ([`GridImage::check`]): what it returns is safe to index.
pub fn decode(bytes: &[u8]) -> Result<GridImage, GridSpecError> {
    let mut fields = Fields::new(bytes);
    let magic = fields.text("the magic")?;
    if magic != MAGIC {
        return Err(GridSpecError::Magic {
            found: magic.to_owned(),
        });
    }
    let version = fields.int::<i64>("the version")?;
    if version != VERSION {
        return Err(GridSpecError::Version { found: version });
    }
    let base_period_ns = fields.int("the base period")?;
    let priority = match fields.int::<u8>("the priority")? {
        0 => None,
        p => Some(p),
    };
    let mlock = fields.bool("mlock")?;
    let k = count(&mut fields, "the CPUs", 1)?;
    let mut cpus = Vec::new();
    for _ in 0..k {
        cpus.push(fields.int("a CPU")?);
    }
    let line = fields.int("the grid's line")?;
    let clock = fields.text("the clock")?;
    let clock = GridClock::from_name(clock).ok_or_else(|| GridSpecError::Clock {
        name: clock.to_owned(),
    })?;
    let track_ticks = fields.int("track_ticks")?;
    let spin_us = fields.int("spin_us")?;
    let assembly = match fields.int::<i64>("the assembly's tag")? {
        0 => None,
        1 => Some(AssemblyImage {
            name: fields.text("the assembly's name")?.to_owned(),
            generation: Generation(fields.int("the assembly's generation")?),
            base: fields.int("the assembly's first component")?,
        }),
        tag => return Err(GridSpecError::AssemblyTag { tag }),
    };
    // program, line, and an info's five values at least.
    let d = count(&mut fields, "the declared types", 7)?;
    let mut declared = Vec::new();
    for i in 0..d {
        declared.push(DeclaredImage {
            program: fields.text("a declared type's program")?.to_owned(),
            line: fields.int("a declared type's line")?,
            info: info(&mut fields, Place::Declared(i))?,
        });
    }
    // Eight values, then an info's five at least.
    let n = count(&mut fields, "the components", 13)?;
    let mut components = Vec::new();
    for i in 0..n {
        components.push(component(&mut fields, i)?);
    }
    let m = count(&mut fields, "the connections", 5)?;
    let mut connections = Vec::new();
    for _ in 0..m {
        let mut index = |what| fields.int::<usize>(what);
        let from = PortAt {
            component: index("a connection's source component")?,
            port: index("a connection's output")?,
        };
        let to = PortAt {
            component: index("a connection's target component")?,
            port: index("a connection's input")?,
        };
        connections.push(ConnectionImage {
            from,
            to,
            line: fields.int("a connection's line")?,
        });
    }
    if !fields.is_done() {
        return Err(GridSpecError::Trailing {
            offset: fields.offset(),
        });
    }
    let image = GridImage {
        base_period_ns,
        cpus,
        priority,
        mlock,
        line,
        clock,
        track_ticks,
        spin_us,
        assembly,
        declared,
        components,
        connections,
    };
    image.check()?;
    Ok(image)
}

/// Reads a count of entries of at least `values` values each; refused when the bytes left
/// cannot hold them (every value takes a byte or more), so that no count is trusted further
/// than the bytes go.
fn count(
    fields: &mut Fields<'_>,
    what: &'static str,
    values: usize,
) -> Result<usize, GridSpecError> {
    let count: usize = fields.int(what)?;
    let remaining = fields.remaining();
    if count > remaining / values {
        return Err(GridSpecError::Count {
            what,
            count,
            remaining,
        });
    }
    Ok(count)
}

fn component(fields: &mut Fields<'_>, i: usize) -> Result<ComponentImage, GridSpecError> {
    let at = Place::Component(i);
    let name = fields.text("a component's name")?.to_owned();
    let type_name = fields.text("a component's type")?.to_owned();
    let program = match fields.text("a component's program")? {
        "" => None,
        program => Some(program.to_owned()),
    };
    let host = fields.text("a component's host")?.to_owned();
    let period = fields.int("a component's period")?;
    let policy = fields.text("a component's policy")?;
    let policy = OverrunPolicy::from_name(policy).ok_or_else(|| GridSpecError::Policy {
        component: i,
        name: policy.to_owned(),
    })?;
    let line = fields.int("a component's line")?;
    let p = count(fields, "a component's parameters", 2)?;
    let mut params = Vec::new();
    for _ in 0..p {
        let name = fields.text("a parameter's name")?;
        params.push((name.to_owned(), param_value(fields, at, name)?));
    }
    Ok(ComponentImage {
        name,
        type_name,
        program,
        host,
        period,
        policy,
        line,
        params,
        info: info(fields, at)?,
    })
}

fn info(fields: &mut Fields<'_>, at: Place) -> Result<InfoImage, GridSpecError> {
    let type_name = fields.text("a type's name")?.to_owned();
    let doc = fields.text("a type's doc")?.to_owned();
    let inputs = ports(fields, at, "a type's inputs")?;
    let outputs = ports(fields, at, "a type's outputs")?;
    let q = count(fields, "a type's parameters", 3)?;
    let mut params = Vec::new();
    for _ in 0..q {
        let name = fields.text("a declared parameter's name")?;
        let ty = fields.text("a declared parameter's type")?;
        let ty = PARAM_TYPES
            .into_iter()
            .find(|t| t.to_string() == ty)
            .ok_or_else(|| GridSpecError::ParamType {
                at,
                param: name.to_owned(),
                ty: ty.to_owned(),
            })?;
        let default = match fields.bool("whether a parameter has a default")? {
            true => Some(param_value(fields, at, name)?),
            false => None,
        };
        params.push(ParamDeclImage {
            name: name.to_owned(),
            ty,
            default,
        });
    }
    Ok(InfoImage {
        type_name,
        doc,
        inputs,
        outputs,
        params,
    })
}

fn ports(
    fields: &mut Fields<'_>,
    at: Place,
    what: &'static str,
) -> Result<Vec<PortImage>, GridSpecError> {
    let k = count(fields, what, 2)?;
    let mut ports = Vec::new();
    for _ in 0..k {
        let name = fields.text("a port's name")?;
        let ty = fields.text("a port's type")?;
        let ty = PortType::parse(ty).ok_or_else(|| GridSpecError::PortType {
            at,
            port: name.to_owned(),
            ty: ty.to_owned(),
        })?;
        ports.push(PortImage {
            name: name.to_owned(),
            ty,
        });
    }
    Ok(ports)
}

/// A parameter's value: the payload value of its kind (bytes are no parameter).
fn param_value(
    fields: &mut Fields<'_>,
    at: Place,
    param: &str,
) -> Result<ParamValue, GridSpecError> {
    Ok(match fields.value("a parameter's value")? {
        Value::Bool(b) => ParamValue::Bool(b),
        Value::I64(i) => ParamValue::I64(i),
        Value::F64(x) => ParamValue::F64(x),
        Value::F64s(xs) => ParamValue::F64s(xs.to_vec()),
        Value::Text(t) => ParamValue::Text(t.to_owned()),
        other @ Value::Bytes(_) => {
            return Err(GridSpecError::ParamKind {
                at,
                param: param.to_owned(),
                found: other.kind(),
            })
        }
    })
}
