//! A component host: the process that steps some of the grid's components.
//!
//! It waits for release notices. Released at n, a component reads each input as valid at n —
//! the version of its source's outputs that the notice names, taken from the samples that source
//! published — steps, publishes its outputs stamped valid from n + period, and sends a done
//! notice with its execution time. A host steps its components one after another, in the
//! order they were released.
//!
//! In a grid with assemblies, the hosts of an assembly's components are made for its
//! generation; a host of the system's own components (the bus) outlives assemblies: told of an
//! assembly being prepared, it loads it and subscribes to the outputs its inputs will read
//! ([`Host::prepare_step`]), and switches to them at the first release of that generation.
//! A release marked TRACK is stepped with [`Component::track`]; a component that reports an
//! unsafe state afterwards answers with status UNSAFE.
//!
//! Before its first release's outputs are valid, a reader reads a component's *initial
//! outputs* ([`Component::initial_outputs`], zeros unless the component says otherwise): the
//! host publishes them as the version valid from 0 whenever it answers a warm-up release
//! (PING), so every reader that subscribed by then — the coordinator's recorder, the hosts
//! that answered the round before — holds them before tick 0 ([`Versions`] keeps them apart
//! from the released versions).

use core::time::Duration;

use modbot_ipc_schema::grid::{
    record_len, write_record, Done, OutHeader, PortValue, Prepare, Release, HANDOVER,
    OUT_HEADER_LEN, PING, READY, STOPPING, UPGRADE,
};
use zerocopy::IntoBytes;

use super::component::{Component, ComponentError, Generation, Registry, Released, Tick};
use super::outputs_view::{self, OutputsView, SharedOutputs};
use super::spec::GridSpec;
use super::versions::{self, Versions};
use super::wire::{self, Listener, Notifier, Pub, Sub};
use modbot_core::transport::channels::Channels;
use modbot_core::transport::TransportError;

mod handover;

pub use handover::process_runs;

type Source = Versions;

/// Loads assembly `name` as generation `generation` for the running grid `system` (the
/// checked grid the supervisor wrote for that generation: the grid itself reads no description).
pub type LoadAssembly = std::sync::Arc<
    dyn Fn(&GridSpec, &str, Generation) -> Result<GridSpec, LoadError> + Send + Sync,
>;

/// Why an assembly could not be loaded: the loader's own error (the grid, which reads no
/// description, does not know its type).
pub type LoadError = Box<dyn std::error::Error + Send + Sync>;

/// Where one component's inputs come from, for one assembly generation.
struct Binding {
    generation: Generation,
    sources: Vec<Source>,
    /// For each input: (source position, output port of that source).
    inputs: Vec<(usize, usize)>,
}

struct Hosted {
    index: usize,
    name: String,
    period: u64,
    component: Box<dyn Component>,
    inputs: Vec<PortValue>,
    outputs: Vec<PortValue>,
    /// Its initial outputs: published as the version valid from 0.
    initial: Vec<PortValue>,
    binding: Binding,
    /// The binding of the assembly being prepared: it replaces `binding` at the first release
    /// of its generation.
    next: Option<Binding>,
    out: Pub,
    out_len: usize,
}

/// An assembly a system host is preparing for: its bindings, opened one source at a time.
struct Preparing {
    spec: GridSpec,
    /// Per hosted component, its sources: opened on a thread of their own (milliseconds each,
    /// which the serving thread must not spend).
    opening: std::sync::mpsc::Receiver<Result<Vec<Vec<Source>>, TransportError>>,
}

