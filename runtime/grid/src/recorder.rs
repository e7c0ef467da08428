//! The coordinator's recorder: every output of every component as valid at every tick, read
//! from the components' output samples and written as a trace (see [`super::trace`]).
//!
//! At tick n the coordinator knows, for each component, which version of its outputs is valid
//! (the `valid_from` of its last release that finished in time, or 0 for the initial zeros);
//! the recorder takes that version from the samples it received. A version the recorder cannot
//! find is counted as missing (it would mean a sample was lost) and written as `?`.
//!
//! With assemblies only the system's own components are recorded (the bus): they stay the
//! same whatever the assembly, so a run with switches has one trace.

use std::io::Write;

use modbot_ipc_schema::grid::PortValue;

use super::spec::GridSpec;
use super::trace::TraceWriter;
use super::versions::{self, Versions};
use super::wire;
use modbot_core::transport::channels::Channels;
use modbot_core::transport::TransportError;

/// How many components of `spec` a trace records: the system's own with assemblies, else all.
pub fn recorded(spec: &GridSpec) -> usize {
    spec.assembly
        .as_ref()
        .map_or(spec.components.len(), |a| a.base)
}

/// Writes the trace of a run.
pub struct Recorder<W: Write> {
    comps: Vec<Versions>,
    writer: TraceWriter<W>,
    /// Versions that were not found when needed.
    pub missing: u64,
}

impl<W: Write> Recorder<W> {
    /// Subscribes to every component's outputs on `ch`, writing the trace to `out`.
    pub fn new(ch: &dyn Channels, spec: &GridSpec, out: W) -> Result<Recorder<W>, TransportError> {
        let comps = (0..recorded(spec))
            .map(|c| {
                let zeros: Vec<PortValue> = spec.output_types(c).iter().map(|t| t.zero()).collect();
                let period = spec.components[c].period;
                Ok(Versions::new(
                    wire::out_subscriber(ch, &spec.out_service(c))?,
                    zeros,
                    versions::depth(period, period),
                ))
            })
            .collect::<Result<Vec<_>, TransportError>>()?;
        Ok(Recorder {
            comps,
            writer: TraceWriter::of_first(out, spec, recorded(spec)),
            missing: 0,
        })
    }

    /// The same recorder writing the grid's state hash every `every` ticks and after the last
    /// (0: never; see [`TraceWriter::with_state_hash_every`]).
    pub fn with_state_hash_every(mut self, every: u64) -> Recorder<W> {
        self.writer = self.writer.with_state_hash_every(every);
        self
    }

    /// Records tick `n`, where component c's valid outputs are version `valid_from[c]`, and
    /// the grid's state hash at n is `state_hash`.
    pub fn tick(&mut self, n: u64, valid_from: &[u64], state_hash: u64) -> std::io::Result<()> {
        for (c, v) in self.comps.iter_mut().enumerate() {
            let want = valid_from.get(c).copied().unwrap_or(0);
            match v.get(want) {
                Some(values) => self.writer.tick(n, c, values)?,
                // The trace cannot say what was valid: its values are `?` on this line, and
                // the comparison with the reference fails there.
                None => self.missing += 1,
            }
        }
        self.writer.end_tick(n)?;
        self.writer.state_hash(n, state_hash)
    }

    /// Flushes the trace.
    pub fn finish(self) -> std::io::Result<W> {
        self.writer.finish()
    }
}
