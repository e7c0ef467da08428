//! A system's domain: the namespace of all its shared-memory resources.
//!
//! Every iceoryx2 file of a domain starts with the prefix `modbot_<domain>.`: two systems (or
//! two tests) with different domains never see each other. Domain names are `[a-z0-9_]`, so no
//! prefix is a prefix of another domain's.

use std::path::Path;

use thiserror::Error;

/// The largest frame a module's inbox takes by default (a 64 KiB payload plus header room).
pub const DEFAULT_MAX_FRAME: usize = 64 * 1024 + 64;

/// Where iceoryx2 keeps its node and service files for modbot's domains (its default is
/// `/tmp/iceoryx2/`): on tmpfs, beside the shared memory, because a system of 254 modules
/// creates thousands of them while it starts. The `iox2` CLI sees a domain with
/// `root-path = "/dev/shm/iceoryx2/"` besides the domain's prefix in its `[global]` config.
pub const ICEORYX2_ROOT: &str = "/dev/shm/iceoryx2/";

/// A bad domain name.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("invalid domain name '{0}': use 1 to 40 characters of a-z, 0-9 and _")]
pub struct DomainNameError(pub String);

/// Shared memory another user owns, closed to this process.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DomainAccessError {
    /// The domain's files belong to another user: that user started the system.
    #[error(
        "permission denied: domain '{domain}' belongs to uid {owner} (run as that user): {} is \
         closed to uid {user}",
        path.display()
    )]
    Domain {
        domain: String,
        owner: u32,
        user: u32,
        path: std::path::PathBuf,
    },
    /// iceoryx2's directory, shared by every domain of the machine, belongs to another user.
    #[error(
        "permission denied: {} (iceoryx2's directory, shared by every domain) belongs to uid \
         {owner} and is closed to uid {user}: run as that user",
        path.display()
    )]
    Directory {
        owner: u32,
        user: u32,
        path: std::path::PathBuf,
    },
}

/// A domain and the settings its modules share.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Domain {
    name: String,
    max_frame: usize,
}

impl Domain {
    /// The domain `name`.
    pub fn new(name: &str) -> Result<Domain, DomainNameError> {
        let ok = !name.is_empty()
            && name.len() <= 40
            && name
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_');
        if !ok {
            return Err(DomainNameError(name.to_owned()));
        }
        Ok(Domain {
            name: name.to_owned(),
            max_frame: DEFAULT_MAX_FRAME,
        })
    }

