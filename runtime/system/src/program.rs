//! From a program name in a description to the executable to spawn.
//!
//! [`ProgramResolver`] is the seam: the loader asks it for every module's program, and an
//! unknown program is an error of the description. [`DefaultResolver`] is what `modbot` uses;
//! tests pass a closure (`|name: &str| Some(PathBuf::from(name))`).

use std::ffi::OsString;
use std::path::{Component, Path, PathBuf};

/// Finds the executable for a program name written in a description.
pub trait ProgramResolver {
    /// The executable for `program`, or `None` when there is none.
    fn resolve(&self, program: &str) -> Option<PathBuf>;

    /// Where [`ProgramResolver::resolve`] looked, for the message when it found nothing, e.g.
    /// "not found next to modbot (/opt/robot/bin) or on $PATH".
    fn searched(&self, program: &str) -> String {
        let _ = program;
        "not found".to_owned()
    }
}

impl<F: Fn(&str) -> Option<PathBuf>> ProgramResolver for F {
    fn resolve(&self, program: &str) -> Option<PathBuf> {
        self(program)
    }
}

/// The resolver of the `modbot` command.
///
/// - A name containing `/` is a path: relative to the description file's directory, then to
///   the current directory.
/// - Any other name is looked up next to the running executable (so `target/release/modbot`
///   finds `target/release/modbot-sonar`), then on `$PATH`.
///
/// Only an executable regular file (after following links) counts. Found paths are absolute.
#[derive(Debug, Clone)]
pub struct DefaultResolver {
    /// The description file's directory: relative program paths are tried here first.
    description_dir: Option<PathBuf>,
    /// The current directory, the second place for relative program paths.
    cwd: Option<PathBuf>,
    /// The running executable's directory: cargo puts the module programs next to `modbot`.
    exe_dir: Option<PathBuf>,
    /// The running executable's file name, for messages ("next to modbot").
    exe_name: String,
    /// The search path for bare names, `$PATH` when the resolver was made.
    search_path: Option<OsString>,
}

impl Default for DefaultResolver {
    fn default() -> Self {
        DefaultResolver::new()
    }
}

impl DefaultResolver {
    /// A resolver for descriptions given as text: relative paths are taken from the current
    /// directory only.
    pub fn new() -> DefaultResolver {
        let exe = std::env::current_exe().ok();
        DefaultResolver {
            description_dir: None,
            cwd: std::env::current_dir().ok(),
            exe_dir: exe.as_deref().and_then(Path::parent).map(Path::to_path_buf),
            exe_name: exe
                .as_deref()
                .and_then(Path::file_name)
                .map_or_else(|| "modbot".to_owned(), |n| n.to_string_lossy().into_owned()),
            search_path: std::env::var_os("PATH"),
        }
    }

    /// A resolver for the description file `description`: relative paths are taken from its
    /// directory first.
    pub fn for_file(description: &Path) -> DefaultResolver {
        let mut sut = DefaultResolver::new();
        let dir = description.parent().unwrap_or(Path::new(""));
        sut.description_dir = Some(match &sut.cwd {
            Some(cwd) => cwd.join(dir),
            None => dir.to_path_buf(),
        });
        sut
    }

    /// Looks for bare names in `dir` instead of the running executable's directory.
    pub fn with_exe_dir(mut self, dir: impl Into<PathBuf>) -> DefaultResolver {
        self.exe_dir = Some(dir.into());
        self
    }

    /// Uses `path` (a `$PATH`-style list) as the search path for bare names.
    pub fn with_search_path(mut self, path: impl Into<OsString>) -> DefaultResolver {
        self.search_path = Some(path.into());
        self
    }

    /// The places tried for `program`, in order.
    fn candidates(&self, name: &str) -> Vec<PathBuf> {
        let program = Path::new(name);
        if program.is_absolute() {
            return vec![program.to_path_buf()];
        }
        if name.contains('/') {
            // Without `.` components, so `./bin/x` is reported as `DIR/bin/x`.
            let program: PathBuf = program
                .components()
                .filter(|c| *c != Component::CurDir)
                .collect();
            return [&self.description_dir, &self.cwd]
                .into_iter()
                .flatten()
                .map(|dir| dir.join(&program))
                .collect();
        }
        let on_path = self
            .search_path
            .iter()
            .flat_map(std::env::split_paths)
            .filter(|dir| !dir.as_os_str().is_empty());
        self.exe_dir
            .iter()
            .cloned()
            .chain(on_path)
            .map(|dir| dir.join(program))
            .collect()
    }

