//! The tick thread's side of a live upgrade of a host (see `modbot_grid::host`'s `handover`):
//! a new process of a host of the running generation offers itself (a SUCCESSOR done notice);
//! the running process is told (an UPGRADE release) and answers once its end of the handover
//! is open; the coordinator then names the tick the new one takes over at with a HANDOVER
//! release, the last notice of
//! the host's batch — after the releases of the tick being run (it takes over at the next), or,
//! in a lockstep grid held between ticks, at once once the host is idle (it takes over at the
//! tick the grid holds before). Nothing else changes: the same components, generation and
//! services; the done notices of a release are matched by component and tick, whichever
//! process sends them.

use std::io::Write;

use modbot_ipc_schema::grid::{Done, Generation, Release, HANDOVER, UPGRADE};

use super::{send_release, Coordinator};
use modbot_grid::GridClock;

/// A new process of a host, waiting to take its components over.
#[derive(Debug, Clone, Copy)]
pub(super) struct Successor {
    /// The host, as the coordinator's links count them.
    host: usize,
    pid: u32,
    /// The running process answered the UPGRADE notice: its end of the handover is open.
    ready: bool,
}

impl<W: Write> Coordinator<W> {
    /// A SUCCESSOR done notice (`tick`: one of the host's components, `exec_ns`: the new
    /// process's pid) of generation `g`.
    pub(super) fn successor_offered(&mut self, done: &Done, current: Generation) {
        let g = Generation(done.generation.get());
        let pid = u32::try_from(done.exec_ns.get()).unwrap_or(0);
        let c = usize::try_from(done.tick.get()).unwrap_or(usize::MAX);
        let Some(host) = self.comps.get(c).map(|comp| comp.host) else {
            tracing::warn!("a new host process (pid {pid}) names no component of this grid");
            return;
        };
        let name = &self.hosts[host].name;
        if self.hosts[host].generation != g || (g != current && g != Generation::SYSTEM) {
            tracing::warn!(
                "a new process (pid {pid}) of host {name} of generation {g}, which does not run \
                 now: not handed over"
            );
            return;
        }
        if self.incoming.is_some() {
            tracing::warn!(
                "a new process (pid {pid}) of host {name} offers itself while an assembly is \
                 prepared: not handed over (the switch replaces the host)"
            );
            return;
        }
        tracing::info!("a new process (pid {pid}) of host {name} stands by to take over");
        let link = &mut self.hosts[host];
        let Ok(notice) = Release::new(0, u64::from(pid), UPGRADE, &[]) else {
            return;
        };
        if send_release(link, &notice.with(link.generation.0, 0)) {
            self.successor = Some(Successor {
                host,
                pid,
                ready: false,
            });
        }
    }

    /// The running process's answer to the UPGRADE notice (`tick`: one of its components).
    pub(super) fn upgrade_answered(&mut self, done: &Done) {
        let c = usize::try_from(done.tick.get()).unwrap_or(usize::MAX);
        let host = self.comps.get(c).map(|comp| comp.host);
        let Some(s) = self.successor.as_mut().filter(|s| Some(s.host) == host) else {
            return;
        };
        if done.status.get() == Done::OK {
            s.ready = true;
        } else {
            tracing::warn!(
                "host {}: the running process cannot hand its components over (see its log): \
                 process {} does not take over",
                self.hosts[s.host].name,
                s.pid
            );
            self.successor = None;
        }
    }

    /// After the releases of tick `at − 1`: a new process waiting takes its host over at `at`.
    pub(super) fn hand_over_after_tick(&mut self, at: u64) {
        if let Some(s) = self.successor.take_if(|s| s.ready) {
            self.hand_over(s, at);
        }
    }

    /// A lockstep grid held between ticks: a new process waiting takes its host over at the
    /// tick the grid holds before, once the host's releases are done.
    pub(super) fn hand_over_between_ticks(&mut self) {
        let Some(s) = self.successor.filter(|s| s.ready) else {
            return;
        };
        if self.spec.timing.clock != GridClock::Lockstep
            || self
                .comps
                .iter()
                .any(|c| c.host == s.host && c.pending.is_some())
        {
            return;
        }
        self.successor = None;
        self.hand_over(s, self.tick);
    }

    fn hand_over(&mut self, s: Successor, at: u64) {
        let link = &mut self.hosts[s.host];
        let Ok(notice) = Release::new(at, u64::from(s.pid), HANDOVER, &[]) else {
            return;
        };
        let notice = notice.with(link.generation.0, 0);
        if !send_release(link, &notice) {
            return;
        }
        tracing::info!(
            "host {}: process {} takes its components over at tick {at}",
            link.name,
            s.pid
        );
        let name = link.name.clone();
        self.replay_log.upgrade(at, &name);
        self.handovers += 1;
    }

    /// How many hosts were handed over to a new process so far.
    pub fn handovers(&self) -> u64 {
        self.handovers
    }

    /// A switch replaces the hosts: a new process of one of them no longer takes it over.
    pub(super) fn forget_successor(&mut self) {
        if let Some(s) = self.successor.take() {
            tracing::info!(
                "the switch replaces host {}: its new process (pid {}) does not take over",
                self.hosts[s.host].name,
                s.pid
            );
        }
    }
}
