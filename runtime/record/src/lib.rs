//! modbot-record: the data recorder (MoRC's Data Recorder) — the `record` component, which
//! writes the signals of a run to an HDF5 file that h5py, MATLAB or HDFView open, off the
//! real-time path. Uses `modbot-grid` (whose [`modbot_grid::record_type`] is the recorder's
//! interface, known to every process) and the HDF5 C library (`hdf5-metno`).
//!
//! A description says `record { signals = { "ptp.q", "robot.link_position" }, file = "run.h5" }`;
//! the grid makes that a component on a host of its own, which the program `modbot-recorder`
//! (this crate's [`register`] in a host program) steps every tick.
//!
//! # Layout
//! - [`component`]: the component — a release hands its inputs over as a row, without a lock,
//!   an allocation or a wait; [`register`].
//! - [`rows`]: the pool of rows passed between the real-time thread and the writer.
//! - [`writer`]: the writer thread, which appends batches to the file (when full, and at least
//!   every 40 ms); [`batch`]: a batch of rows, per dataset.
//! - [`control`]: a program starting and stopping recordings while the recorder runs.
//! - [`file`]: the file's layout (datasets, attributes) and its appends (SWMR: consistent on
//!   the disk at every moment).
//! - [`mark`]: the writer mark a killed writer leaves, and taking it off.
//! - [`path`]: which file a recorder writes (a restarted one does not replace its own).
//! - [`read`]: a signal read back from a recording.
//! - [`replay`]: the player of a source's recorded outputs and the comparer in the
//!   recorder's place, for `modbot replay`.
//! - [`replay_file`]: what a replayable recording keeps beside its rows (`/replay`).

pub mod batch;
pub mod compare;
pub mod component;
pub mod control;
pub mod file;
pub mod mark;
pub mod path;
pub mod read;
pub mod replay;
pub mod replay_file;
pub mod rows;
pub mod writer;

pub use component::register;
