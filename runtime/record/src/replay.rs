//! The components a replay puts in place of a recorded run's sources and recorder
//! (`modbot replay`, with `modbot_grid::replay`): a [`Player`] of a source's recorded outputs,
//! and a [`Comparer`] that gets what the recorder got — the recorded signals as valid at each
//! tick, computed again — and compares it with the recording's row, bit for bit, with the
//! generation and the grid's state hash; for a what-if (`--param`) it also writes the replayed
//! rows to a recording of their own.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use modbot_grid::component::{Component, PortType, PortValue, Released};
use modbot_grid::record_type::Signal;

use super::batch::Batch;
use super::file::{Header, RecordFile};
use super::read::{read_signal, read_state_hash, ReadError, Series};
use super::rows::{put_values, HEAD_WORDS};

/// A recording's rows, read into memory for a replay.
pub struct Recording {
    /// The tick of each row (ascending).
    ticks: Vec<i64>,
    generation: Vec<f64>,
    state_hash: Option<Vec<u64>>,
    /// Each signal read: (name, values).
    signals: Vec<(String, Series)>,
}

impl Recording {
    /// Reads `signals` of the recording at `path`, and its ticks, generations and state hashes.
    pub fn read(path: &Path, signals: &[String]) -> Result<Recording, ReadError> {
        let all = |s: &str| read_signal(path, s, i64::MIN, i64::MAX);
        let ticks = all("tick")?.ticks;
        let generation = all("generation")?.values;
        let state_hash = read_state_hash(path)?;
        let signals = signals
            .iter()
            .map(|s| Ok((s.clone(), all(s)?)))
            .collect::<Result<Vec<_>, ReadError>>()?;
        Ok(Recording {
            ticks,
            generation,
            state_hash,
            signals,
        })
    }

    /// The last tick recorded.
    pub fn last_tick(&self) -> Option<u64> {
        self.ticks.last().and_then(|t| u64::try_from(*t).ok())
    }

    /// The row of tick `n`.
    fn row(&self, n: u64) -> Option<usize> {
        let n = i64::try_from(n).ok()?;
        self.ticks.binary_search(&n).ok()
    }

    fn series(&self, name: &str) -> Option<&Series> {
        self.signals.iter().find(|(s, _)| s == name).map(|(_, s)| s)
    }
}

/// Writes row `r` of `series` into `value` (of its port type).
fn put(value: &mut PortValue, series: &Series, r: usize) {
    let row = series.row(r);
    match value {
        PortValue::F64(x) => *x = row[0],
        PortValue::I64(i) => *i = row[0] as i64,
        PortValue::Bool(b) => *b = row[0] != 0.0,
        PortValue::F64s(xs) => {
            let n = xs.len().min(row.len());
            xs[..n].copy_from_slice(&row[..n]);
        }
    }
}

/// A source played back: released at n, it puts out what the recording says was valid at
/// n + its period (its outputs become valid then, as the real source's did).
pub struct Player {
    recording: Arc<Recording>,
    /// Told of a tick the recording has no row for.
    verdict: Arc<Mutex<Verdict>>,
    /// The recorded signal of each output (`comp.port`).
    outputs: Vec<String>,
    period: u64,
}

impl Player {
    /// A player of component `name`'s outputs `outputs` (port names), released every
    /// `period` ticks; `None` names the first output the recording lacks.
    pub fn new(
        recording: Arc<Recording>,
        verdict: Arc<Mutex<Verdict>>,
        name: &str,
        outputs: &[&str],
        period: u64,
    ) -> Result<Player, String> {
        let outputs: Vec<String> = outputs.iter().map(|p| format!("{name}.{p}")).collect();
        if let Some(missing) = outputs.iter().find(|s| recording.series(s).is_none()) {
            return Err(missing.clone());
        }
        Ok(Player {
            recording,
            verdict,
            outputs,
            period,
        })
    }

    fn put_row(&self, n: u64, outputs: &mut [PortValue]) {
        let Some(r) = self.recording.row(n) else {
            // Past the recording's end nothing reads it any more; inside it, the recorder
            // dropped the row (a real-time overrun) and what the source put out is unknown.
            if self.recording.last_tick().is_some_and(|last| n <= last) {
                if let Ok(mut v) = self.verdict.lock() {
                    v.gap.get_or_insert(n);
                }
            }
            return;
        };
        for (value, name) in outputs.iter_mut().zip(&self.outputs) {
            if let Some(series) = self.recording.series(name) {
                put(value, series, r);
            }
        }
    }
}

impl Component for Player {
    fn initial_outputs(&mut self, outputs: &mut [PortValue]) {
        self.put_row(0, outputs);
    }

    fn step(&mut self, rel: &Released, _: &[PortValue], outputs: &mut [PortValue]) {
        self.put_row(rel.tick.0 + self.period, outputs);
    }

    fn track(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        self.step(rel, inputs, outputs);
    }
}

/// Where a replay first parted from its recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Divergence {
    pub tick: u64,
    /// The generation running then.
    pub generation: u16,
    /// Each signal that differs at that tick: (signal, index in its row, recorded, replayed).
    /// Empty: only the state hash differs.
    pub signals: Vec<(String, usize, f64, f64)>,
    /// The state hashes (recorded, replayed), when they differ.
    pub state_hash: Option<(u64, u64)>,
}

