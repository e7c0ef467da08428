//! Which file a recorder writes: the one its declaration names, unless a recorder of the same
//! run wrote that one already — a recorder restarted after a crash, or the recorder of an
//! assembly loaded a second time — which then writes `NAME.1.h5`, `NAME.2.h5`, ... so that
//! nothing recorded before is lost. A file of an earlier run is replaced.
//!
//! "The same run" is the supervisor's: every process it starts gets the run's start as
//! `MODBOT_EPOCH_NS` (CLOCK_MONOTONIC), and a file changed since then belongs to this run.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use modbot_core::transport::launch::EPOCH_NS;

/// The file to write for a declaration naming `wanted`.
pub fn choose(wanted: &Path) -> PathBuf {
    choose_since(wanted, run_start())
}

/// Like [`choose`], for a run that started at `start` (`None`: no run; `wanted` is replaced).
pub fn choose_since(wanted: &Path, start: Option<SystemTime>) -> PathBuf {
    let Some(start) = start else {
        return wanted.to_path_buf();
    };
    let ours = |p: &Path| {
        std::fs::metadata(p)
            .and_then(|m| m.modified())
            .is_ok_and(|t| t >= start)
    };
    candidates(wanted)
        .find(|p| !ours(p))
        .unwrap_or_else(|| wanted.to_path_buf())
}

/// The files a declaration naming `wanted` may write, in the order they are taken: `wanted`,
/// then `NAME.1.EXT`, `NAME.2.EXT`, ...
pub fn candidates(wanted: &Path) -> impl Iterator<Item = PathBuf> + '_ {
    let stem = wanted
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let ext = wanted.extension().map(|e| e.to_string_lossy().into_owned());
    let numbered = (1..).map(move |n| {
        let name = match &ext {
            Some(ext) => format!("{stem}.{n}.{ext}"),
            None => format!("{stem}.{n}"),
        };
        wanted.with_file_name(name)
    });
    std::iter::once(wanted.to_path_buf()).chain(numbered)
}

/// The run's start on the wall clock, from `MODBOT_EPOCH_NS` (`None` without a supervisor).
fn run_start() -> Option<SystemTime> {
    let epoch_ns: u64 = std::env::var(EPOCH_NS).ok()?.parse().ok()?;
    let now = nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC).ok()?;
    let now_ns =
        u64::try_from(now.tv_sec()).ok()? * 1_000_000_000 + u64::try_from(now.tv_nsec()).ok()?;
    let since = Duration::from_nanos(now_ns.checked_sub(epoch_ns)?);
    SystemTime::now().checked_sub(since)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_of_this_run_is_kept_and_one_of_an_earlier_run_replaced() {
        let dir = std::env::temp_dir().join(format!("modbot-record-path-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let wanted = dir.join("run.h5");
        let before = SystemTime::now() - Duration::from_secs(3600);
        assert_eq!(
            choose_since(&wanted, Some(before)),
            wanted,
            "nothing there yet"
        );
        std::fs::write(&wanted, b"first").unwrap();
        assert_eq!(choose_since(&wanted, Some(before)), dir.join("run.1.h5"));
        std::fs::write(dir.join("run.1.h5"), b"second").unwrap();
        assert_eq!(choose_since(&wanted, Some(before)), dir.join("run.2.h5"));
        let later = SystemTime::now() + Duration::from_secs(3600);
        assert_eq!(
            choose_since(&wanted, Some(later)),
            wanted,
            "an earlier run's"
        );
        assert_eq!(choose_since(&wanted, None), wanted, "no run");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
