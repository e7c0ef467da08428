//! The values a component exchanges with its FMU at every release, laid out once: per FMI type,
//! the value references and a buffer, and per port where its values are in it — so a release
//! moves them without allocating.
//!
//! An i64 port into an FMI `Int32` input is converted visibly: a value beyond what an Int32
//! holds is clamped to its nearest (`i32::MIN` or `i32::MAX`), and [`Values::take`] reports
//! the first time it happens on each port, so the component logs it once.

use modbot_grid::component::PortValue;

use super::interface::{Kind, Port};

/// One FMI type's value references and values.
#[derive(Debug, Default, Clone)]
pub struct Typed<T> {
    pub refs: Vec<u32>,
    pub values: Vec<T>,
}

/// The values of one direction (the inputs, or the outputs), by FMI type.
#[derive(Debug, Default, Clone)]
pub struct Values {
    pub real: Typed<f64>,
    pub int32: Typed<i32>,
    pub int64: Typed<i64>,
    pub boolean: Typed<bool>,
    /// Port by port: its FMI type, where its values start in that type's buffer, how many.
    slots: Vec<(Kind, usize, usize)>,
    /// Port by port: whether a value was clamped on it already (and reported).
    clamped: Vec<bool>,
}

/// A value clamped to what an FMI `Int32` holds, the first time on its port.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Clamped {
    /// The port, in input port order.
    pub port: usize,
    /// The value it had.
    pub value: i64,
    /// The value the FMU is given.
    pub to: i32,
}

impl Values {
    /// The layout of `ports`.
    pub fn new(ports: &[Port]) -> Values {
        let mut v = Values::default();
        for p in ports {
            let len = p.ty.wire_len() / 8;
            let at = match p.kind {
                Kind::Real => grow(&mut v.real, &p.refs, len),
                Kind::Int32 => grow(&mut v.int32, &p.refs, len),
                Kind::Int64 => grow(&mut v.int64, &p.refs, len),
                Kind::Bool => grow(&mut v.boolean, &p.refs, len),
                // No port has it (structural parameters only).
                Kind::UInt64 => 0,
            };
            v.slots.push((p.kind, at, len));
            v.clamped.push(false);
        }
        v
    }

    /// Copies `ports` (the component's inputs, in port order) into the buffers. Returns the
    /// first value clamped to an Int32 on a port where none was before.
    pub fn take(&mut self, ports: &[PortValue]) -> Option<Clamped> {
        let mut first = None;
        for (port, (&(kind, at, len), value)) in self.slots.iter().zip(ports).enumerate() {
            match (kind, value) {
                (Kind::Real, PortValue::F64(x)) => self.real.values[at] = *x,
                (Kind::Real, PortValue::F64s(xs)) => {
                    let n = len.min(xs.len());
                    self.real.values[at..at + n].copy_from_slice(&xs[..n]);
                }
                (Kind::Int32, PortValue::I64(i)) => {
                    let to = (*i).clamp(i32::MIN.into(), i32::MAX.into()) as i32;
                    self.int32.values[at] = to;
                    if i64::from(to) != *i && !self.clamped[port] {
                        self.clamped[port] = true;
                        first = first.or(Some(Clamped {
                            port,
                            value: *i,
                            to,
                        }));
                    }
                }
                (Kind::Int64, PortValue::I64(i)) => self.int64.values[at] = *i,
                (Kind::Bool, PortValue::Bool(b)) => self.boolean.values[at] = *b,
                // A value of another type than the port's: the grid never sends one.
                _ => {}
            }
        }
        first
    }

    /// Copies the buffers into `ports` (the component's outputs, in port order).
    pub fn give(&self, ports: &mut [PortValue]) {
        for (&(kind, at, len), value) in self.slots.iter().zip(ports) {
            match (kind, value) {
                (Kind::Real, PortValue::F64(x)) => *x = self.real.values[at],
                (Kind::Real, PortValue::F64s(xs)) => {
                    let n = len.min(xs.len());
                    xs[..n].copy_from_slice(&self.real.values[at..at + n]);
                }
                (Kind::Int32, PortValue::I64(i)) => *i = i64::from(self.int32.values[at]),
                (Kind::Int64, PortValue::I64(i)) => *i = self.int64.values[at],
                (Kind::Bool, PortValue::Bool(b)) => *b = self.boolean.values[at],
                _ => {}
            }
        }
    }
}

/// Adds a port's references and `len` values to `typed`; returns where its values start.
fn grow<T: Default + Clone>(typed: &mut Typed<T>, refs: &[u32], len: usize) -> usize {
    let at = typed.values.len();
    typed.refs.extend_from_slice(refs);
    typed.values.resize(at + len, T::default());
    at
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_grid::component::PortType;

    fn port(name: &str, ty: PortType, kind: Kind, refs: &[u32]) -> Port {
        Port {
            name: name.into(),
            ty,
            kind,
            refs: refs.to_vec(),
            shape: Vec::new(),
        }
    }

    #[test]
    fn ports_travel_through_the_buffers_of_their_fmi_types_and_back() {
        let ports = [
            port("q", PortType::F64s(3), Kind::Real, &[4, 5, 6]),
            port("n", PortType::I64, Kind::Int32, &[9]),
            port("y", PortType::F64, Kind::Real, &[1]),
            port("on", PortType::Bool, Kind::Bool, &[2]),
            port("big", PortType::F64s(2), Kind::Real, &[7]),
        ];
        let mut sut = Values::new(&ports);
        assert_eq!(sut.real.refs, [4, 5, 6, 1, 7]);
        assert_eq!(sut.real.values.len(), 6);
        let inputs = [
            PortValue::F64s(vec![1.0, 2.0, 3.0]),
            PortValue::I64(1 << 40),
            PortValue::F64(-1.5),
            PortValue::Bool(true),
            PortValue::F64s(vec![8.0, 9.0]),
        ];
        let clamped = sut.take(&inputs);
        assert_eq!(sut.real.values, [1.0, 2.0, 3.0, -1.5, 8.0, 9.0]);
        assert_eq!(
            sut.int32.values,
            [i32::MAX],
            "an i64 beyond Int32 is clamped"
        );
        assert_eq!(
            clamped,
            Some(Clamped {
                port: 1,
                value: 1 << 40,
                to: i32::MAX
            }),
            "and the first time is reported"
        );
        assert_eq!(sut.take(&inputs), None, "once per port");
        let mut outputs: Vec<PortValue> = ports.iter().map(|p| p.ty.zero()).collect();
        sut.give(&mut outputs);
        assert_eq!(outputs[0], inputs[0]);
        assert_eq!(outputs[1], PortValue::I64(i64::from(i32::MAX)));
        assert_eq!(&outputs[2..], &inputs[2..]);
    }
}