/// What the comparer found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Verdict {
    /// Rows compared.
    pub rows: u64,
    /// The last tick compared.
    pub last: Option<u64>,
    /// The first tick that differs, if any.
    pub first: Option<Divergence>,
    /// A row the recording lacks, at this tick (the recorder dropped it).
    pub missing: Option<u64>,
    /// The first tick whose row a source's player needed and the recording lacks (a
    /// real-time recorder that overran): the replay ends before it.
    pub gap: Option<u64>,
}

/// In place of the recorder: compares what it gets with the recording's row of the tick.
pub struct Comparer {
    recording: Arc<Recording>,
    signals: Vec<Signal>,
    verdict: Arc<Mutex<Verdict>>,
    what_if: Option<WhatIf>,
}

/// The replayed rows written to a recording of their own.
struct WhatIf {
    file: RecordFile,
    batch: Batch,
    row: Vec<u64>,
}

impl Comparer {
    /// A comparer of `signals` (the recorder's inputs, in order) with `recording`, telling
    /// `verdict`; with `what_if`, writing the replayed rows to that file (`base_period_s` for
    /// its times).
    pub fn new(
        recording: Arc<Recording>,
        signals: Vec<Signal>,
        verdict: Arc<Mutex<Verdict>>,
        what_if: Option<(PathBuf, f64)>,
    ) -> Result<Comparer, super::file::FileError> {
        let what_if = match what_if {
            Some((path, base_period_s)) => {
                let header = Header {
                    base_period_s,
                    period_s: base_period_s,
                    ..Header::default()
                };
                let types: Vec<PortType> = signals.iter().map(|s| s.ty).collect();
                let all: Vec<usize> = (0..signals.len()).collect();
                let width = HEAD_WORDS + types.iter().map(|t| t.wire_len() / 8).sum::<usize>();
                Some(WhatIf {
                    file: RecordFile::create(&path, &signals, &header, 1000)?,
                    batch: Batch::new(&types, &all, base_period_s),
                    row: vec![0; width],
                })
            }
            None => None,
        };
        Ok(Comparer {
            recording,
            signals,
            verdict,
            what_if,
        })
    }

    fn compare(&self, rel: &Released, inputs: &[PortValue]) -> Result<Option<Divergence>, ()> {
        let rec = &self.recording;
        let Some(r) = rec.row(rel.tick.0) else {
            return Err(());
        };
        let mut differs = Vec::new();
        for (signal, value) in self.signals.iter().zip(inputs) {
            let Some(series) = rec.series(&signal.name) else {
                continue;
            };
            let recorded = series.row(r);
            let replayed: &[f64] = match value {
                PortValue::F64s(xs) => xs,
                _ => &[value_f64(value)],
            };
            for (i, (a, b)) in recorded.iter().zip(replayed).enumerate() {
                if a.to_bits() != b.to_bits() {
                    differs.push((signal.name.clone(), i, *a, *b));
                }
            }
        }
        let generation = rec.generation.get(r).copied().unwrap_or(0.0);
        if generation != f64::from(rel.generation.0) {
            differs.push((
                "generation".into(),
                0,
                generation,
                f64::from(rel.generation.0),
            ));
        }
        let hashes = rec
            .state_hash
            .as_ref()
            .and_then(|h| h.get(r))
            .filter(|h| **h != rel.state_hash)
            .map(|h| (*h, rel.state_hash));
        if differs.is_empty() && hashes.is_none() {
            return Ok(None);
        }
        Ok(Some(Divergence {
            tick: rel.tick.0,
            generation: rel.generation.0,
            signals: differs,
            state_hash: hashes,
        }))
    }

    fn write(&mut self, rel: &Released, inputs: &[PortValue]) {
        let Some(w) = self.what_if.as_mut() else {
            return;
        };
        w.row[0] = rel.tick.0;
        w.row[1] = u64::from(rel.generation.0);
        w.row[2] = rel.state_hash;
        put_values(&mut w.row, inputs);
        w.batch.add(&w.row);
        if w.batch.rows >= 1000 {
            flush(w);
        }
    }
}

fn flush(w: &mut WhatIf) {
    if let Err(e) = w.file.append(w.batch.rows, &w.batch.columns) {
        tracing::error!("the what-if recording is incomplete: {e}");
    }
    w.batch.clear();
}

/// A scalar port value as the recording holds it (an i64 or a bool as a number).
fn value_f64(v: &PortValue) -> f64 {
    match v {
        PortValue::F64(x) => *x,
        PortValue::I64(i) => *i as f64,
        PortValue::Bool(b) => f64::from(u8::from(*b)),
        PortValue::F64s(xs) => xs.first().copied().unwrap_or(0.0),
    }
}

impl Component for Comparer {
    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let found = self.compare(rel, inputs);
        self.write(rel, inputs);
        if let Some(out) = outputs.first_mut() {
            *out = PortValue::I64(0);
        }
        let Ok(mut verdict) = self.verdict.lock() else {
            return;
        };
        match found {
            Err(()) => {
                verdict.missing.get_or_insert(rel.tick.0);
            }
            Ok(d) => {
                verdict.rows += 1;
                verdict.last = Some(rel.tick.0);
                if verdict.first.is_none() {
                    verdict.first = d;
                }
            }
        }
    }

    /// Nothing, as the recorder (see its `state_hash`).
    fn state_hash(&self, _: &[PortValue], _: &mut modbot_grid::StateHasher) {}

    fn terminate(&mut self) {
        if let Some(mut w) = self.what_if.take() {
            flush(&mut w);
            if let Err(e) = w.file.close() {
                tracing::error!("the what-if recording is incomplete: {e}");
            }
        }
    }
}
