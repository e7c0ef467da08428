//! A system under `modbot up`, as the grid, scale, fault and swap benchmarks start, watch
//! and stop it.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_core::{CallOptions, Domain, IpcTransport, Module, ModuleBuilder, ReceiveMode};
use modbot_ipc_schema::{ArgError, Args};
use modbot_supervisor::status;

use crate::opts::Opts;
use crate::procs::{self, Proc};

/// A system running under `modbot up`, started by a benchmark: every line the supervisor
/// printed with the instant it arrived here, a tool endpoint in this process for calls, and a
/// stop that leaves nothing behind. Dropping it (on an error) stops the system too.
pub struct Supervised {
    pub domain: Domain,
    /// When `modbot up` was spawned.
    pub spawned: Instant,
    up: Option<Proc>,
    lines: Arc<Mutex<Vec<(Instant, String)>>>,
    tool: Option<Module<()>>,
}

impl Supervised {
    /// Spawns `modbot up FILE ARGS...` (the description names `domain`); it dies with this
    /// process and gets `grace` to stop after SIGTERM.
    pub fn start(
        opts: &Opts,
        domain: &Domain,
        file: &Path,
        args: &[String],
        grace: Duration,
    ) -> anyhow::Result<Supervised> {
        Supervised::start_with_env(opts, domain, file, args, grace, &[])
    }

    /// Like [`Supervised::start`], with variables `env` for `modbot up` (which its modules
    /// inherit): the soak's `MODBOT_DATA_DIR`, say.
    pub fn start_with_env(
        opts: &Opts,
        domain: &Domain,
        file: &Path,
        args: &[String],
        grace: Duration,
        env: &[(&str, &Path)],
    ) -> anyhow::Result<Supervised> {
        let modbot = procs::binary(opts, "modbot")?;
        let mut cmd = Command::new(&modbot);
        cmd.arg("up")
            .arg(file)
            .args(args)
            .envs(env.iter().copied())
            .env("MODBOT_DOMAIN", domain.name())
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        die_with_parent(&mut cmd);
        let spawned = Instant::now();
        let mut child = cmd
            .spawn()
            .with_context(|| format!("cannot start {} up", modbot.display()))?;
        let lines = Arc::new(Mutex::new(Vec::new()));
        if let Some(out) = child.stdout.take() {
            read_lines(out, lines.clone());
        }
        if let Some(err) = child.stderr.take() {
            read_lines(err, lines.clone());
        }
        Ok(Supervised {
            domain: domain.clone(),
            spawned,
            up: Some(Proc::new(child, "modbot up").with_grace(grace)),
            lines,
            tool: None,
        })
    }

    /// The pid of `modbot up` (the supervisor).
    pub fn up_pid(&self) -> u32 {
        self.up.as_ref().map_or(0, Proc::pid)
    }