/// The components of one host, and its notice channels.
pub struct Host {
    name: String,
    generation: Generation,
    hosted: Vec<Hosted>,
    releases: Sub,
    done: Pub,
    /// Notified once per batch of done notices (the coordinator may sleep on it).
    done_wake: Notifier,
    /// The done notices of the releases being served, sent as one sample.
    done_batch: Vec<u8>,
    /// Scratch: the releases of one sample.
    batch: Vec<Release>,
    wake: Listener,
    /// A host of the system's own components in a grid with assemblies: the assembly notices.
    prepare: Option<Sub>,
    /// The newest generation it was asked to prepare, and its loader.
    loading: Option<(
        Generation,
        std::sync::mpsc::Receiver<Result<GridSpec, LoadError>>,
    )>,
    preparing: Option<Preparing>,
    /// The spec it was made from, to load other assemblies against.
    spec: GridSpec,
    /// Releases not executed because an input's version the notice named was not there.
    pub stale: u64,
    /// Where bindings replaced at a switch go to be dropped, off the serving thread.
    reaper: std::sync::mpsc::Sender<Binding>,
    /// The latest outputs, for the host's module (its blackboard), and the newest release tick
    /// served.
    view: SharedOutputs,
    last_tick: u64,
    /// The node, kept for a live upgrade's handover ([`Host::keep_node`]).
    node: Option<std::sync::Arc<dyn Channels>>,
    /// A live upgrade this process takes part in (see [`handover`]).
    upgrade: Option<handover::Upgrade>,
    /// Why this new process did not take the components over.
    refused: Option<String>,
    /// The running process's end of a handover to a new process standing by.
    handing: Option<handover::Handing>,
    /// The thread that opens the end of a handover (started with the host: a thread started
    /// by the serving thread later would take milliseconds to lock its stack into memory).
    opener: Option<handover::Opener>,
}

/// A thread that drops what it is sent. It is started before the serving thread raises its
/// priority, so it runs at normal priority.
fn reaper() -> Result<std::sync::mpsc::Sender<Binding>, TransportError> {
    let (tx, rx) = std::sync::mpsc::channel::<Binding>();
    std::thread::Builder::new()
        .name("reaper".into())
        .spawn(move || rx.into_iter().for_each(drop))
        .map_err(|e| TransportError::Spawn {
            thread: "reaper",
            failure: e.into(),
        })?;
    Ok(tx)
}

