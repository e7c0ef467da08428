//! The recording's HDF5 file: its layout, created empty, and appended to batch by batch.
//!
//! # Layout
//! ```text
//! /                 attributes: base_period (s), period (s, the recorder's), signals (their
//!                   names in order), description and description_file (the system
//!                   description's text and path), assembly and assembly_file (with an
//!                   assembly's recorder), writer ("modbot-record <version>")
//! /tick             i64 (rows,)   the tick each row was recorded at: the count of complete rows
//! /time             f64 (rows,)   tick · base_period, in seconds
//! /generation       i64 (rows,)   the assembly generation of the release (0 without assemblies)
//! /<comp>.<port>    per signal, (rows,) of f64 or i64 (a bool as 0 or 1), or of the array
//!                   type f64[N] for an f64[N] port — h5py reads it as rows × N; attributes:
//!                   type (the port type, "f64[6]"), unit (where the description says)
//! ```
//! Every dataset is chunked with an unlimited first dimension and grows in place
//! ([`RecordFile::append`]); each append is crash-atomic (hdf5-pure publishes the new length
//! last and raises no in-use mark), so a writer killed at any moment leaves a file that h5py
//! opens, holding every batch appended before. The signals are appended first and `tick`
//! last, so `tick`'s length is the number of rows every dataset holds.

use std::path::{Path, PathBuf};

use hdf5_pure::{
    make_f64_type, make_i64_type, AttrValue, Datatype, FileAccessProperties, FileBuilder,
    MaxExtent, SyncPolicy,
};
use modbot_grid::component::PortType;
use modbot_grid::record_type::Signal;

