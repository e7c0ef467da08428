//! modbot-transport: how frames move between module processes — the bottom of modbot's
//! crates (it uses only `modbot-ipc-schema` and iceoryx2).
//!
//! # Layout
//! - this file: the [`Transport`], [`Endpoint`] and [`Directory`] traits and [`TransportError`];
//! - [`channels`]: named byte channels and wake-ups, the time grid's links (both backends);
//! - [`ipc`]: the iceoryx2 backend (endpoints, the supervisor's published directory, the relay
//!   for tools without an address); [`local`]: the in-process backend for fast tests;
//! - [`domain`]: a domain's name, its iceoryx2 prefix and root, and the sweep of its files;
//! - [`launch`]: what a supervisor tells the module processes it starts, through their
//!   environment (written by the supervisor, read by the transport and the module runtime).
//!
//! The traits here are the whole interface the message manager needs; [`ipc`] implements them
//! on iceoryx2 shared memory (real runs, one process per module) and [`local`] inside one process
//! (fast unit tests). The same test suite runs against both.
//!
//! Service layout of the iceoryx2 backend, per domain (it scales to 254 modules because a
//! module connects only to the peers it actually talks to):
//! - `claim.addr.N`, `claim.name.NAME`: event services created exclusively, so an address or
//!   a name has one owner (a module started by a supervisor takes the address and name it was
//!   assigned without them: the supervisor's directory says who holds what);
//! - `inbox.N`: publish-subscribe `[u8]`, module N's only subscriber; senders open a publisher
//!   on first use. Full inboxes refuse new frames (no silent overwrite): the sender sees it;
//! - `bcast` and `group.NAME`: publish-subscribe for broadcast and multicast, subscribed only
//!   by the modules that listen (see [`Joins`]); a module opens its publisher on its first
//!   broadcast;
//! - not a service: the wake-up table `/dev/shm/modbot_<domain>.wake`, a futex word per
//!   address and per bus; a module in blocking mode sleeps on its own word and its buses' at
//!   once, and a sender wakes it with one system call only when it sleeps;
//! - `bb.N`: module N's blackboard snapshots, history 1;
//! - `heartbeat`: publish-subscribe, every module publishes its 48-byte heartbeat there and the
//!   supervisor subscribes (one publisher per module, few subscribers: it stays small);
//! - `directory`: a blackboard the supervisor writes: who is in the domain (see
//!   [`ipc::DirectoryWriter`]);
//! - `relay`: request-response, the supervisor's: calls of tools that hold no address (see
//!   [`ipc::RelayServer`]).
//!
//! Liveness comes from the supervisor's directory, or without a supervisor from iceoryx2 nodes:
//! one per module, named `mNNN.MODE.NAME`.

mod channel_spec;
pub mod channels;
pub mod domain;
mod failure;
pub mod ipc;
pub mod launch;
pub mod local;
pub mod spec_image;

use core::time::Duration;

use modbot_ipc_schema::directory::DirectoryError;
use modbot_ipc_schema::Addr;
use thiserror::Error;

use crate::channel_spec::ChannelSpec;
pub use crate::failure::{IoFailure, IpcFailure};

/// How a module receives: spinning on its inbox, or sleeping until woken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReceiveMode {
    /// Spin on the inbox: lowest latency, one core busy. Give the module a core of its own.
    BusyPoll,
    /// Sleep until a sender's wake-up event: no CPU while idle, tens of microseconds more.
    Blocking,
}

impl ReceiveMode {
    pub fn code(self) -> char {
        match self {
            ReceiveMode::BusyPoll => 'p',
            ReceiveMode::Blocking => 'b',
        }
    }

    pub fn from_code(c: char) -> Option<ReceiveMode> {
        match c {
            'p' => Some(ReceiveMode::BusyPoll),
            'b' => Some(ReceiveMode::Blocking),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ReceiveMode::BusyPoll => "busy-poll",
            ReceiveMode::Blocking => "blocking",
        }
    }
}

/// What the directory knows about one module.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PeerInfo {
    pub addr: Addr,
    pub name: String,
    pub pid: u32,
    pub mode: ReceiveMode,
    pub alive: bool,
    /// The digest of its method names ([`modbot_ipc_schema::directory::methods_digest`]); 0
    /// if the directory does not know it.
    pub methods_digest: u32,
    /// How often a live upgrade replaced its process (published directories only; 0 else):
    /// a new pid with a higher count took over the module, calls and all.
    pub upgrades: u16,
}

/// Where a frame goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dest<'a> {
    Module(Addr),
    Broadcast,
    Group(&'a str),
}

