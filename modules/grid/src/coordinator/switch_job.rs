//! An assembly switch, the service thread's side: the supervisor loads the assembly file and
//! writes its checked grid (`load_assembly`), the supervisor starts its hosts, a thread opens
//! the coordinator's links to them and hands them to the tick thread, the prepared hosts are
//! pinged until they answer, and the tick thread is asked to announce the switch (its side is
//! `incoming`); the outcome is kept for `assembly()`.

use std::sync::mpsc::Sender;
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::{link, SwitchState};
use modbot_core::domain::Domain;
use modbot_core::transport::channels::Channels;
use modbot_core::{CallOptions, Module};
use modbot_grid::component::Generation;
use modbot_grid::switch::{Outcome, State, Status};
use modbot_grid::wire::{self, Pub};
use modbot_grid::GridSpec;
use modbot_ipc_schema::grid::Prepare;
use modbot_ipc_schema::Value;
use zerocopy::IntoBytes;

use super::shared::Shared;
use super::tick_thread::ToTick;
use crate::grid_args::read_grid;

/// How long a new assembly may take to be prepared.
const PREPARE_TIMEOUT: Duration = Duration::from_secs(20);

/// Where a switch asked for stands.
#[derive(Default)]
enum Phase {
    #[default]
    Idle,
    /// The supervisor loads the assembly file; its answer comes to `Shared::loaded`.
    Loading,
    /// The tick thread was asked to begin; its answer is awaited.
    Beginning(Box<GridSpec>),
    /// Its hosts start, the system's hosts load it, the links open.
    Preparing { last_ping: Instant },
    /// The tick thread was asked to announce the switch.
    Announcing,
    /// Its components track; it takes over at the tick.
    Announced(u64),
}

/// The switch under way and the outcomes of the last ones.
pub struct Switching {
    phase: Phase,
    /// (assembly, generation, when asked).
    job: Option<(String, u16, Instant)>,
    /// `assembly()`'s answer: the running assembly and the outcomes of the last switches (its
    /// state is set when it is published).
    status: Status,
    /// The tick thread's last word on the switch, and its tick count.
    state: SwitchState,
    failure: Option<String>,
    ticks: u64,
    node: Arc<dyn Channels>,
    /// The assembly notices to the system's hosts (only in a grid with assemblies).
    prepare: Option<Pub>,
    to_tick: Sender<ToTick>,
    /// Where the supervisor writes the assemblies' checked grids.
    domain: Domain,
}

impl Switching {
    pub fn new(
        node: Arc<dyn Channels>,
        to_tick: Sender<ToTick>,
        assemblies: bool,
        domain: Domain,
    ) -> anyhow::Result<Switching> {
        Ok(Switching {
            phase: Phase::Idle,
            job: None,
            status: Status::default(),
            state: SwitchState::Idle,
            failure: None,
            ticks: 0,
            prepare: if assemblies {
                Some(wire::prepare_publisher(&*node)?)
            } else {
                None
            },
            node,
            to_tick,
            domain,
        })
    }

    /// Whether a switch is asked for or under way (the service thread then looks at the tick
    /// thread's news often).
    pub fn busy(&self) -> bool {
        self.job.is_some() || !matches!(self.phase, Phase::Idle)
    }

    pub fn ticks(&mut self, ticks: u64) {
        self.ticks = ticks;
    }

    pub fn current(&mut self, module: &mut Module<Shared>, name: String, generation: u16) {
        self.status.assembly = name;
        self.status.generation = generation;
        self.publish(module);
    }

    pub fn state(&mut self, state: SwitchState, failure: Option<String>) {
        // A late release of the incoming assembly near its switch postpones it.
        if let (SwitchState::Announced { at, .. }, Phase::Announced(announced)) =
            (&state, &mut self.phase)
        {
            *announced = *at;
        }
        self.state = state;
        self.failure = failure;
    }