    fn absolute(&self, path: PathBuf) -> PathBuf {
        match &self.cwd {
            Some(cwd) if path.is_relative() => cwd.join(path),
            _ => path,
        }
    }
}

impl ProgramResolver for DefaultResolver {
    fn resolve(&self, program: &str) -> Option<PathBuf> {
        if program.is_empty() {
            return None;
        }
        self.candidates(program)
            .into_iter()
            .find(|p| is_executable_file(p))
            .map(|p| self.absolute(p))
    }

    fn searched(&self, program: &str) -> String {
        if program.contains('/') {
            let tried: Vec<String> = self
                .candidates(program)
                .iter()
                .map(|p| p.display().to_string())
                .collect();
            return format!("no executable file at {}", tried.join(" nor at "));
        }
        match &self.exe_dir {
            Some(dir) => format!(
                "not found next to {} ({}) or on $PATH",
                self.exe_name,
                dir.display()
            ),
            None => "not found on $PATH".to_owned(),
        }
    }
}

/// Whether `path` is a regular file (after links) that someone may execute.
fn is_executable_file(path: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

#[cfg(test)]
mod tests {
    use std::fs;
    use std::os::unix::fs::PermissionsExt;

    use super::*;

    /// A scratch directory removed on drop.
    struct Scratch(PathBuf);

    impl Scratch {
        fn new(tag: &str) -> Scratch {
            use std::sync::atomic::{AtomicU32, Ordering};
            static NEXT: AtomicU32 = AtomicU32::new(0);
            let n = NEXT.fetch_add(1, Ordering::Relaxed);
            let dir = std::env::temp_dir()
                .join(format!("modbot-program-{tag}-{}-{n}", std::process::id()));
            fs::create_dir_all(&dir).unwrap();
            Scratch(dir)
        }

        fn file(&self, name: &str, mode: u32) -> PathBuf {
            let path = self.0.join(name);
            if let Some(parent) = path.parent() {
                fs::create_dir_all(parent).unwrap();
            }
            fs::write(&path, "#!/bin/sh\n").unwrap();
            fs::set_permissions(&path, fs::Permissions::from_mode(mode)).unwrap();
            path
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn bare_name_is_found_next_to_the_executable_before_the_search_path() {
        let exe = Scratch::new("exe");
        let on_path = Scratch::new("path");
        let near = exe.file("modbot-sonar", 0o755);
        on_path.file("modbot-sonar", 0o755);
        let sut = DefaultResolver::new()
            .with_exe_dir(&exe.0)
            .with_search_path(&on_path.0);
        assert_eq!(sut.resolve("modbot-sonar"), Some(near));
    }

    #[test]
    fn bare_name_is_found_on_the_search_path() {
        let exe = Scratch::new("exe");
        let on_path = Scratch::new("path");
        let found = on_path.file("modbot-mobility", 0o755);
        let sut = DefaultResolver::new()
            .with_exe_dir(&exe.0)
            .with_search_path(
                std::env::join_paths([Path::new("/nonexistent"), &on_path.0]).unwrap(),
            );
        assert_eq!(sut.resolve("modbot-mobility"), Some(found));
    }

    #[test]
    fn file_that_is_not_executable_or_not_a_file_does_not_count() {
        let exe = Scratch::new("exe");
        exe.file("plain", 0o644);
        fs::create_dir_all(exe.0.join("dir")).unwrap();
        let sut = DefaultResolver::new()
            .with_exe_dir(&exe.0)
            .with_search_path("");
        assert_eq!(sut.resolve("plain"), None);
        assert_eq!(sut.resolve("dir"), None);
        assert_eq!(sut.resolve(""), None);
    }

    #[test]
    fn relative_path_is_taken_from_the_description_directory() {
        let root = Scratch::new("desc");
        let program = root.file("bin/controller", 0o755);
        let sut = DefaultResolver::for_file(&root.0.join("robot.lua"));
        assert_eq!(sut.resolve("bin/controller"), Some(program.clone()));
        assert_eq!(sut.resolve("./bin/controller"), Some(program.clone()));
        assert_eq!(sut.resolve(program.to_str().unwrap()), Some(program));
        assert_eq!(sut.resolve("bin/missing"), None);
        assert!(sut
            .searched("bin/missing")
            .starts_with("no executable file at "));
    }

    #[test]
    fn message_for_a_missing_name_says_where_it_looked() {
        let sut = DefaultResolver::new().with_exe_dir("/opt/robot/bin");
        assert!(sut
            .searched("modbot-sonr")
            .ends_with("(/opt/robot/bin) or on $PATH"));
    }
}
