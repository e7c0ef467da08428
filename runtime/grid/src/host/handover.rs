//! A live upgrade of a host (`modbot upgrade host_ctrl_g2`): a new process of the host takes
//! its components over at a tick, their state carried to the bit, so the grid steps on as if
//! nothing happened (no tick missed, every output the same).
//!
//! 1. The new process starts in **standby** ([`Host::standby`]): it makes the host's
//!    components as any host does, checks that each can carry its state (a type that cannot is
//!    refused here, before anything changed), subscribes to its sources and releases, and
//!    offers itself to the coordinator (a [`SUCCESSOR`] done notice with its pid). It serves
//!    no release.
//! 2. The coordinator answers with a [`HANDOVER`](modbot_ipc_schema::grid::HANDOVER) release
//!    for tick `at`, after every release before `at` (between ticks in a held lockstep grid,
//!    else after the releases of `at − 1`). Both processes read it.
//! 3. The running process — every release before `at` served, its done notices sent — saves
//!    its components' state ([`Host::carry`]: each component's own state, its outputs, the
//!    versions of its sources it keeps), sends it on the host's handover channel and waits for
//!    the new process's verdict, as long as that process lives: taken, it serves no more (the
//!    supervisor hands its module over next and it ends); refused, it serves on as before.
//! 4. The new process loads the state and serves every release from `at` on; it writes
//!    [`GRID`] into the upgrade's directory for the supervisor. A state it cannot load (a
//!    component whose state's layout changed) is refused: the old process serves on, the new
//!    one ends and says why ([`Host::refused`]).
//!
//! The handover allocates and opens its channels once, off the steady ticks; in a grid in real
//! time the tick `at` is as late as the handover takes (a state of some kilobytes: well under a
//! millisecond here, the channels' opening aside).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use modbot_core::transport::channels::Channels;
use modbot_core::transport::TransportError;
use modbot_core::upgrade::GRID;
use modbot_ipc_schema::grid::{Done, Release, SUCCESSOR};
use zerocopy::IntoBytes;

use super::{Host, HostError};
use crate::carry::{Carry, CarryError};
use crate::wire::{self, Pub, Sub};

/// How long either side waits for the other before it gives up (the old process serves on; the
/// new one ends with the reason).
const WAIT_LIMIT: Duration = Duration::from_secs(30);

/// Where a host process stands in a live upgrade.
pub(super) enum Upgrade {
    /// A new process, waiting to take the components over.
    Standby(Standby),
    /// The process that handed its components over at tick `at`: it serves no release.
    HandedOver { at: u64 },
}

/// A new process's end of the handover.
pub(super) struct Standby {
    state: Sub,
    verdict: Pub,
    /// Whether the coordinator was told this process stands by.
    offered: bool,
    /// The upgrade's directory (the supervisor's), for [`GRID`].
    dir: Option<PathBuf>,
}

impl Host {
    /// Keeps `node`: a HANDOVER notice opens the host's end of the handover there.
    pub fn keep_node(&mut self, node: Arc<dyn Channels>) {
        self.node = Some(node);
    }

    /// Makes this process a new process of the host, standing by to take its components over
    /// from the running one (see the module's text); `dir`: the upgrade's directory. Refused
    /// for a component that cannot carry its state, and for a host of the system's own
    /// components in a grid with assemblies (it follows the assemblies being prepared).
    pub fn standby(
        &mut self,
        node: Arc<dyn Channels>,
        dir: Option<PathBuf>,
    ) -> Result<(), HostError> {
        if self.prepare.is_some() {
            return Err(HostError::Upgrade(format!(
                "host {} steps the system's own components, which follow the assemblies being \
                 prepared: it does not upgrade (swap the assembly instead)",
                self.name
            )));
        }
        let mut measure = Carry::measure();
        self.carry(&mut measure)
            .map_err(|(name, error)| HostError::Carry { name, error })?;
        let (state, verdict) = wire::handover_in(&*node, &self.spec.handover_service(&self.name))?;
        // Mapped here, not at the first release after the handover.
        for h in &self.hosted {
            for source in &h.binding.sources {
                source.connect();
            }
        }
        self.node = Some(node);
        self.upgrade = Some(Upgrade::Standby(Standby {
            state,
            verdict,
            offered: false,
            dir,
        }));
        Ok(())
    }

