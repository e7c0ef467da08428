//! Swapping assemblies on the tick thread: the assembly being prepared ([`Incoming`]), its
//! links handed over one at a time, the warm-up of its hosts, the announced switch tick (put
//! off while its releases near the switch are late), tracking releases until then, and the
//! switch itself; what [`SwitchState`] reports to `modbot assembly`.

use std::io::Write;

use modbot_ipc_schema::grid::{Generation, Release, MAX_SOURCES, PING};

use super::MAX_POSTPONE_TICKS;
use super::{comps_of, release, send_release, Comp, Coordinator, HostLink, ReleaseAt};
use modbot_grid::GridSpec;

impl Incoming {
    pub(super) fn fail(&mut self, why: String) {
        if self.failure.is_none() {
            tracing::error!("the assembly being prepared fails: {why}");
            self.failure = Some(why);
        }
    }
}

/// An assembly being prepared while the current one runs.
pub(super) struct Incoming {
    pub(super) spec: GridSpec,
    /// Its components, by index in its spec (those of the system are not used: the system's
    /// components are the coordinator's own, whatever the assembly).
    pub(super) comps: Vec<Comp>,
    /// Links to its hosts, opened one per tick.
    pub(super) hosts: Vec<HostLink>,
    pub(super) host_names: Vec<String>,
    /// System hosts that loaded it and subscribed to its outputs.
    pub(super) ready: usize,
    /// Which of its hosts answered a warm-up release.
    pub(super) answered: Vec<bool>,
    /// Tracking from this tick; the switch at the second.
    pub(super) schedule: Option<(u64, u64)>,
    /// The switch tick first announced (a late release near the switch postpones it).
    pub(super) first_at: u64,
    /// Ticks between the last late release and the switch.
    pub(super) lead: u64,
    pub(super) failure: Option<String>,
}

/// Where a switch stands, for the coordinator's program and `modbot assembly`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SwitchState {
    /// No assembly is being prepared.
    Idle,
    /// Preparing: the links to its hosts are opened, the system's hosts load it.
    Preparing {
        opened: usize,
        hosts: usize,
        ready: usize,
        system_hosts: usize,
        answered: usize,
    },
    /// Its components run alongside (tracking) from `from`; it takes over at `at`.
    Announced { from: u64, at: u64 },
}

/// Why an assembly cannot begin to be prepared ([`Coordinator::begin_switch`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum BeginSwitchError {
    #[error("an assembly is being prepared already")]
    Busy,
    #[error("generation {generation} is not newer than the running {running}")]
    NotNewer {
        generation: Generation,
        running: Generation,
    },
}

impl<W: Write> Coordinator<W> {
    /// Releases the components of the assembly being prepared, once it is announced: to
    /// track until their outputs are the ones the switch tick reads.
    pub(super) fn release_incoming(&mut self, n: u64, now_ns: u64) {
        let base = self.base();
        let Some(inc) = self.incoming.as_mut() else {
            return;
        };
        let Some((from, mut at)) = inc.schedule else {
            return;
        };
        if n < from || inc.failure.is_some() {
            return;
        }
        // Tracking outputs are obeyed by nothing: an overrun is only counted (a fresh process
        // is slow at first). A late release whose outputs the switch tick would read postpones
        // the switch; `fault` applies once the assembly is live.
        let late_near_switch = (base..inc.comps.len()).find(|&c| {
            let x = &inc.comps[c];
            n.is_multiple_of(x.period) && x.pending.is_some() && n + x.period >= at
        });
        if let Some(c) = late_near_switch {
            let later = n + 2 * inc.spec.assembly_max_period() + inc.lead;
            if later > inc.first_at + MAX_POSTPONE_TICKS {
                let name = &inc.spec.components[c].name;
                inc.fail(format!(
                    "component {name} overran its deadline at tick {n} while it was prepared, \
                     and the switch was postponed {} ticks already",
                    at - inc.first_at
                ));
                return;
            }
            tracing::info!(
                "component {} of the incoming assembly is late at tick {n}: the switch moves \
                 from tick {at} to {later}",
                inc.spec.components[c].name
            );
            at = later;
            inc.schedule = Some((from, at));
            self.replay_log.postpone(n, inc.spec.generation(), at);
        }
        let generation = inc.spec.generation();
        let mut versions = [0u64; MAX_SOURCES];
        for c in base..inc.comps.len() {
            let comp = &inc.comps[c];
            if !n.is_multiple_of(comp.period) {
                continue;
            }
            if let Some(m) = comp.pending {
                inc.comps[c].overruns += 1;
                let name = &inc.spec.components[c].name;
                self.replay_log.overrun(n, generation, name, m);
                continue;
            }
            for (slot, &s) in versions.iter_mut().zip(&comp.sources) {
                *slot = if s < base {
                    self.comps[s].valid_from
                } else {
                    inc.comps[s].valid_from
                };
            }
            let flags = if n + comp.period < at {
                Release::TRACK
            } else {
                0
            };
            let at = ReleaseAt {
                n,
                now_ns,
                generation,
                flags,
                state_hash: self.tick_hash,
            };
            release(&mut inc.comps[c], c, &at, &versions, &mut inc.hosts);
        }
    }

