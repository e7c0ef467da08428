//! The writer thread: takes the rows the real-time thread recorded, gathers them into a batch
//! per dataset, and appends the batch to the file — when it holds [`Flush::rows`] rows, or
//! [`Flush::interval`] after the last append, whichever comes first. So what a SIGKILL of the
//! recorder loses is what was recorded in the last `interval` (in real time) or the last
//! `rows` rows (in lockstep, where the real-time side waits for a free row: see
//! [`crate::component`]), plus the rows in the pool.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use modbot_grid::component::PortType;

use super::file::{FileError, RecordFile};
use super::rows::{Rows, HEAD_WORDS};

/// When a batch is appended.
#[derive(Debug, Clone, Copy)]
pub struct Flush {
    /// A batch of this many rows is appended at once.
    pub rows: usize,
    /// A batch is appended at most this long after the last one, however small.
    pub interval: Duration,
}

/// The writer thread of a recording.
pub struct Writer {
    thread: Option<JoinHandle<Result<u64, FileError>>>,
    stop: Arc<AtomicBool>,
    /// Whether the thread still takes rows (it stops on an error writing the file).
    alive: Arc<AtomicBool>,
}

/// The batch being gathered: per dataset, its words (an f64 as its bits).
struct Batch {
    /// Words per signal.
    widths: Vec<usize>,
    base_period_s: f64,
    /// Per dataset: the signals, then generation, time, tick.
    columns: Vec<Vec<u64>>,
    rows: usize,
}

impl Batch {
    fn new(types: &[PortType], base_period_s: f64) -> Batch {
        let widths: Vec<usize> = types.iter().map(|t| t.wire_len() / 8).collect();
        let columns = vec![Vec::new(); widths.len() + 3];
        Batch {
            widths,
            base_period_s,
            columns,
            rows: 0,
        }
    }

    fn add(&mut self, row: &[u64]) {
        let n = self.widths.len();
        let mut at = HEAD_WORDS;
        for (column, &width) in self.columns.iter_mut().zip(&self.widths) {
            match row.get(at..at + width) {
                Some(words) => column.extend_from_slice(words),
                None => column.resize(column.len() + width, 0),
            }
            at += width;
        }
        let (tick, generation) = (row[0], row[1]);
        self.columns[n].push(generation);
        let time = tick as f64 * self.base_period_s;
        self.columns[n + 1].push(time.to_bits());
        self.columns[n + 2].push(tick);
        self.rows += 1;
    }

    fn clear(&mut self) {
        self.columns.iter_mut().for_each(Vec::clear);
        self.rows = 0;
    }
}

impl Writer {
    /// Starts the thread that writes the rows of `rows` (whose signals are of `types`) to
    /// `file`. Start it from a thread of normal priority: it inherits the scheduling.
    pub fn spawn(
        rows: Arc<Rows>,
        mut file: RecordFile,
        types: &[PortType],
        base_period_s: f64,
        flush: Flush,
    ) -> std::io::Result<Writer> {
        let stop = Arc::new(AtomicBool::new(false));
        let alive = Arc::new(AtomicBool::new(true));
        let mut batch = Batch::new(types, base_period_s);
        let (stopping, living) = (stop.clone(), alive.clone());
        let thread = std::thread::Builder::new()
            .name("record writer".into())
            .spawn(move || {
                let written = write_all(&rows, &mut file, &mut batch, flush, &stopping);
                living.store(false, Ordering::Release);
                let closed = file.close();
                let written = written?;
                closed.map(|()| written)
            })?;
        Ok(Writer {
            thread: Some(thread),
            stop,
            alive,
        })
    }

    /// Wakes the thread (rows are waiting). Takes no lock.
    pub fn wake(&self) {
        if let Some(t) = &self.thread {
            t.thread().unpark();
        }
    }

    /// Whether the thread still takes rows.
    pub fn alive(&self) -> bool {
        self.alive.load(Ordering::Acquire)
    }

    /// Writes what is left, closes the file and joins the thread: the rows written, or why
    /// the file could not be written.
    pub fn finish(&mut self) -> Result<u64, FileError> {
        self.stop.store(true, Ordering::Release);
        self.wake();
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => {
                tracing::error!("the record writer thread panicked");
                Ok(0)
            }
            None => Ok(0),
        }
    }
}

impl Drop for Writer {
    fn drop(&mut self) {
        if let Err(e) = self.finish() {
            tracing::error!("the recording is incomplete: {e}");
        }
    }
}

/// The thread's loop: gathers and appends until told to stop and every row is written.
fn write_all(
    rows: &Rows,
    file: &mut RecordFile,
    batch: &mut Batch,
    flush: Flush,
    stop: &AtomicBool,
) -> Result<u64, FileError> {
    let mut last = Instant::now();
    let mut written = 0u64;
    loop {
        let stopping = stop.load(Ordering::Acquire);
        while batch.rows < flush.rows {
            let Some(row) = rows.pop() else { break };
            batch.add(&row);
            rows.give_back(row);
        }
        let due = batch.rows >= flush.rows
            || (batch.rows > 0 && (stopping || last.elapsed() >= flush.interval));
        if due {
            file.append(batch.rows, &batch.columns)?;
            written += batch.rows as u64;
            batch.clear();
            last = Instant::now();
            continue;
        }
        if stopping && rows.pending() == 0 {
            return Ok(written);
        }
        // Woken by the real-time side when a batch is ready; looks again well within the
        // interval otherwise.
        std::thread::park_timeout(flush.interval / 5);
    }
}
