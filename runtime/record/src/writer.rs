//! The writer thread: takes the rows the real-time thread recorded, gathers them into a batch
//! per dataset, and appends the batch to the file — when it holds [`Flush::rows`] rows, or
//! [`Flush::interval`] after the last append, whichever comes first. So what a SIGKILL of the
//! recorder loses is what was recorded in the last `interval` (in real time) or the last
//! `rows` rows (in lockstep, where the real-time side waits for a free row: see
//! [`crate::component`]), plus the rows in the pool.
//!
//! It writes one file at a time, or none: a program starts and stops recordings
//! ([`crate::control`]); rows that come while no file is open are given back unwritten.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam::channel::{unbounded, Receiver};
use modbot_grid::record_type::Signal;

use super::batch::Batch;
use super::control::{self, Control, ControlError, Handle, Stopped};
use super::file::{FileError, Header, RecordFile};
use super::rows::Rows;

/// When a batch is appended.
#[derive(Debug, Clone, Copy)]
pub struct Flush {
    /// A batch of this many rows is appended at once (and a chunk of the file holds as many).
    pub rows: usize,
    /// A batch is appended at most this long after the last one, however small.
    pub interval: Duration,
}

/// What the recording is of: the signals, the file's header, the grid's base period.
pub struct Recording {
    pub signals: Vec<Signal>,
    pub header: Header,
    pub base_period_s: f64,
}

/// The writer thread of a recorder.
pub struct Writer {
    thread: Option<JoinHandle<Result<u64, FileError>>>,
    stop: Arc<AtomicBool>,
    /// Whether the thread still takes rows (it stops on an error writing the file).
    alive: Arc<AtomicBool>,
    /// Its requests ([`crate::control`]); registered while the writer lives.
    _handle: Arc<Handle>,
}

/// The file being written and its batch.
struct Open {
    file: RecordFile,
    batch: Batch,
    written: u64,
}

/// The thread's state.
struct Thread {
    rows: Arc<Rows>,
    recording: Recording,
    flush: Flush,
    open: Option<Open>,
    requests: Receiver<Control>,
    /// Rows written to every file so far.
    written: u64,
}

