//! The recording's HDF5 file: its layout, created empty, and appended to batch by batch.
//!
//! # Layout
//! ```text
//! /                 attributes: base_period (s), period (s, the recorder's), signals (their
//!                   names in order), description and description_file (the system
//!                   description's text and path), assembly and assembly_file (with an
//!                   assembly's recorder), writer ("modbot-record <version>")
//! /tick             i64 (ticks,)     the tick each row was recorded at: the count of complete rows
//! /time             f64 (ticks,)     tick · base_period, in seconds
//! /generation       i64 (ticks,)     the assembly generation of the release (0 without assemblies)
//! /state_hash       u64 (ticks,)     the grid's state hash at the tick (`modbot_grid::state_hash`;
//!                   attribute hash: how it is computed)
//! /<comp>.<port>    per signal: f64 or i64 (a bool as 0 or 1) of shape (ticks,) for a
//!                   scalar port, f64 (ticks, N) for an f64[N] port; attributes: type (the
//!                   port type, "f64[6]"), unit (where the description says)
//! ```
//! Every dataset is chunked (`chunk_rows` rows, whole rows) with an unlimited first dimension
//! and grows along it ([`RecordFile::append`]). The file is written by the HDF5 C library
//! (`hdf5-metno`) in its single-writer/multiple-reader mode (SWMR): every append writes the
//! new chunks, then the chunk index, then the dataset's new extent, in an order that keeps the
//! file consistent on the disk at every moment, so a writer killed at any moment leaves a file
//! holding every batch it had flushed. The signals are appended first and `tick` last, so
//! `tick`'s length is the number of rows every dataset holds. How such a file is opened, and
//! how its writer mark goes, is [`crate::mark`]'s.

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;
use modbot_grid::component::PortType;
use modbot_grid::record_type::Signal;
use ndarray::{s, ArrayView1, ArrayView2};

use super::mark::WriterMark;

/// Why the recording cannot be written.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", .path.display())]
pub struct FileError {
    pub path: PathBuf,
    #[source]
    pub source: hdf5::Error,
}

/// What the file says about the run beside its signals.
#[derive(Debug, Clone, Default)]
pub struct Header {
    pub base_period_s: f64,
    pub period_s: f64,
    /// (signal, unit).
    pub units: Vec<(String, String)>,
    /// The description files whose text it keeps: (path, text); the system's first.
    pub sources: Vec<(String, String)>,
}

/// How a dataset's words are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Element {
    F64,
    I64,
    U64,
}

/// A dataset of the file and its shape per row.
struct Column {
    dataset: hdf5::Dataset,
    element: Element,
    /// Values per row: `None` for a scalar dataset (ticks,), `Some(n)` for (ticks, n).
    width: Option<usize>,
}

impl Column {
    fn words_per_row(&self) -> usize {
        self.width.unwrap_or(1)
    }
}

/// A recording file, open for appending.
pub struct RecordFile {
    path: PathBuf,
    file: hdf5::File,
    /// Per dataset, in the order a batch is appended: the signals, then generation, state
    /// hash, time, tick.
    columns: Vec<Column>,
    /// Complete rows in the file.
    rows: usize,
    /// Held while the file is written: says its writer lives ([`crate::mark`]).
    _mark: WriterMark,
}