    /// At tick `n`, the announced one: the prepared assembly takes over. The system's
    /// components read its outputs from this tick on, the replaced assembly is no longer
    /// released (its hosts are listed in [`Coordinator::take_retired`]), and a fault ends.
    pub(super) fn switch(&mut self, n: u64) {
        let Some(inc) = self.incoming.take() else {
            return;
        };
        self.forget_successor();
        let base = self.base();
        let old = self
            .spec
            .assembly
            .as_ref()
            .map(|a| a.generation)
            .unwrap_or(Generation::SYSTEM);
        let old_hosts: Vec<String> = self
            .hosts
            .iter()
            .filter(|h| h.generation != Generation::SYSTEM)
            .map(|h| self.spec.host_module(&h.name))
            .collect();
        // Dropping a link unmaps shared memory (milliseconds): the old assembly's links are
        // handed out with [`Coordinator::take_retired_links`] to be dropped off this thread.
        let (keep, old_links): (Vec<HostLink>, Vec<HostLink>) = std::mem::take(&mut self.hosts)
            .into_iter()
            .partition(|h| h.generation == Generation::SYSTEM);
        self.hosts = keep;
        self.switched.retired_links.extend(old_links);
        let offset = self.hosts.len();
        self.hosts.extend(inc.hosts);
        // What the replaced assembly still had running never becomes valid.
        if self.replay_log.on() {
            for (c, comp) in self.comps.iter().enumerate().skip(base) {
                if let Some(m) = comp.pending {
                    let name = &self.spec.components[c].name;
                    self.replay_log.late(m, self.spec.generation(), name);
                }
            }
        }
        self.comps.truncate(base);
        for (c, comp) in self.comps.iter_mut().enumerate() {
            comp.sources = inc.spec.sources(c);
        }
        self.comps
            .extend(inc.comps.into_iter().skip(base).map(|mut c| {
                c.host += offset;
                c
            }));
        // Base comps' hosts keep their positions (the links of generation 0 come first and
        // are never removed).
        self.versions = vec![0; self.comps.len()];
        self.spec = inc.spec;
        let name = self
            .spec
            .assembly
            .as_ref()
            .map_or(String::new(), |a| a.name.clone());
        let generation = self.spec.generation();
        let announced = inc.schedule.map_or(n, |(_, at)| at);
        self.replay_log.switch(n, generation);
        self.switched
            .record
            .push((generation, name.clone(), announced, n));
        if let Some(why) = self.fault.take() {
            tracing::info!("the fault ends with the switch: {why}");
        }
        tracing::info!(
            "tick {n}: assembly {name} (generation {generation}) took over from generation {old}"
        );
        self.switched.retired.extend(old_hosts);
    }

    /// Begins preparing `spec` (a grid with the next assembly, of a new generation): its
    /// components run alongside once [`Coordinator::announce`] is called.
    pub fn begin_switch(&mut self, spec: GridSpec) -> Result<(), BeginSwitchError> {
        if self.incoming.is_some() {
            return Err(BeginSwitchError::Busy);
        }
        if spec.generation() <= self.spec.generation() {
            return Err(BeginSwitchError::NotNewer {
                generation: spec.generation(),
                running: self.spec.generation(),
            });
        }
        let host_names = spec.assembly_hosts();
        let mut comps = comps_of(&spec, &host_names);
        for c in comps.iter_mut().take(self.base()) {
            c.host = usize::MAX;
        }
        self.incoming = Some(Incoming {
            answered: vec![false; host_names.len()],
            host_names,
            comps,
            hosts: Vec::new(),
            ready: 0,
            schedule: None,
            first_at: 0,
            lead: 0,
            failure: None,
            spec,
        });
        Ok(())
    }

