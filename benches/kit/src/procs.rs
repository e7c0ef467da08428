//! The processes of a benchmark: children of this executable, the modbot system binaries next
//! to it, CPU pinning, SCHED_FIFO, and isolated domains that leave nothing behind.
//!
//! Every benchmark runs its sides as separate processes: the measuring side is this process,
//! the other side a child started as `modbot-benches child ROLE ARGS...` ([`spawn_role`]).
//! A child dies with its parent (`PR_SET_PDEATHSIG`), and a [`Proc`] stops its child when it
//! is dropped, so an error or Ctrl-C never leaves a spinning process behind. A [`Scratch`]
//! removes the shared-memory files of the benchmark's domain and its socket files on drop.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_core::Domain;
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

use crate::opts::Opts;

/// A child process, stopped (SIGTERM, then SIGKILL) and reaped when dropped.
#[derive(Debug)]
pub struct Proc {
    child: Child,
    /// What the process is, for error messages.
    label: String,
    /// How long it gets to exit after SIGTERM before SIGKILL.
    grace: Duration,
}

impl Proc {
    /// Takes charge of a started child.
    pub fn new(child: Child, label: impl Into<String>) -> Proc {
        Proc {
            child,
            label: label.into(),
            grace: Duration::from_secs(2),
        }
    }

    /// Starts `cmd` (stdout discarded, stderr inherited).
    pub fn spawn(mut cmd: Command, label: impl Into<String>) -> anyhow::Result<Proc> {
        let label = label.into();
        cmd.stdout(Stdio::null()).stderr(Stdio::inherit());
        let child = cmd
            .spawn()
            .with_context(|| format!("cannot start {label} ({cmd:?})"))?;
        Ok(Proc::new(child, label))
    }

    /// Sets how long the process may take to exit after SIGTERM.
    pub fn with_grace(mut self, grace: Duration) -> Proc {
        self.grace = grace;
        self
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// An error if the process has exited (it should still run).
    pub fn check_running(&mut self) -> anyhow::Result<()> {
        match self.child.try_wait() {
            Ok(Some(status)) => bail!("{} exited early ({status})", self.label),
            Ok(None) => Ok(()),
            Err(e) => bail!("cannot watch {}: {e}", self.label),
        }
    }

    /// Waits up to `timeout` for the process to exit by itself.
    pub fn wait_timeout(&mut self, timeout: Duration) -> anyhow::Result<Option<ExitStatus>> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait()? {
                return Ok(Some(status));
            }
            if Instant::now() >= end {
                return Ok(None);
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// SIGTERM, up to the grace period, then SIGKILL; returns how it ended.
    pub fn stop(mut self) -> anyhow::Result<ExitStatus> {
        self.terminate()
    }

    fn terminate(&mut self) -> anyhow::Result<ExitStatus> {
        if let Some(status) = self.child.try_wait()? {
            return Ok(status);
        }
        let _ = kill(pid(self.child.id()), Signal::SIGTERM);
        if let Some(status) = self.wait_timeout(self.grace)? {
            return Ok(status);
        }
        let _ = self.child.kill();
        Ok(self.child.wait()?)
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Err(e) = self.terminate() {
            eprintln!("warning: stopping {}: {e}", self.label);
        }
    }
}

fn pid(p: u32) -> Pid {
    Pid::from_raw(i32::try_from(p).unwrap_or(i32::MAX))
}

/// Starts this executable as `child ROLE ARGS...`: one side of a benchmark.
pub fn spawn_role(opts: &Opts, role: &str, args: &[String]) -> anyhow::Result<Proc> {
    let mut cmd = Command::new(&opts.exe);
    cmd.arg("child").arg(role).args(args);
    Proc::spawn(cmd, format!("child {role}"))
}

/// Called first in every child: it dies with the benchmark that started it.
pub fn child_setup() {
    if let Err(e) = nix::sys::prctl::set_pdeathsig(Signal::SIGTERM) {
        eprintln!("warning: the child will not follow its parent's death: {e}");
    }
    if let Err(e) = modbot_core::signals::install_termination_handler() {
        eprintln!("warning: cannot handle SIGTERM: {e}");
    }
}

/// Whether this process was asked to stop (SIGTERM/SIGINT).
pub fn interrupted() -> bool {
    modbot_core::signals::termination_requested()
}

/// An error when this process was asked to stop: measuring loops call it now and then.
pub fn check_interrupted() -> anyhow::Result<()> {
    if interrupted() {
        bail!("interrupted");
    }
    Ok(())
}

/// The online cores of this machine, whatever this process is pinned to (unlike
/// `available_parallelism`, which counts only the cores of the affinity mask).
pub fn cores() -> usize {
    std::fs::read_to_string("/sys/devices/system/cpu/online")
        .ok()
        .and_then(|text| count_cpus(text.trim()))
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from))
}