/// Errors of the transport layer.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum TransportError {
    #[error("address {addr} is already taken by '{holder}' (pid {pid})")]
    AddressTaken {
        addr: Addr,
        holder: String,
        pid: u32,
    },
    #[error("name '{name}' is already taken by the module at address {addr} (pid {pid})")]
    NameTaken { name: String, addr: Addr, pid: u32 },
    #[error(
        "the inbox of address {addr} is being created by another process (or one was stopped \
         while it created it)"
    )]
    InboxInCreation { addr: Addr },
    #[error("address {0} is not a module address (1..=254)")]
    BadAddress(Addr),
    #[error("module name '{0}' is invalid: use 1 to 48 characters of a-z, A-Z, 0-9, _ and -")]
    BadName(String),
    #[error("no free address left in the domain")]
    NoFreeAddress,
    #[error("frame of {len} bytes exceeds the domain's maximum of {max} bytes")]
    FrameTooLarge { len: usize, max: usize },
    /// Every sender slot of the inbox is held by a live process or by one that died and was
    /// not cleaned up yet; the inbox's creator chose how many there are.
    #[error(
        "module {addr}'s inbox takes {slots} senders at once and all are taken (a supervisor \
         sizes inboxes to its system with MODBOT_INBOX_SENDERS; dead senders' slots free when \
         they are cleaned up)"
    )]
    InboxSendersTaken { addr: Addr, slots: usize },
    /// Another supervisor holds what a domain has one of (its directory, its relay for tools):
    /// its system runs, or is starting beside this one. `pid` when it is known.
    #[error("another supervisor runs in the domain{}", pid.map(|p| format!(" (pid {p})")).unwrap_or_default())]
    AnotherSupervisor { pid: Option<u32> },
    /// Every address of the domain is taken, and no supervisor relays the calls of a tool
    /// that holds none.
    #[error("every address of the domain is taken and no supervisor relays calls")]
    DomainFull,
    /// iceoryx2 failed in operation `op`. The failure is part of the message, not an error
    /// [`source`](std::error::Error::source), so that a chain of causes names it once.
    #[error("iceoryx2 {op} failed: {failure}")]
    Ipc {
        op: &'static str,
        failure: IpcFailure,
    },
    /// The claim of an address or a name (`service`, created exclusively) was refused though
    /// no live module holds it, after the dead were cleaned up.
    #[error(
        "iceoryx2 claim failed: {service}: {failure} (another process may be starting with \
         the same address or name)"
    )]
    Claim {
        service: String,
        failure: IpcFailure,
    },
    /// A service that others create and remove was created and removed by them meanwhile, each
    /// time this process tried to `op`.
    #[error("{op} failed: other processes created and removed it meanwhile, again and again")]
    Contended { op: &'static str },
    /// Every slot of the published directory is held by processes that still hold what
    /// supervisors that died published there.
    #[error(
        "cannot create the directory: processes of the domain still hold the directories of \
         {slots} supervisors that died: stop the domain's tools"
    )]
    DirectorySlotsHeld { slots: usize },
    /// The directory's image could not be read or written (operation `op`).
    #[error("{op} failed: {error}")]
    DirectoryImage {
        op: &'static str,
        error: DirectoryError,
    },
    /// The domain's wake-up table (a file in `/dev/shm`) could not be opened or mapped.
    #[error("wake-up table {}: {failure}", path.display())]
    WakeTable {
        path: std::path::PathBuf,
        failure: IoFailure,
    },
    /// The domain's wake-up table has the size of another modbot version's.
    #[error(
        "wake-up table {} has {len} bytes, not {expected}: it was left by another modbot \
         version (stop the domain with `modbot down`, or remove the file)",
        path.display()
    )]
    WakeTableSize {
        path: std::path::PathBuf,
        len: u64,
        expected: usize,
    },
    /// Sleeping on the wake-up table failed (`futex_waitv` needs Linux 5.16 or later).
    #[error("wait for a wake-up failed: futex_waitv: {0} (needs Linux 5.16 or later)")]
    WakeWait(IoFailure),
    /// The supervisor did not answer a call relayed through it within `timeout`.
    #[error("the supervisor did not answer a relayed call within {} ms", timeout.as_millis())]
    RelayTimeout { timeout: Duration },
    /// The in-process backend's channel `name` exists with another spec.
    #[error("channel {name} is {have:?}, opened as {asked:?}")]
    ChannelSpecDiffers {
        name: String,
        have: ChannelSpec,
        asked: ChannelSpec,
    },
    /// The in-process backend's channel `name` has all the `max` publishers it admits.
    #[error("channel {name} has its {max} publishers")]
    ChannelPublishersTaken { name: String, max: usize },
    /// The in-process backend's channel `name` has all the `max` subscribers it admits.
    #[error("channel {name} has its {max} subscribers")]
    ChannelSubscribersTaken { name: String, max: usize },
    /// A thread could not be started.
    #[error("cannot start the {thread} thread: {failure}")]
    Spawn {
        thread: &'static str,
        failure: IoFailure,
    },
    #[error(transparent)]
    Access(#[from] domain::DomainAccessError),
}