    /// Why this new process did not take the components over, once it is known: it ends then.
    pub fn refused(&self) -> Option<&str> {
        self.refused.as_deref()
    }

    /// Whether this process serves releases (not standing by, not handed over).
    pub(super) fn serves(&self) -> bool {
        self.upgrade.is_none()
    }

    /// Standing by: tells the coordinator once (with the index of one of its components, and
    /// its pid).
    pub(super) fn offer(&mut self) -> Result<(), TransportError> {
        let Some(Upgrade::Standby(standby)) = self.upgrade.as_mut() else {
            return Ok(());
        };
        if standby.offered {
            return Ok(());
        }
        standby.offered = true;
        let first = self.hosted.first().map_or(0, |h| h.index as u64);
        let done = Done::new(first, SUCCESSOR, Done::OK, u64::from(std::process::id()), 0)
            .of_generation(self.generation.0);
        self.done.send_bytes(done.as_bytes())?;
        if let Err(e) = self.done_wake.notify() {
            tracing::debug!("done wake-up not sent: {e:?}");
        }
        tracing::info!(
            "standing by to take host {}'s components over (pid {})",
            self.name,
            std::process::id()
        );
        Ok(())
    }

    /// A HANDOVER release: the running process hands over, the new one (the pid it names)
    /// takes over; anyone else ignores it.
    pub(super) fn handover(&mut self, release: &Release) -> Result<(), TransportError> {
        let at = release.tick.get();
        let pid = u32::try_from(release.released_ns.get()).unwrap_or(0);
        match &self.upgrade {
            None => self.hand_over(at, pid),
            Some(Upgrade::Standby(_)) if pid == std::process::id() => self.take_over(at),
            Some(Upgrade::HandedOver { at: before }) => {
                tracing::debug!("a handover at tick {at}: this process handed over at {before}");
                Ok(())
            }
            Some(Upgrade::Standby(_)) => Ok(()),
        }
    }

    /// The running process: saves and sends the components' state, and serves no more once
    /// process `pid` took it.
    fn hand_over(&mut self, at: u64, pid: u32) -> Result<(), TransportError> {
        // The releases before `at` are done: the grid need not wait for what follows.
        self.finish_batch()?;
        let Some(node) = self.node.clone() else {
            tracing::warn!(
                "a handover at tick {at}, but this host cannot open its end: serving on"
            );
            return Ok(());
        };
        if !process_runs(pid) {
            tracing::warn!("the new process {pid} is gone before tick {at}: serving on");
            return Ok(());
        }
        for h in &mut self.hosted {
            for source in &mut h.binding.sources {
                source.take_arrived();
            }
        }
        let mut measure = Carry::measure();
        let state = match self.carry(&mut measure) {
            Ok(()) => {
                let mut state = vec![0u8; 1 + measure.len()];
                state[0] = 1;
                match self.carry(&mut Carry::save(&mut state[1..])) {
                    Ok(()) => state,
                    Err((name, e)) => refusal(&name, &e),
                }
            }
            Err((name, e)) => refusal(&name, &e),
        };
        let (out, verdict) =
            wire::handover_out(&*node, &self.spec.handover_service(&self.name), state.len())?;
        out.send_bytes(&state)?;
        if state[0] != 1 {
            tracing::warn!(
                "cannot hand the components over ({}): serving on",
                String::from_utf8_lossy(&state[1..])
            );
            return Ok(());
        }
        let began = Instant::now();
        let taken = loop {
            let mut said = None;
            while verdict.receive(&mut |b| said = b.first().copied())? {}
            if let Some(v) = said {
                break v == 1;
            }
            if !process_runs(pid) || began.elapsed() > WAIT_LIMIT {
                break false;
            }
            std::thread::sleep(Duration::from_micros(100));
        };
        if taken {
            tracing::info!(
                "host {}: the components were handed over to pid {pid} at tick {at} ({} bytes \
                 of state)",
                self.name,
                state.len() - 1
            );
            self.upgrade = Some(Upgrade::HandedOver { at });
        } else {
            tracing::warn!(
                "host {}: pid {pid} did not take the components over: serving on",
                self.name
            );
        }
        Ok(())
    }

