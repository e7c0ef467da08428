//! The writer mark of a recording. While the HDF5 library writes a file in SWMR mode, the
//! file's superblock says so, and a reader opens it only as a SWMR reader (h5py:
//! `h5py.File(path, "r", swmr=True)`); a clean close takes the mark off. A writer killed
//! mid-run leaves a consistent file that still carries the mark: [`unmark`] takes it off
//! (what HDF5's `h5clear -s` does), once the writer is known to be gone.
//!
//! Whether the writer is gone is told by a lock: a recorder holds a shared `flock` on its file
//! for as long as it writes ([`WriterMark`]), which the kernel drops when the process dies, so
//! a file whose lock can be taken exclusively has no writer. (The HDF5 library lets go of its
//! own lock when SWMR writing starts.)

use std::path::{Path, PathBuf};

use nix::fcntl::{Flock, FlockArg};

/// Why a file's writer mark could not be looked at or taken off.
#[derive(Debug, thiserror::Error)]
pub enum MarkError {
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: cannot clear the HDF5 writer mark: {why}", .path.display())]
    Hdf5 { path: PathBuf, why: String },
}

/// What [`unmark`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unmarked {
    /// The file opens as it is (closed cleanly, or never SWMR).
    Clean,
    /// A dead writer's mark was taken off.
    Cleared,
    /// Its writer still writes it: left alone.
    WriterAlive,
}

/// The lock a recorder holds on its file while it writes it.
#[derive(Debug)]
pub struct WriterMark {
    _lock: Flock<std::fs::File>,
}

impl WriterMark {
    /// Takes the lock on `path` (shared: readers that lock as HDF5 does still open it).
    pub fn take(path: &Path) -> Result<WriterMark, MarkError> {
        let failed = |source| MarkError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = std::fs::File::open(path).map_err(failed)?;
        let lock = Flock::lock(file, FlockArg::LockSharedNonblock)
            .map_err(|(_, errno)| failed(std::io::Error::from(errno)))?;
        Ok(WriterMark { _lock: lock })
    }
}

/// Whether a process holds a [`WriterMark`] on `path`.
fn writer_alive(path: &Path) -> Result<bool, MarkError> {
    let file = std::fs::File::open(path).map_err(|source| MarkError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    match Flock::lock(file, FlockArg::LockExclusiveNonblock) {
        Ok(_unlocked_on_drop) => Ok(false),
        Err((_, nix::errno::Errno::EWOULDBLOCK)) => Ok(true),
        Err((_, errno)) => Err(MarkError::Io {
            path: path.to_path_buf(),
            source: errno.into(),
        }),
    }
}

/// Takes the writer mark off the recording at `path` if its writer is gone; a file being
/// written, or one without a mark, is left as it is.
pub fn unmark(path: &Path) -> Result<Unmarked, MarkError> {
    if writer_alive(path)? {
        return Ok(Unmarked::WriterAlive);
    }
    if hdf5::File::open(path).is_ok() {
        return Ok(Unmarked::Clean);
    }
    clear_status_flags(path)?;
    Ok(Unmarked::Cleared)
}

/// Opens `path` for writing with HDF5's file access property `clear_status_flags` (the one
/// `h5clear -s` sets) and closes it: the superblock's writer flags go.
fn clear_status_flags(path: &Path) -> Result<(), MarkError> {
    let failed = |why: String| MarkError::Hdf5 {
        path: path.to_path_buf(),
        why,
    };
    let name = std::ffi::CString::new(path.as_os_str().as_encoded_bytes())
        .map_err(|_| failed("the path holds a NUL byte".into()))?;
    let fapl = hdf5::plist::FileAccess::build()
        .finish()
        .map_err(|e| failed(e.to_string()))?;
    hdf5::sync::sync(|| {
        let yes: hdf5_sys::h5::hbool_t = 1;
        // SAFETY: `fapl` is a live file access property list (dropped after this closure), the
        // property name is a NUL-terminated C string, and the library copies the property's
        // size, that of its hbool_t (hdf5-sys's type, as detected from the library), from
        // `&yes`, which lives until the call returns. The library's lock is held (`sync`).
        let set = unsafe {
            hdf5_sys::h5p::H5Pset(
                fapl.id(),
                c"clear_status_flags".as_ptr(),
                std::ptr::from_ref(&yes).cast_mut().cast(),
            )
        };
        if set < 0 {
            return Err(failed("this HDF5 library has no clear_status_flags".into()));
        }
        // SAFETY: `name` is a NUL-terminated path and `fapl` a live property list; the
        // returned id is closed below and not used after.
        let file = unsafe {
            hdf5_sys::h5f::H5Fopen(name.as_ptr(), hdf5_sys::h5f::H5F_ACC_RDWR, fapl.id())
        };
        if file < 0 {
            return Err(failed("it does not open for writing".into()));
        }
        // SAFETY: `file` is the id H5Fopen just returned.
        let closed = unsafe { hdf5_sys::h5f::H5Fclose(file) };
        if closed < 0 {
            return Err(failed("closing it failed".into()));
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::file::{Header, RecordFile};
    use modbot_grid::component::PortType;
    use modbot_grid::record_type::Signal;

    #[test]
    fn a_file_being_written_is_left_alone_and_a_closed_one_opens_as_it_is() {
        let dir = std::env::temp_dir().join(format!("modbot-record-mark-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.h5");
        let signals = [Signal {
            name: "a.y".into(),
            ty: PortType::F64,
        }];
        let sut = RecordFile::create(&path, &signals, &Header::default(), 10).unwrap();
        assert_eq!(unmark(&path).unwrap(), Unmarked::WriterAlive);
        sut.close().unwrap();
        assert_eq!(unmark(&path).unwrap(), Unmarked::Clean);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