    /// The tick thread's answer to the begin request.
    pub fn began(&mut self, module: &mut Module<Shared>, result: Result<(), String>) {
        let Phase::Beginning(spec) = std::mem::take(&mut self.phase) else {
            return;
        };
        let Some((name, generation, _)) = self.job.clone() else {
            return;
        };
        if let Err(why) = result {
            return self.fail(module, why);
        }
        let hosts = spec.assembly_hosts();
        let notice = match Prepare::new(generation, &name) {
            Ok(n) => n,
            Err(e) => return self.fail(module, e.to_string()),
        };
        if let Some(prepare) = &self.prepare {
            if let Err(e) = prepare.send_bytes(notice.as_bytes()) {
                return self.fail(module, format!("the assembly notice was not sent: {e}"));
            }
        }
        for h in &hosts {
            let args = [
                Value::Text(h),
                Value::Text(&name),
                Value::I64(i64::from(generation)),
                Value::Text(spec.host_program(h).unwrap_or("")),
            ];
            if let Err(e) = module.ctx().call("supervisor", "spawn_host", &args) {
                return self.fail(module, format!("the supervisor cannot start host {h}: {e}"));
            }
        }
        // The links take milliseconds each to open: a thread of normal priority opens them
        // and hands them to the tick thread in the order it expects.
        let (node, to_tick) = (self.node.clone(), self.to_tick.clone());
        std::thread::spawn(move || {
            for h in &hosts {
                match link(&*node, &spec, h) {
                    Ok(l) => {
                        if to_tick.send(ToTick::Link(Box::new(l))).is_err() {
                            return;
                        }
                    }
                    Err(e) => {
                        tracing::error!("the link to host {h} of the assembly failed: {e}");
                        return;
                    }
                }
            }
        });
        self.phase = Phase::Preparing {
            last_ping: Instant::now(),
        };
        self.publish(module);
    }

    /// The tick thread's answer to the announce request.
    pub fn announced(&mut self, module: &mut Module<Shared>, at: Option<u64>) {
        if !matches!(self.phase, Phase::Announcing) {
            return;
        }
        let Some((name, generation, asked)) = self.job.clone() else {
            return;
        };
        match at {
            Some(at) => {
                tracing::info!(
                    "assembly {name} (generation {generation}) prepared in {} ms: it takes over at tick {at}",
                    asked.elapsed().as_millis()
                );
                self.phase = Phase::Announced(at);
                self.publish(module);
            }
            None => self.fail(module, "the tick thread had no assembly to announce".into()),
        }
    }

    /// An assembly took over at a tick.
    pub fn switched(
        &mut self,
        module: &mut Module<Shared>,
        generation: u16,
        announced: u64,
        at: u64,
    ) {
        let Some((name, g, _)) = self.job.clone() else {
            return;
        };
        if g == generation {
            // A host of the system's components restarted from now on loads this assembly.
            let told = module.ctx().call(
                "supervisor",
                "current_assembly",
                &[Value::Text(&name), Value::I64(i64::from(generation))],
            );
            if let Err(e) = told {
                tracing::warn!("cannot tell the supervisor the running assembly: {e}");
            }
            self.status.outcomes.push(Outcome::Switched {
                generation,
                assembly: name,
                announced,
                tick: at,
            });
            self.finish(module);
        }
    }

