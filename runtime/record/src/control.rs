//! Starting and stopping a recording while the recorder runs: a robot program's `record { }`
//! and `stop_record { }` (MoRC's programs record the runs they make) reach the recorder through
//! methods of its host process, `start` and `stop` (the program `modbot-recorder`), which
//! hand a [`Control`] to the writer thread and wait for its answer. The real-time side is not
//! involved: its rows go on flowing, and the writer writes them to the file of the moment, or
//! to none.
//!
//! A recorder declared without a file (`record { signals = { ... } }` in a system
//! description, without `modbot up --record`) records only between a `start` and a `stop`.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, Weak};
use std::time::{Duration, Instant};

use crossbeam::channel::{bounded, RecvTimeoutError, Sender};

use crate::file::FileError;

/// Why a recording cannot be started or stopped.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    #[error("this host runs no recorder")]
    NoRecorder,
    #[error("this host runs {0} recorders: give each a host of its own (record {{ host = ... }})")]
    SeveralRecorders(usize),
    #[error("the recorder's writer has stopped")]
    WriterStopped,
    #[error("the recorder's writer stopped before it answered")]
    NoAnswer,
    #[error("the recorder's writer did not answer within {} s", .0.as_secs())]
    Timeout(Duration),
    #[error("signal '{name}' is not the recorder's: it records {known}")]
    UnknownSignal { name: String, known: String },
    #[error("nothing is being recorded")]
    NotRecording,
    #[error(transparent)]
    File(#[from] FileError),
}

/// How long a method waits for the writer (it finishes the batch at hand, closes a file,
/// creates one).
const ANSWER: Duration = Duration::from_secs(30);

/// How often a method waiting for the writer calls back (its module's heartbeat).
const BETWEEN: Duration = Duration::from_millis(50);

/// What a recording was, when it stops.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stopped {
    pub path: PathBuf,
    /// Rows written to it.
    pub rows: u64,
}

/// A request to the writer thread.
pub enum Control {
    /// Record `signals` (names among the recorder's; empty: all) to `file` from the next row
    /// on, closing the file written until then; answers the file written (a file of this run
    /// is not replaced: [`crate::path`]).
    Start {
        file: PathBuf,
        signals: Vec<String>,
        answer: Sender<Result<PathBuf, ControlError>>,
    },
    /// Writes what is gathered, closes the file; answers what it was.
    Stop {
        answer: Sender<Result<Stopped, ControlError>>,
    },
}

/// The way to a running recorder's writer.
pub struct Handle {
    pub(crate) requests: Sender<Control>,
    /// The writer thread, woken when a request waits.
    pub(crate) thread: std::thread::Thread,
}

/// The recorders this process runs (one per recorder component), newest last.
static RUNNING: Mutex<Vec<Weak<Handle>>> = Mutex::new(Vec::new());

/// Makes `handle` reachable by [`start`] and [`stop`] for as long as it lives.
pub(crate) fn register(handle: &Arc<Handle>) {
    let mut running = RUNNING.lock().unwrap_or_else(|p| p.into_inner());
    running.retain(|h| h.strong_count() > 0);
    running.push(Arc::downgrade(handle));
}

/// The one recorder this process runs.
fn the_recorder() -> Result<Arc<Handle>, ControlError> {
    let running = RUNNING.lock().unwrap_or_else(|p| p.into_inner());
    let live: Vec<Arc<Handle>> = running.iter().filter_map(Weak::upgrade).collect();
    match live.len() {
        1 => Ok(live[0].clone()),
        0 => Err(ControlError::NoRecorder),
        n => Err(ControlError::SeveralRecorders(n)),
    }
}

/// Hands a request to the writer and waits for its answer, calling `meanwhile` every
/// [`BETWEEN`] (closing a large file on a slow disk takes seconds, and the method's module
/// must go on beating meanwhile: [`modbot_core::Ctx::keep_alive`]).
fn ask<T>(
    make: impl FnOnce(Sender<Result<T, ControlError>>) -> Control,
    meanwhile: &mut dyn FnMut(),
) -> Result<T, ControlError> {
    let recorder = the_recorder()?;
    let (answer, answered) = bounded(1);
    recorder
        .requests
        .send(make(answer))
        .map_err(|_| ControlError::WriterStopped)?;
    recorder.thread.unpark();
    let asked = Instant::now();
    loop {
        match answered.recv_timeout(BETWEEN) {
            Ok(answer) => return answer,
            Err(RecvTimeoutError::Disconnected) => return Err(ControlError::NoAnswer),
            Err(RecvTimeoutError::Timeout) if asked.elapsed() >= ANSWER => {
                return Err(ControlError::Timeout(ANSWER))
            }
            Err(RecvTimeoutError::Timeout) => meanwhile(),
        }
    }
}

/// Starts recording `signals` (empty: every one) to `file`: the file written. `meanwhile` is
/// called while the writer closes the file before and creates this one (see [`ask`]).
pub fn start(
    file: PathBuf,
    signals: Vec<String>,
    meanwhile: &mut dyn FnMut(),
) -> Result<PathBuf, ControlError> {
    ask(
        |answer| Control::Start {
            file,
            signals,
            answer,
        },
        meanwhile,
    )
}

/// Stops recording: the file and its rows. `meanwhile` is called while the writer closes it.
pub fn stop(meanwhile: &mut dyn FnMut()) -> Result<Stopped, ControlError> {
    ask(|answer| Control::Stop { answer }, meanwhile)
}
