//! A live upgrade of a host (`modbot upgrade host_ctrl_g2`): a new process of the host takes
//! its components over at a tick, their state carried to the bit, so the grid steps on as if
//! nothing happened (no tick missed, every output the same).
//!
//! 1. The new process starts in **standby** ([`Host::standby`]): it makes the host's
//!    components as any host does, checks that each can carry its state (a type that cannot is
//!    refused here, before anything changed), subscribes to its sources and releases, and
//!    offers itself to the coordinator (a [`SUCCESSOR`] done notice with its pid). It serves
//!    no release.
//! 2. The coordinator tells the running process with an [`UPGRADE`] release: it opens its end
//!    of the handover on a thread of its own (milliseconds the serving thread must not spend)
//!    and answers. The coordinator then sends a
//!    [`HANDOVER`](modbot_ipc_schema::grid::HANDOVER) release for tick `at`, after every
//!    release before `at` (between ticks in a held lockstep grid, else after the releases of
//!    `at − 1`). Both processes read it.
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
//! The handover allocates the state's buffer once, off the steady ticks; in a grid in real
//! time the releases of tick `at` wait for the handover (saving, sending and loading some
//! kilobytes of state).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use modbot_core::transport::channels::Channels;
use modbot_core::transport::TransportError;
use modbot_core::upgrade::GRID;
use modbot_ipc_schema::grid::{Done, Release, SUCCESSOR, UPGRADE};
use zerocopy::IntoBytes;

use super::{Host, HostError};
use crate::carry::{Carry, CarryError};
use crate::wire::{self, Pub, Sub};

/// The first byte of a sample on either channel that carries nothing but a greeting: each end
/// sends one as soon as it knows of the other, so that both connect (map the other's memory)
/// before the handover, not at its tick. (A state says 1 or 0 first, a verdict 1 or 0.)
const HELLO: u8 = 2;

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

/// What the opener thread opens: the running process's end of a handover.
type Opened = Result<(Pub, Sub), TransportError>;