    /// The new process: loads the state the running one sends, and serves from `at` on.
    fn take_over(&mut self, at: u64) -> Result<(), TransportError> {
        let Some(Upgrade::Standby(standby)) = self.upgrade.take() else {
            return Ok(());
        };
        let began = Instant::now();
        let mut state: Option<Vec<u8>> = None;
        while state.is_none() {
            while standby.state.receive(&mut |b| state = Some(b.to_vec()))? {}
            if state.is_none() {
                if began.elapsed() > WAIT_LIMIT {
                    let _ = standby.verdict.send_bytes(&[0]);
                    self.refused = Some(format!(
                        "the running process sent no state within {} s of tick {at}'s handover",
                        WAIT_LIMIT.as_secs()
                    ));
                    return Ok(());
                }
                std::thread::sleep(Duration::from_micros(100));
            }
        }
        let state = state.unwrap_or_default();
        let loaded = match state.split_first() {
            Some((1, bytes)) => {
                let mut load = Carry::load(bytes);
                self.carry(&mut load)
                    .map_err(|(name, e)| named(&name, &e))
                    .and_then(|()| load.finish().map_err(|e| named("", &e)))
            }
            Some((_, why)) => Err(format!(
                "the running process cannot hand its components over: {}",
                String::from_utf8_lossy(why)
            )),
            None => Err("the running process sent an empty state".into()),
        };
        if let Err(why) = loaded {
            let _ = standby.verdict.send_bytes(&[0]);
            self.refused = Some(format!("the state handed over at tick {at}: {why}"));
            return Ok(());
        }
        standby.verdict.send_bytes(&[1])?;
        let outputs = self.hosted.iter().map(|h| h.outputs.as_slice());
        let lockstep = self.spec.timing.clock == crate::GridClock::Lockstep;
        crate::outputs_view::refresh(&self.view, self.last_tick, outputs, lockstep);
        tracing::info!(
            "host {}: took the components over at tick {at} ({} bytes of state)",
            self.name,
            state.len() - 1
        );
        if let Some(dir) = &standby.dir {
            if let Err(e) = modbot_core::upgrade::write_file(dir, GRID, at.to_string().as_bytes()) {
                tracing::warn!("the upgrade's directory is not told: {e}");
            }
        }
        Ok(())
    }

    /// Visits the state of every component of the host (see [`Carry`]): the host's last tick;
    /// per component its index, its own state (framed: a type whose layout changed is refused
    /// by name), its outputs (and initial ones) and the versions of its sources it keeps. On an
    /// error: the component's name (empty: the host's own part).
    pub(super) fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), (String, CarryError)> {
        let host = |e| (String::new(), e);
        c.length("the host's components", self.hosted.len())
            .map_err(host)?;
        c.u64("the host's last tick", &mut self.last_tick)
            .map_err(host)?;
        for h in &mut self.hosted {
            let name = h.name.clone();
            let mut visit = |c: &mut Carry<'_>| -> Result<(), CarryError> {
                let mut index = h.index as u64;
                c.u64("the component's index", &mut index)?;
                if index != h.index as u64 {
                    return Err(CarryError::Shape {
                        what: "the component's index",
                        expected: h.index,
                        got: usize::try_from(index).unwrap_or(usize::MAX),
                    });
                }
                c.framed("its own state", |inner| h.component.carry(inner))?;
                c.ports("its outputs", &mut h.outputs)?;
                c.ports("its initial outputs", &mut h.initial)?;
                c.length("its sources", h.binding.sources.len())?;
                for source in &mut h.binding.sources {
                    source.carry(c)?;
                }
                Ok(())
            };
            visit(c).map_err(|e| (name, e))?;
        }
        Ok(())
    }
}

/// A state that says why it cannot be handed over.
fn refusal(name: &str, e: &CarryError) -> Vec<u8> {
    let mut state = vec![0u8];
    state.extend_from_slice(named(name, e).as_bytes());
    state
}

fn named(name: &str, e: &CarryError) -> String {
    if name.is_empty() {
        e.to_string()
    } else {
        format!("component {name}: {e}")
    }
}

/// Whether process `pid` still runs (a signal 0 reaches it, or it is another user's).
fn process_runs(pid: u32) -> bool {
    let Ok(pid) = i32::try_from(pid) else {
        return false;
    };
    if pid <= 0 {
        return false;
    }
    match nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid), None) {
        Ok(()) => true,
        Err(e) => e == nix::errno::Errno::EPERM,
    }
}
