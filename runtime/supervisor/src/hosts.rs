//! The host processes of assemblies, started and stopped at the coordinator's request while
//! the system runs: `spawn_host(host, assembly, generation[, program])` and `retire(module)`,
//! handled between the supervisor's other work; and `current_assembly(assembly, generation)`:
//! after a switch, a host of the system's own components (the bus bridge, the recorder) that
//! dies is restarted with the running assembly, not the one the system started with.

use modbot_grid::component::Generation;
use modbot_grid::spec::GridRole;
use modbot_ipc_schema::{Addr, Args};
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;
use thiserror::Error;

use super::assemblies::assembly_generation;
use super::processes::{spec_generation_args, SPEC_GENERATION_ARG};
use super::shared::{HostRequest, Shared};
use super::status::RunState;
use super::{Slot, Supervisor, SupervisorError};
use modbot_core::ctx::Ctx;
use modbot_core::error::MethodError;
use modbot_core::module::Reply;

/// Why a host of an assembly could not be started (`spawn_host`).
#[derive(Debug, Error)]
pub(super) enum SpawnHostError {
    #[error("the system has no assemblies")]
    NoAssemblies,
    #[error("module {name} exists already")]
    Exists { name: String },
    #[error("no address is free")]
    NoAddress,
    #[error("the program '{0}' makes no component type the description declares")]
    UnknownProgram(String),
    #[error(transparent)]
    Spawn(#[from] SupervisorError),
}

impl Supervisor {
    /// Starts and stops the assembly hosts the coordinator asked for.
    pub(super) fn handle_host_requests(&mut self) {
        let requests = std::mem::take(&mut self.endpoint.state_mut().requests);
        for request in requests {
            match request {
                HostRequest::Spawn {
                    host,
                    assembly,
                    generation,
                    program,
                } => {
                    let spawned = self.spawn_host(&host, &assembly, generation, program.as_deref());
                    if let Err(e) = spawned {
                        self.say(&format!(
                            "cannot start host {host} of assembly {assembly}: {e}"
                        ));
                    }
                }
                HostRequest::Retire(name) => self.retire(&name),
                HostRequest::Current {
                    assembly,
                    generation,
                } => self.current_assembly(&assembly, generation),
            }
        }
    }

    fn spawn_host(
        &mut self,
        host: &str,
        assembly: &str,
        generation: Generation,
        program: Option<&str>,
    ) -> Result<(), SpawnHostError> {
        let Some(mut template) = self.spec.host_template.clone() else {
            return Err(SpawnHostError::NoAssemblies);
        };
        if let Some(program) = program {
            let Some((_, path)) = self.spec.host_programs.iter().find(|(n, _)| n == program) else {
                return Err(SpawnHostError::UnknownProgram(program.to_owned()));
            };
            template.program = path.clone();
            template.program_name = program.to_owned();
        }
        let name = modbot_grid::spec::host_module_of(host, generation);
        if let Some(i) = self.spec.modules.iter().position(|m| m.name == name) {
            if self.slots[i].state != RunState::Retired {
                return Err(SpawnHostError::Exists { name });
            }
        }
        let own = self.endpoint.addr().0;
        let busy: Vec<u8> = self
            .spec
            .modules
            .iter()
            .zip(&self.slots)
            .filter(|(_, s)| s.state != RunState::Retired || s.child.is_some())
            .map(|(m, _)| m.addr)
            .collect();
        let addr = (Addr::FIRST..=Addr::LAST)
            .rev()
            .find(|a| *a != own && !busy.contains(a))
            .ok_or(SpawnHostError::NoAddress)?;
        let mut m = template;
        m.name = name.clone();
        m.addr = addr;
        // The template's arguments name the first generation's checked grid: this host serves
        // its assembly's.
        m.args = spec_generation_args(generation);
        m.args.extend(["--host".to_owned(), host.to_owned()]);
        let slot = Slot::new(m.restart.clone());
        // A retired slot is reused, so that a run of many swaps keeps a short table.
        let reuse = self
            .slots
            .iter()
            .position(|s| s.state == RunState::Retired && s.child.is_none());
        let i = match reuse {
            Some(i) => {
                self.spec.modules[i] = m;
                self.slots[i] = slot;
                i
            }
            None => {
                self.spec.modules.push(m);
                self.slots.push(slot);
                self.spec.modules.len() - 1
            }
        };
        self.logs.name_width = self.logs.name_width.max(name.len());
        self.spawn(i).map_err(|e| {
            self.slots[i].state = RunState::Retired;
            SpawnHostError::Spawn(e)
        })?;
        self.say(&format!(
            "{name}: host {host} of assembly {assembly} (generation {generation}) started"
        ));
        Ok(())
    }

