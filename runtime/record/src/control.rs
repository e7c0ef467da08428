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
use std::time::Duration;

use crossbeam::channel::{bounded, Sender};

/// How long a method waits for the writer (it finishes the batch at hand, closes a file,
/// creates one).
const ANSWER: Duration = Duration::from_secs(30);

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
        answer: Sender<Result<PathBuf, String>>,
    },
    /// Writes what is gathered, closes the file; answers what it was.
    Stop {
        answer: Sender<Result<Stopped, String>>,
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
fn the_recorder() -> Result<Arc<Handle>, String> {
    let running = RUNNING.lock().unwrap_or_else(|p| p.into_inner());
    let live: Vec<Arc<Handle>> = running.iter().filter_map(Weak::upgrade).collect();
    match live.len() {
        1 => Ok(live[0].clone()),
        0 => Err("this host runs no recorder".into()),
        n => Err(format!(
            "this host runs {n} recorders: give each a host of its own (record {{ host = ... }})"
        )),
    }
}

fn ask<T>(make: impl FnOnce(Sender<Result<T, String>>) -> Control) -> Result<T, String> {
    let recorder = the_recorder()?;
    let (answer, answered) = bounded(1);
    recorder
        .requests
        .send(make(answer))
        .map_err(|_| "the recorder's writer has stopped".to_owned())?;
    recorder.thread.unpark();
    answered
        .recv_timeout(ANSWER)
        .map_err(|_| "the recorder's writer did not answer".to_owned())?
}

/// Starts recording `signals` (empty: every one) to `file`: the file written.
pub fn start(file: PathBuf, signals: Vec<String>) -> Result<PathBuf, String> {
    ask(|answer| Control::Start {
        file,
        signals,
        answer,
    })
}

/// Stops recording: the file and its rows.
pub fn stop() -> Result<Stopped, String> {
    ask(|answer| Control::Stop { answer })
}
