//! The iceoryx2 backend: frames in shared memory between processes, without copies.
//!
//! - this file: endpoints (inbox, broadcast and groups, wake-ups, heartbeats, snapshots);
//! - `directory`: who is in the domain (the supervisor's published directory, or a scan);
//!   `directory_slots`: the services it lives in;
//! - `relay`: calls of tools without a module address, made by the supervisor;
//! - `wake`: the wake-ups of modules in blocking mode and of the grid (futex words in shared
//!   memory).

mod channels;
mod directory;
mod directory_slots;
mod relay;
mod wake;

pub use channels::IpcChannels;
pub use directory::DirectoryWriter;
use directory::{PublishedDirectory, ScannedDirectory};
pub use relay::{RelayClient, RelayRequest, RelayServer};
use wake::{WakeTable, Word};

use core::time::Duration;
use std::collections::HashMap;
use std::sync::Arc;

use iceoryx2::config::Config;
use iceoryx2::port::publisher::{Publisher, PublisherCreateError};
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use modbot_ipc_schema::Addr;

use super::{
    Dest, Directory, Endpoint, IpcResult, Opening, ReceiveMode, Rx, SendError, Snapshots,
    Transport, TransportError, Tx,
};
use crate::domain::Domain;

type Pub = Publisher<ipc::Service, [u8], ()>;
type Sub = Subscriber<ipc::Service, [u8], ()>;
/// A publish-subscribe service of byte frames (an inbox, a bus, heartbeats, snapshots).
type BytesService =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, [u8], ()>;
/// A claim of an address or a name: an event service this process created.
type Claim = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

/// Most modules (and tools) a domain holds at once, plus room for stale ports.
const MAX_NODES: usize = 300;
/// Frames an inbox holds before it refuses more.
const INBOX_DEPTH: usize = 64;
/// Largest broadcast or multicast frame.
const BCAST_MAX_FRAME: usize = 4096;

fn service_name(name: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name).ipc("service name")
}

/// The iceoryx2 backend for one domain.
#[derive(Debug, Clone)]
pub struct IpcTransport {
    domain: Domain,
    config: Config,
    /// Opened for a tool (see [`Transport::opened_as_tool`]).
    tool: std::cell::Cell<bool>,
    /// A supervisor publishes the domain's directory and cleans up after the dead: this
    /// process neither scans nor cleans.
    supervised: bool,
    /// Whether this process closed the domain's files to other users (after its first node).
    closed: std::cell::Cell<bool>,
}

impl IpcTransport {
    pub fn new(domain: &Domain) -> Result<IpcTransport, TransportError> {
        set_log_level_from_env_or(LogLevel::Error);
        // A process its supervisor started runs as the supervisor's user, which checked the
        // domain's access and closed its files: each of those walks /dev/shm, and 253
        // processes starting together each walking thousands of files is quadratic.
        let launched = crate::launch::launched_by_live_supervisor(domain.name());
        if !launched {
            domain.check_access()?;
        }
        let mut config = Config::default();
        config.global.prefix = FileName::new(domain.prefix().as_bytes()).ipc("prefix")?;
        // iceoryx2's node and service files (thousands at full size) on tmpfs, beside the
        // shared memory: creating them on a disk file system costs start-up seconds.
        config
            .global
            .set_root_path(&Path::new(crate::domain::ICEORYX2_ROOT.as_bytes()).ipc("root path")?);
        // A subscriber keeps room for this many connections of departed publishers that still
        // hold samples; the default (128) costs ~0.45 MiB of heap per subscriber.
        config
            .defaults
            .publish_subscribe
            .subscriber_expired_connection_buffer = 4;
        // An inbox this process creates has this many sender slots (`inbox_service`).
        config.defaults.publish_subscribe.max_publishers = crate::launch::inbox_senders();
        // A process its supervisor started knows it (asking iceoryx2 reads every node
        // attached to the directory: quadratic when hundreds of modules start together).
        let supervised = launched || directory::is_published(&config);
        if supervised {
            // Each of these scans every node of the domain; the supervisor cleans instead.
            config.global.node.cleanup_dead_nodes_on_creation = false;
            config.global.node.cleanup_dead_nodes_on_destruction = false;
            config.global.service.cleanup_dead_nodes_on_open = false;
        }
        Ok(IpcTransport {
            domain: domain.clone(),
            config,
            tool: std::cell::Cell::new(false),
            supervised,
            closed: std::cell::Cell::new(launched),
        })
    }