/// Why a host could not start.
#[derive(Debug, thiserror::Error)]
pub enum HostError {
    #[error("host '{0}' has no components in this grid")]
    NoComponents(String),
    #[error("component '{name}' cannot be instantiated: {error}")]
    Instantiate {
        name: String,
        #[source]
        error: ComponentError,
    },
    #[error("component '{name}' cannot carry its state to a new process: {error}")]
    Carry {
        name: String,
        #[source]
        error: crate::carry::CarryError,
    },
    #[error("{0}")]
    Upgrade(String),
    #[error(transparent)]
    Transport(#[from] TransportError),
}

/// The outputs of component `s` as read by component `reader` of `spec`.
fn source(
    node: &dyn Channels,
    spec: &GridSpec,
    reader: usize,
    s: usize,
) -> Result<Source, TransportError> {
    let zeros: Vec<PortValue> = spec.output_types(s).iter().map(|t| t.zero()).collect();
    let depth = versions::depth(spec.components[reader].period, spec.components[s].period);
    Ok(Versions::new(
        wire::out_subscriber(node, &spec.out_service(s))?,
        zeros,
        depth,
    ))
}

/// Waits (up to 10 s) until every source's host publishes, and connects to it here: the first
/// receive would otherwise map the publisher's memory on the serving thread, at the switch.
fn connect(node: &dyn Channels, spec: &GridSpec, hosted: &[usize], opened: &[Vec<Source>]) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    for (&c, sources) in hosted.iter().zip(opened) {
        for (s, source) in spec.sources(c).into_iter().zip(sources) {
            let service = spec.out_service(s);
            while wire::out_publishers(node, &service).unwrap_or(0) == 0
                && std::time::Instant::now() < deadline
            {
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            source.connect();
        }
    }
}

fn input_bindings(spec: &GridSpec, c: usize) -> Vec<(usize, usize)> {
    (0..spec.components[c].info.inputs.len())
        .map(|i| spec.input_binding(c, i))
        .collect()
}

impl Host {
    /// Instantiates and initialises the components of `host` and opens their channels.
    pub fn new(
        node: &dyn Channels,
        spec: &GridSpec,
        registry: &Registry,
        host: &str,
    ) -> Result<Host, HostError> {
        let mine = spec.components_of(host);
        if mine.is_empty() {
            return Err(HostError::NoComponents(host.to_owned()));
        }
        let generation = spec.host_generation(host);
        let mut hosted = Vec::new();
        for c in mine {
            let cs = &spec.components[c];
            let mut component =
                registry
                    .instantiate(&cs.type_name, &cs.params)
                    .map_err(|error| HostError::Instantiate {
                        name: cs.name.clone(),
                        error,
                    })?;
            let out_types = spec.output_types(c);
            let mut initial: Vec<PortValue> = out_types.iter().map(|t| t.zero()).collect();
            component.initial_outputs(&mut initial);
            let sources = spec
                .sources(c)
                .into_iter()
                .map(|s| source(node, spec, c, s))
                .collect::<Result<Vec<_>, TransportError>>()?;
            let out_len = OUT_HEADER_LEN + record_len(&out_types);
            hosted.push(Hosted {
                index: c,
                name: cs.name.clone(),
                period: cs.period.max(1),
                component,
                inputs: cs.info.inputs.iter().map(|p| p.ty.zero()).collect(),
                outputs: initial.clone(),
                initial,
                binding: Binding {
                    generation: spec.generation(),
                    sources,
                    inputs: input_bindings(spec, c),
                },
                next: None,
                out: wire::out_publisher(node, &spec.out_service(c), out_len)?,
                out_len,
            });
        }
        let view = OutputsView {
            names: hosted
                .iter()
                .flat_map(|h| {
                    let info = &spec.components[h.index].info;
                    info.outputs
                        .iter()
                        .map(|p| format!("{}.{}", h.name, p.name))
                })
                .collect(),
            values: hosted.iter().flat_map(|h| h.outputs.clone()).collect(),
            ..OutputsView::default()
        };
        let prepare = if spec.assembly.is_some() && generation == Generation::SYSTEM {
            Some(wire::prepare_subscriber(node)?)
        } else {
            None
        };
        Ok(Host {
            name: host.to_owned(),
            generation,
            hosted,
            releases: wire::release_subscriber(node, &spec.release_service(host))?,
            done: wire::done_publisher(node)?,
            done_wake: wire::done_wake_notifier(node)?,
            done_batch: Vec::with_capacity(wire::DONE_BATCH * core::mem::size_of::<Done>()),
            batch: Vec::with_capacity(spec.components_of(host).len() + 1),
            wake: wire::wake_listener(node, &spec.wake_service(host))?,
            prepare,
            loading: None,
            preparing: None,
            spec: spec.clone(),
            stale: 0,
            reaper: reaper()?,
            view: std::sync::Arc::new(std::sync::Mutex::new(view)),
            last_tick: 0,
            node: None,
            upgrade: None,
            refused: None,
            handing: None,
            opener: None,
        })
    }