impl RecordFile {
    /// Creates (or replaces) the file at `path` for `signals`, with no rows, in chunks of
    /// `chunk_rows` rows, and starts writing it (SWMR).
    pub fn create(
        path: &Path,
        signals: &[Signal],
        header: &Header,
        chunk_rows: u64,
    ) -> Result<RecordFile, FileError> {
        let failed = |source| FileError {
            path: path.to_path_buf(),
            source,
        };
        let file = hdf5::File::with_options()
            .with_fapl(|p| p.libver_latest())
            .create(path)
            .map_err(failed)?;
        let mut columns = Vec::with_capacity(signals.len() + 4);
        let chunk = usize::try_from(chunk_rows.max(1)).unwrap_or(usize::MAX);
        let built = (|| {
            text_attr(&file, "signals", &names(signals))?;
            text_attr(
                &file,
                "writer",
                &format!("modbot-record {}", env!("CARGO_PKG_VERSION")),
            )?;
            f64_attr(&file, "base_period", header.base_period_s)?;
            f64_attr(&file, "period", header.period_s)?;
            for ((path, text), what) in header.sources.iter().zip(["description", "assembly"]) {
                text_attr(&file, &format!("{what}_file"), path)?;
                text_attr(&file, what, text)?;
            }
            for s in signals {
                let column = empty(&file, &s.name, s.ty, chunk)?;
                text_attr(&column.dataset, "type", &s.ty.to_string())?;
                if let Some((_, unit)) = header.units.iter().find(|(n, _)| *n == s.name) {
                    text_attr(&column.dataset, "unit", unit)?;
                }
                columns.push(column);
            }
            columns.push(empty(&file, "generation", PortType::I64, chunk)?);
            let hash = empty_u64(&file, STATE_HASH, chunk)?;
            text_attr(&hash.dataset, "hash", STATE_HASH_HOW)?;
            columns.push(hash);
            let time = empty(&file, "time", PortType::F64, chunk)?;
            text_attr(&time.dataset, "unit", "s")?;
            columns.push(time);
            columns.push(empty(&file, "tick", PortType::I64, chunk)?);
            // Every object is there: from now on the file only grows, readers may look.
            file.start_swmr()
        })();
        built.map_err(failed)?;
        let mark = WriterMark::take(path).map_err(|e| failed(e.to_string().into()))?;
        Ok(RecordFile {
            path: path.to_path_buf(),
            file,
            columns,
            rows: 0,
            _mark: mark,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends one batch of `rows` rows: per dataset (the signals, then generation, state hash,
    /// time, tick), its words row after row (an f64 as its bits), and flushes it to the file.
    pub fn append(&mut self, rows: usize, columns: &[Vec<u64>]) -> Result<(), FileError> {
        if rows == 0 {
            return Ok(());
        }
        let (from, to) = (self.rows, self.rows + rows);
        let written = (|| {
            for (column, words) in self.columns.iter().zip(columns) {
                let words = &words[..rows * column.words_per_row()];
                match column.width {
                    None => {
                        column.dataset.resize(to)?;
                        write_1d(column, words, s![from..to])?;
                    }
                    Some(n) => {
                        column.dataset.resize((to, n))?;
                        write_2d(column, words, (rows, n), s![from..to, ..])?;
                    }
                }
            }
            self.file.flush()
        })();
        written.map_err(|source| FileError {
            path: self.path.clone(),
            source,
        })?;
        self.rows = to;
        Ok(())
    }

    /// Closes the file: the writer mark goes, the file opens like any other.
    pub fn close(self) -> Result<(), FileError> {
        let RecordFile {
            path,
            file,
            columns,
            _mark,
            ..
        } = self;
        drop(columns);
        file.close().map_err(|source| FileError { path, source })
    }
}

fn write_1d(
    column: &Column,
    words: &[u64],
    at: ndarray::SliceInfo<[ndarray::SliceInfoElem; 1], ndarray::Ix1, ndarray::Ix1>,
) -> hdf5::Result<()> {
    match column.element {
        Element::F64 => {
            let values: &[f64] = bytemuck::cast_slice(words);
            column.dataset.write_slice(ArrayView1::from(values), at)
        }
        Element::I64 => {
            let values: &[i64] = bytemuck::cast_slice(words);
            column.dataset.write_slice(ArrayView1::from(values), at)
        }
        Element::U64 => column.dataset.write_slice(ArrayView1::from(words), at),
    }
}

fn write_2d(
    column: &Column,
    words: &[u64],
    shape: (usize, usize),
    at: ndarray::SliceInfo<[ndarray::SliceInfoElem; 2], ndarray::Ix2, ndarray::Ix2>,
) -> hdf5::Result<()> {
    let bad = |e: ndarray::ShapeError| hdf5::Error::from(e.to_string());
    match column.element {
        Element::F64 => {
            let values: &[f64] = bytemuck::cast_slice(words);
            let view = ArrayView2::from_shape(shape, values).map_err(bad)?;
            column.dataset.write_slice(view, at)
        }
        Element::I64 => {
            let values: &[i64] = bytemuck::cast_slice(words);
            let view = ArrayView2::from_shape(shape, values).map_err(bad)?;
            column.dataset.write_slice(view, at)
        }
        Element::U64 => {
            let view = ArrayView2::from_shape(shape, words).map_err(bad)?;
            column.dataset.write_slice(view, at)
        }
    }
}

/// The dataset of the grid's state hash per row.
pub const STATE_HASH: &str = "state_hash";

/// How the state hash is computed (its dataset's attribute `hash`).
const STATE_HASH_HOW: &str = "SipHash-2-4 with keys 0, 0 over (component index, component hash) \
     of the versions valid at the tick, in component order; a component's hash is over its \
     outputs (tag, little-endian bits) unless it adds more state: modbot_grid::state_hash";

/// Adds the empty, growable u64 dataset `name`.
fn empty_u64(file: &hdf5::File, name: &str, chunk: usize) -> hdf5::Result<Column> {
    let dataset = file
        .new_dataset::<u64>()
        .chunk(chunk)
        .shape(0..)
        .create(name)?;
    Ok(Column {
        dataset,
        element: Element::U64,
        width: None,
    })
}

/// The signals' names, comma-separated.
fn names(signals: &[Signal]) -> String {
    let names: Vec<&str> = signals.iter().map(|s| s.name.as_str()).collect();
    names.join(",")
}

/// Adds the empty, growable dataset `name` for values of type `ty`.
fn empty(file: &hdf5::File, name: &str, ty: PortType, chunk: usize) -> hdf5::Result<Column> {
    let (element, width) = match ty {
        PortType::F64 => (Element::F64, None),
        PortType::I64 | PortType::Bool => (Element::I64, None),
        PortType::F64s(n) => (Element::F64, Some(n)),
    };
    let builder = match element {
        Element::F64 => file.new_dataset::<f64>(),
        Element::I64 | Element::U64 => file.new_dataset::<i64>(),
    };
    let dataset = match width {
        None => builder.chunk(chunk).shape(0..).create(name)?,
        Some(n) => builder
            .chunk((chunk, n.max(1)))
            .shape((0.., n))
            .create(name)?,
    };
    Ok(Column {
        dataset,
        element,
        width,
    })
}

/// Adds the text attribute `name` to `at`.
pub(crate) fn text_attr(at: &hdf5::Location, name: &str, value: &str) -> hdf5::Result<()> {
    let value: VarLenUnicode = value
        .parse()
        .map_err(|e: hdf5::types::StringError| hdf5::Error::from(e.to_string()))?;
    at.new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&value)
}

fn f64_attr(at: &hdf5::Location, name: &str, value: f64) -> hdf5::Result<()> {
    at.new_attr::<f64>().create(name)?.write_scalar(&value)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signal(name: &str, ty: PortType) -> Signal {
        Signal {
            name: name.into(),
            ty,
        }
    }

    #[test]
    fn appended_batches_read_back_as_ticks_by_width_with_their_attributes() {
        let dir = std::env::temp_dir().join(format!("modbot-record-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.h5");
        let signals = [
            signal("a.q", PortType::F64s(2)),
            signal("b.n", PortType::I64),
        ];
        let header = Header {
            base_period_s: 0.001,
            period_s: 0.001,
            units: vec![("a.q".into(), "rad".into())],
            sources: vec![("/x/arm.lua".into(), "domain \"arm\"\n".into())],
        };
        let mut sut = RecordFile::create(&path, &signals, &header, 50).unwrap();
        for batch in 0..3u64 {
            // Batches of 40 rows in chunks of 50: appends end inside chunks too.
            let ticks: Vec<u64> = (batch * 40..batch * 40 + 40).collect();
            let q: Vec<u64> = ticks
                .iter()
                .flat_map(|&t| [(t as f64).to_bits(), (-(t as f64)).to_bits()])
                .collect();
            let time: Vec<u64> = ticks
                .iter()
                .map(|&t| (t as f64 * 0.001).to_bits())
                .collect();
            let hashes: Vec<u64> = ticks.iter().map(|&t| u64::MAX - t).collect();
            let columns = [q, ticks.clone(), vec![0; 40], hashes, time, ticks];
            sut.append(40, &columns).unwrap();
        }
        sut.close().unwrap();
        let file = hdf5::File::open(&path).unwrap();
        let tick: Vec<i64> = file.dataset("tick").unwrap().read_raw().unwrap();
        assert_eq!(tick, (0..120).collect::<Vec<i64>>());
        let q = file.dataset("a.q").unwrap();
        assert_eq!(q.shape(), vec![120, 2]);
        let q: ndarray::Array2<f64> = q.read_2d().unwrap();
        assert_eq!((q[[1, 0]], q[[1, 1]], q[[119, 1]]), (1.0, -1.0, -119.0));
        assert_eq!(file.dataset("b.n").unwrap().shape(), vec![120]);
        let hash: Vec<u64> = file.dataset("state_hash").unwrap().read_raw().unwrap();
        assert_eq!((hash[0], hash[119]), (u64::MAX, u64::MAX - 119));
        let unit: VarLenUnicode = file
            .dataset("a.q")
            .unwrap()
            .attr("unit")
            .unwrap()
            .read_scalar()
            .unwrap();
        assert_eq!(unit.as_str(), "rad");
        let base: f64 = file.attr("base_period").unwrap().read_scalar().unwrap();
        assert_eq!(base, 0.001);
        let text: VarLenUnicode = file.attr("description").unwrap().read_scalar().unwrap();
        assert_eq!(text.as_str(), "domain \"arm\"\n");
        drop(file);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