    /// From now on a host of the system's own components starts (and restarts) with
    /// `assembly` as generation `generation`: the checked grid of that generation.
    fn current_assembly(&mut self, assembly: &str, generation: Generation) {
        for m in &mut self.spec.modules {
            let system_host = matches!(
                GridRole::of(&m.name),
                Some(GridRole::Host { generation: g, .. }) if g == Generation::SYSTEM
            );
            if !system_host || !m.args.iter().any(|a| a == "--host") {
                continue;
            }
            let mut args = spec_generation_args(generation);
            let mut old = m.args.iter();
            while let Some(a) = old.next() {
                if a == SPEC_GENERATION_ARG {
                    old.next();
                } else {
                    args.push(a.clone());
                }
            }
            m.args = args;
        }
        tracing::debug!("the system's hosts restart with assembly {assembly} from now on");
    }

    /// Stops module `name` for good (SIGTERM; SIGKILL after the grace period, by `watch`).
    fn retire(&mut self, name: &str) {
        let Some(i) = self.spec.modules.iter().position(|m| m.name == name) else {
            return;
        };
        let slot = &mut self.slots[i];
        slot.retiring = true;
        slot.restart_at_ns = self.epoch.elapsed().as_nanos() as u64
            + self.spec.supervision.stop_grace.as_nanos() as u64;
        match &slot.child {
            Some(_) => {
                let _ = kill(Pid::from_raw(slot.pid as i32), Signal::SIGCONT);
                let _ = kill(Pid::from_raw(slot.pid as i32), Signal::SIGTERM);
            }
            None => slot.state = RunState::Retired,
        }
        self.shown.changed();
    }
}

pub(super) fn spawn_host_method(
    shared: &mut Shared,
    _: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let (host, assembly, generation) = (args.text(0)?, args.text(1)?, args.i64(2)?);
    // The host's program if a declared component type needs one of its own ("": the built-in).
    let program = match args.get(3) {
        Some(_) => args.text(3)?,
        None => "",
    };
    if !shared.hosts_allowed {
        return Err(MethodError::Failed(
            "this system has no assemblies: no host can be started".into(),
        ));
    }
    let generation = assembly_generation(generation)?;
    modbot_grid::spec::check_host(host).map_err(|e| MethodError::Failed(e.to_string()))?;
    modbot_system::assembly::check_assembly_name(assembly)
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    shared.requests.push(HostRequest::Spawn {
        host: (*host).to_owned(),
        assembly: (*assembly).to_owned(),
        generation,
        program: (!program.is_empty()).then(|| program.to_owned()),
    });
    Ok(())
}

pub(super) fn retire_method(
    shared: &mut Shared,
    _: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let name = args.text(0)?;
    let of_an_assembly = matches!(
        GridRole::of(name),
        Some(GridRole::Host { generation, .. }) if generation != Generation::SYSTEM
    );
    if !shared.hosts_allowed || !of_an_assembly {
        return Err(MethodError::Failed(format!(
            "only the host of an assembly can be retired, not {name}"
        )));
    }
    shared
        .requests
        .push(HostRequest::Retire((*name).to_owned()));
    Ok(())
}

pub(super) fn current_assembly_method(
    shared: &mut Shared,
    _: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let (assembly, generation) = (args.text(0)?, args.i64(1)?);
    if !shared.hosts_allowed {
        return Err(MethodError::Failed("this system has no assemblies".into()));
    }
    let generation = assembly_generation(generation)?;
    modbot_system::assembly::check_assembly_name(assembly)
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    shared.requests.push(HostRequest::Current {
        assembly: (*assembly).to_owned(),
        generation,
    });
    Ok(())
}