    /// The latest outputs of its components, refreshed whenever it served releases (see
    /// [`outputs_view`]).
    pub fn outputs_view(&self) -> SharedOutputs {
        self.view.clone()
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Sleeps until released or `timeout` passed (`None`: until released), then serves every
    /// release waiting.
    pub fn wait_and_serve(
        &mut self,
        timeout: Option<Duration>,
        now: &dyn Fn() -> u64,
    ) -> Result<usize, TransportError> {
        self.wait(timeout);
        self.serve(now)
    }

    /// Sleeps until released or `timeout` passed (`None`: until released); whether it was.
    /// [`Host::serve`] takes the wake-up.
    pub fn wait(&self, timeout: Option<Duration>) -> bool {
        self.wake.wait(timeout)
    }

    /// Serves every release notice waiting, then tells the coordinator once; returns how many.
    pub fn serve(&mut self, now: &dyn Fn() -> u64) -> Result<usize, TransportError> {
        // Taken before looking: a release sent after this wakes the next wait.
        self.wake.drain();
        self.offer()?;
        self.poll_handing();

        let mut served = 0;
        loop {
            // Copied out of the sample (no allocation while the batch fits what a tick's
            // batch holds), so the sample goes back before the steps.
            let mut batch = std::mem::take(&mut self.batch);
            batch.clear();
            let received = self
                .releases
                .receive(&mut |sample| match Release::batch(sample) {
                    Ok(releases) => batch.extend(releases.copied()),
                    Err(e) => tracing::warn!("a malformed release batch is ignored: {e}"),
                });
            if !received? {
                self.batch = batch;
                break;
            }
            for release in &batch {
                if release.component.get() == HANDOVER {
                    self.handover(release)?;
                } else if release.component.get() == UPGRADE {
                    self.prepare_handover(release);
                } else if self.serves() {
                    self.step(release, now)?;
                    served += 1;
                }
            }
            self.batch = batch;
        }
        if served > 0 {
            self.finish_batch()?;
        }
        Ok(served)
    }

    /// After serving releases: the view refreshed, the done notices sent and the coordinator
    /// woken.
    fn finish_batch(&mut self) -> Result<(), TransportError> {
        let outputs = self.hosted.iter().map(|h| h.outputs.as_slice());
        // In lockstep the view is current before the done notice leaves, so a program that saw
        // the grid held reads these outputs (see `outputs_view`).
        let lockstep = self.spec.timing.clock == crate::GridClock::Lockstep;
        outputs_view::refresh(&self.view, self.last_tick, outputs, lockstep);
        if self.done_batch.is_empty() {
            return Ok(());
        }
        self.send_done()?;
        if let Err(e) = self.done_wake.notify() {
            tracing::debug!("done wake-up not sent: {e:?}");
        }
        Ok(())
    }

    /// Adds a done notice to the batch sent when the releases waiting are served.
    fn push_done(&mut self, done: &Done) -> Result<(), TransportError> {
        if self.done_batch.len() + done.as_bytes().len() > self.done_batch.capacity() {
            self.send_done()?;
        }
        self.done_batch.extend_from_slice(done.as_bytes());
        Ok(())
    }

    /// Sends the done notices gathered, as one sample.
    fn send_done(&mut self) -> Result<(), TransportError> {
        if self.done_batch.is_empty() {
            return Ok(());
        }
        let sent = self.done.send_bytes(&self.done_batch);
        self.done_batch.clear();
        sent
    }

    /// Between releases, for a host of the system's own components in a grid with
    /// assemblies: takes an assembly notice, and does one bounded piece of the preparation
    /// (loading runs on a thread of its own; one output service is opened per call), so the
    /// releases are never held up for long. Answers the coordinator when it is ready.
    pub fn prepare_step(
        &mut self,
        node: &std::sync::Arc<dyn Channels>,
        load: &LoadAssembly,
    ) -> Result<(), TransportError> {
        let Some(notices) = self.prepare.as_ref() else {
            return Ok(());
        };
        let mut notice = None;
        while let Ok(true) = notices.receive(&mut |sample| {
            notice = Prepare::parse(sample)
                .ok()
                .and_then(|p| Some((Generation(p.generation.get()), p.name()?.to_owned())));
        }) {
            let Some((generation, name)) = notice.take() else {
                continue;
            };
            let loading = self.loading.as_ref().map(|l| l.0);
            let preparing = self.preparing.as_ref().map(|p| p.spec.generation());
            let prepared = self.hosted.iter().filter_map(|h| h.next.as_ref());
            if loading
                .into_iter()
                .chain(preparing)
                .any(|g| g >= generation)
                || prepared.into_iter().any(|b| b.generation >= generation)
                || self
                    .hosted
                    .iter()
                    .any(|h| h.binding.generation >= generation)
            {
                continue;
            }
            let (tx, rx) = std::sync::mpsc::channel();
            let (system, load) = (self.spec.clone(), load.clone());
            std::thread::spawn(move || {
                let loaded = load(&system, &name, generation);
                let _ = tx.send(loaded);
            });
            self.preparing = None;
            self.loading = Some((generation, rx));
        }
        if let Some((generation, rx)) = &self.loading {
            let generation = *generation;
            match rx.try_recv() {
                Ok(Ok(spec)) => {
                    self.loading = None;
                    let (tx, rx) = std::sync::mpsc::channel();
                    let (node, opening) = (node.clone(), spec.clone());
                    let hosted: Vec<usize> = self.hosted.iter().map(|h| h.index).collect();
                    std::thread::spawn(move || {
                        let opened = hosted
                            .iter()
                            .map(|&c| {
                                opening
                                    .sources(c)
                                    .into_iter()
                                    .map(|s| source(&*node, &opening, c, s))
                                    .collect::<Result<Vec<_>, _>>()
                            })
                            .collect::<Result<Vec<_>, _>>();
                        if let Ok(opened) = &opened {
                            connect(&*node, &opening, &hosted, opened);
                        }
                        let _ = tx.send(opened);
                    });
                    self.preparing = Some(Preparing { spec, opening: rx });
                }
                Ok(Err(why)) => {
                    tracing::error!("assembly generation {generation} cannot be prepared: {why}");
                    self.loading = None;
                    return self.answer_ready(generation, Done::FAILED);
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => return Ok(()),
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    self.loading = None;
                    return self.answer_ready(generation, Done::FAILED);
                }
            }
        }
        let Some(prep) = self.preparing.as_ref() else {
            return Ok(());
        };
        let generation = prep.spec.generation();
        let opened = match prep.opening.try_recv() {
            Ok(Ok(opened)) => opened,
            Ok(Err(e)) => {
                tracing::error!(
                    "assembly generation {generation}: its inputs cannot be opened: {e}"
                );
                self.preparing = None;
                return self.answer_ready(generation, Done::FAILED);
            }
            Err(std::sync::mpsc::TryRecvError::Empty) => return Ok(()),
            Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                self.preparing = None;
                return self.answer_ready(generation, Done::FAILED);
            }
        };
        let Some(prep) = self.preparing.take() else {
            return Ok(());
        };
        for (h, sources) in self.hosted.iter_mut().zip(opened) {
            h.next = Some(Binding {
                generation,
                sources,
                inputs: input_bindings(&prep.spec, h.index),
            });
        }
        tracing::info!(
            "ready for assembly '{}' (generation {generation})",
            prep.spec.assembly.as_ref().map_or("", |a| a.name.as_str())
        );
        self.answer_ready(generation, Done::OK)
    }