    /// Sets the sender slots of the inboxes this process creates (see
    /// [`launch::INBOX_SENDERS`](crate::launch::INBOX_SENDERS), which sets them by default),
    /// within [`launch::MIN_INBOX_SENDERS`](crate::launch::MIN_INBOX_SENDERS)`..=`
    /// [`launch::DEFAULT_INBOX_SENDERS`](crate::launch::DEFAULT_INBOX_SENDERS).
    pub fn with_inbox_senders(mut self, senders: usize) -> IpcTransport {
        self.config.defaults.publish_subscribe.max_publishers =
            crate::launch::inbox_senders_within(senders);
        self
    }

    /// The transport of the supervisor itself: it scans and cleans, whatever an earlier
    /// supervisor of the domain left behind.
    pub fn for_supervisor(domain: &Domain) -> Result<IpcTransport, TransportError> {
        domain.check_access()?;
        let mut t = IpcTransport::new(domain)?;
        t.supervised = false;
        t.closed = std::cell::Cell::new(false);
        t.config.global.node.cleanup_dead_nodes_on_creation = true;
        t.config.global.node.cleanup_dead_nodes_on_destruction = true;
        t.config.global.service.cleanup_dead_nodes_on_open = true;
        Ok(t)
    }

    /// The directory as iceoryx2's node files tell it, and the cleaning of dead nodes: the
    /// supervisor's (it publishes what it learns) and the fallback of unsupervised domains.
    pub fn scanned_directory(&self) -> Box<dyn Directory> {
        Box::new(self.scan())
    }

    fn scan(&self) -> ScannedDirectory {
        ScannedDirectory {
            config: self.config.clone(),
        }
    }

    pub fn domain(&self) -> &Domain {
        &self.domain
    }

    /// The channels and wake-ups of this domain, through a node of its own named
    /// `node_name` (the grid's processes: see [`crate::channels`]).
    pub fn channels(&self, node_name: &str) -> Result<IpcChannels, TransportError> {
        Ok(IpcChannels::new(
            self.node_of(node_name)?,
            Arc::new(WakeTable::open(&self.domain)?),
        ))
    }

    /// A node of this domain that is not a module.
    pub fn node(&self, node_name: &str) -> Result<Node<ipc::Service>, TransportError> {
        self.node_of(node_name)
    }

    fn node_of<S: iceoryx2::service::Service>(
        &self,
        node_name: &str,
    ) -> Result<Node<S>, TransportError> {
        let name = NodeName::new(node_name).ipc("node name")?;
        let node = NodeBuilder::new()
            .name(&name)
            .config(&self.config)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<S>()
            .ipc("node creation")?;
        if !self.closed.replace(true) {
            // iceoryx2 opens its management segment to everyone; the domain is one user's.
            self.domain.close_shared_files();
        }
        Ok(node)
    }

