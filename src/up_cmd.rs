//! `modbot up FILE` and `modbot down`: run a system under the supervisor, and stop it.

use std::path::Path;
use std::process::ExitCode;
use std::time::Duration;

use modbot_core::signals::Shutdown;
use modbot_core::{Domain, IpcTransport};
use modbot_supervisor::processes::{self, GridRun};
use modbot_supervisor::{status, RunOptions, Supervisor, SupervisorError};
use modbot_system::{self as system, DefaultResolver};

/// `modbot up FILE [--for SECONDS] [--var KEY=VALUE]... [--ticks N] [--trace OUT]`; `domain`,
/// when the command line (or MODBOT_DOMAIN) gives one, overrides the description's.
pub fn up(
    file: &Path,
    domain: Option<&str>,
    run_for: Option<f64>,
    vars: &[(String, String)],
    grid_run: &GridRun,
    station: Option<&str>,
) -> anyhow::Result<ExitCode> {
    let resolver = DefaultResolver::for_file(file);
    // The domain from the command line is the system's from the start: the assembly data its
    // assembly files read is that domain's too (where its robot programs write).
    let mut spec = match system::load_in_domain(file, &resolver, vars, domain) {
        Ok(spec) => spec,
        Err(e) => {
            eprintln!("modbot up: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    if let Some(given) = domain {
        tracing::info!("domain '{given}' from the command line");
    }
    let replayable = spec
        .grid
        .as_ref()
        .and_then(crate::replay_keep::Replayable::of);
    let asked = vars
        .iter()
        .any(|(k, v)| k == system::REPLAY_VAR && v == "true");
    if asked && replayable.is_none() {
        eprintln!(
            "modbot up: --replayable: nothing is recorded to a file; give --record FILE (the \
             description's record {{ }} without a file, or none)"
        );
        return Ok(ExitCode::from(2));
    }
    let mut grid_run = grid_run.clone();
    if let Some(r) = &replayable {
        grid_run.replay_log = Some(r.log.clone());
    }
    if let Err(e) = processes::add_processes(&mut spec, &resolver, file, &grid_run) {
        eprintln!("modbot up: {e}");
        return Ok(ExitCode::from(2));
    }
    // Again, with the clock `--lockstep` set.
    let run_id = format!(
        "{}-{}-{}",
        spec.domain,
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos()),
        std::process::id()
    );
    let replayable = spec
        .grid
        .as_ref()
        .and_then(crate::replay_keep::Replayable::of)
        .map(|r| r.of_run(run_id));
    let run_for = match run_for {
        Some(s) if s.is_finite() && s >= 0.0 => Some(Duration::from_secs_f64(s)),
        Some(s) => anyhow::bail!("--for {s}: expected a number of seconds >= 0"),
        None => None,
    };
    let domain = Domain::new(&spec.domain)?;
    let shutdown = match Shutdown::on_signals() {
        Ok(s) => s,
        Err(e) => anyhow::bail!("cannot handle SIGINT/SIGTERM: {e}"),
    };
    let sup = match Supervisor::start(spec, shutdown) {
        Ok(sup) => sup,
        Err(e) => {
            // What this run started is stopped by now; a domain another system uses is
            // left alone.
            if !matches!(e, SupervisorError::DomainInUse { .. }) {
                sweep(&domain);
            }
            eprintln!("modbot up: {e}");
            return Ok(ExitCode::from(1));
        }
    };
    // A node of this process while the run ends and the recording takes the checked grids in:
    // a tool leaving the domain meanwhile (`modbot down` itself) sees a live process and does
    // not remove the domain's last files, the grids' images among them.
    let keeping = replayable.as_ref().and_then(|_| {
        IpcTransport::for_supervisor(&domain)
            .and_then(|t| t.channels(&format!("up.keep.{}", std::process::id())))
            .map_err(|e| {
                tracing::warn!("no node to keep the domain's files for the recording: {e}")
            })
            .ok()
    });
    let station = station.and_then(|listen| start_station(&domain, listen));
    let summary = sup.run(&RunOptions {
        run_for,
        show_status: true,
    });
    if let Some(child) = station {
        stop_station(child);
    }
    // Before the sweep: the checked grids of the generations are in the domain.
    let mut kept = true;
    if let Some(r) = &replayable {
        match r.keep(&domain) {
            Ok(()) => println!(
                "modbot up: {} is replayable (modbot replay)",
                r.path().display()
            ),
            Err(e) => {
                eprintln!("modbot up: {e:#}");
                kept = false;
            }
        }
    }
    drop(keeping);
    sweep(&domain);
    println!(
        "modbot up: ran {:.1} s in domain '{}'",
        summary.ran_for.as_secs_f64(),
        domain.name()
    );
    print!("{}", status::table(&summary.rows));
    if summary.ok && kept {
        println!("modbot up: every module stopped cleanly");
        Ok(ExitCode::SUCCESS)
    } else {
        for p in &summary.problems {
            eprintln!("modbot up: {p}");
        }
        Ok(ExitCode::from(1))
    }
}

/// `--station`: the control station (`modbot-station`, next to this program) for the system,
/// on `listen`; it prints its address. It gets SIGTERM when `modbot up` dies. A station that
/// cannot start is said and the system runs without it.
fn start_station(domain: &Domain, listen: &str) -> Option<std::process::Child> {
    use std::os::unix::process::CommandExt;
    let program = std::env::current_exe()
        .ok()?
        .with_file_name("modbot-station");
    let mut command = std::process::Command::new(&program);
    command
        .args(["--domain", domain.name(), "--listen", listen])
        .env_remove("MODBOT_SUPERVISOR");
    // SAFETY: prctl is async-signal-safe and touches only the child being set up.
    unsafe {
        command.pre_exec(|| {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    match command.spawn() {
        Ok(child) => Some(child),
        Err(e) => {
            eprintln!(
                "modbot up: no station: cannot run {}: {e}",
                program.display()
            );
            None
        }
    }
}

/// Stops the station before the domain is cleaned up (SIGTERM: it leaves the domain).
fn stop_station(mut child: std::process::Child) {
    // SAFETY: kill with a pid this process spawned and has not reaped.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGTERM);
    }
    let _ = child.wait();
}

/// Removes what the system left in `domain`, unless a process of the domain still lives (a
/// tool): its files stay, and the last process to leave removes them. A process that is just
/// leaving (a module or tool ending as the system stops; on a loaded machine its node takes a
/// moment to go) is waited for, up to 2 s.
fn sweep(domain: &Domain) {
    match IpcTransport::for_supervisor(domain) {
        Ok(t) => {
            let mut swept = t.sweep_after_system();
            for _ in 0..20 {
                if swept {
                    break;
                }
                std::thread::sleep(Duration::from_millis(100));
                swept = t.sweep_after_system();
            }
            if !swept {
                tracing::info!(
                    "processes still in domain '{}' keep its files",
                    domain.name()
                );
            }
        }
        // The domain is closed to this user (a refused start, which says so itself), say.
        Err(e) => tracing::debug!("cannot clean domain '{}': {e}", domain.name()),
    }
}
