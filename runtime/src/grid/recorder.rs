//! The coordinator's recorder: every output of every component as valid at every tick, read
//! from the components' output samples and written as a trace (see [`super::trace`]).
//!
//! At tick n the coordinator knows, for each component, which version of its outputs is valid
//! (the `valid_from` of its last release that finished in time, or 0 for the initial zeros);
//! the recorder takes that version from the samples it received. A version the recorder cannot
//! find is counted as missing (it would mean a sample was lost) and written as the last value.

use std::io::Write;

use iceoryx2::prelude::*;
use modbot_ipc_schema::grid::{read_record, OutHeader, PortValue, OUT_HEADER_LEN};
use zerocopy::FromBytes;

use super::spec::GridSpec;
use super::trace::TraceWriter;
use super::wire::{self, Sub, Threadsafe};
use crate::transport::TransportError;

/// Versions kept per component: LET only ever reads one of the newest two.
const KEPT: usize = 4;

struct Versions {
    sub: Sub<Threadsafe>,
    /// (valid_from, outputs), newest overwriting the oldest.
    ring: Vec<(u64, Vec<PortValue>)>,
    next: usize,
    zeros: Vec<PortValue>,
}

/// Writes the trace of a run.
pub struct Recorder<W: Write> {
    comps: Vec<Versions>,
    writer: TraceWriter<W>,
    /// Versions that were not found when needed.
    pub missing: u64,
}

impl<W: Write> Recorder<W> {
    /// Subscribes to every component's outputs on `node`, writing the trace to `out`.
    pub fn new(
        node: &Node<Threadsafe>,
        spec: &GridSpec,
        out: W,
    ) -> Result<Recorder<W>, TransportError> {
        let comps = spec
            .components
            .iter()
            .enumerate()
            .map(|(c, _)| {
                let zeros: Vec<PortValue> = spec.output_types(c).iter().map(|t| t.zero()).collect();
                Ok(Versions {
                    sub: wire::out_subscriber(node, &spec.out_service(c))?,
                    ring: (0..KEPT).map(|_| (u64::MAX, zeros.clone())).collect(),
                    next: 0,
                    zeros,
                })
            })
            .collect::<Result<Vec<_>, TransportError>>()?;
        Ok(Recorder {
            comps,
            writer: TraceWriter::new(out, spec),
            missing: 0,
        })
    }

    /// Records tick `n`, where component c's valid outputs are version `valid_from[c]`.
    pub fn tick(&mut self, n: u64, valid_from: &[u64]) -> std::io::Result<()> {
        for (c, v) in self.comps.iter_mut().enumerate() {
            while let Ok(Some(sample)) = v.sub.receive() {
                let bytes = sample.payload();
                let Ok((header, record)) = OutHeader::ref_from_prefix(bytes) else {
                    continue;
                };
                if bytes.len() < OUT_HEADER_LEN {
                    continue;
                }
                let slot = &mut v.ring[v.next];
                if read_record(record, &mut slot.1).is_ok() {
                    slot.0 = header.valid_from.get();
                    v.next = (v.next + 1) % KEPT;
                }
            }
            let want = valid_from[c];
            let values = if want == 0 {
                &v.zeros
            } else {
                match v.ring.iter().find(|(from, _)| *from == want) {
                    Some((_, values)) => values,
                    None => {
                        self.missing += 1;
                        &v.ring[(v.next + KEPT - 1) % KEPT].1
                    }
                }
            };
            self.writer.tick(n, c, values)?;
        }
        self.writer.end_tick(n)
    }

    /// Flushes the trace.
    pub fn finish(self) -> std::io::Result<W> {
        self.writer.finish()
    }
}
