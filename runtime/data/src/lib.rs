//! Assembly data: MoRC's *Assembly Data* database, where robot programs leave the parameters
//! an assembly reads when it is loaded (a goal, a speed) and the results of every command run
//! (its start and end tick, the peak following error, the settling time, ...), for later
//! commands, later programs and the operator (`modbot data ls`, `modbot data get KEY`).
//!
//! It is an embedded database ([redb](https://www.redb.org)) in one file per domain, which
//! every process of the system may open at the same time: the program interpreter writes,
//! the coordinator and the hosts read an assembly's parameters while they load it (redb's
//! `MultiWriter` mode: one write transaction at a time, readers never wait). It outlives the
//! system: `modbot down` and `modbot up` find it where it was.
//!
//! # Layout
//! - this file: [`Store`] — open, read and write keys, add and list command runs.
//! - `run`: [`Run`], one command run, and its encoding (a sequence of modbot values, the
//!   MessagePack of `modbot_ipc_schema::value`).
//! - `place`: where a domain's file lives ([`path_for`]: `$MODBOT_DATA_DIR/<domain>.redb`,
//!   by default in the user's data directory).
//! - `error`: [`DataError`], which names the file.

mod error;
mod place;
mod run;

use std::path::{Path, PathBuf};

use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::{OwnedValue, Value};
use redb::{ConcurrencyMode, ReadableDatabase, ReadableTable, TableDefinition};

pub use error::DataError;
pub use place::{path_for, DATA_DIR_ENV};
pub use run::Run;

/// Keys → one encoded value each.
const VALUES: TableDefinition<&str, &[u8]> = TableDefinition::new("values");
/// Command runs by number, from 1 → an encoded [`Run`].
const RUNS: TableDefinition<u64, &[u8]> = TableDefinition::new("runs");

/// The longest key: keys are names for people (`goto.q`, `ptp.peak_following`).
pub const MAX_KEY_LEN: usize = 128;

/// A domain's assembly data, open.
pub struct Store {
    db: redb::Database,
    /// The file, for messages.
    path: PathBuf,
}

