//! Carrying a component's state into another instance of its type, bit for bit: what a live
//! upgrade of a grid host needs so that the new process steps on exactly as the old one would
//! have (docs/upgrade.md; not yet used by a host).
//!
//! One method serves both directions ([`crate::component::Component::carry`]): it visits every
//! field its `step` depends on beyond its parameters, in one order, and the [`Carry`] it is
//! given either measures, saves into a buffer, or loads from one. Save and load cannot then
//! disagree on the order. Floats move as their bits; an array's length must match on load.

use modbot_ipc_schema::grid::PortValue;
use thiserror::Error;

/// Why a state cannot be carried.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CarryError {
    #[error("its type cannot carry its state into another instance")]
    Unsupported,
    #[error("the state ends before {what} ({left} bytes left, {need} needed)")]
    Truncated {
        what: &'static str,
        left: usize,
        need: usize,
    },
    #[error("{what} has {got} elements in the state and {expected} in this instance")]
    Shape {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("the state has {0} bytes more than this instance takes")]
    Trailing(usize),
    #[error("{what} has a value of another type in the state")]
    Kind { what: &'static str },
}

enum Mode<'a> {
    Measure,
    Save(&'a mut [u8]),
    Load(&'a [u8]),
}

/// Measures, saves or loads the fields a component visits.
pub struct Carry<'a> {
    mode: Mode<'a>,
    /// Bytes visited so far.
    at: usize,
}