impl TransportError {
    /// iceoryx2's `failure` in operation `op`.
    pub fn ipc(op: &'static str, failure: impl Into<IpcFailure>) -> TransportError {
        TransportError::Ipc {
            op,
            failure: failure.into(),
        }
    }
}

/// What a module receives besides its inbox.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Joins<'a> {
    /// Broadcast frames. Only modules that listen (they handle REPORTs) subscribe, so a
    /// broadcast reaches the modules that want it and nobody pays for the others.
    pub broadcast: bool,
    /// Multicast groups.
    pub groups: &'a [String],
}

impl Joins<'_> {
    /// Nothing but the inbox (tools, raw endpoints).
    pub const NONE: Joins<'static> = Joins {
        broadcast: false,
        groups: &[],
    };
}

/// Why a frame was not delivered. Nothing is dropped silently: the sender always learns it.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SendError {
    #[error("module {0} has no inbox: it is not running")]
    NoReceiver(Addr),
    #[error("module {0}'s inbox is full: the frame was not delivered")]
    InboxFull(Addr),
    #[error(transparent)]
    Transport(#[from] TransportError),
}

/// Checks a module name.
pub fn check_name(name: &str) -> Result<(), TransportError> {
    let ok = !name.is_empty()
        && name.len() <= 48
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(TransportError::BadName(name.to_owned()))
    }
}

/// The highest address a tool (the CLI, a benchmark driver) takes when it can take a lower one.
pub const TOOL_FIRST: u8 = 239;

/// The receive side of a module's endpoint: its inbox, broadcast and groups.
pub trait Rx {
    /// Lends the next waiting frame, if any, to `on_frame`; returns whether there was one.
    fn try_receive(&mut self, on_frame: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError>;

    /// Sleeps until a frame may have arrived, a signal came, or `timeout` passed.
    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError>;

    /// Whether the endpoint was opened in standby, not yet subscribed to its inbox (a process
    /// taking over a running module: [`launch::UPGRADE_DIR`]).
    fn standby(&self) -> bool {
        false
    }

    /// Subscribes a standby endpoint to its inbox and buses: from now on it receives every
    /// frame sent to its address, as the process it takes over does. Nothing for one that is
    /// not in standby.
    fn attach(&mut self) -> Result<(), TransportError> {
        Ok(())
    }
}

/// The send side of a module's endpoint.
pub trait Tx {
    /// Sends a frame of `len` bytes, written in place by `fill` (into shared memory).
    fn send(
        &mut self,
        to: Dest<'_>,
        len: usize,
        fill: &mut dyn FnMut(&mut [u8]),
    ) -> Result<(), SendError>;

    /// Opens the connection to `to` ahead of the first send (it costs about a millisecond).
    fn connect(&mut self, to: Addr) -> Result<(), SendError>;

    /// Forgets the connection to `to` (its module died; it will be reopened on next use).
    fn disconnect(&mut self, to: Addr);

    /// Frames this endpoint could not deliver since it opened.
    fn dropped(&self) -> u64;

    /// Publishes this module's heartbeat (a [`modbot_ipc_schema::heartbeat::Heartbeat`]) to
    /// whoever supervises the domain. Backends without a supervisor ignore it.
    fn heartbeat(&mut self, _beat: &[u8]) -> Result<(), TransportError> {
        Ok(())
    }
}

/// Blackboard snapshots: publish your own, read the latest of others.
pub trait Snapshots {
    /// Publishes a snapshot of `len` bytes, written in place by `fill`.
    fn publish(
        &mut self,
        len: usize,
        fill: &mut dyn FnMut(&mut [u8]),
    ) -> Result<(), TransportError>;

    /// Lends the newest snapshot of module `of` received so far to `read`, if any.
    fn read_latest(
        &mut self,
        of: Addr,
        read: &mut dyn FnMut(&[u8]),
    ) -> Result<bool, TransportError>;
}

/// The phone book's source of truth: which modules exist and whether they live.
pub trait Directory {
    /// Calls `f` for every module of the domain, alive or dead.
    fn list(&self, f: &mut dyn FnMut(PeerInfo)) -> Result<(), TransportError>;