    fn claim(
        &self,
        node: &Node<ipc::Service>,
        addr: Addr,
        name: &str,
    ) -> Result<Vec<Claim>, TransportError> {
        let dir = self.scan();
        let mut claims = Vec::new();
        for (service, is_addr) in [
            (format!("claim.addr.{}", addr.0), true),
            (format!("claim.name.{name}"), false),
        ] {
            let sname = service_name(&service)?;
            let mut attempt = 0;
            loop {
                match node.service_builder(&sname).event().max_nodes(2).create() {
                    Ok(f) => {
                        claims.push(f);
                        break;
                    }
                    Err(e) if attempt == 0 => {
                        // Held by a live module, or left by a dead one: look, clean, retry once.
                        let mut holder = None;
                        let mine = *node.id();
                        dir.list_with_ids(&mut |id, p| {
                            let same = if is_addr {
                                p.addr == addr
                            } else {
                                p.name == name
                            };
                            if same && p.alive && id != &mine {
                                holder = Some(p);
                            }
                        })?;
                        if let Some(p) = holder {
                            return Err(if is_addr {
                                TransportError::AddressTaken {
                                    addr,
                                    holder: p.name,
                                    pid: p.pid,
                                }
                            } else {
                                TransportError::NameTaken {
                                    name: name.to_owned(),
                                    addr: p.addr,
                                    pid: p.pid,
                                }
                            });
                        }
                        dir.reap_dead();
                        attempt += 1;
                        tracing::debug!(
                            "claim {service} busy ({e:?}); cleaned dead nodes, retrying"
                        );
                    }
                    Err(e) => {
                        return Err(TransportError::Claim {
                            service,
                            failure: e.into(),
                        });
                    }
                }
            }
        }
        Ok(claims)
    }
}

fn inbox_service(node: &Node<ipc::Service>, addr: Addr) -> Result<BytesService, TransportError> {
    // No `max_publishers`: whoever creates the inbox gives it the sender slots of its
    // configuration (`launch::INBOX_SENDERS`), and an opener takes what the inbox has instead
    // of requiring a number of its own. Fewer slots make every receive cheaper (iceoryx2 looks
    // at each one); a sender finds out at once if they are all taken (`InboxSendersTaken`).
    use iceoryx2::service::builder::publish_subscribe::{
        PublishSubscribeOpenError, PublishSubscribeOpenOrCreateError,
    };
    node.service_builder(&service_name(&format!("inbox.{}", addr.0))?)
        .publish_subscribe::<[u8]>()
        .max_subscribers(2)
        .max_nodes(MAX_NODES)
        .subscriber_max_buffer_size(INBOX_DEPTH)
        .subscriber_max_borrowed_samples(4)
        .history_size(0)
        .enable_safe_overflow(false)
        .open_or_create()
        .map_err(|e| match e {
            PublishSubscribeOpenOrCreateError::PublishSubscribeOpenError(
                PublishSubscribeOpenError::HangsInCreation,
            ) => TransportError::InboxInCreation { addr },
            e => TransportError::ipc("open inbox", e),
        })
}

fn shared_bus(node: &Node<ipc::Service>, name: &str) -> Result<BytesService, TransportError> {
    node.service_builder(&service_name(name)?)
        .publish_subscribe::<[u8]>()
        .max_publishers(MAX_NODES)
        .max_subscribers(MAX_NODES)
        .max_nodes(MAX_NODES)
        .subscriber_max_buffer_size(16)
        .subscriber_max_borrowed_samples(4)
        .history_size(0)
        .enable_safe_overflow(false)
        .open_or_create()
        .ipc("open broadcast")
}

/// Subscribers to `services` (an inbox, then buses), each with its buffer size.
fn subscribe(services: &[(BytesService, usize)]) -> Result<Vec<Sub>, TransportError> {
    services
        .iter()
        .map(|(service, buffer)| {
            service
                .subscriber_builder()
                .buffer_size(*buffer)
                .create()
                .ipc("inbox or bus subscriber")
        })
        .collect()
}

/// Refuses `addr` or `name` if the published directory lists another live process with it.
fn refuse_taken(dir: &PublishedDirectory, addr: Addr, name: &str) -> Result<(), TransportError> {
    let mut taken = Ok(());
    dir.list(&mut |p| {
        if !p.alive || p.pid == std::process::id() || taken.is_err() {
            return;
        }
        if p.addr == addr {
            taken = Err(TransportError::AddressTaken {
                addr,
                holder: p.name.clone(),
                pid: p.pid,
            });
        } else if p.name == name {
            taken = Err(TransportError::NameTaken {
                name: name.to_owned(),
                addr: p.addr,
                pid: p.pid,
            });
        }
    })?;
    taken
}