/// Why the recording cannot be written.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", .path.display())]
pub struct FileError {
    pub path: PathBuf,
    #[source]
    pub source: hdf5_pure::Error,
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

/// The datasets, in the order a batch is appended (the signals, then generation, time, tick).
fn datasets(signals: &[Signal]) -> Vec<String> {
    let mut names: Vec<String> = signals.iter().map(|s| s.name.clone()).collect();
    names.extend(["generation", "time", "tick"].map(String::from));
    names
}

/// A recording file, open for appending.
pub struct RecordFile {
    path: PathBuf,
    file: hdf5_pure::File,
    /// Per dataset (in [`datasets`] order), its handle.
    handles: Vec<hdf5_pure::Dataset>,
}

impl RecordFile {
    /// Creates (or replaces) the file at `path` for `signals`, with no rows, in chunks of
    /// `chunk_rows` rows (a batch of whole chunks is appended without rewriting anything).
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
        let mut b = FileBuilder::new();
        b.set_attr("base_period", AttrValue::F64(header.base_period_s));
        b.set_attr("period", AttrValue::F64(header.period_s));
        let names: Vec<&str> = signals.iter().map(|s| s.name.as_str()).collect();
        b.set_attr("signals", AttrValue::VarLenString(names.join(",")));
        b.set_attr(
            "writer",
            AttrValue::VarLenString(format!("modbot-record {}", env!("CARGO_PKG_VERSION"))),
        );
        for ((path, text), what) in header.sources.iter().zip(["description", "assembly"]) {
            b.set_attr(
                &format!("{what}_file"),
                AttrValue::VarLenString(path.clone()),
            );
            b.set_attr(what, AttrValue::VarLenString(text.clone()));
        }
        for s in signals {
            let d = empty(&mut b, chunk_rows, &s.name, s.ty);
            d.set_attr("type", AttrValue::VarLenString(s.ty.to_string()));
            if let Some((_, unit)) = header.units.iter().find(|(n, _)| *n == s.name) {
                d.set_attr("unit", AttrValue::VarLenString(unit.clone()));
            }
        }
        empty(&mut b, chunk_rows, "generation", PortType::I64);
        empty(&mut b, chunk_rows, "time", PortType::F64)
            .set_attr("unit", AttrValue::VarLenString("s".into()));
        empty(&mut b, chunk_rows, "tick", PortType::I64);
        b.write(path).map_err(failed)?;
        let access = FileAccessProperties::new().with_sync_policy(SyncPolicy::OnClose);
        let file = hdf5_pure::File::open_rw_with_options(path, access).map_err(failed)?;
        let handles = datasets(signals)
            .iter()
            .map(|name| file.dataset(name))
            .collect::<Result<Vec<_>, _>>()
            .map_err(failed)?;
        Ok(RecordFile {
            path: path.to_path_buf(),
            file,
            handles,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends one batch: per dataset (in [`datasets`] order: the signals, then generation,
    /// time, tick), the rows' little-endian bytes.
    pub fn append(&mut self, columns: &[Vec<u8>]) -> Result<(), FileError> {
        for (handle, bytes) in self.handles.iter_mut().zip(columns) {
            handle.append_raw(bytes).map_err(|source| FileError {
                path: self.path.clone(),
                source,
            })?;
        }
        Ok(())
    }

    /// Closes the file (and syncs it to the disk).
    pub fn close(self) -> Result<(), FileError> {
        let path = self.path;
        drop(self.handles);
        self.file
            .close()
            .map_err(|source| FileError { path, source })
    }
}

/// Adds the empty, growable dataset `name` for values of type `ty`.
fn empty<'b>(
    b: &'b mut FileBuilder,
    chunk_rows: u64,
    name: &str,
    ty: PortType,
) -> &'b mut hdf5_pure::DatasetBuilder {
    let d = b.create_dataset(name);
    match ty {
        PortType::F64 => d.with_dtype(make_f64_type()),
        PortType::I64 | PortType::Bool => d.with_dtype(make_i64_type()),
        PortType::F64s(n) => d.with_dtype(Datatype::Array {
            base_type: Box::new(make_f64_type()),
            dimensions: vec![u32::try_from(n).unwrap_or(u32::MAX)],
        }),
    };
    d.with_shape(&[0])
        .with_maxshape(&[MaxExtent::Unlimited])
        .with_chunks(&[chunk_rows.max(1)])
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
    fn appended_batches_read_back_with_their_attributes() {
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
        let le = |words: &[u64]| {
            words
                .iter()
                .flat_map(|w| w.to_le_bytes())
                .collect::<Vec<u8>>()
        };
        for batch in 0..3u64 {
            let ticks: Vec<u64> = (batch * 50..batch * 50 + 50).collect();
            let q: Vec<u64> = ticks
                .iter()
                .flat_map(|&t| [(t as f64).to_bits(), (-(t as f64)).to_bits()])
                .collect();
            let time: Vec<u64> = ticks
                .iter()
                .map(|&t| (t as f64 * 0.001).to_bits())
                .collect();
            let columns = [le(&q), le(&ticks), le(&vec![0; 50]), le(&time), le(&ticks)];
            sut.append(&columns).unwrap();
        }
        sut.close().unwrap();
        let file = hdf5_pure::File::open(&path).unwrap();
        assert_eq!(
            file.dataset("tick").unwrap().read_i64().unwrap(),
            (0..150).collect::<Vec<i64>>()
        );
        let q = file.dataset("a.q").unwrap().read_raw().unwrap();
        let q: Vec<f64> = q
            .chunks(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
            .collect();
        assert_eq!((q.len(), q[2], q[3]), (300, 1.0, -1.0));
        let attrs = file.dataset("a.q").unwrap().attrs().unwrap();
        assert_eq!(
            attrs.get("unit"),
            Some(&AttrValue::VarLenString("rad".into()))
        );
        let root = file.root().attrs().unwrap();
        assert_eq!(root.get("base_period"), Some(&AttrValue::F64(0.001)));
        assert_eq!(
            root.get("description"),
            Some(&AttrValue::VarLenString("domain \"arm\"\n".into()))
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
