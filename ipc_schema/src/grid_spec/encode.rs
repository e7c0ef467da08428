//! Writing an image: the layout of the module doc, field by field.

use super::{ComponentImage, GridImage, InfoImage, PortImage, MAGIC, VERSION};
use crate::fields::{push, push_u64};
use crate::grid::ParamValue;
use crate::value::{F64s, Value};

/// Appends `image` to `out`, as given: an image that breaks the rules of
/// [`decode`](super::decode) (see [`GridImage::check`]) is refused there. Numbers past
/// `i64::MAX` are written as `i64::MAX`.
pub fn encode(image: &GridImage, out: &mut Vec<u8>) {
    push(out, Value::Text(MAGIC));
    push(out, Value::I64(VERSION));
    push_u64(out, image.base_period_ns);
    push_u64(out, image.priority.map_or(0, u64::from));
    push(out, Value::Bool(image.mlock));
    push_len(out, image.cpus.len());
    for &cpu in &image.cpus {
        push_len(out, cpu);
    }
    push_u64(out, u64::from(image.line));
    push(out, Value::Text(image.clock.name()));
    push_u64(out, image.track_ticks);
    push_u64(out, image.spin_us);
    match &image.assembly {
        None => push(out, Value::I64(0)),
        Some(assembly) => {
            push(out, Value::I64(1));
            push(out, Value::Text(&assembly.name));
            push_u64(out, u64::from(assembly.generation.0));
            push_len(out, assembly.base);
        }
    }
    push_len(out, image.declared.len());
    for declared in &image.declared {
        push(out, Value::Text(&declared.program));
        push_u64(out, u64::from(declared.line));
        push_info(out, &declared.info);
    }
    push_len(out, image.components.len());
    for component in &image.components {
        push_component(out, component);
    }
    push_len(out, image.connections.len());
    for c in &image.connections {
        for n in [c.from.component, c.from.port, c.to.component, c.to.port] {
            push_len(out, n);
        }
        push_u64(out, u64::from(c.line));
    }
}

fn push_len(out: &mut Vec<u8>, n: usize) {
    push_u64(out, n as u64);
}

fn push_component(out: &mut Vec<u8>, c: &ComponentImage) {
    push(out, Value::Text(&c.name));
    push(out, Value::Text(&c.type_name));
    push(out, Value::Text(c.program.as_deref().unwrap_or("")));
    push(out, Value::Text(&c.host));
    push_u64(out, c.period);
    push(out, Value::Text(c.policy.name()));
    push_u64(out, u64::from(c.line));
    push_len(out, c.params.len());
    for (name, value) in &c.params {
        push(out, Value::Text(name));
        push_param(out, value);
    }
    push_info(out, &c.info);
}

fn push_info(out: &mut Vec<u8>, info: &InfoImage) {
    push(out, Value::Text(&info.type_name));
    push(out, Value::Text(&info.doc));
    for ports in [&info.inputs, &info.outputs] {
        push_ports(out, ports);
    }
    push_len(out, info.params.len());
    for decl in &info.params {
        push(out, Value::Text(&decl.name));
        push(out, Value::Text(&decl.ty.to_string()));
        push(out, Value::Bool(decl.default.is_some()));
        if let Some(value) = &decl.default {
            push_param(out, value);
        }
    }
}

fn push_ports(out: &mut Vec<u8>, ports: &[PortImage]) {
    push_len(out, ports.len());
    for port in ports {
        push(out, Value::Text(&port.name));
        push(out, Value::Text(&port.ty.to_string()));
    }
}

/// A parameter's value as the payload value of its kind.
fn push_param(out: &mut Vec<u8>, value: &ParamValue) {
    push(
        out,
        match value {
            ParamValue::Bool(b) => Value::Bool(*b),
            ParamValue::I64(i) => Value::I64(*i),
            ParamValue::F64(x) => Value::F64(*x),
            ParamValue::F64s(xs) => Value::F64s(F64s::from_slice(xs)),
            ParamValue::Text(t) => Value::Text(t),
        },
    );
}
