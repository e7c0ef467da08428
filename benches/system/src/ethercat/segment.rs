//! The benchmark's own EtherCAT segment: a network namespace with two veth pairs in it, one for
//! the master and the slave emulator, one for the raw ping-pong and its echo. Frames pass only
//! between the two ends of a pair, inside the namespace. The namespace (and with it both pairs)
//! is deleted when the [`Segment`] drops, whatever happened before.
//!
//! The processes of the benchmark run inside the namespace under `ip netns exec` (which execs
//! the program: the pid of the spawned `ip` is the program's). [`Lines`] reads a child's
//! standard output on a thread of its own, so waiting for a line has a timeout.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_kit::procs::Proc;

/// A namespace of this run with its two veth pairs.
#[derive(Debug)]
pub struct Segment {
    /// The namespace (`modbot-bench-…`, unique per run).
    pub ns: String,
    /// The master's end of the first pair.
    pub master: String,
    /// The emulator's end of the first pair.
    pub slaves: String,
    /// The raw ping-pong's end of the second pair.
    pub ping: String,
    /// The echo's end of the second pair.
    pub echo: String,
}

/// Runs `ip ARGS`: an error with what `ip` said.
pub(crate) fn ip(args: &[&str]) -> anyhow::Result<()> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .context("cannot run `ip` (iproute2; ./setup.sh --tests installs it)")?;
    if !out.status.success() {
        bail!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(())
}

impl Segment {
    /// Makes the namespace and both pairs, up, with carrier on all four ends.
    pub fn new() -> anyhow::Result<Segment> {
        let id = format!("{:x}", std::process::id() & 0xfffff);
        let ns = format!("modbot-bench-{id}");
        // A namespace of the same name is a leftover of a crashed run with this pid.
        let _ = Command::new("ip")
            .args(["netns", "del", &ns])
            .stderr(Stdio::null())
            .status();
        ip(&["netns", "add", &ns])?;
        // From here on, dropping the segment deletes the namespace.
        let segment = Segment {
            master: format!("ebm{id}"),
            slaves: format!("ebs{id}"),
            ping: format!("ebp{id}"),
            echo: format!("ebe{id}"),
            ns,
        };
        let ns = segment.ns.as_str();
        for (a, b) in [
            (&segment.master, &segment.slaves),
            (&segment.ping, &segment.echo),
        ] {
            ip(&[
                "-n", ns, "link", "add", a, "type", "veth", "peer", "name", b,
            ])?;
            ip(&["-n", ns, "link", "set", a, "up"])?;
            ip(&["-n", ns, "link", "set", b, "up"])?;
        }
        // Frames sent before both ends have carrier vanish.
        let carrier = |end: &str| {
            Command::new("ip")
                .args(["-n", ns, "link", "show", end])
                .output()
                .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("state UP"))
        };
        let ends = [
            &segment.master,
            &segment.slaves,
            &segment.ping,
            &segment.echo,
        ];
        let deadline = Instant::now() + Duration::from_secs(5);
        while !ends.iter().all(|e| carrier(e)) {
            if Instant::now() > deadline {
                bail!("the veth pairs in {ns} have no carrier after 5 s");
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(segment)
    }

    /// `program` run inside the namespace.
    pub fn exec(&self, program: &Path) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", &self.ns]).arg(program);
        cmd
    }
}

impl Drop for Segment {
    fn drop(&mut self) {
        // Deleting the namespace deletes the veth pairs in it.
        match Command::new("ip").args(["netns", "del", &self.ns]).output() {
            Ok(o) if o.status.success() => {}
            Ok(o) => eprintln!(
                "warning: ip netns del {}: {}",
                self.ns,
                String::from_utf8_lossy(&o.stderr).trim()
            ),
            Err(e) => eprintln!("warning: ip netns del {}: {e}", self.ns),
        }
    }
}

/// A child process with its standard output read line by line on a thread.
pub struct Lines {
    pub proc: Proc,
    lines: mpsc::Receiver<String>,
}

impl Lines {
    /// Starts `cmd` with its standard output piped (stderr inherited).
    pub fn spawn(mut cmd: Command, label: &str) -> anyhow::Result<Lines> {
        cmd.stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        let mut child = cmd
            .spawn()
            .with_context(|| format!("cannot start {label} ({cmd:?})"))?;
        let out = child.stdout.take().context("no stdout")?;
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Ok(Lines {
            proc: Proc::new(child, label),
            lines,
        })
    }

    /// The next line that starts with `prefix` (others are skipped), within `timeout`.
    pub fn wait_for(&mut self, prefix: &str, timeout: Duration) -> anyhow::Result<String> {
        let deadline = Instant::now() + timeout;
        loop {
            modbot_bench_kit::procs::check_interrupted()?;
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!("no line '{prefix}…' within {timeout:?}");
            }
            match self
                .lines
                .recv_timeout(left.min(Duration::from_millis(200)))
            {
                Ok(line) if line.starts_with(prefix) => return Ok(line),
                Ok(_) | Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    self.proc.check_running()?;
                    bail!("the process closed its output before a line '{prefix}…'");
                }
            }
        }
    }
}

/// Puts the main thread of process `pid` under SCHED_FIFO at `prio`: whether it was allowed.
pub fn fifo_for(pid: u32, prio: u8) -> bool {
    let param = nix::libc::sched_param {
        sched_priority: i32::from(prio),
    };
    // SAFETY: `param` is a valid sched_param that outlives the call; the kernel only reads it.
    let rc = unsafe {
        nix::libc::sched_setscheduler(pid as nix::libc::pid_t, nix::libc::SCHED_FIFO, &param)
    };
    rc == 0
}
