//! The `record` component: at every release, its inputs (the signals as valid at the tick) go
//! into a row of the pool ([`crate::rows`]); the writer thread ([`crate::writer`]) appends them
//! to the file. The release takes no lock, does no I/O and allocates nothing; when every row is
//! full it drops the row and counts it (output `dropped`) — unless `lossless` (the lockstep
//! clock), where it waits for the writer.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use modbot_grid::component::{
    Component, ComponentError, ParamError, Params, PortValue, Registry, Released, BASE_PERIOD_S,
    PERIOD_S,
};
use modbot_grid::record_type::{self, Signal};

use super::file::{Header, RecordFile};
use super::mark::Unmarked;
use super::rows::{Rows, HEAD_WORDS};
use super::writer::{Flush, Recording, Writer};

/// A batch is appended at least this often, and holds at most this much of the run (a chunk
/// of the file): what a SIGKILL loses, with the rows in the pool.
const FLUSH_INTERVAL: Duration = Duration::from_millis(40);
/// In real time, the pool holds this much of the run, for a writer held up by the disk.
const POOL_TIME: Duration = Duration::from_secs(2);
/// The pool holds at most this many bytes.
const POOL_BYTES: usize = 16 << 20;
/// In lossless mode, how long a release waits before it looks for a free row again.
const LOSSLESS_WAIT: Duration = Duration::from_micros(50);

/// Adds the `record` component, made by this process, to `registry` (the program
/// `modbot-recorder`).
pub fn register(registry: &mut Registry) {
    registry.register(record_type::info, make);
}

/// The description files and their texts: as the system was loaded (`source_texts`), or else
/// as the files hold them now.
fn sources(p: &Params) -> Result<Vec<(String, String)>, ComponentError> {
    let paths: Vec<&str> = p.text(record_type::SOURCES)?.lines().collect();
    let texts = record_type::parse_texts(p.text(record_type::SOURCE_TEXTS)?);
    Ok(paths
        .iter()
        .enumerate()
        .map(|(i, path)| {
            let text = match texts.get(i) {
                Some(text) if texts.len() == paths.len() => (*text).to_owned(),
                _ => std::fs::read_to_string(path)
                    .unwrap_or_else(|e| format!("(the description could not be read: {e})")),
            };
            ((*path).to_owned(), text)
        })
        .collect())
}

/// A recorder for these (complete) params: creates its file and starts its writer.
pub fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    let signals = record_type::parse_signals(p.text(record_type::SIGNALS)?)?;
    let (base_period_s, period_s) = (p.f64(BASE_PERIOD_S)?, p.f64(PERIOD_S)?);
    if period_s.is_nan() || period_s <= 0.0 {
        return Err(
            ParamError::invalid(PERIOD_S, format!("must be positive, not {period_s}")).into(),
        );
    }
    let lossless = p.bool(record_type::LOSSLESS)?;
    let header = Header {
        base_period_s,
        period_s,
        units: record_type::parse_units(p.text(record_type::UNITS)?),
        sources: sources(p)?,
    };
    let width = HEAD_WORDS + signals.iter().map(|s| s.ty.wire_len() / 8).sum::<usize>();
    let per_second = 1.0 / period_s;
    let flush_rows = ((FLUSH_INTERVAL.as_secs_f64() * per_second) as usize).clamp(1, 4096);
    let flush = Flush {
        rows: flush_rows,
        interval: FLUSH_INTERVAL,
    };
    // Without a file, it records only when a program starts a recording.
    let wanted = p.text(record_type::FILE)?;
    let file = match wanted {
        "" => None,
        wanted => {
            let wanted = Path::new(wanted);
            let path = super::path::choose(wanted);
            unmark_earlier(wanted, &path);
            let file = RecordFile::create(&path, &signals, &header, flush_rows as u64)
                .map_err(|e| ComponentError::param_refused(record_type::FILE, e))?;
            Some(file)
        }
    };
    let path = file.as_ref().map(|f| f.path().to_path_buf());
    let capacity = if lossless {
        flush_rows
    } else {
        let rows = (POOL_TIME.as_secs_f64() * per_second) as usize;
        rows.clamp(64, (POOL_BYTES / (8 * width)).max(64))
    };
    let rows = Arc::new(Rows::new(capacity, width));
    let recording = Recording {
        signals: signals.clone(),
        header,
        base_period_s,
    };
    let writer =
        Writer::spawn(rows.clone(), file, recording, flush).map_err(ComponentError::other)?;
    let mode = if lossless { "lossless" } else { "never waits" };
    match path {
        Some(path) => tracing::info!(
            "recording {} signal(s) to {} ({mode})",
            signals.len(),
            path.display()
        ),
        None => tracing::info!(
            "{} signal(s) to record when a program starts a recording ({mode})",
            signals.len()
        ),
    }
    Ok(Box::new(Recorder {
        signals,
        rows,
        writer,
        flush_rows,
        lossless,
        dropped: 0,
    }))
}

/// Takes the writer mark off the files of this run written before `path` (for a declaration
/// naming `wanted`) whose writers are gone: a recorder that was killed left its mark there.
fn unmark_earlier(wanted: &Path, path: &Path) {
    for earlier in super::path::candidates(wanted).take_while(|p| p != path) {
        match super::mark::unmark(&earlier) {
            Ok(Unmarked::Cleared) => tracing::info!(
                "{}: took off the writer mark a recorder that died left",
                earlier.display()
            ),
            Ok(Unmarked::Clean | Unmarked::WriterAlive) => {}
            Err(e) => tracing::warn!("{e}"),
        }
    }
}

struct Recorder {
    /// What it records (for messages).
    signals: Vec<Signal>,
    rows: Arc<Rows>,
    writer: Writer,
    /// The writer is woken when this many rows wait.
    flush_rows: usize,
    /// Wait for a free row rather than drop one.
    lossless: bool,
    /// Rows dropped so far.
    dropped: i64,
}

impl Component for Recorder {
    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let (tick, generation) = (rel.tick.0, rel.generation.0);
        let mut recorded = self.rows.push(tick, generation, rel.state_hash, inputs);
        while !recorded && self.lossless && self.writer.alive() {
            self.writer.wake();
            std::thread::sleep(LOSSLESS_WAIT);
            recorded = self.rows.push(tick, generation, rel.state_hash, inputs);
        }
        if !recorded {
            self.dropped += 1;
        }
        if self.rows.pending() >= self.flush_rows {
            self.writer.wake();
        }
        outputs[0] = PortValue::I64(self.dropped);
    }

    /// Nothing: it observes the controlled system and is not part of it, and its count of
    /// dropped rows depends on the disk. A run with a recorder hashes as one without.
    fn state_hash(&self, _: &[PortValue], _: &mut modbot_grid::StateHasher) {}

    fn terminate(&mut self) {
        match self.writer.finish() {
            Ok(rows) => tracing::info!(
                "recorded {rows} row(s) of {} signal(s), {} dropped",
                self.signals.len(),
                self.dropped
            ),
            Err(e) => tracing::error!("the recording is incomplete: {e}"),
        }
    }
}