impl Writer {
    /// Starts the thread that writes the rows of `rows` to `file` (`None`: to no file until a
    /// program starts a recording). Start it from a thread of normal priority: it inherits the
    /// scheduling.
    pub fn spawn(
        rows: Arc<Rows>,
        file: Option<RecordFile>,
        recording: Recording,
        flush: Flush,
    ) -> std::io::Result<Writer> {
        let stop = Arc::new(AtomicBool::new(false));
        let alive = Arc::new(AtomicBool::new(true));
        let (requests, requested) = unbounded();
        let all: Vec<usize> = (0..recording.signals.len()).collect();
        let open = file.map(|file| Open {
            batch: batch_of(&recording, &all),
            file,
            written: 0,
        });
        let mut state = Thread {
            rows,
            recording,
            flush,
            open,
            requests: requested,
            written: 0,
        };
        let (stopping, living) = (stop.clone(), alive.clone());
        let thread = std::thread::Builder::new()
            .name("record writer".into())
            .spawn(move || {
                let written = state.run(&stopping);
                living.store(false, Ordering::Release);
                let closed = state.close().map(|_| ());
                let written = written?;
                closed.map(|()| written)
            })?;
        let handle = Arc::new(Handle {
            requests,
            thread: thread.thread().clone(),
        });
        control::register(&handle);
        Ok(Writer {
            thread: Some(thread),
            stop,
            alive,
            _handle: handle,
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

/// A batch of the recording's signals at `recorded`.
fn batch_of(recording: &Recording, recorded: &[usize]) -> Batch {
    let types: Vec<_> = recording.signals.iter().map(|s| s.ty).collect();
    Batch::new(&types, recorded, recording.base_period_s)
}

impl Thread {
    /// Gathers and appends until told to stop and every row is written.
    fn run(&mut self, stop: &AtomicBool) -> Result<u64, FileError> {
        let mut last = Instant::now();
        loop {
            let stopping = stop.load(Ordering::Acquire);
            while let Ok(request) = self.requests.try_recv() {
                self.serve(request);
            }
            let gathered = self.gather();
            let due = gathered >= self.flush.rows
                || (gathered > 0 && (stopping || last.elapsed() >= self.flush.interval));
            if due {
                self.append()?;
                last = Instant::now();
                continue;
            }
            if stopping && self.rows.pending() == 0 {
                return Ok(self.written + self.open.as_ref().map_or(0, |o| o.written));
            }
            // Woken by the real-time side when a batch is ready, or by a request; looks again
            // well within the interval otherwise.
            std::thread::park_timeout(self.flush.interval / 5);
        }
    }

    /// Takes waiting rows into the batch (up to a batch), or gives them back unwritten when
    /// no file is open; the rows in the batch.
    fn gather(&mut self) -> usize {
        let Some(open) = self.open.as_mut() else {
            while let Some(row) = self.rows.pop() {
                self.rows.give_back(row);
            }
            return 0;
        };
        while open.batch.rows < self.flush.rows {
            let Some(row) = self.rows.pop() else { break };
            open.batch.add(&row);
            self.rows.give_back(row);
        }
        open.batch.rows
    }

    fn append(&mut self) -> Result<(), FileError> {
        if let Some(open) = self.open.as_mut() {
            open.file.append(open.batch.rows, &open.batch.columns)?;
            open.written += open.batch.rows as u64;
            open.batch.clear();
        }
        Ok(())
    }

    /// Writes the batch at hand and the rows waiting, and closes the file: what it was.
    fn close(&mut self) -> Result<Option<Stopped>, FileError> {
        let appended = loop {
            self.gather();
            if let Err(e) = self.append() {
                break Err(e);
            }
            if self.rows.pending() == 0 {
                break Ok(());
            }
        };
        let Some(open) = self.open.take() else {
            return appended.map(|()| None);
        };
        let path = open.file.path().to_path_buf();
        let closed = open.file.close();
        appended?;
        closed?;
        self.written += open.written;
        Ok(Some(Stopped {
            path,
            rows: open.written,
        }))
    }

    fn serve(&mut self, request: Control) {
        match request {
            Control::Start {
                file,
                signals,
                answer,
            } => {
                let _ = answer.send(self.start(&file, &signals));
            }
            Control::Stop { answer } => {
                let stopped = match self.close() {
                    Ok(Some(stopped)) => Ok(stopped),
                    Ok(None) => Err(ControlError::NotRecording),
                    Err(e) => Err(e.into()),
                };
                if let Ok(s) = &stopped {
                    tracing::info!("recorded {} row(s) to {}", s.rows, s.path.display());
                }
                let _ = answer.send(stopped);
            }
        }
    }

    /// Closes the file being written, if any, and opens `file` for `signals`.
    fn start(&mut self, file: &Path, signals: &[String]) -> Result<PathBuf, ControlError> {
        let recorded = self.chosen(signals)?;
        self.close()?;
        let path = super::path::choose(file);
        let chosen: Vec<Signal> = recorded
            .iter()
            .map(|&i| self.recording.signals[i].clone())
            .collect();
        let chunk = self.flush.rows as u64;
        let created = RecordFile::create(&path, &chosen, &self.recording.header, chunk)?;
        self.open = Some(Open {
            batch: batch_of(&self.recording, &recorded),
            file: created,
            written: 0,
        });
        tracing::info!("recording {} signal(s) to {}", chosen.len(), path.display());
        Ok(path)
    }

    /// The indices of `signals` among the recording's (empty: all of them).
    fn chosen(&self, signals: &[String]) -> Result<Vec<usize>, ControlError> {
        let all = &self.recording.signals;
        if signals.is_empty() {
            return Ok((0..all.len()).collect());
        }
        signals
            .iter()
            .map(|name| {
                all.iter().position(|s| s.name == *name).ok_or_else(|| {
                    let known: Vec<&str> = all.iter().map(|s| s.name.as_str()).collect();
                    ControlError::UnknownSignal {
                        name: name.clone(),
                        known: known.join(", "),
                    }
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_grid::component::{PortType, PortValue};

    #[test]
    fn a_program_starts_and_stops_a_recording_of_chosen_signals_and_rows_in_between_are_written() {
        let dir = std::env::temp_dir().join(format!("modbot-record-ctl-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let signals = vec![
            Signal {
                name: "a.y".into(),
                ty: PortType::F64,
            },
            Signal {
                name: "b.q".into(),
                ty: PortType::F64s(2),
            },
        ];
        let rows = Arc::new(Rows::new(64, crate::rows::HEAD_WORDS + 3));
        let recording = Recording {
            signals,
            header: Header::default(),
            base_period_s: 0.001,
        };
        let flush = Flush {
            rows: 10,
            interval: Duration::from_millis(40),
        };
        let mut sut = Writer::spawn(rows.clone(), None, recording, flush).unwrap();
        let values = |t: u64| [PortValue::F64(t as f64), PortValue::F64s(vec![1.0, -1.0])];
        // Before a recording starts, rows are given back unwritten.
        for tick in 0..5 {
            assert!(rows.push(tick, 0, tick * 7, &values(tick)));
        }
        assert!(
            control::start(dir.join("run.h5"), vec!["nope.x".into()], &mut || ())
                .unwrap_err()
                .to_string()
                .contains("signal 'nope.x' is not the recorder's: it records a.y, b.q")
        );
        let path = control::start(dir.join("run.h5"), vec!["b.q".into()], &mut || ()).unwrap();
        for tick in 5..30 {
            while !rows.push(tick, 0, tick * 7, &values(tick)) {
                sut.wake();
                std::thread::sleep(Duration::from_millis(1));
            }
        }
        let stopped = control::stop(&mut || ()).unwrap();
        assert_eq!(
            stopped,
            Stopped {
                path: path.clone(),
                rows: 25
            }
        );
        assert!(matches!(
            control::stop(&mut || ()).unwrap_err(),
            control::ControlError::NotRecording
        ));
        sut.finish().unwrap();
        let file = hdf5::File::open(&path).unwrap();
        let mut names = file.member_names().unwrap();
        names.sort();
        assert_eq!(names, ["b.q", "generation", "state_hash", "tick", "time"]);
        let tick: Vec<i64> = file.dataset("tick").unwrap().read_raw().unwrap();
        assert_eq!(tick, (5..30).collect::<Vec<i64>>());
        assert_eq!(file.dataset("b.q").unwrap().shape(), vec![25, 2]);
        drop(file);
        let q = crate::read::read_signal(&path, "b.q", 10, 12).unwrap();
        assert_eq!(
            (&q.ticks[..], q.width, q.row(2)),
            (&[10, 11, 12][..], 2, &[1.0, -1.0][..])
        );
        let hashes = crate::read::read_state_hash(&path).unwrap().unwrap();
        assert_eq!(hashes, (5..30).map(|t| t * 7).collect::<Vec<u64>>());
        let t = crate::read::read_signal(&path, "tick", 28, 99).unwrap();
        assert_eq!((t.width, t.values), (1, vec![28.0, 29.0]));
        let missing = crate::read::read_signal(&path, "a.y", 0, 99).unwrap_err();
        assert!(
            missing.to_string().contains("has no signal 'a.y'"),
            "{missing}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
