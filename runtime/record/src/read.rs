//! Reading a recording back (a robot program's `recorded(...)`): one signal over a range of
//! ticks, from a finished file, one being written, or one a killed recorder left (as a SWMR
//! reader, [`crate::mark`]).

use std::path::{Path, PathBuf};

use ndarray::s;

/// Why a signal could not be read.
#[derive(Debug, thiserror::Error)]
#[error("{}: {why}", .path.display())]
pub struct ReadError {
    pub path: PathBuf,
    pub why: String,
}

/// A signal's values over the rows of a range of ticks.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The tick of each row.
    pub ticks: Vec<i64>,
    /// Values per row: 1 for a scalar signal, N for an f64[N] one.
    pub width: usize,
    /// The values, row after row (an i64 signal's as f64).
    pub values: Vec<f64>,
}

impl Series {
    /// Row `i`'s values.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.values[i * self.width..(i + 1) * self.width]
    }
}

/// The datasets every recording has besides its signals.
pub const BOOKKEEPING: [&str; 4] = ["tick", "time", "generation", crate::file::STATE_HASH];

/// The group of a replayable recording's schedule and grids (not a signal).
const GROUP_REPLAY: &str = "replay";

/// The signals a recording holds (`comp.port`), sorted: its datasets but the bookkeeping ones.
pub fn signals(path: &Path) -> Result<Vec<String>, ReadError> {
    let failed = |why: String| ReadError {
        path: path.to_path_buf(),
        why,
    };
    let file = hdf5::File::open_as(path, hdf5::OpenMode::ReadSWMR)
        .map_err(|e| failed(format!("does not open as a recording: {e}")))?;
    let mut names: Vec<String> = file
        .member_names()
        .map_err(|e| failed(format!("its datasets cannot be listed: {e}")))?
        .into_iter()
        .filter(|n| !BOOKKEEPING.contains(&n.as_str()) && n != GROUP_REPLAY)
        .collect();
    names.sort();
    Ok(names)
}

/// The rows of `signal` (`comp.port`, or `time`, `tick`, `generation`) whose ticks are in
/// `from..=to`.
pub fn read_signal(path: &Path, signal: &str, from: i64, to: i64) -> Result<Series, ReadError> {
    let failed = |why: String| ReadError {
        path: path.to_path_buf(),
        why,
    };
    let file = hdf5::File::open_as(path, hdf5::OpenMode::ReadSWMR)
        .map_err(|e| failed(format!("does not open as a recording: {e}")))?;
    let ticks: Vec<i64> = file
        .dataset("tick")
        .and_then(|d| d.read_raw())
        .map_err(|e| failed(format!("has no ticks: {e}")))?;
    let a = ticks.partition_point(|&t| t < from);
    let b = ticks.partition_point(|&t| t <= to);
    let dataset = file.dataset(signal).map_err(|_| {
        let names = file.member_names().unwrap_or_default().join(", ");
        failed(format!("has no signal '{signal}' (it has {names})"))
    })?;
    let shape = dataset.shape();
    let integer = dataset
        .dtype()
        .and_then(|t| t.to_descriptor())
        .is_ok_and(|d| matches!(d, hdf5::types::TypeDescriptor::Integer(_)));
    let read = |e: hdf5::Error| failed(format!("'{signal}': {e}"));
    let (width, values) = match (shape.len(), integer) {
        (1, false) => (
            1,
            dataset
                .read_slice_1d::<f64, _>(s![a..b])
                .map_err(read)?
                .to_vec(),
        ),
        (1, true) => {
            let v = dataset.read_slice_1d::<i64, _>(s![a..b]).map_err(read)?;
            (1, v.iter().map(|&i| i as f64).collect())
        }
        (2, _) => {
            let v = dataset
                .read_slice_2d::<f64, _>(s![a..b, ..])
                .map_err(read)?;
            (shape[1], v.iter().copied().collect())
        }
        _ => return Err(failed(format!("'{signal}' has shape {shape:?}"))),
    };
    Ok(Series {
        ticks: ticks[a..b].to_vec(),
        width,
        values,
    })
}

/// The grid's state hash of every row (see `modbot_grid::state_hash`), or `None` for a
/// recording written before recordings kept it.
pub fn read_state_hash(path: &Path) -> Result<Option<Vec<u64>>, ReadError> {
    let failed = |why: String| ReadError {
        path: path.to_path_buf(),
        why,
    };
    let file = hdf5::File::open_as(path, hdf5::OpenMode::ReadSWMR)
        .map_err(|e| failed(format!("does not open as a recording: {e}")))?;
    let Ok(dataset) = file.dataset(crate::file::STATE_HASH) else {
        return Ok(None);
    };
    let rows = file
        .dataset("tick")
        .map_err(|e| failed(format!("has no ticks: {e}")))?
        .shape()
        .first()
        .copied()
        .unwrap_or(0);
    let hashes: Vec<u64> = dataset
        .read_slice_1d::<u64, _>(s![..rows.min(dataset.shape().first().copied().unwrap_or(0))])
        .map_err(|e| failed(format!("'{}': {e}", crate::file::STATE_HASH)))?
        .to_vec();
    Ok(Some(hashes))
}