    fn answer_ready(&mut self, generation: Generation, status: u16) -> Result<(), TransportError> {
        let done = Done::new(0, READY, status, 0, 0).of_generation(generation.0);
        self.done.send_bytes(done.as_bytes())
    }

    fn step(&mut self, release: &Release, now: &dyn Fn() -> u64) -> Result<(), TransportError> {
        let n = release.tick.get();
        let generation = Generation(release.generation.get());
        if release.component.get() == PING {
            // Before tick 0: the initial outputs reach every reader subscribed by now.
            for h in &self.hosted {
                publish(h, 0, 0)?;
            }
            let done = Done::new(n, PING, Done::OK, 0, 0).of_generation(self.generation.0);
            return self.push_done(&done);
        }
        if release.component.get() == STOPPING {
            tracing::info!("the grid stops after tick {n}");
            for h in &mut self.hosted {
                h.component.stopping();
            }
            return Ok(());
        }
        let c = usize::from(release.component.get());
        let Some(h) = self.hosted.iter_mut().find(|h| h.index == c) else {
            tracing::warn!(
                "release of component {c}, which is not on host {}",
                self.name
            );
            return Ok(());
        };
        if h.next.as_ref().is_some_and(|b| b.generation == generation) {
            if let Some(next) = h.next.take() {
                let old = std::mem::replace(&mut h.binding, next);
                // Dropping its subscribers unmaps shared memory (milliseconds): not here.
                if let Err(e) = self.reaper.send(old) {
                    tracing::debug!("the reaper thread is gone; dropping here");
                    drop(e.0);
                }
            }
        }
        if h.binding.generation != generation {
            tracing::warn!(
                "component {} at tick {n}: release of assembly generation {generation}, \
                 prepared for {}",
                h.name,
                h.binding.generation
            );
        }
        let mut versions = [0u64; modbot_ipc_schema::grid::MAX_SOURCES];
        for (slot, v) in versions.iter_mut().zip(release.versions()) {
            *slot = v;
        }
        // LET: every input exactly as valid at n, or the release is not executed.
        let mut stale = None;
        for (i, &(s, port)) in h.binding.inputs.iter().enumerate() {
            let Some(source) = h.binding.sources.get_mut(s) else {
                stale = Some((i, 0));
                break;
            };
            match source.get(versions[s]) {
                Some(values) => h.inputs[i].assign(&values[port]),
                None => {
                    stale = Some((i, versions[s]));
                    break;
                }
            }
        }
        if let Some((i, version)) = stale {
            self.stale += 1;
            tracing::warn!(
                "component {} at tick {n}: input {i} version {version} is gone (the host was \
                 held up); the release is not executed",
                h.name
            );
            let done = Done::new(n, c as u16, Done::STALE, 0, 0).of_generation(generation.0);
            return self.push_done(&done);
        }
        self.last_tick = self.last_tick.max(n);
        let start = now();
        let rel = Released {
            tick: Tick(n),
            generation,
            flags: release.flags.get(),
            now_ns: start,
            state_hash: release.state_hash.get(),
        };
        if release.has(Release::TRACK) {
            h.component.track(&rel, &h.inputs, &mut h.outputs);
        } else {
            h.component.step(&rel, &h.inputs, &mut h.outputs);
        }
        let end = now();
        publish(h, n + h.period, n)?;
        // After publishing: the readers of the outputs do not wait for it.
        let mut hasher = crate::StateHasher::new();
        h.component.state_hash(&h.outputs, &mut hasher);
        let status = if h.component.unsafe_state() {
            Done::UNSAFE
        } else {
            Done::OK
        };
        let done = Done::new(
            n,
            c as u16,
            status,
            end.saturating_sub(start),
            start.saturating_sub(release.released_ns.get()),
        )
        .of_generation(generation.0)
        .with_flags(if h.component.holding() {
            Done::HOLDING
        } else {
            0
        })
        .with_state_hash(hasher.finish());
        self.push_done(&done)
    }
}

/// Publishes `h`'s outputs — its initial ones for version 0 — as valid from `valid_from`,
/// released at `release`.
fn publish(h: &Hosted, valid_from: u64, release: u64) -> Result<(), TransportError> {
    let outputs = if valid_from == 0 {
        &h.initial
    } else {
        &h.outputs
    };
    h.out.send(h.out_len, &mut |buf| {
        let header = OutHeader {
            valid_from: valid_from.into(),
            release: release.into(),
        };
        buf[..OUT_HEADER_LEN].copy_from_slice(header.as_bytes());
        if let Err(e) = write_record(outputs, &mut buf[OUT_HEADER_LEN..]) {
            tracing::error!("outputs of component {} not written: {e}", h.index);
        }
    })
}

impl Drop for Host {
    fn drop(&mut self) {
        for h in &mut self.hosted {
            h.component.terminate();
        }
    }
}