/// A thread that opens the running process's end of a handover when asked: (channel, length).
/// Dropped, it ends the thread and waits for it: the thread holds the node, which must be
/// dropped (its files and directory removed) before the process exits.
pub(super) struct Opener {
    ask: Option<std::sync::mpsc::Sender<(String, usize)>>,
    opened: std::sync::mpsc::Receiver<Opened>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Opener {
    fn drop(&mut self) {
        self.ask.take();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Opener {
    fn start(node: Arc<dyn Channels>) -> std::io::Result<Opener> {
        let (ask, asked) = std::sync::mpsc::channel::<(String, usize)>();
        let (tell, opened) = std::sync::mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("handover".into())
            .spawn(move || {
                for (service, len) in asked {
                    let end =
                        wire::handover_out(&*node, &service, len).and_then(|(out, verdict)| {
                            // Connected now, not at the handover's tick: the greeting maps the new
                            // process's end here, and it greets back (see HELLO).
                            out.send_bytes(&[HELLO])?;
                            verdict.connect();
                            Ok((out, verdict))
                        });
                    if tell.send(end).is_err() {
                        return;
                    }
                }
            })?;
        Ok(Opener {
            ask: Some(ask),
            opened,
            thread: Some(thread),
        })
    }
}

/// The running process's end of the handover, once a new process stands by.
pub(super) enum Handing {
    /// Being opened by the opener thread, for a state of `len` bytes.
    Opening { pid: u32, len: usize },
    /// Open: the state goes out on `out`, the verdict comes in on `verdict`.
    Open {
        pid: u32,
        len: usize,
        out: Pub,
        verdict: Sub,
    },
}

/// A new process's end of the handover.
pub(super) struct Standby {
    state: Sub,
    verdict: Pub,
    /// Whether the coordinator was told this process stands by.
    offered: bool,
    /// The upgrade's directory (the supervisor's), for [`GRID`].
    dir: Option<PathBuf>,
    /// A state that came before this process read the HANDOVER notice.
    early: Option<Vec<u8>>,
}

impl Host {
    /// Keeps `node`: an UPGRADE notice opens the host's end of the handover there, on a thread
    /// started now.
    pub fn keep_node(&mut self, node: Arc<dyn Channels>) {
        match Opener::start(node.clone()) {
            Ok(opener) => self.opener = Some(opener),
            Err(e) => tracing::warn!("no thread to open a live upgrade's handover: {e}"),
        }
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
            early: None,
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
        // The running process's greeting: greeted back, both ends are connected.
        let mut greeted = false;
        let early = &mut standby.early;
        while standby.state.receive(&mut |b| match b.first() {
            Some(&HELLO) => greeted = true,
            _ => *early = Some(b.to_vec()),
        })? {}
        if greeted {
            standby.verdict.send_bytes(&[HELLO])?;
        }
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

    /// An UPGRADE release (a new process, `released_ns` its pid, stands by): the running
    /// process opens its end of the handover on a thread of its own; [`Host::poll_handing`]
    /// answers once it is open. A new process ignores it.
    pub(super) fn prepare_handover(&mut self, release: &Release) {
        if self.upgrade.is_some() {
            return;
        }
        let pid = u32::try_from(release.released_ns.get()).unwrap_or(0);
        let mut measure = Carry::measure();
        if let Err((name, e)) = self.carry(&mut measure) {
            tracing::warn!(
                "host {}: {}: its components cannot be handed over",
                self.name,
                named(&name, &e)
            );
            return self.answer_upgrade(Done::FAILED);
        }
        let (len, service) = (1 + measure.len(), self.spec.handover_service(&self.name));
        let asked = self
            .opener
            .as_ref()
            .and_then(|o| o.ask.as_ref())
            .is_some_and(|ask| ask.send((service, len)).is_ok());
        if !asked {
            return self.answer_upgrade(Done::FAILED);
        }
        self.handing = Some(Handing::Opening { pid, len });
    }

    /// Between releases: answers the coordinator once the end of the handover is open.
    pub(super) fn poll_handing(&mut self) {
        let Some(Handing::Opening { pid, len }) = &self.handing else {
            return;
        };
        let (pid, len) = (*pid, *len);
        let Some(opener) = self.opener.as_ref() else {
            return;
        };
        match opener.opened.try_recv() {
            Err(std::sync::mpsc::TryRecvError::Empty) => {}
            Ok(Ok((out, verdict))) => {
                self.handing = Some(Handing::Open {
                    pid,
                    len,
                    out,
                    verdict,
                });
                self.answer_upgrade(Done::OK);
            }
            Ok(Err(e)) => {
                tracing::warn!("host {}: the handover cannot be opened: {e}", self.name);
                self.handing = None;
                self.answer_upgrade(Done::FAILED);
            }
            Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                self.handing = None;
                self.answer_upgrade(Done::FAILED);
            }
        }
    }

    /// The answer to an UPGRADE release (`tick`: one of the host's components).
    fn answer_upgrade(&mut self, status: u16) {
        let first = self.hosted.first().map_or(0, |h| h.index as u64);
        let done = Done::new(first, UPGRADE, status, 0, 0).of_generation(self.generation.0);
        if let Err(e) = self.done.send_bytes(done.as_bytes()) {
            tracing::warn!("the answer to the upgrade notice is not sent: {e}");
        }
        if let Err(e) = self.done_wake.notify() {
            tracing::debug!("done wake-up not sent: {e:?}");
        }
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
        // The end opened for this new process, unless the state grew past it.
        let (out, verdict) = match self.handing.take() {
            Some(Handing::Open {
                pid: p,
                len,
                out,
                verdict,
            }) if p == pid && len >= state.len() => (out, verdict),
            _ => wire::handover_out(&*node, &self.spec.handover_service(&self.name), state.len())?,
        };
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
            while verdict.receive(&mut |b| said = b.first().copied().filter(|v| *v != HELLO))? {}
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
        let Some(Upgrade::Standby(mut standby)) = self.upgrade.take() else {
            return Ok(());
        };
        let began = Instant::now();
        let mut state: Option<Vec<u8>> = standby.early.take();
        while state.is_none() {
            while standby.state.receive(&mut |b| {
                if b.first() != Some(&HELLO) {
                    state = Some(b.to_vec());
                }
            })? {}
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
pub fn process_runs(pid: u32) -> bool {
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