impl Store {
    /// Opens the store at `path`, making it (and its directory) if there is none.
    pub fn open(path: &Path) -> Result<Store, DataError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| DataError::io(path, e))?;
        }
        let db = builder()
            .create(path)
            .map_err(|e| DataError::open(path, e))?;
        let store = Store {
            db,
            path: path.to_owned(),
        };
        // The tables exist from the start, so a reader never meets a store without them.
        store.write(|tx| {
            tx.open_table(VALUES)?;
            tx.open_table(RUNS)?;
            Ok(())
        })?;
        Ok(store)
    }

    /// Opens the store at `path` if there is one (`None`: nothing was ever stored there).
    pub fn open_existing(path: &Path) -> Result<Option<Store>, DataError> {
        match std::fs::metadata(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(DataError::io(path, e)),
            Ok(_) => {}
        }
        let db = builder().open(path).map_err(|e| DataError::open(path, e))?;
        Ok(Some(Store {
            db,
            path: path.to_owned(),
        }))
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The value of `key`, if it has one.
    pub fn get(&self, key: &str) -> Result<Option<OwnedValue>, DataError> {
        self.read(VALUES, |table| {
            Ok(table.get(key)?.map(|v| v.value().to_vec()))
        })?
        .map(|bytes| decode_one(&self.path, key, &bytes))
        .transpose()
    }

    /// Sets `key` to `value` (any modbot value: a number, a text, an f64 array, ...).
    pub fn put(&self, key: &str, value: &OwnedValue) -> Result<(), DataError> {
        self.put_all(&[(key.to_owned(), value.clone())])
    }

    /// Sets every key of `entries`, in one transaction: a reader sees all of them or none.
    pub fn put_all(&self, entries: &[(String, OwnedValue)]) -> Result<(), DataError> {
        for (key, _) in entries {
            check_key(key)?;
        }
        let encoded = entries
            .iter()
            .map(|(k, v)| encode(&[v.as_value()]).map(|b| (k.as_str(), b)))
            .collect::<Result<Vec<_>, _>>()?;
        self.write(|tx| {
            let mut table = tx.open_table(VALUES)?;
            for (key, bytes) in &encoded {
                table.insert(*key, bytes.as_slice())?;
            }
            Ok(())
        })
    }

    /// Removes `key`; whether it was there.
    pub fn remove(&self, key: &str) -> Result<bool, DataError> {
        let mut removed = false;
        self.write(|tx| {
            removed = tx.open_table(VALUES)?.remove(key)?.is_some();
            Ok(())
        })?;
        Ok(removed)
    }

    /// Every key and its value, sorted by key.
    pub fn entries(&self) -> Result<Vec<(String, OwnedValue)>, DataError> {
        let raw = self.read(VALUES, |table| {
            table
                .iter()?
                .map(|e| e.map(|(k, v)| (k.value().to_owned(), v.value().to_vec())))
                .collect::<Result<Vec<_>, _>>()
                .map_err(redb::Error::from)
        })?;
        raw.into_iter()
            .map(|(k, bytes)| decode_one(&self.path, &k, &bytes).map(|v| (k, v)))
            .collect()
    }

    /// Adds a command run; returns its number (1, 2, ... in the order they were added).
    pub fn add_run(&self, run: &Run) -> Result<u64, DataError> {
        for (key, _) in &run.values {
            check_key(key)?;
        }
        let bytes = run.encode()?;
        let mut number = 0;
        self.write(|tx| {
            let mut table = tx.open_table(RUNS)?;
            number = table.last()?.map_or(0, |(k, _)| k.value()) + 1;
            table.insert(number, bytes.as_slice())?;
            Ok(())
        })?;
        Ok(number)
    }

    /// Run `number`, if there is one.
    pub fn run(&self, number: u64) -> Result<Option<Run>, DataError> {
        self.read(RUNS, |table| {
            Ok(table.get(number)?.map(|v| v.value().to_vec()))
        })?
        .map(|bytes| Run::decode(&bytes).map_err(|e| DataError::corrupt(&self.path, e.to_string())))
        .transpose()
    }

    /// Every run with its number, oldest first.
    pub fn runs(&self) -> Result<Vec<(u64, Run)>, DataError> {
        let raw = self.read(RUNS, |table| {
            table
                .iter()?
                .map(|e| e.map(|(k, v)| (k.value(), v.value().to_vec())))
                .collect::<Result<Vec<_>, _>>()
                .map_err(redb::Error::from)
        })?;
        raw.into_iter()
            .map(|(n, bytes)| {
                Run::decode(&bytes)
                    .map(|r| (n, r))
                    .map_err(|e| DataError::corrupt(&self.path, e.to_string()))
            })
            .collect()
    }

    /// What `f` reads from `table` in one read transaction; `R::default()` (nothing) when
    /// the table was never made.
    fn read<K: redb::Key + 'static, R: Default>(
        &self,
        table: TableDefinition<K, &[u8]>,
        f: impl FnOnce(&redb::ReadOnlyTable<K, &'static [u8]>) -> Result<R, redb::Error>,
    ) -> Result<R, DataError> {
        let tx = self
            .db
            .begin_read()
            .map_err(|e| DataError::db(&self.path, e.into()))?;
        let table = match tx.open_table(table) {
            Ok(t) => t,
            Err(redb::TableError::TableDoesNotExist(_)) => return Ok(R::default()),
            Err(e) => return Err(DataError::db(&self.path, e.into())),
        };
        f(&table).map_err(|e| DataError::db(&self.path, e))
    }

    fn write(
        &self,
        f: impl FnOnce(&redb::WriteTransaction) -> Result<(), redb::Error>,
    ) -> Result<(), DataError> {
        let tx = self
            .db
            .begin_write()
            .map_err(|e| DataError::db(&self.path, e.into()))?;
        f(&tx).map_err(|e| DataError::db(&self.path, e))?;
        tx.commit().map_err(|e| DataError::db(&self.path, e.into()))
    }
}

/// Every process opens the file the same way: shared, one writer at a time.
fn builder() -> redb::Builder {
    let mut b = redb::Builder::new();
    b.set_concurrency_mode(ConcurrencyMode::MultiWriter);
    b
}

/// A key is 1 to [`MAX_KEY_LEN`] bytes of printable text without spaces.
fn check_key(key: &str) -> Result<(), DataError> {
    let ok = !key.is_empty()
        && key.len() <= MAX_KEY_LEN
        && key
            .chars()
            .all(|c| c.is_ascii_graphic() || (!c.is_ascii() && !c.is_control()));
    if ok {
        Ok(())
    } else {
        Err(DataError::Key(key.to_owned()))
    }
}

/// Values, one after another.
fn encode(values: &[Value<'_>]) -> Result<Vec<u8>, DataError> {
    let mut out = Vec::new();
    for v in values {
        v.encode_to_vec(&mut out).map_err(DataError::Value)?;
    }
    Ok(out)
}

fn decode_one(path: &Path, key: &str, bytes: &[u8]) -> Result<OwnedValue, DataError> {
    let mut values = Values::new(bytes, 0);
    match (values.next(), values.next()) {
        (Some(Ok(v)), None) => Ok(v.to_owned_value()),
        (Some(Err(e)), _) => Err(DataError::corrupt(path, format!("key '{key}': {e}"))),
        _ => Err(DataError::corrupt(
            path,
            format!("key '{key}' does not hold one value"),
        )),
    }
}

#[cfg(test)]
mod tests;
