//! Real-time settings of a module process: CPU affinity and SCHED_FIFO priority.
//!
//! They are applied by the supervisor to every thread of the process right after it started
//! (threads it creates later inherit them). Where the machine or the user's rights do not
//! permit a setting, the module runs without it and the caller gets a warning that says so.
//! Memory locking is done by the module itself (see [`super::env::MLOCKALL`]).

use nix::sched::{sched_setaffinity, CpuSet};
use nix::unistd::Pid;

pub use modbot_core::realtime::{real_time_thread, runs_fifo};

/// Applies `cpus` (if any) and `priority` (if any) to every thread of process `pid`; returns
/// one warning per setting that could not be applied.
pub fn apply(pid: u32, cpus: &[usize], priority: Option<u8>) -> Vec<String> {
    let mut warnings = Vec::new();
    if cpus.is_empty() && priority.is_none() {
        return warnings;
    }
    let threads = threads_of(pid);
    if !cpus.is_empty() {
        match cpu_set(cpus) {
            Ok(set) => {
                if let Some(e) = threads
                    .iter()
                    .find_map(|&tid| sched_setaffinity(Pid::from_raw(tid), &set).err())
                {
                    warnings.push(format!(
                        "CPU affinity {cpus:?} not applied ({e}); the module runs on any CPU"
                    ));
                }
            }
            Err(w) => warnings.push(w.to_string()),
        }
    }
    if let Some(prio) = priority {
        let param = libc::sched_param {
            sched_priority: i32::from(prio),
        };
        let refused = threads.iter().find_map(|&tid| {
            // SAFETY: `param` is a valid, initialised sched_param that outlives the call; the
            // kernel only reads it. A tid that exited meanwhile just yields ESRCH.
            let rc = unsafe { libc::sched_setscheduler(tid, libc::SCHED_FIFO, &param) };
            (rc != 0).then(std::io::Error::last_os_error)
        });
        if let Some(e) = refused {
            warnings.push(format!(
                "SCHED_FIFO priority {prio} not applied ({e}); the module runs with normal scheduling"
            ));
        }
    }
    warnings
}

/// Why an affinity mask cannot be made of the CPUs asked for.
#[derive(Debug, thiserror::Error)]
enum AffinityError {
    #[error("CPU {cpu} cannot be used for affinity ({source})")]
    Cpu { cpu: usize, source: nix::Error },
    #[error(
        "CPU affinity {cpus:?} not applied: this machine has CPUs 0..{}; the module runs on any \
         CPU",
        .online.saturating_sub(1)
    )]
    NoneOnline { cpus: Vec<usize>, online: usize },
}

fn cpu_set(cpus: &[usize]) -> Result<CpuSet, AffinityError> {
    let online = std::thread::available_parallelism().map_or(1, usize::from);
    let mut set = CpuSet::new();
    let mut usable = 0;
    for &cpu in cpus {
        if cpu >= online {
            continue;
        }
        set.set(cpu)
            .map_err(|source| AffinityError::Cpu { cpu, source })?;
        usable += 1;
    }
    if usable == 0 {
        let cpus = cpus.to_vec();
        return Err(AffinityError::NoneOnline { cpus, online });
    }
    Ok(set)
}

/// The thread ids of process `pid` (just the pid if /proc cannot be read).
fn threads_of(pid: u32) -> Vec<i32> {
    let mut tids: Vec<i32> = std::fs::read_dir(format!("/proc/{pid}/task"))
        .map(|dir| {
            dir.flatten()
                .filter_map(|e| e.file_name().to_str()?.parse().ok())
                .collect()
        })
        .unwrap_or_default();
    if tids.is_empty() {
        tids.push(pid as i32);
    }
    tids
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn affinity_to_a_cpu_the_machine_does_not_have_is_a_warning_not_a_failure() {
        let warnings = apply(std::process::id(), &[4096 - 1], None);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("not applied"), "{warnings:?}");
    }

    #[test]
    fn no_settings_means_nothing_to_apply() {
        assert!(apply(std::process::id(), &[], None).is_empty());
    }
}
