//! The versions of one component's outputs a reader keeps: what arrived on its output
//! service, by the tick each version is valid from. A host reads its inputs from these, the
//! recorder its trace; both ask for exactly the version LET names and get it, or nothing.
//!
//! How many to keep: a reader released at n asks for the version valid at n; by the time it
//! serves that release its source may have published newer ones, one per source period. In
//! lockstep a reader is at most its own period behind, so twice the longest period of the two
//! plus a margin covers it; a reader held up for longer (SIGSTOP, a starved process) finds
//! the version gone and says so ([`Versions::get`] is `None`) instead of reading another.
//!
//! Version 0 is the source's initial outputs (what is valid before its first release's):
//! zeros until a sample valid from 0 arrives (its host publishes one when it answers a
//! warm-up release), kept apart from the ring, since no release overwrites it.

use modbot_ipc_schema::grid::{read_record, OutHeader, PortValue};
use zerocopy::FromBytes;

use super::carry::{Carry, CarryError};
use super::wire::Sub;

/// Versions kept beyond twice the longest period involved.
const MARGIN: usize = 8;

/// How many versions a reader of a source keeps, for periods (in base ticks) of the reader and
/// the source.
pub fn depth(reader_period: u64, source_period: u64) -> usize {
    let longest = reader_period
        .max(source_period)
        .min(super::wire::OUT_DEPTH as u64) as usize;
    (2 * longest + MARGIN).min(super::wire::OUT_DEPTH)
}

/// The newest versions of one source's outputs.
pub struct Versions {
    sub: Sub,
    /// (valid_from, outputs), the newest overwriting the oldest; `u64::MAX`: empty.
    ring: Vec<(u64, Vec<PortValue>)>,
    next: usize,
    /// Version 0: the initial outputs.
    initial: Vec<PortValue>,
}

impl Versions {
    /// Keeps `depth` versions of what `sub` receives; `zeros` are version 0 until the source's
    /// initial outputs arrive (and give every version its types).
    pub fn new(sub: Sub, zeros: Vec<PortValue>, depth: usize) -> Versions {
        Versions {
            sub,
            ring: (0..depth.max(1))
                .map(|_| (u64::MAX, zeros.clone()))
                .collect(),
            next: 0,
            initial: zeros,
        }
    }

    /// Takes every sample that arrived into the ring. No allocation: the ring's values have
    /// their types and lengths already.
    pub fn take_arrived(&mut self) {
        let (ring, next, initial) = (&mut self.ring, &mut self.next, &mut self.initial);
        while let Ok(true) = self.sub.receive(&mut |sample| {
            let Ok((header, record)) = OutHeader::ref_from_prefix(sample) else {
                return;
            };
            if header.valid_from.get() == 0 {
                // The initial outputs (a record that does not fit leaves the last ones).
                let _ = read_record(record, initial);
                return;
            }
            let slot = &mut ring[*next];
            if read_record(record, &mut slot.1).is_ok() {
                slot.0 = header.valid_from.get();
                *next = (*next + 1) % ring.len();
            } else {
                slot.0 = u64::MAX;
            }
        }) {}
    }

    /// Takes what arrived, then lends version `want` (0: the initial outputs); `None` if it
    /// is not here (never arrived, or overwritten by newer ones).
    pub fn get(&mut self, want: u64) -> Option<&[PortValue]> {
        self.take_arrived();
        if want == 0 {
            return Some(&self.initial);
        }
        self.ring
            .iter()
            .find(|(from, _)| *from == want)
            .map(|(_, v)| v.as_slice())
    }

    /// Carries the versions kept (and the initial outputs) into the same reader in a new
    /// process of the host (a live upgrade): the new process then holds every version the old
    /// one could still read, those published before it subscribed included. The sender takes
    /// what arrived first; what arrives after a load goes in after the carried versions.
    pub fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        c.ports("a source's initial outputs", &mut self.initial)?;
        c.length("the versions a reader keeps", self.ring.len())?;
        for (from, values) in &mut self.ring {
            c.u64("a version's tick", from)?;
            c.ports("a version's outputs", values)?;
        }
        let mut next = self.next as u64;
        c.u64("the next version's place", &mut next)?;
        self.next = usize::try_from(next)
            .ok()
            .filter(|n| *n < self.ring.len())
            .ok_or(CarryError::Shape {
                what: "the next version's place",
                expected: self.ring.len(),
                got: usize::try_from(next).unwrap_or(usize::MAX),
            })?;
        Ok(())
    }

    /// Makes the connection to the source's publisher here (it maps the publisher's memory), so
    /// that the first receive on a real-time thread does not.
    pub fn connect(&self) {
        self.sub.connect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reader_keeps_twice_the_longest_period_plus_a_margin_up_to_what_the_service_buffers() {
        assert_eq!(depth(1, 1), 10);
        assert_eq!(depth(10, 1), 28);
        assert_eq!(depth(1, 1000), super::super::wire::OUT_DEPTH);
    }
}
