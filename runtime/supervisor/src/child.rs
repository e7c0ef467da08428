//! Starting one module process: its command line and environment, its death with the
//! supervisor, and its log lines.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::thread::JoinHandle;

use crossbeam::channel::Sender;

use super::env;
use modbot_core::domain::Domain;
use modbot_system::{ModuleSpec, Supervision};

/// What every module of one system gets alike, whenever it starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SystemEnv {
    /// When the system started ([`env::EPOCH_NS`]): the same for every module and every
    /// restart.
    pub epoch_ns: u64,
    /// The sender slots of every inbox ([`env::INBOX_SENDERS`]).
    pub inbox_senders: usize,
}

impl SystemEnv {
    /// The system of `modules` modules, started at `epoch_ns`.
    pub fn new(epoch_ns: u64, modules: usize) -> SystemEnv {
        SystemEnv {
            epoch_ns,
            inbox_senders: env::inbox_senders_for(modules),
        }
    }
}

/// A line a module printed, tagged with the module's index in the system description.
#[derive(Debug)]
pub struct LogLine {
    pub module: usize,
    pub line: String,
}

/// The environment variables a module process gets on top of the supervisor's own: the
/// description's `env`, then the supervisor's settings (see [`env`]), which win over a
/// description that sets the same names.
pub(super) fn environment(
    spec: &ModuleSpec,
    domain: &Domain,
    supervision: &Supervision,
    system: &SystemEnv,
) -> BTreeMap<String, String> {
    let mut vars: BTreeMap<String, String> = spec.env.iter().cloned().collect();
    let ours = [
        (env::DOMAIN, domain.name().to_owned()),
        (env::GROUPS, spec.groups.join(",")),
        (
            env::HEARTBEAT_MS,
            supervision.heartbeat_period.as_millis().max(1).to_string(),
        ),
        (env::MLOCKALL, if spec.mlock { "1" } else { "0" }.to_owned()),
        (env::EPOCH_NS, system.epoch_ns.to_string()),
        (env::INBOX_SENDERS, system.inbox_senders.to_string()),
        (env::ASSIGNED, format!("{}.{}", spec.addr, spec.name)),
        (
            env::SUPERVISOR,
            format!("{}.{}", std::process::id(), domain.name()),
        ),
    ];
    for (name, value) in ours {
        vars.insert(name.to_owned(), value);
    }
    vars
}

/// Starts the module process of `spec`, with its output sent line by line to `logs`, and the
/// [`environment`] of its system.
///
/// The child is in a process group of its own (a Ctrl-C at the terminal reaches only the
/// supervisor, which stops the modules in order) and gets SIGKILL when the supervisor dies,
/// however it dies.
pub fn spawn(
    index: usize,
    spec: &ModuleSpec,
    domain: &Domain,
    supervision: &Supervision,
    system: &SystemEnv,
    logs: &Sender<LogLine>,
) -> std::io::Result<(Child, Vec<JoinHandle<()>>)> {
    let mut cmd = Command::new(&spec.program);
    cmd.arg("--domain")
        .arg(domain.name())
        .arg("--name")
        .arg(&spec.name)
        .arg("--addr")
        .arg(spec.addr.to_string())
        .arg("--mode")
        .arg(match spec.mode {
            modbot_core::ReceiveMode::BusyPoll => "busy",
            modbot_core::ReceiveMode::Blocking => "blocking",
        })
        .args(&spec.args)
        .envs(environment(spec, domain, supervision, system))
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
    let mut readers = Vec::new();
    if let Some(out) = child.stdout.take() {
        readers.extend(forward_lines(index, out, logs.clone()));
    }
    if let Some(err) = child.stderr.take() {
        readers.extend(forward_lines(index, err, logs.clone()));
    }
    Ok((child, readers))
}

/// Sends each line of `stream` to `logs` from a thread of its own, until the stream ends.
fn forward_lines(
    module: usize,
    stream: impl Read + Send + 'static,
    logs: Sender<LogLine>,
) -> Option<JoinHandle<()>> {
    let spawned = std::thread::Builder::new()
        .name(format!("log-{module}"))
        .spawn(move || {
            // A child's end wakes the supervisor's loop, not this thread.
            modbot_core::signals::block_child_signal();
            for line in BufReader::new(stream).lines() {
                let Ok(line) = line else { break };
                if logs.send(LogLine { module, line }).is_err() {
                    break;
                }
            }
        });
    match spawned {
        Ok(handle) => Some(handle),
        Err(e) => {
            tracing::warn!("module {module}'s output is not shown: no thread to read it ({e})");
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;
    use modbot_system::RestartPolicy;

    fn module(name: &str, env: &[(&str, &str)]) -> ModuleSpec {
        ModuleSpec {
            name: name.into(),
            addr: 2,
            program: PathBuf::from("/bin/true"),
            program_name: "true".into(),
            args: vec![],
            restart: RestartPolicy::default(),
            cpus: vec![],
            priority: None,
            mlock: false,
            env: env
                .iter()
                .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
                .collect(),
            mode: modbot_core::ReceiveMode::Blocking,
            groups: vec!["sensors".into(), "all".into()],
            line: 1,
        }
    }

    #[test]
    fn every_module_gets_the_systems_epoch_and_the_supervisors_settings() {
        let domain = Domain::new("envtest").unwrap();
        let supervision = Supervision::default();
        let sonar = environment(
            &module("sonar", &[("MODBOT_SIM_SPEED", "2")]),
            &domain,
            &supervision,
            &SystemEnv::new(123_456_789, 2),
        );
        let mobility = environment(
            &module("mobility", &[]),
            &domain,
            &supervision,
            &SystemEnv::new(123_456_789, 2),
        );
        assert_eq!(sonar[env::EPOCH_NS], "123456789");
        assert_eq!(mobility[env::EPOCH_NS], sonar[env::EPOCH_NS]);
        assert_eq!(
            sonar[env::SIM_SPEED],
            "2",
            "the description's env passes through"
        );
        assert_eq!(sonar[env::DOMAIN], "envtest");
        assert_eq!(sonar[env::GROUPS], "sensors,all");
        assert_eq!(sonar[env::HEARTBEAT_MS], "100");
        assert_eq!(sonar[env::MLOCKALL], "0");
        assert_eq!(
            sonar[env::INBOX_SENDERS],
            env::inbox_senders_for(2).to_string(),
            "inboxes are sized to the system"
        );
    }

    #[test]
    fn the_supervisors_settings_win_over_the_description() {
        let domain = Domain::new("envtest").unwrap();
        let sut = environment(
            &module("sonar", &[(env::EPOCH_NS, "1"), (env::DOMAIN, "other")]),
            &domain,
            &Supervision::default(),
            &SystemEnv::new(99, 1),
        );
        assert_eq!(sut[env::EPOCH_NS], "99");
        assert_eq!(sut[env::DOMAIN], "envtest");
    }
}