    /// Removes the resources dead modules left behind; returns how many were cleaned. A
    /// published directory leaves this to its supervisor (0).
    fn reap_dead(&self) -> usize;

    /// A number that changes whenever a published directory changes (its generation); a
    /// scanned directory cannot tell without scanning and says 0: its readers list it on a
    /// timer.
    fn generation(&self) -> u64 {
        0
    }

    /// Whether a supervisor publishes this directory: listing it is cheap (no scan), and
    /// [`Directory::generation`] says when it changed.
    fn published(&self) -> bool {
        false
    }
}

/// A module's connection to its domain.
pub struct Endpoint {
    pub addr: Addr,
    pub rx: Box<dyn Rx>,
    pub tx: Box<dyn Tx>,
    pub snapshots: Box<dyn Snapshots>,
    pub directory: Box<dyn Directory>,
}

/// A module about to open its endpoint: what [`Transport::open`] hands a backend once it
/// checked the address and the name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Opening<'a> {
    /// A module address (1..=254).
    pub addr: Addr,
    /// A valid module name (see [`check_name`]).
    pub name: &'a str,
    pub mode: ReceiveMode,
    /// What it receives besides its inbox.
    pub joins: Joins<'a>,
}

/// A backend: opens endpoints in one domain.
pub trait Transport {
    /// Claims `addr` and `name` and opens the module's endpoint, subscribed to what `joins`
    /// names.
    fn open(
        &self,
        addr: Addr,
        name: &str,
        mode: ReceiveMode,
        joins: &Joins<'_>,
    ) -> Result<Endpoint, TransportError> {
        if !addr.is_module() {
            return Err(TransportError::BadAddress(addr));
        }
        check_name(name)?;
        self.open_checked(Opening {
            addr,
            name,
            mode,
            joins: *joins,
        })
    }

    /// What a backend implements of [`Transport::open`]: claims the checked `module`'s address
    /// and name and opens its endpoint. Callers call [`Transport::open`].
    fn open_checked(&self, module: Opening<'_>) -> Result<Endpoint, TransportError>;

    /// Opens an endpoint at a free address, for a tool (the CLI, a benchmark driver): the
    /// highest free one at or below [`TOOL_FIRST`], else above it.
    fn open_tool(
        &self,
        name: &str,
        mode: ReceiveMode,
        joins: &Joins<'_>,
    ) -> Result<Endpoint, TransportError> {
        let mut taken = [false; 256];
        self.directory()?.list(&mut |p| {
            if p.alive {
                taken[usize::from(p.addr.0)] = true;
            }
        })?;
        // Tools search from TOOL_FIRST down, then the rest: the addresses at the top belong to
        // the supervisor and the grid's processes, which the supervisor assigns from 254 down,
        // and a short-lived tool must not take one of them while its process starts.
        let order = (Addr::FIRST..=TOOL_FIRST)
            .rev()
            .chain((TOOL_FIRST + 1..=Addr::LAST).rev());
        for a in order {
            if taken[usize::from(a)] {
                continue;
            }
            match self.open(
                Addr(a),
                &format!("{name}-{}", std::process::id()),
                mode,
                joins,
            ) {
                // A process that answered an earlier tool at this address may be creating its
                // inbox right now (or was stopped while it did, SIGSTOP): another address.
                Err(
                    TransportError::AddressTaken { .. } | TransportError::InboxInCreation { .. },
                ) => continue,
                Ok(endpoint) => {
                    self.opened_as_tool();
                    return Ok(endpoint);
                }
                other => return other,
            }
        }
        Err(TransportError::NoFreeAddress)
    }

    /// The directory alone, without claiming an address.
    fn directory(&self) -> Result<Box<dyn Directory>, TransportError>;

    /// Runs when the last module of this process leaves: removes the domain's files if no
    /// module of it lives anymore (under a supervisor, if the supervisor has stopped and left
    /// them to the last process of the domain).
    fn sweep_if_empty(&self) -> bool;

    /// Marks this transport as a tool's: a tool is short-lived and may run while a system
    /// starts in the domain, so when it leaves it tidies only what is certainly dead.
    fn opened_as_tool(&self) {}
}

/// Names the operation an iceoryx2 failure happened in: `ServiceName::new(n).ipc("service
/// name")?`.
pub trait IpcResult<T> {
    /// The error as [`TransportError::Ipc`] of operation `op`.
    fn ipc(self, op: &'static str) -> Result<T, TransportError>;
}

impl<T, E: Into<IpcFailure>> IpcResult<T> for Result<T, E> {
    #[inline]
    fn ipc(self, op: &'static str) -> Result<T, TransportError> {
        self.map_err(|e| TransportError::ipc(op, e))
    }
}
