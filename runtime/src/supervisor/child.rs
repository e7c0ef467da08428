//! Starting one module process: its command line and environment, its death with the
//! supervisor, and its log lines.

use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};

use crossbeam::channel::Sender;

use super::env;
use crate::domain::Domain;
use crate::system::{ModuleSpec, Supervision};

/// A line a module printed, tagged with the module's index in the system description.
#[derive(Debug)]
pub struct LogLine {
    pub module: usize,
    pub line: String,
}

/// Starts the module process of `spec`, with its output sent line by line to `logs`.
///
/// The child is in a process group of its own (a Ctrl-C at the terminal reaches only the
/// supervisor, which stops the modules in order) and gets SIGKILL when the supervisor dies,
/// however it dies.
pub fn spawn(
    index: usize,
    spec: &ModuleSpec,
    domain: &Domain,
    supervision: &Supervision,
    logs: &Sender<LogLine>,
) -> std::io::Result<Child> {
    let mut cmd = Command::new(&spec.program);
    cmd.arg("--domain")
        .arg(domain.name())
        .arg("--name")
        .arg(&spec.name)
        .arg("--addr")
        .arg(spec.addr.to_string())
        .arg("--mode")
        .arg(match spec.mode {
            crate::ReceiveMode::BusyPoll => "busy",
            crate::ReceiveMode::Blocking => "blocking",
        })
        .args(&spec.args)
        .envs(spec.env.iter().map(|(k, v)| (k, v)))
        .env(env::DOMAIN, domain.name())
        .env(env::GROUPS, spec.groups.join(","))
        .env(
            env::HEARTBEAT_MS,
            supervision.heartbeat_period.as_millis().max(1).to_string(),
        )
        .env(env::MLOCKALL, if spec.mlock { "1" } else { "0" })
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0);
    let parent = std::process::id() as libc::pid_t;
    // SAFETY: the closure runs in the child between fork and exec and calls only prctl and
    // getppid, which are async-signal-safe; it allocates nothing and touches no locks.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(
                libc::PR_SET_PDEATHSIG,
                libc::SIGKILL as libc::c_ulong,
                0,
                0,
                0,
            ) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            // The supervisor may have died before prctl took effect: then no signal would come.
            if libc::getppid() != parent {
                return Err(std::io::Error::other(
                    "the supervisor exited during start-up",
                ));
            }
            Ok(())
        })
    };
    let mut child = cmd.spawn()?;
    if let Some(out) = child.stdout.take() {
        forward_lines(index, out, logs.clone());
    }
    if let Some(err) = child.stderr.take() {
        forward_lines(index, err, logs.clone());
    }
    Ok(child)
}

/// Sends each line of `stream` to `logs` from a thread of its own, until the stream ends.
fn forward_lines(module: usize, stream: impl Read + Send + 'static, logs: Sender<LogLine>) {
    let spawned = std::thread::Builder::new()
        .name(format!("log-{module}"))
        .spawn(move || {
            for line in BufReader::new(stream).lines() {
                let Ok(line) = line else { break };
                if logs.send(LogLine { module, line }).is_err() {
                    break;
                }
            }
        });
    if let Err(e) = spawned {
        tracing::warn!("module {module}'s output is not shown: no thread to read it ({e})");
    }
}
