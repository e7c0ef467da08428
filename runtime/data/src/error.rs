//! Why assembly data could not be read or written: every error names the file.

use std::path::{Path, PathBuf};

use thiserror::Error;

/// An assembly data error.
#[derive(Debug, Error)]
pub enum DataError {
    #[error("assembly data {}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("assembly data {}: cannot open the database: {source}", .path.display())]
    Open {
        path: PathBuf,
        #[source]
        source: redb::DatabaseError,
    },
    #[error("assembly data {}: {source}", .path.display())]
    Db {
        path: PathBuf,
        #[source]
        source: redb::Error,
    },
    #[error("assembly data {}: not understood: {why}", .path.display())]
    Corrupt { path: PathBuf, why: String },
    #[error("'{0}' is not a key: use 1 to 128 printable characters without spaces")]
    Key(String),
    #[error("a value cannot be stored: {0}")]
    Value(modbot_ipc_schema::ValueError),
}

impl DataError {
    pub(super) fn io(path: &Path, source: std::io::Error) -> DataError {
        DataError::Io {
            path: path.to_owned(),
            source,
        }
    }

    pub(super) fn open(path: &Path, source: redb::DatabaseError) -> DataError {
        DataError::Open {
            path: path.to_owned(),
            source,
        }
    }

    pub(super) fn db(path: &Path, source: redb::Error) -> DataError {
        DataError::Db {
            path: path.to_owned(),
            source,
        }
    }

    pub(super) fn corrupt(path: &Path, why: impl Into<String>) -> DataError {
        DataError::Corrupt {
            path: path.to_owned(),
            why: why.into(),
        }
    }
}