/// Counts a kernel CPU list such as `0-3,6`.
fn count_cpus(list: &str) -> Option<usize> {
    let mut n = 0;
    for part in list.split(',') {
        n += match part.split_once('-') {
            Some((a, b)) => {
                b.parse::<usize>()
                    .ok()?
                    .checked_sub(a.parse::<usize>().ok()?)?
                    + 1
            }
            None => {
                part.parse::<usize>().ok()?;
                1
            }
        };
    }
    (n > 0).then_some(n)
}

/// The core for one side of a two-process benchmark (`side` 0 or 1), if `--pin` was given.
pub fn core_for(opts: &Opts, side: usize) -> Option<usize> {
    opts.pin.then(|| side % cores())
}

/// A core as a child argument: its number, or `-` for "not pinned".
pub fn core_arg(core: Option<usize>) -> String {
    core.map_or_else(|| "-".to_owned(), |c| c.to_string())
}

/// Parses [`core_arg`].
pub fn parse_core(text: &str) -> anyhow::Result<Option<usize>> {
    if text == "-" {
        return Ok(None);
    }
    text.parse()
        .map(Some)
        .with_context(|| format!("core '{text}': expected a number or -"))
}

/// Restores this thread's CPU affinity when dropped.
#[derive(Debug)]
pub struct Pinned {
    before: Option<nix::sched::CpuSet>,
}

impl Drop for Pinned {
    fn drop(&mut self) {
        if let Some(set) = &self.before {
            let _ = nix::sched::sched_setaffinity(Pid::from_raw(0), set);
        }
    }
}

/// Pins this thread (and the children it starts from now) to `core`, until the guard drops.
/// `None` pins nothing.
pub fn pin(core: Option<usize>) -> anyhow::Result<Pinned> {
    let Some(core) = core else {
        return Ok(Pinned { before: None });
    };
    let before =
        nix::sched::sched_getaffinity(Pid::from_raw(0)).context("cannot read the CPU affinity")?;
    let mut set = nix::sched::CpuSet::new();
    set.set(core)
        .with_context(|| format!("core {core} cannot be used for affinity"))?;
    nix::sched::sched_setaffinity(Pid::from_raw(0), &set).with_context(|| {
        format!(
            "cannot pin to core {core} (this machine has cores 0..{})",
            cores() - 1
        )
    })?;
    Ok(Pinned {
        before: Some(before),
    })
}

/// Restores this thread's scheduling policy when dropped.
#[derive(Debug)]
pub struct Fifo {
    before: Option<(i32, i32)>,
}

impl Drop for Fifo {
    fn drop(&mut self) {
        if let Some((policy, prio)) = self.before {
            let _ = set_scheduler(policy, prio);
        }
    }
}