/// The service every module publishes its heartbeat on.
fn heartbeat_service(node: &Node<ipc::Service>) -> Result<BytesService, TransportError> {
    node.service_builder(&service_name("heartbeat")?)
        .publish_subscribe::<[u8]>()
        .max_publishers(MAX_NODES)
        .max_subscribers(4)
        .max_nodes(MAX_NODES)
        .history_size(0)
        .subscriber_max_buffer_size(4)
        .subscriber_max_borrowed_samples(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .ipc("open heartbeat service")
}

fn node_name(addr: Addr, mode: ReceiveMode, name: &str) -> String {
    format!("m{:03}.{}.{}", addr.0, mode.code(), name)
}

fn parse_node_name(text: &str) -> Option<(Addr, ReceiveMode, String)> {
    let rest = text.strip_prefix('m')?;
    let (addr, rest) = rest.split_once('.')?;
    let (mode, name) = rest.split_once('.')?;
    let mut chars = mode.chars();
    let mode = ReceiveMode::from_code(chars.next()?)?;
    Some((Addr(addr.parse().ok()?), mode, name.to_owned()))
}

impl Transport for IpcTransport {
    fn open_checked(&self, module: Opening<'_>) -> Result<Endpoint, TransportError> {
        let Opening { addr, name, .. } = module;
        let node = self.node(&node_name(addr, module.mode, name))?;
        // Under a supervisor, the address and name it assigned are this module's by its word.
        let assigned = self.supervised
            && std::env::var(crate::launch::ASSIGNED)
                .is_ok_and(|a| a == format!("{}.{name}", addr.0));
        let published = PublishedDirectory::open(&node, &self.config)?;
        let claims = if assigned {
            Vec::new()
        } else {
            // The supervisor's modules hold no claims: what it published says who they are.
            if let Some(dir) = &published {
                refuse_taken(dir, addr, name)?;
            }
            self.claim(&node, addr, name)?
        };
        let bus_names: Vec<String> = module
            .joins
            .broadcast
            .then(|| "bcast".to_owned())
            .into_iter()
            .chain(module.joins.groups.iter().map(|g| format!("group.{g}")))
            .collect();
        let table = Arc::new(WakeTable::open(&self.domain)?);
        // A sleeping module waits on its own word and its buses' (groups may share one).
        let mut words = vec![Word::module(addr)];
        for bus in &bus_names {
            let w = Word::bus(bus);
            if !words.contains(&w) {
                words.push(w);
            }
        }
        debug_assert!(words.len() <= wake::MAX_WAIT_WORDS);
        // The inbox, then the buses, with each one's buffer.
        let mut services = vec![(inbox_service(&node, addr)?, INBOX_DEPTH)];
        for bus in &bus_names {
            services.push((shared_bus(&node, bus)?, 16));
        }
        // A process taking over a running module subscribes when the handover begins.
        let standby = assigned && std::env::var_os(crate::launch::UPGRADE_DIR).is_some();
        let (subs, standby) = if standby {
            (Vec::new(), Some(services))
        } else {
            (subscribe(&services)?, None)
        };
        let heartbeat = heartbeat_service(&node)?
            .publisher_builder()
            .initial_max_slice_len(modbot_ipc_schema::heartbeat::LEN)
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_samples(1)
            .create()
            .ipc("heartbeat publisher")?;
        let node = std::rc::Rc::new(node);
        let sleeps = (module.mode == ReceiveMode::Blocking).then(|| Sleeper {
            table: table.clone(),
            waits: vec![rustix::thread::futex::Wait::new(); words.len()],
            words,
        });
        let rx = IpcRx {
            subs,
            sleeps,
            next: 0,
            standby,
        };
        let tx = IpcTx {
            node: node.clone(),
            me: addr,
            max_frame: self.domain.max_frame(),
            peers: (0..256).map(|_| None).collect(),
            buses: HashMap::new(),
            dropped: 0,
            heartbeat: PeerLink {
                publisher: heartbeat,
                wake: None,
                service: None,
            },
            wake: table,
            _claims: claims,
        };
        let snapshots = IpcSnapshots {
            node,
            me: addr,
            publisher: None,
            readers: HashMap::new(),
        };
        let directory: Box<dyn Directory> = match published {
            Some(published) => Box::new(published),
            None => self.scanned_directory(),
        };
        Ok(Endpoint {
            addr,
            rx: Box::new(rx),
            tx: Box::new(tx),
            snapshots: Box::new(snapshots),
            directory,
        })
    }

    fn directory(&self) -> Result<Box<dyn Directory>, TransportError> {
        if self.supervised {
            let node = self.node(&format!("dir.{}", std::process::id()))?;
            if let Some(published) = PublishedDirectory::open(&node, &self.config)? {
                return Ok(Box::new(published.owning(node)));
            }
        }
        Ok(self.scanned_directory())
    }

    fn opened_as_tool(&self) {
        self.tool.set(true);
    }

    fn sweep_if_empty(&self) -> bool {
        if self.supervised
            && (crate::launch::launched_by_live_supervisor(self.domain.name())
                || directory::is_published(&self.config))
        {
            // The supervisor removes the domain's files when the system stops; one that
            // stopped while other processes lived left them to the last of those, and as long
            // as its directory exists someone still holds it.
            return false;
        }
        // A system may be starting in this domain right now: only files older than this
        // check are removed, so what a process creates while we look is left alone.
        let before = std::time::SystemTime::now();
        self.scan().reap_dead();
        if self.tool.get() {
            // A system may be starting: its first node is invisible to a listing for a
            // moment, and removing its files would cut it off. Dead nodes are reaped above
            // (iceoryx2 removes what they held); what stays after a clean exit is the
            // prefix's global management file, the wake-up table and the checked grids'
            // images, removed when nothing else of the domain exists.
            let files = self.domain.files();
            let table = format!("{}{}", self.domain.prefix(), wake::FILE_SUFFIX);
            let images = format!(
                "{}{}",
                self.domain.prefix(),
                crate::spec_image::SPEC_IMAGE_INFIX
            );
            let only_management = !files.is_empty()
                && files.iter().all(|f| {
                    f.file_name().is_some_and(|n| {
                        let n = n.to_string_lossy();
                        n.ends_with(".global_mgmt") || n == table.as_str() || n.starts_with(&images)
                    })
                });
            return only_management && self.domain.remove_files_older_than(before) > 0;
        }
        self.remove_files_unless_alive(before)
    }
}

impl IpcTransport {
    /// After a system stopped, or failed to start: removes what dead processes left, and the
    /// domain's files if no process of the domain lives any more. A process that still does (an
    /// operator's console, `modbot top`, a module started by hand) keeps its files and goes on
    /// working; the last process to leave the domain removes what is left
    /// ([`Transport::sweep_if_empty`]). Returns whether the files were removed.
    pub fn sweep_after_system(&self) -> bool {
        // A process may be starting in the domain while we look: only files older than this
        // check are removed.
        let before = std::time::SystemTime::now();
        self.scan().reap_dead();
        self.remove_files_unless_alive(before)
    }

    /// Removes the domain's files older than `before` if no node of the domain lives.
    fn remove_files_unless_alive(&self, before: std::time::SystemTime) -> bool {
        // Any node that is not known dead counts, not only modules (a supervisor's heartbeat
        // monitor, say), and so does one whose state cannot be read right now.
        let mut alive = 0;
        let listed = Node::<ipc::Service>::list(&self.config, |state| {
            if !matches!(state, NodeState::Dead(_)) {
                alive += 1;
            }
            CallbackProgression::Continue
        });
        if listed.is_err() || alive > 0 {
            return false;
        }
        self.domain.remove_files_older_than(before);
        true
    }
}

/// How a module in blocking mode sleeps: on its words of the domain's wake-up table.
struct Sleeper {
    table: Arc<WakeTable>,
    /// Its own word, then its buses'.
    words: Vec<Word>,
    /// Scratch space for the wait, so that waiting allocates nothing.
    waits: Vec<rustix::thread::futex::Wait>,
}

struct IpcRx {
    /// The inbox first, then broadcast and the groups.
    subs: Vec<Sub>,
    /// Blocking mode only.
    sleeps: Option<Sleeper>,
    /// Which bus to look at first next time, so broadcast cannot starve the inbox or back.
    next: usize,
    /// In standby: the services to subscribe to at [`Rx::attach`] (the inbox has room for two
    /// subscribers: the running module's and this one's).
    standby: Option<Vec<(BytesService, usize)>>,
}

impl Rx for IpcRx {
    fn try_receive(&mut self, on_frame: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError> {
        if let [inbox] = self.subs.as_slice() {
            // Only an inbox (most modules): no turn to take.
            return Ok(match inbox.receive().ipc("receive")? {
                Some(sample) => {
                    on_frame(sample.payload());
                    true
                }
                None => false,
            });
        }
        let n = self.subs.len();
        if n == 0 {
            return Ok(false); // standby
        }
        for i in 0..n {
            let idx = (self.next + i) % n;
            if let Some(sample) = self.subs[idx].receive().ipc("receive")? {
                self.next = (idx + 1) % n;
                on_frame(sample.payload());
                return Ok(true);
            }
        }
        Ok(false)
    }

    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        let Some(sleeper) = &mut self.sleeps else {
            std::thread::sleep(timeout.min(Duration::from_micros(50)));
            return Ok(());
        };
        let subs = &self.subs;
        sleeper.table.wait(
            &sleeper.words,
            &mut sleeper.waits,
            &mut || {
                for sub in subs {
                    if sub.has_samples().ipc("has samples")? {
                        return Ok(true);
                    }
                }
                Ok(false)
            },
            timeout,
        )
    }

    fn standby(&self) -> bool {
        self.standby.is_some()
    }

    fn attach(&mut self) -> Result<(), TransportError> {
        if let Some(services) = self.standby.take() {
            self.subs = subscribe(&services)?;
        }
        Ok(())
    }
}

struct PeerLink {
    publisher: Pub,
    /// Whom to wake after a frame is delivered (a module's or a bus's word).
    wake: Option<Word>,
    /// The inbox service this link reaches (modules only), to tell a full inbox from one that
    /// nobody reads any more.
    service: Option<BytesService>,
}

struct IpcTx {
    node: std::rc::Rc<Node<ipc::Service>>,
    me: Addr,
    max_frame: usize,
    /// Indexed by address: the publishers opened so far.
    peers: Vec<Option<PeerLink>>,
    /// Broadcast and group publishers, by service name.
    buses: HashMap<String, PeerLink>,
    dropped: u64,
    /// The heartbeat publisher.
    heartbeat: PeerLink,
    /// The domain's wake-up table.
    wake: Arc<WakeTable>,
    /// Held for the endpoint's life: they make the address and the name ours.
    _claims: Vec<Claim>,
}

impl IpcTx {
    fn open_peer(&mut self, to: Addr) -> Result<(), SendError> {
        if self.peers[usize::from(to.0)].is_some() {
            return Ok(());
        }
        let service = inbox_service(&self.node, to)?;
        let publisher = service
            .publisher_builder()
            .initial_max_slice_len(self.max_frame)
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_samples(2)
            .backpressure_strategy(BackpressureStrategy::DiscardData)
            .create()
            .map_err(|e| match e {
                PublisherCreateError::ExceedsMaxSupportedPublishers => {
                    TransportError::InboxSendersTaken {
                        addr: to,
                        slots: service.static_config().max_publishers(),
                    }
                }
                e => TransportError::ipc("inbox publisher", e),
            })?;
        self.peers[usize::from(to.0)] = Some(PeerLink {
            publisher,
            wake: Some(Word::module(to)),
            service: Some(service),
        });
        Ok(())
    }

    fn open_bus(&mut self, bus: &str) -> Result<(), SendError> {
        if self.buses.contains_key(bus) {
            return Ok(());
        }
        let publisher = shared_bus(&self.node, bus)?
            .publisher_builder()
            .initial_max_slice_len(BCAST_MAX_FRAME)
            .max_loaned_samples(2)
            .backpressure_strategy(BackpressureStrategy::DiscardData)
            .create()
            .ipc("bus publisher")?;
        self.buses.insert(
            bus.to_owned(),
            PeerLink {
                publisher,
                wake: Some(Word::bus(bus)),
                service: None,
            },
        );
        Ok(())
    }
}

fn send_on(
    link: &PeerLink,
    wake: Option<&WakeTable>,
    len: usize,
    fill: &mut dyn FnMut(&mut [u8]),
) -> Result<usize, TransportError> {
    let mut sample = link.publisher.loan_slice_uninit(len).ipc("loan")?;
    let payload = sample.payload_mut();
    // SAFETY: the payload is `len` bytes of shared memory mapped by iceoryx2. Those pages are
    // zero-filled by the kernel when first mapped and afterwards only ever hold bytes written
    // by earlier frames, so every byte is initialised; `MaybeUninit<u8>` and `u8` have the same
    // layout. `fill` writes the whole frame before it is sent.
    let bytes = unsafe {
        core::slice::from_raw_parts_mut(payload.as_mut_ptr().cast::<u8>(), payload.len())
    };
    fill(bytes);
    // SAFETY: see above; every byte is initialised.
    let sample = unsafe { sample.assume_init() };
    let delivered = sample.send().ipc("send")?;
    if delivered > 0 {
        if let (Some(table), Some(word)) = (wake, link.wake) {
            table.notify(word);
        }
    }
    Ok(delivered)
}

impl Tx for IpcTx {
    fn send(
        &mut self,
        to: Dest<'_>,
        len: usize,
        fill: &mut dyn FnMut(&mut [u8]),
    ) -> Result<(), SendError> {
        match to {
            Dest::Module(addr) => {
                if len > self.max_frame {
                    return Err(TransportError::FrameTooLarge {
                        len,
                        max: self.max_frame,
                    }
                    .into());
                }
                self.open_peer(addr)?;
                let link = self.peers[usize::from(addr.0)]
                    .as_ref()
                    .expect("opened above");
                let delivered = send_on(link, Some(&self.wake), len, fill)?;
                if delivered == 0 {
                    self.dropped += 1;
                    let subscribers = link
                        .service
                        .as_ref()
                        .map_or(0, |s| s.dynamic_config().number_of_subscribers());
                    if subscribers > 0 {
                        return Err(SendError::InboxFull(addr));
                    }
                    // Nobody reads the inbox this link reaches. The process now at this
                    // address may serve a new one (the old files were swept while it started,
                    // say): the link is opened anew, by name, for the next frame.
                    self.peers[usize::from(addr.0)] = None;
                    return Err(SendError::NoReceiver(addr));
                }
                Ok(())
            }
            Dest::Broadcast | Dest::Group(_) => {
                if len > BCAST_MAX_FRAME {
                    return Err(TransportError::FrameTooLarge {
                        len,
                        max: BCAST_MAX_FRAME,
                    }
                    .into());
                }
                let bus = match to {
                    Dest::Group(g) => format!("group.{g}"),
                    _ => "bcast".to_owned(),
                };
                self.open_bus(&bus)?;
                let link = &self.buses[&bus];
                send_on(link, Some(&self.wake), len, fill)?;
                Ok(())
            }
        }
    }

    fn connect(&mut self, to: Addr) -> Result<(), SendError> {
        if to == self.me || !to.is_module() {
            return Ok(());
        }
        self.open_peer(to)
    }

    fn disconnect(&mut self, to: Addr) {
        self.peers[usize::from(to.0)] = None;
    }

    fn dropped(&self) -> u64 {
        self.dropped
    }

    fn heartbeat(&mut self, beat: &[u8]) -> Result<(), TransportError> {
        send_on(&self.heartbeat, None, beat.len(), &mut |buf| {
            buf.copy_from_slice(beat)
        })
        .map(|_| ())
    }
}

/// The supervisor's side of the heartbeat service: every module's latest heartbeat.
pub struct HeartbeatMonitor {
    _node: Node<ipc::Service>,
    subscriber: Sub,
}

impl HeartbeatMonitor {
    /// Subscribes to the heartbeats of `transport`'s domain.
    pub fn new(transport: &IpcTransport) -> Result<HeartbeatMonitor, TransportError> {
        let node = transport.node(&format!("hbmon.{}", std::process::id()))?;
        let subscriber = heartbeat_service(&node)?
            .subscriber_builder()
            .buffer_size(4)
            .create()
            .ipc("heartbeat subscriber")?;
        Ok(HeartbeatMonitor {
            _node: node,
            subscriber,
        })
    }

    /// Lends every heartbeat received since the last call to `f`, oldest first.
    pub fn drain(&self, f: &mut dyn FnMut(&[u8])) -> Result<usize, TransportError> {
        let mut n = 0;
        while let Some(sample) = self.subscriber.receive().ipc("receive heartbeat")? {
            f(sample.payload());
            n += 1;
        }
        Ok(n)
    }
}

/// A received blackboard snapshot, kept to be read in place.
type SnapshotSample = Sample<ipc::Service, [u8], ()>;

struct IpcSnapshots {
    pub(self) node: std::rc::Rc<Node<ipc::Service>>,
    me: Addr,
    publisher: Option<Pub>,
    /// Per module read: its subscriber and the newest snapshot taken from it.
    readers: HashMap<Addr, (Sub, Option<SnapshotSample>)>,
}

fn bb_service(node: &Node<ipc::Service>, addr: Addr) -> Result<BytesService, TransportError> {
    node.service_builder(&service_name(&format!("bb.{}", addr.0))?)
        .publish_subscribe::<[u8]>()
        // A snapshot starts 64-byte aligned, so readers view its bulk items as `&[T]`.
        .payload_alignment(
            Alignment::new(modbot_ipc_schema::snapshot::BULK_ALIGN).expect("a power of two"),
        )
        .max_publishers(2)
        .max_subscribers(64)
        .max_nodes(MAX_NODES)
        .history_size(1)
        .subscriber_max_buffer_size(2)
        .subscriber_max_borrowed_samples(2)
        .enable_safe_overflow(true)
        .open_or_create()
        .ipc("open snapshot service")
}

impl Snapshots for IpcSnapshots {
    fn publish(
        &mut self,
        len: usize,
        fill: &mut dyn FnMut(&mut [u8]),
    ) -> Result<(), TransportError> {
        if self.publisher.is_none() {
            self.publisher = Some(
                bb_service(&self.node, self.me)?
                    .publisher_builder()
                    .initial_max_slice_len(len.max(256))
                    .allocation_strategy(AllocationStrategy::PowerOfTwo)
                    .max_loaned_samples(1)
                    .create()
                    .ipc("snapshot publisher")?,
            );
        }
        let link = PeerLink {
            publisher: self.publisher.take().expect("created above"),
            wake: None,
            service: None,
        };
        let result = send_on(&link, None, len, fill);
        self.publisher = Some(link.publisher);
        result.map(|_| ())
    }

    fn read_latest(
        &mut self,
        of: Addr,
        read: &mut dyn FnMut(&[u8]),
    ) -> Result<bool, TransportError> {
        if !self.readers.contains_key(&of) {
            let sub = bb_service(&self.node, of)?
                .subscriber_builder()
                .buffer_size(2)
                .history_request(1)
                .create()
                .ipc("snapshot subscriber")?;
            self.readers.insert(of, (sub, None));
        }
        let (sub, latest) = self.readers.get_mut(&of).expect("inserted above");
        while let Some(sample) = sub.receive().ipc("receive snapshot")? {
            *latest = Some(sample);
        }
        match latest {
            Some(sample) => {
                read(sample.payload());
                Ok(true)
            }
            None => Ok(false),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_names_carry_address_mode_and_name() {
        let text = node_name(Addr(7), ReceiveMode::Blocking, "nav_sonar");
        assert_eq!(text, "m007.b.nav_sonar");
        assert_eq!(
            parse_node_name(&text),
            Some((Addr(7), ReceiveMode::Blocking, "nav_sonar".into()))
        );
        assert_eq!(parse_node_name("coordinator"), None);
    }
}