    /// The first line arrived at or after `after` for which `pred` holds, waiting up to
    /// `timeout`; an error if `modbot up` exits first.
    pub fn wait_line(
        &mut self,
        what: &str,
        after: Instant,
        timeout: Duration,
        pred: impl Fn(&str) -> bool,
    ) -> anyhow::Result<(Instant, String)> {
        let mut seen = 0;
        let end = Instant::now() + timeout;
        let mut exited = false;
        loop {
            {
                let lines = self.lines.lock().unwrap_or_else(|p| p.into_inner());
                if let Some((t, l)) = lines[seen..].iter().find(|(t, l)| *t >= after && pred(l)) {
                    return Ok((*t, l.clone()));
                }
                seen = lines.len();
            }
            if exited {
                bail!(
                    "modbot up exited while waiting for {what}; its last lines:\n{}",
                    self.tail(20)
                );
            }
            if let Some(up) = self.up.as_mut() {
                if up.check_running().is_err() {
                    // One more look once the readers have the last lines.
                    exited = true;
                    std::thread::sleep(Duration::from_millis(50));
                    continue;
                }
            }
            if Instant::now() > end {
                bail!(
                    "timed out after {timeout:?} waiting for {what}; the last lines of modbot up:\n{}",
                    self.tail(20)
                );
            }
            procs::check_interrupted()?;
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Waits for the supervisor's "all N module(s) up in X ms"; returns the time from the spawn.
    pub fn wait_up(&mut self, timeout: Duration) -> anyhow::Result<Duration> {
        let (t, _) = self.wait_line("every module to be up", self.spawned, timeout, |l| {
            l.contains("| all ") && l.contains("module(s) up in")
        })?;
        Ok(t - self.spawned)
    }

    /// Polls `f` every 2 ms until it gives a value, `timeout` passes or `modbot up` exits.
    pub fn wait_for<T>(
        &mut self,
        what: &str,
        timeout: Duration,
        mut f: impl FnMut() -> anyhow::Result<Option<T>>,
    ) -> anyhow::Result<T> {
        self.poll_until(what, timeout, |_| f())
    }

    /// Like [`Supervised::wait_for`] with the tool endpoint passed to `f`.
    pub fn wait_with_tool<T>(
        &mut self,
        what: &str,
        timeout: Duration,
        mut f: impl FnMut(&mut Module<()>) -> anyhow::Result<Option<T>>,
    ) -> anyhow::Result<T> {
        self.poll_until(what, timeout, |s| f(s.tool()?))
    }

    fn poll_until<T>(
        &mut self,
        what: &str,
        timeout: Duration,
        mut f: impl FnMut(&mut Self) -> anyhow::Result<Option<T>>,
    ) -> anyhow::Result<T> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(v) = f(self)? {
                return Ok(v);
            }
            self.check_running()?;
            if Instant::now() > end {
                bail!(
                    "timed out after {timeout:?} waiting for {what}; the last lines of modbot up:\n{}",
                    self.tail(20)
                );
            }
            procs::check_interrupted()?;
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Sleeps, but returns an error at once if `modbot up` exits meanwhile.
    pub fn sleep(&mut self, d: Duration) -> anyhow::Result<()> {
        let end = Instant::now() + d;
        while Instant::now() < end {
            self.check_running()?;
            procs::check_interrupted()?;
            std::thread::sleep(Duration::from_millis(5).min(end - Instant::now()));
        }
        Ok(())
    }

    /// An error (with its last lines) if `modbot up` has exited.
    pub fn check_running(&mut self) -> anyhow::Result<()> {
        let running = self.up.as_mut().map(Proc::check_running);
        match running {
            Some(Err(e)) => {
                std::thread::sleep(Duration::from_millis(50));
                Err(e.context(format!("its last lines:\n{}", self.tail(20))))
            }
            _ => Ok(()),
        }
    }

    /// The last `n` lines `modbot up` printed.
    pub fn tail(&self, n: usize) -> String {
        let lines = self.lines.lock().unwrap_or_else(|p| p.into_inner());
        let from = lines.len().saturating_sub(n);
        lines[from..]
            .iter()
            .map(|(_, l)| l.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Every line so far that holds `needle`.
    pub fn lines_with(&self, needle: &str) -> Vec<String> {
        let lines = self.lines.lock().unwrap_or_else(|p| p.into_inner());
        lines
            .iter()
            .filter(|(_, l)| l.contains(needle))
            .map(|(_, l)| l.clone())
            .collect()
    }

    /// A tool endpoint of this process in the system's domain (opened on first use).
    pub fn tool(&mut self) -> anyhow::Result<&mut Module<()>> {
        if self.tool.is_none() {
            let tool = ModuleBuilder::new("bench", 0)
                .mode(ReceiveMode::Blocking)
                .open_tool(IpcTransport::new(&self.domain)?, ())
                .context("the benchmark cannot join the system's domain")?;
            self.tool = Some(tool);
        }
        self.tool.as_mut().context("no tool endpoint")
    }

    /// Calls a method that answers one text value.
    pub fn call_text(&mut self, module: &str, method: &str) -> anyhow::Result<String> {
        self.call_one(module, method, |a| a.text(0).map(str::to_owned))
    }

    /// Calls a method that answers one bytes value.
    pub fn call_bytes(&mut self, module: &str, method: &str) -> anyhow::Result<Vec<u8>> {
        self.call_one(module, method, |a| a.bytes(0).map(<[u8]>::to_vec))
    }

    /// Calls a method without arguments and picks its answer.
    fn call_one<T>(
        &mut self,
        module: &str,
        method: &str,
        pick: impl FnOnce(&Args<'_>) -> Result<T, ArgError>,
    ) -> anyhow::Result<T> {
        self.tool()?.call_blocking(
            module,
            method,
            &[],
            CallOptions::timeout(Duration::from_secs(1)),
            |r| match r {
                Ok(a) => pick(a).map_err(|e| anyhow::anyhow!("{module}.{method}: {e}")),
                Err(e) => Err(anyhow::anyhow!("{module}.{method}: {e}")),
            },
        )
    }

    /// The supervisor's table (`modbot ls`).
    pub fn status(&mut self) -> anyhow::Result<Vec<status::Row>> {
        let bytes = self.call_bytes("supervisor", "status")?;
        status::decode(&bytes).context("supervisor.status")
    }

    /// The pid of the running module `name`.
    pub fn pid_of(&mut self, name: &str) -> anyhow::Result<u32> {
        let rows = self.status()?;
        rows.iter()
            .find(|r| r.name == name && r.pid != 0 && r.state == "running")
            .map(|r| r.pid)
            .with_context(|| format!("module {name} is not running: {rows:?}"))
    }

    /// Stops the system (SIGTERM to `modbot up`, SIGKILL after the grace period) and returns
    /// the domain's files that were left (removed now), with how `modbot up` ended.
    pub fn stop(mut self) -> anyhow::Result<Vec<PathBuf>> {
        Ok(self.stop_with_status()?.1)
    }

    /// Like [`Supervised::stop`], with `modbot up`'s exit status.
    pub fn stop_with_status(
        &mut self,
    ) -> anyhow::Result<(Option<std::process::ExitStatus>, Vec<PathBuf>)> {
        self.tool = None;
        let status = match self.up.take() {
            Some(up) => Some(up.stop()?),
            None => None,
        };
        // Let the last module processes (killed with the supervisor) go.
        let end = Instant::now() + Duration::from_secs(2);
        while !self.domain.files().is_empty() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(20));
        }
        let left = self.domain.files();
        if !left.is_empty() {
            self.domain.remove_files();
        }
        Ok((status, left))
    }
}

impl Drop for Supervised {
    fn drop(&mut self) {
        self.tool = None;
        drop(self.up.take());
        self.domain.remove_files();
    }
}

/// `cmd`'s process gets SIGTERM when this thread ends (so a killed benchmark stops its
/// systems).
pub fn die_with_parent(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: the closure runs in the child between fork and exec; it only calls prctl, which is
    // async-signal-safe, and allocates nothing.
    unsafe {
        cmd.pre_exec(|| {
            let rc = nix::libc::prctl(
                nix::libc::PR_SET_PDEATHSIG,
                nix::libc::SIGTERM as nix::libc::c_ulong,
                0,
                0,
                0,
            );
            if rc != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

/// A line the supervisor itself printed (`modbot | ...`), not one of a module's.
pub fn is_supervisor_line(line: &str) -> bool {
    line.trim_start().starts_with("modbot |")
}

/// Stores each line of `stream` with the instant it arrived, from a thread of its own; the
/// supervisor's status table (reprinted on every change: 254 lines at a time for a big system)
/// is left out.
fn read_lines(stream: impl Read + Send + 'static, lines: Arc<Mutex<Vec<(Instant, String)>>>) {
    std::thread::spawn(move || {
        for line in BufReader::new(stream).lines() {
            let Ok(line) = line else { break };
            if is_table_line(&line) {
                continue;
            }
            let now = Instant::now();
            lines
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push((now, line));
        }
    });
}

/// A line of the supervisor's status table: its header, or a row (`  12  m12  running ...`).
fn is_table_line(line: &str) -> bool {
    let t = line.trim_start();
    t.starts_with("ADDR  NAME")
        || (t
            .split_whitespace()
            .next()
            .is_some_and(|w| w.parse::<u8>().is_ok())
            && t.split_whitespace().count() >= 6)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_table_lines_are_told_from_the_supervisors_lines() {
        assert!(is_table_line(
            "ADDR  NAME  STATE           PID RESTARTS  LAST EXIT"
        ));
        assert!(is_table_line(
            "  45  m45   running       10727        0  -                                  0       0       0"
        ));
        assert!(!is_table_line("modbot | all 16 module(s) up in 588 ms"));
        assert!(!is_table_line(
            "victim | 2026-11-23 INFO module victim is up"
        ));
    }

    #[test]
    fn supervisor_lines_are_told_from_module_lines() {
        assert!(is_supervisor_line(
            "   modbot | victim ended (killed by SIGKILL); restart 1 in 10 ms"
        ));
        assert!(!is_supervisor_line("victim | INFO module victim is up"));
    }
}