    /// Takes the link to the next host of the assembly being prepared; a link that is not the
    /// one expected (of another generation, or a host out of turn) is refused and returned.
    pub fn add_incoming_link(&mut self, link: Box<HostLink>) -> Result<(), Box<HostLink>> {
        let Some(inc) = self.incoming.as_mut() else {
            return Err(link);
        };
        let expected = inc.host_names.get(inc.hosts.len());
        if expected != Some(&link.name) || link.generation != inc.spec.host_generation(&link.name) {
            return Err(link);
        }
        inc.hosts.push(*link);
        Ok(())
    }

    /// Sends a warm-up release to every host of the assembly being prepared that has not
    /// answered one yet.
    pub fn ping_incoming(&mut self) {
        let Some(inc) = self.incoming.as_mut() else {
            return;
        };
        let generation = inc.spec.generation();
        for (h, link) in inc.hosts.iter_mut().enumerate() {
            if inc.answered.get(h) == Some(&false) {
                if let Ok(ping) = Release::new(h as u64, 0, PING, &[]) {
                    send_release(link, &ping.with(generation.0, 0));
                }
            }
        }
    }

    /// The assembly being prepared runs alongside from the next tick and takes over at the
    /// returned tick: after it tracked for the grid's `track_ticks`, and each of its
    /// components was released twice (the longest period twice), plus `lead` ticks. A late
    /// release near the switch postpones it (see [`Coordinator::switch_state`]).
    pub fn announce(&mut self, lead: u64) -> Option<u64> {
        // Its hosts subscribed to the system's outputs before now, and a subscriber gets only
        // what is published after it: the first tracking release must name versions of the
        // system's components published from now on (released at this tick or later).
        let longest_base = self.comps[..self.base()]
            .iter()
            .map(|c| c.period)
            .max()
            .unwrap_or(1);
        let from = self.tick + longest_base;
        let track = self.spec.timing.track_ticks;
        let inc = self.incoming.as_mut()?;
        let at = from + track.max(2 * inc.spec.assembly_max_period()) + lead;
        inc.schedule = Some((from, at));
        inc.first_at = at;
        inc.lead = lead;
        self.replay_log
            .announce(self.tick, inc.spec.generation(), from, at);
        Some(at)
    }

    /// Gives up the assembly being prepared; returns its hosts' module names.
    pub fn abort_switch(&mut self) -> Vec<String> {
        match self.incoming.take() {
            Some(mut inc) => {
                self.switched.retired_links.append(&mut inc.hosts);
                inc.host_names
                    .iter()
                    .map(|h| inc.spec.host_module(h))
                    .collect()
            }
            None => Vec::new(),
        }
    }

    /// Why the assembly being prepared cannot take over, once that is known.
    pub fn switch_failure(&self) -> Option<&str> {
        self.incoming.as_ref().and_then(|i| i.failure.as_deref())
    }

    /// Where the switch stands.
    pub fn switch_state(&self) -> SwitchState {
        match &self.incoming {
            None => SwitchState::Idle,
            Some(Incoming {
                schedule: Some((from, at)),
                ..
            }) => SwitchState::Announced {
                from: *from,
                at: *at,
            },
            Some(inc) => SwitchState::Preparing {
                opened: inc.hosts.len(),
                hosts: inc.host_names.len(),
                ready: inc.ready,
                system_hosts: self.spec.base_hosts().len(),
                answered: inc.answered.iter().filter(|a| **a).count(),
            },
        }
    }

    /// The switches done: (generation, assembly, announced tick, tick it took over).
    pub fn switches(&self) -> &[(Generation, String, u64, u64)] {
        &self.switched.record
    }

    /// The module names of the hosts of replaced assemblies, to be stopped; each once.
    /// The links to the hosts of the assembly that was replaced, to be dropped elsewhere.
    pub fn take_retired_links(&mut self) -> Vec<HostLink> {
        std::mem::take(&mut self.switched.retired_links)
    }

    pub fn take_retired(&mut self) -> Vec<String> {
        std::mem::take(&mut self.switched.retired)
    }
}