    /// One step: starts a switch asked for, and moves the one under way along.
    pub fn step(&mut self, module: &mut Module<Shared>) {
        if let Some((name, generation)) = module.state_mut().requested.take() {
            tracing::info!("switch to assembly {name} (generation {generation}) asked for");
            self.job = Some((name.clone(), generation, Instant::now()));
            self.phase = Phase::Loading;
            let args = [Value::Text(&name), Value::I64(i64::from(generation))];
            let opts = CallOptions {
                timeout: PREPARE_TIMEOUT,
                ..CallOptions::default()
            };
            match module
                .ctx()
                .call_with("supervisor", "load_assembly", &args, opts)
            {
                Ok(call) => module.state_mut().loading = Some(call),
                Err(e) => return self.fail(module, format!("the supervisor cannot load it: {e}")),
            }
            self.publish(module);
        }
        let Some((_, _, asked)) = self.job.clone() else {
            return;
        };
        if matches!(self.phase, Phase::Preparing { .. } | Phase::Announced(_)) {
            if let Some(why) = self.failure.clone() {
                return self.fail(module, why);
            }
        }
        match &mut self.phase {
            Phase::Idle | Phase::Beginning(_) | Phase::Announcing => {}
            Phase::Loading => match module.state_mut().loaded.take() {
                Some(Ok(())) => match read_grid(&self.domain, Generation(self.job_generation())) {
                    Ok(spec) => {
                        let _ = self.to_tick.send(ToTick::Begin(Box::new(spec.clone())));
                        self.phase = Phase::Beginning(Box::new(spec));
                    }
                    Err(e) => self.fail(module, format!("its checked grid cannot be read: {e}")),
                },
                Some(Err(why)) => self.fail(module, why),
                None => {}
            },
            Phase::Preparing { last_ping } => {
                if let SwitchState::Preparing {
                    opened,
                    hosts,
                    ready,
                    system_hosts,
                    answered,
                } = self.state
                {
                    if opened == hosts && ready >= system_hosts && answered == hosts {
                        let _ = self.to_tick.send(ToTick::Announce);
                        self.phase = Phase::Announcing;
                    } else if last_ping.elapsed() >= Duration::from_millis(10) && opened == hosts {
                        *last_ping = Instant::now();
                        let _ = self.to_tick.send(ToTick::Ping);
                    }
                    if asked.elapsed() > PREPARE_TIMEOUT {
                        let why = format!(
                            "not prepared within {} s: {opened}/{hosts} host links open, {answered}/{hosts} hosts answering, {ready}/{system_hosts} system hosts ready",
                            PREPARE_TIMEOUT.as_secs()
                        );
                        self.fail(module, why);
                    }
                } else if asked.elapsed() > PREPARE_TIMEOUT {
                    self.fail(module, "the tick thread never began preparing".into());
                }
            }
            Phase::Announced(at) => {
                if self.ticks > *at + 2 {
                    let why = format!("the switch announced for tick {at} did not happen");
                    self.fail(module, why);
                }
            }
        }
    }

    /// The generation of the switch under way.
    fn job_generation(&self) -> u16 {
        self.job.as_ref().map_or(0, |j| j.1)
    }

    fn fail(&mut self, module: &mut Module<Shared>, why: String) {
        let (name, generation) = self
            .job
            .as_ref()
            .map_or((String::new(), 0), |j| (j.0.clone(), j.1));
        tracing::error!(
            "assembly {name} (generation {generation}) not switched to: {why}; the running one stays"
        );
        // The tick thread gives the assembly up and names its hosts, to be retired.
        let _ = self.to_tick.send(ToTick::Abort);
        self.status.outcomes.push(Outcome::Failed {
            generation,
            assembly: name,
            reason: why,
        });
        self.finish(module);
    }

    fn finish(&mut self, module: &mut Module<Shared>) {
        self.job = None;
        self.phase = Phase::Idle;
        self.failure = None;
        if self.status.outcomes.len() > 64 {
            let _ = self.status.outcomes.remove(0);
        }
        let shared = module.state_mut();
        shared.busy = false;
        // A late answer of the supervisor's to this switch's load is not taken for the next.
        shared.loading = None;
        shared.loaded = None;
        self.publish(module);
    }

    /// Writes `assembly()`'s answer: the running assembly, the switch under way, the recent
    /// outcomes.
    fn publish(&mut self, module: &mut Module<Shared>) {
        self.status.state = match (&self.job, &self.phase) {
            (Some((name, generation, _)), Phase::Announced(at)) => State::Announced {
                generation: *generation,
                assembly: name.clone(),
                tick: *at,
            },
            (Some((name, generation, _)), _) => State::Preparing {
                generation: *generation,
                assembly: name.clone(),
            },
            _ => State::Idle,
        };
        let answer = &mut module.state_mut().status;
        answer.clear();
        self.status.encode(answer);
    }
}