    /// Sets the largest frame, in bytes, that an inbox takes. Every module of a domain must
    /// use the same value.
    pub fn with_max_frame(mut self, bytes: usize) -> Domain {
        self.max_frame = bytes.max(64);
        self
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn max_frame(&self) -> usize {
        self.max_frame
    }

    /// The iceoryx2 prefix of every resource of this domain.
    pub fn prefix(&self) -> String {
        format!("modbot_{}.", self.name)
    }

    /// The domain's files in `/dev/shm` (shared memory, and iceoryx2's node and service
    /// files under [`ICEORYX2_ROOT`]), in iceoryx2's default `/tmp/iceoryx2`, and in the
    /// temporary directory (what its processes unpacked there: [`Domain::temp_prefix`]),
    /// whoever left them.
    pub fn files(&self) -> Vec<std::path::PathBuf> {
        let prefix = self.prefix();
        let mut found = Vec::new();
        collect_with_prefix(Path::new("/dev/shm"), &prefix, &mut found);
        collect_with_prefix(Path::new("/tmp/iceoryx2"), &prefix, &mut found);
        collect_top_level(&std::env::temp_dir(), &prefix, &mut found);
        found
    }

    /// The name prefix of what process `pid` of the domain keeps in the temporary directory
    /// (`std::env::temp_dir()`), such as an FMU's unpacked archive:
    /// `modbot_<domain>.tmp.<pid>.`. It is among the domain's [`files`](Domain::files), so it
    /// goes with them, and [`Domain::remove_temp_of`] removes a dead process's at once.
    pub fn temp_prefix(&self, pid: u32) -> String {
        format!("{}tmp.{pid}.", self.prefix())
    }

    /// Removes what process `pid` kept in the temporary directory (call it once the process
    /// is gone); how many entries went.
    pub fn remove_temp_of(&self, pid: u32) -> usize {
        let mut found = Vec::new();
        collect_top_level(&std::env::temp_dir(), &self.temp_prefix(pid), &mut found);
        self.remove(found)
    }

    /// Whether this process may use the domain: `Err` names the user it belongs to when
    /// iceoryx2's directory or a file of the domain is closed to this process's user (another
    /// user started the system). Looked at before anything is created, so a refused start
    /// leaves nothing behind.
    pub fn check_access(&self) -> Result<(), DomainAccessError> {
        use nix::unistd::{access, AccessFlags};
        use std::os::unix::fs::MetadataExt;
        let root = Path::new(ICEORYX2_ROOT.trim_end_matches('/'));
        let dirs = [
            root.to_path_buf(),
            root.join("nodes"),
            root.join("services"),
        ];
        let own_files = self.shm_files();
        // Only a refusal counts: a file that went away meanwhile (iceoryx2 creates and removes
        // them all the time) is no sign of another user.
        let refused = |p: &Path, flags: AccessFlags| {
            matches!(
                access(p, flags),
                Err(nix::errno::Errno::EACCES | nix::errno::Errno::EPERM)
            )
        };
        let closed = dirs
            .iter()
            .find(|d| {
                refused(
                    d.as_path(),
                    AccessFlags::R_OK | AccessFlags::W_OK | AccessFlags::X_OK,
                )
            })
            .or_else(|| {
                own_files
                    .iter()
                    .find(|f| refused(f.as_path(), AccessFlags::R_OK | AccessFlags::W_OK))
            });
        let Some(path) = closed else {
            return Ok(());
        };
        let owner_of = |p: &Path| std::fs::metadata(p).map(|m| m.uid()).unwrap_or(0);
        let user = nix::unistd::geteuid().as_raw();
        // The domain's own files say whose it is; without them it is the directory's owner.
        match own_files.first() {
            Some(file) => Err(DomainAccessError::Domain {
                domain: self.name.clone(),
                owner: owner_of(file),
                user,
                path: path.clone(),
            }),
            None => Err(DomainAccessError::Directory {
                owner: owner_of(path),
                user,
                path: path.clone(),
            }),
        }
    }

    /// Takes group and other permissions off the domain's shared-memory files that have them
    /// (iceoryx2 opens its management segment to everyone): a domain is one user's. Returns
    /// how many it closed.
    pub fn close_shared_files(&self) -> usize {
        use std::os::unix::fs::PermissionsExt;
        let mut closed = 0;
        for f in self.shm_files() {
            let Ok(meta) = std::fs::metadata(&f) else {
                continue;
            };
            let mode = meta.permissions().mode();
            if mode & 0o077 != 0
                && std::fs::set_permissions(&f, std::fs::Permissions::from_mode(mode & 0o700))
                    .is_ok()
            {
                closed += 1;
            }
        }
        closed
    }

    /// The domain's shared-memory files: those directly in `/dev/shm` (iceoryx2's segments and
    /// its management segment; not its node and service files under [`ICEORYX2_ROOT`], which a
    /// process need not walk — at full size they are thousands).
    fn shm_files(&self) -> Vec<std::path::PathBuf> {
        let prefix = self.prefix();
        let Ok(entries) = std::fs::read_dir("/dev/shm") else {
            return Vec::new();
        };
        entries
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
            .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
            .map(|e| e.path())
            .collect()
    }

    /// Removes every file of this domain. Only call it when no module of the domain runs.
    ///
    /// A directory that held only this domain's files (iceoryx2 keeps one per node) goes too.
    pub fn remove_files(&self) -> usize {
        self.remove(self.files())
    }

    /// Removes the domain's files last modified before `time`: what a process that is just
    /// starting in the domain creates is kept.
    pub fn remove_files_older_than(&self, time: std::time::SystemTime) -> usize {
        let files = self
            .files()
            .into_iter()
            .filter(|f| {
                std::fs::symlink_metadata(f)
                    .and_then(|m| m.modified())
                    .is_ok_and(|t| t < time)
            })
            .collect();
        self.remove(files)
    }

    fn remove(&self, files: Vec<std::path::PathBuf>) -> usize {
        let mut removed = 0;
        let mut parents = Vec::new();
        for f in &files {
            let gone = if f.is_dir() {
                std::fs::remove_dir_all(f)
            } else {
                std::fs::remove_file(f)
            };
            if gone.is_ok() {
                removed += 1;
                if let Some(parent) = f.parent() {
                    parents.push(parent.to_path_buf());
                }
            }
        }
        let temp = std::env::temp_dir();
        for dir in parents {
            let is_root = dir == Path::new("/dev/shm")
                || dir == temp
                || dir == Path::new(ICEORYX2_ROOT.trim_end_matches('/'))
                || dir.parent() == Some(Path::new("/tmp"));
            let shared = dir.ends_with("nodes") || dir.ends_with("services");
            if !is_root && !shared {
                // Fails, as it should, if anything else is in it.
                let _ = std::fs::remove_dir(&dir);
            }
        }
        removed
    }
}

fn collect_with_prefix(dir: &Path, prefix: &str, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        if name.to_string_lossy().starts_with(prefix) {
            out.push(path);
        } else if entry.file_type().is_ok_and(|t| t.is_dir()) {
            collect_with_prefix(&path, prefix, out);
        }
    }
}

/// The entries directly in `dir` whose names start with `prefix` (not below: the temporary
/// directory holds everyone's trees).
fn collect_top_level(dir: &Path, prefix: &str, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    out.extend(
        entries
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(prefix))
            .map(|e| e.path()),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn domain_names_are_checked() {
        assert!(Domain::new("robot_1").is_ok());
        assert!(Domain::new("").is_err());
        assert!(Domain::new("Robot").is_err());
        assert!(Domain::new("a.b").is_err());
        assert_eq!(Domain::new("arm").unwrap().prefix(), "modbot_arm.");
    }

    #[test]
    fn a_dead_process_temporary_directory_goes_and_another_ones_stays() {
        let sut = Domain::new(&format!("tmpdirs{}", std::process::id())).unwrap();
        let dead = std::env::temp_dir().join(format!("{}fmu", sut.temp_prefix(7)));
        let live = std::env::temp_dir().join(format!("{}fmu", sut.temp_prefix(77)));
        for dir in [&dead, &live] {
            std::fs::create_dir_all(dir.join("binaries")).unwrap();
            std::fs::write(dir.join("binaries/x.so"), b"x").unwrap();
        }
        assert_eq!(sut.remove_temp_of(7), 1);
        assert!(!dead.exists() && live.exists());
        assert_eq!(
            sut.files(),
            vec![live.clone()],
            "the domain's files include it"
        );
        assert_eq!(sut.remove_files(), 1);
        assert!(!live.exists() && std::env::temp_dir().exists());
    }
}