fn set_scheduler(policy: i32, prio: i32) -> std::io::Result<()> {
    let param = nix::libc::sched_param {
        sched_priority: prio,
    };
    // SAFETY: `param` is a valid, initialised sched_param that outlives the call; the kernel
    // only reads it. Pid 0 is the calling thread.
    let rc = unsafe { nix::libc::sched_setscheduler(0, policy, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Runs this thread (and the children it starts from now) under SCHED_FIFO at `prio`, until
/// the guard drops. `None` changes nothing. Never busy-spin under it: RT throttling stalls a
/// spinning FIFO thread for about 50 ms per second.
pub fn set_fifo(prio: Option<u8>) -> anyhow::Result<Fifo> {
    let Some(prio) = prio else {
        return Ok(Fifo { before: None });
    };
    // SAFETY: plain queries of the calling thread's scheduling; `param` is written by the
    // kernel and read only after a successful call.
    let before = unsafe {
        let policy = nix::libc::sched_getscheduler(0);
        let mut param = nix::libc::sched_param { sched_priority: 0 };
        if policy < 0 || nix::libc::sched_getparam(0, &mut param) != 0 {
            None
        } else {
            Some((policy, param.sched_priority))
        }
    };
    set_scheduler(nix::libc::SCHED_FIFO, i32::from(prio)).map_err(|e| {
        anyhow::anyhow!(
            "SCHED_FIFO priority {prio} not permitted ({e}): run as root or grant CAP_SYS_NICE \
             (or leave out --fifo)"
        )
    })?;
    Ok(Fifo { before })
}

/// A domain name of this run: `bench_{pid}_{what}`, at most 40 characters of `[a-z0-9_]`.
pub fn domain_name(what: &str) -> String {
    let clean: String = what
        .chars()
        .map(|c| {
            let c = c.to_ascii_lowercase();
            if c.is_ascii_lowercase() || c.is_ascii_digit() {
                c
            } else {
                '_'
            }
        })
        .collect();
    let mut name = format!("bench_{}_{clean}", std::process::id());
    name.truncate(40);
    name
}

/// Everything of one benchmark that lives outside its processes: its domain's files in
/// /dev/shm and /tmp/iceoryx2, and socket files. Removed when dropped: declare it before the
/// processes (so it drops after them).
#[derive(Debug)]
pub struct Scratch {
    pub domain: Domain,
    paths: Vec<PathBuf>,
}

impl Scratch {
    /// A fresh domain `bench_{pid}_{what}`, with `max_frame` bytes per frame (`None`: the
    /// default). Files a crashed earlier run with the same name left are removed first.
    pub fn new(what: &str, max_frame: Option<usize>) -> anyhow::Result<Scratch> {
        let mut domain = Domain::new(&domain_name(what))?;
        if let Some(bytes) = max_frame {
            domain = domain.with_max_frame(bytes);
        }
        domain.remove_files();
        Ok(Scratch {
            domain,
            paths: Vec::new(),
        })
    }

    /// A path in the temporary directory for a socket, file or directory, removed with the
    /// scratch.
    pub fn path(&mut self, what: &str) -> PathBuf {
        let path = std::env::temp_dir().join(format!("{}_{what}", self.domain.name()));
        remove(&path);
        self.paths.push(path.clone());
        path
    }

    /// Removes everything now (again on drop).
    pub fn clean(&self) {
        self.domain.remove_files();
        for p in &self.paths {
            remove(p);
        }
    }
}

/// Removes the file or directory at `path`, if there is one.
fn remove(path: &Path) {
    if path.is_dir() {
        let _ = std::fs::remove_dir_all(path);
    } else {
        let _ = std::fs::remove_file(path);
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        self.clean();
    }
}

/// The /dev/shm files of `domain`: (bytes reserved, bytes actually in memory).
pub fn shm_usage(domain: &Domain) -> (u64, u64) {
    use std::os::unix::fs::MetadataExt;
    domain
        .files()
        .iter()
        .filter(|p| p.starts_with("/dev/shm"))
        .filter_map(|p| std::fs::metadata(p).ok())
        .fold((0, 0), |(len, used), m| {
            (len + m.len(), used + m.blocks() * 512)
        })
}

/// The modbot system binaries the grid, scale, fault, swap and FMU benchmarks start (and the
/// FMU the last one steps, which the workspace's build puts beside them).
pub const SYSTEM_BINARIES: [&str; 11] = [
    "modbot",
    "modbot-station",
    "modbot-fleet",
    "modbot-coordinator",
    "modbot-host",
    "modbot-bus",
    "modbot-sonar",
    "modbot-faulty",
    "modbot-recorder",
    "modbot-fmu-host",
    "modbot_filter3.fmu",
];

/// The directory of this executable: the workspace's binaries are built there too.
pub fn bin_dir(opts: &Opts) -> anyhow::Result<&Path> {
    opts.exe
        .parent()
        .with_context(|| format!("{} has no parent directory", opts.exe.display()))
}

/// The modbot system binary `name`, next to this executable.
pub fn binary(opts: &Opts, name: &str) -> anyhow::Result<PathBuf> {
    let path = bin_dir(opts)?.join(name);
    if !path.is_file() {
        bail!(
            "{} is missing: build the workspace first (cargo build --release --workspace)",
            path.display()
        );
    }
    Ok(path)
}

/// Makes sure the modbot system binaries are next to this executable. Under `cargo run` (the
/// `CARGO` variable is set) they are built, into the same target directory and profile, when
/// one is missing; otherwise a missing one is an error that says how to build it.
pub fn ensure_binaries(opts: &Opts) -> anyhow::Result<()> {
    let dir = bin_dir(opts)?;
    let missing: Vec<&str> = SYSTEM_BINARIES
        .iter()
        .copied()
        .filter(|b| !dir.join(b).is_file())
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    let Some(cargo) = std::env::var_os("CARGO") else {
        bail!(
            "modbot binaries missing next to {}: {}; build them with \
             `cargo build --release --workspace`",
            opts.exe.display(),
            missing.join(", ")
        );
    };
    // <target>/<profile>/modbot-benches: build into the same target dir and profile.
    let profile = dir
        .file_name()
        .and_then(|p| p.to_str())
        .unwrap_or("release");
    let target = dir
        .parent()
        .with_context(|| format!("{} has no parent directory", dir.display()))?;
    let root = crate::checkout::workspace_root();
    let mut cmd = Command::new(cargo);
    cmd.args([
        "build",
        "--workspace",
        "--exclude",
        "modbot-benches",
        "--bins",
    ])
    .arg("--target-dir")
    .arg(target);
    if profile == "release" {
        cmd.arg("--release");
    } else if profile != "debug" {
        cmd.args(["--profile", profile]);
    }
    if let Some(root) = &root {
        cmd.current_dir(root);
    }
    eprintln!(
        "building the modbot binaries ({} missing): {cmd:?}",
        missing.join(", ")
    );
    let status = cmd
        .stdout(Stdio::inherit())
        .stderr(Stdio::inherit())
        .status()
        .context("cannot run cargo")?;
    if !status.success() {
        bail!("building the modbot binaries failed ({status})");
    }
    let still: Vec<&str> = SYSTEM_BINARIES
        .iter()
        .copied()
        .filter(|b| !dir.join(b).is_file())
        .collect();
    if !still.is_empty() {
        bail!(
            "after the build, still missing in {}: {}",
            dir.display(),
            still.join(", ")
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn domain_names_are_valid_and_short() {
        let name = domain_name("Calls 1MiB/a-very-long-description-of-it");
        assert!(name.len() <= 40);
        assert!(Domain::new(&name).is_ok(), "{name}");
        assert!(name.starts_with(&format!("bench_{}_calls_1mib", std::process::id())));
    }

    #[test]
    fn cpu_lists_are_counted() {
        assert_eq!(count_cpus("0-1"), Some(2));
        assert_eq!(count_cpus("0-3,6"), Some(5));
        assert_eq!(count_cpus("0"), Some(1));
        assert_eq!(count_cpus("x"), None);
        assert_eq!(count_cpus("3-1"), None);
    }

    #[test]
    fn core_arguments_round_trip() {
        assert_eq!(parse_core(&core_arg(Some(1))).unwrap(), Some(1));
        assert_eq!(parse_core(&core_arg(None)).unwrap(), None);
        assert!(parse_core("x").is_err());
    }
}