impl<'a> Carry<'a> {
    /// Counts the bytes a state takes ([`Carry::len`] after the visit).
    pub fn measure() -> Carry<'static> {
        Carry {
            mode: Mode::Measure,
            at: 0,
        }
    }

    /// Writes the visited fields into `buf` (as long as a measure said: no allocation).
    pub fn save(buf: &'a mut [u8]) -> Carry<'a> {
        Carry {
            mode: Mode::Save(buf),
            at: 0,
        }
    }

    /// Sets the visited fields from `bytes`.
    pub fn load(bytes: &'a [u8]) -> Carry<'a> {
        Carry {
            mode: Mode::Load(bytes),
            at: 0,
        }
    }

    /// Bytes visited so far.
    pub fn len(&self) -> usize {
        self.at
    }

    pub fn is_empty(&self) -> bool {
        self.at == 0
    }

    /// After a load: every byte was taken.
    pub fn finish(&self) -> Result<(), CarryError> {
        match &self.mode {
            Mode::Load(bytes) if bytes.len() > self.at => {
                Err(CarryError::Trailing(bytes.len() - self.at))
            }
            _ => Ok(()),
        }
    }

    fn bytes<const N: usize>(
        &mut self,
        what: &'static str,
        v: &mut [u8; N],
    ) -> Result<(), CarryError> {
        let at = self.at;
        match &mut self.mode {
            Mode::Measure => {}
            Mode::Save(buf) => {
                let left = buf.len().saturating_sub(at);
                let room = buf.get_mut(at..at + N).ok_or(CarryError::Truncated {
                    what,
                    left,
                    need: N,
                })?;
                room.copy_from_slice(v);
            }
            Mode::Load(bytes) => {
                let left = bytes.len().saturating_sub(at);
                let have = bytes.get(at..at + N).ok_or(CarryError::Truncated {
                    what,
                    left,
                    need: N,
                })?;
                v.copy_from_slice(have);
            }
        }
        self.at += N;
        Ok(())
    }

    pub fn u64(&mut self, what: &'static str, v: &mut u64) -> Result<(), CarryError> {
        let mut b = v.to_le_bytes();
        self.bytes(what, &mut b)?;
        *v = u64::from_le_bytes(b);
        Ok(())
    }

    pub fn i64(&mut self, what: &'static str, v: &mut i64) -> Result<(), CarryError> {
        let mut b = v.to_le_bytes();
        self.bytes(what, &mut b)?;
        *v = i64::from_le_bytes(b);
        Ok(())
    }

    /// An f64 as its bits (NaN payloads and -0.0 kept).
    pub fn f64(&mut self, what: &'static str, v: &mut f64) -> Result<(), CarryError> {
        let mut bits = v.to_bits();
        self.u64(what, &mut bits)?;
        *v = f64::from_bits(bits);
        Ok(())
    }

    pub fn bool(&mut self, what: &'static str, v: &mut bool) -> Result<(), CarryError> {
        let mut b = [u8::from(*v)];
        self.bytes(what, &mut b)?;
        *v = b[0] != 0;
        Ok(())
    }

    /// A tick or count that may not be there yet: whether it is, then its value.
    pub fn optional_u64(
        &mut self,
        what: &'static str,
        v: &mut Option<u64>,
    ) -> Result<(), CarryError> {
        let mut there = v.is_some();
        let mut value = v.unwrap_or(0);
        self.bool(what, &mut there)?;
        self.u64(what, &mut value)?;
        *v = there.then_some(value);
        Ok(())
    }

    /// Flags of the instance's number: their number goes first, and must match on load.
    pub fn bools(&mut self, what: &'static str, v: &mut [bool]) -> Result<(), CarryError> {
        self.length(what, v.len())?;
        for b in v.iter_mut() {
            self.bool(what, b)?;
        }
        Ok(())
    }

    /// Visits `len`; on load, refuses another.
    pub fn length(&mut self, what: &'static str, len: usize) -> Result<(), CarryError> {
        let mut n = len as u64;
        self.u64(what, &mut n)?;
        if n != len as u64 {
            return Err(CarryError::Shape {
                what,
                expected: len,
                got: usize::try_from(n).unwrap_or(usize::MAX),
            });
        }
        Ok(())
    }

    /// An array of the instance's length: its length goes first, and must match on load.
    pub fn f64s(&mut self, what: &'static str, v: &mut [f64]) -> Result<(), CarryError> {
        self.length(what, v.len())?;
        for x in v.iter_mut() {
            self.f64(what, x)?;
        }
        Ok(())
    }

    /// Port values of the instance's number and types (a vector's length included), each as
    /// its bits: a type other than the instance's is refused on load.
    pub fn ports(&mut self, what: &'static str, v: &mut [PortValue]) -> Result<(), CarryError> {
        self.length(what, v.len())?;
        for port in v.iter_mut() {
            let mut kind: u64 = match port {
                PortValue::Bool(_) => 0,
                PortValue::I64(_) => 1,
                PortValue::F64(_) => 2,
                PortValue::F64s(_) => 3,
            };
            let expected = kind;
            self.u64(what, &mut kind)?;
            if kind != expected {
                return Err(CarryError::Kind { what });
            }
            match port {
                PortValue::Bool(b) => self.bool(what, b)?,
                PortValue::I64(i) => self.i64(what, i)?,
                PortValue::F64(x) => self.f64(what, x)?,
                PortValue::F64s(xs) => self.f64s(what, xs)?,
            }
        }
        Ok(())
    }

    /// A block of its own, its length first: on load `f` must take every byte of it (a
    /// component's state, so that one whose layout changed is refused by name, not read
    /// askew).
    pub fn framed(
        &mut self,
        what: &'static str,
        f: impl FnOnce(&mut Carry<'_>) -> Result<(), CarryError>,
    ) -> Result<(), CarryError> {
        let at = self.at;
        let len = match &mut self.mode {
            Mode::Measure => {
                let mut inner = Carry::measure();
                f(&mut inner)?;
                inner.at
            }
            Mode::Save(buf) => {
                let left = buf.len().saturating_sub(at);
                let room =
                    buf.get_mut(at..)
                        .filter(|r| r.len() >= 8)
                        .ok_or(CarryError::Truncated {
                            what,
                            left,
                            need: 8,
                        })?;
                let (head, body) = room.split_at_mut(8);
                let mut inner = Carry::save(body);
                f(&mut inner)?;
                head.copy_from_slice(&(inner.at as u64).to_le_bytes());
                inner.at
            }
            Mode::Load(bytes) => {
                let left = bytes.len().saturating_sub(at);
                let head = bytes.get(at..at + 8).ok_or(CarryError::Truncated {
                    what,
                    left,
                    need: 8,
                })?;
                let mut n = [0u8; 8];
                n.copy_from_slice(head);
                let len = usize::try_from(u64::from_le_bytes(n)).unwrap_or(usize::MAX);
                let body = bytes.get(at + 8..).and_then(|b| b.get(..len)).ok_or(
                    CarryError::Truncated {
                        what,
                        left: left.saturating_sub(8),
                        need: len,
                    },
                )?;
                let mut inner = Carry::load(body);
                f(&mut inner)?;
                inner.finish()?;
                len
            }
        };
        self.at += 8 + len;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A state of every kind, visited in one order both ways.
    #[derive(Debug, Clone, PartialEq)]
    struct State {
        n: u64,
        i: i64,
        x: f64,
        on: bool,
        xs: [f64; 3],
        flags: [bool; 2],
    }

    impl State {
        fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
            c.u64("n", &mut self.n)?;
            c.i64("i", &mut self.i)?;
            c.f64("x", &mut self.x)?;
            c.bool("on", &mut self.on)?;
            c.f64s("xs", &mut self.xs)?;
            c.bools("flags", &mut self.flags)
        }
    }

    fn zero() -> State {
        State {
            n: 0,
            i: 0,
            x: 0.0,
            on: false,
            xs: [0.0; 3],
            flags: [false; 2],
        }
    }

    #[test]
    fn a_state_saved_and_loaded_is_the_same_to_the_bit() {
        let mut old = State {
            n: 7,
            i: -3,
            x: -0.0,
            on: true,
            xs: [1.5, f64::from_bits(0x7ff8_0000_0000_0001), 1e-300],
            flags: [false, true],
        };
        let mut measure = Carry::measure();
        old.carry(&mut measure).unwrap();
        let mut buf = vec![0; measure.len()];
        old.carry(&mut Carry::save(&mut buf)).unwrap();
        let mut new = zero();
        let mut load = Carry::load(&buf);
        new.carry(&mut load).unwrap();
        load.finish().unwrap();
        assert_eq!(new.x.to_bits(), old.x.to_bits());
        assert_eq!(new.xs.map(f64::to_bits), old.xs.map(f64::to_bits));
        assert_eq!(
            (new.n, new.i, new.on, new.flags),
            (7, -3, true, [false, true])
        );
    }

    #[test]
    fn a_short_or_long_state_or_another_length_is_refused() {
        let mut old = zero();
        let mut buf = vec![0; 8 + 8 + 8 + 1 + 8 + 24 + 8 + 2];
        old.carry(&mut Carry::save(&mut buf)).unwrap();
        let refused = zero().carry(&mut Carry::load(&buf[..buf.len() - 1]));
        assert!(matches!(
            refused,
            Err(CarryError::Truncated { what: "flags", .. })
        ));
        let mut long = buf.clone();
        long.push(0);
        let mut load = Carry::load(&long);
        zero().carry(&mut load).unwrap();
        assert_eq!(load.finish(), Err(CarryError::Trailing(1)));
        let mut other = buf.clone();
        other[25] = 4; // the array's length (after n, i, x, on)
        assert_eq!(
            zero().carry(&mut Carry::load(&other)),
            Err(CarryError::Shape {
                what: "xs",
                expected: 3,
                got: 4
            })
        );
    }

    #[test]
    fn port_values_and_framed_blocks_round_trip_and_a_block_read_short_is_refused() {
        let mut ports = vec![
            PortValue::Bool(true),
            PortValue::I64(-9),
            PortValue::F64(-0.0),
            PortValue::F64s(vec![1.0, 2.5]),
        ];
        let mut state = State { n: 1, ..zero() };
        let visit = |c: &mut Carry<'_>, ports: &mut Vec<PortValue>, state: &mut State| {
            c.ports("outputs", ports)?;
            c.framed("component", |inner| state.carry(inner))?;
            c.u64("after", &mut 42)
        };
        let mut measure = Carry::measure();
        visit(&mut measure, &mut ports, &mut state).unwrap();
        let mut buf = vec![0; measure.len()];
        visit(&mut Carry::save(&mut buf), &mut ports, &mut state).unwrap();
        let mut back = vec![
            PortValue::Bool(false),
            PortValue::I64(0),
            PortValue::F64(1.0),
            PortValue::F64s(vec![0.0, 0.0]),
        ];
        let mut loaded = zero();
        let mut load = Carry::load(&buf);
        visit(&mut load, &mut back, &mut loaded).unwrap();
        load.finish().unwrap();
        assert_eq!(back, ports);
        assert!(matches!(back[2], PortValue::F64(x) if x.to_bits() == (-0.0f64).to_bits()));
        assert_eq!(loaded, state);
        // A port of another type, and a component that takes less than its block, are refused.
        let mut other = back.clone();
        other[0] = PortValue::I64(0);
        assert_eq!(
            Carry::load(&buf).ports("outputs", &mut other),
            Err(CarryError::Kind { what: "outputs" })
        );
        let mut load = Carry::load(&buf);
        load.ports("outputs", &mut back).unwrap();
        let short = load.framed("component", |inner| inner.u64("n", &mut 0));
        assert!(matches!(short, Err(CarryError::Trailing(_))), "{short:?}");
    }
}
