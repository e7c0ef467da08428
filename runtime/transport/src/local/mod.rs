//! The in-process backend: the same interface inside one process, for fast unit tests.
//!
//! Each "module" is a thread; frames move through bounded crossbeam channels. Frames are copied
//! into heap buffers here: this backend is for tests, not for real runs.

use core::time::Duration;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use crossbeam::channel::{bounded, Receiver, RecvTimeoutError, Sender, TrySendError};
use modbot_ipc_schema::Addr;

use super::{
    Dest, Directory, Endpoint, Opening, PeerInfo, ReceiveMode, Rx, SendError, Snapshots, Transport,
    TransportError, Tx,
};

mod channels;

pub use channels::LocalChannels;

const INBOX_DEPTH: usize = 64;

struct Slot {
    /// Which opening of the address this is (see [`LocalRx`]'s `Drop`).
    id: u64,
    name: String,
    mode: ReceiveMode,
    alive: bool,
    inbox: Sender<Vec<u8>>,
    groups: Vec<String>,
    /// Listens to broadcast.
    broadcast: bool,
}

#[derive(Default)]
struct LocalDomain {
    slots: HashMap<u8, Slot>,
    snapshots: HashMap<u8, Arc<AlignedBytes>>,
    channels: Arc<channels::LocalChannelSet>,
}

type Shared = Arc<Mutex<LocalDomain>>;

fn registry() -> &'static Mutex<HashMap<String, Shared>> {
    static DOMAINS: OnceLock<Mutex<HashMap<String, Shared>>> = OnceLock::new();
    DOMAINS.get_or_init(Default::default)
}

fn lock(d: &Shared) -> std::sync::MutexGuard<'_, LocalDomain> {
    d.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The in-process backend for one domain (by name, shared by every thread of the process).
#[derive(Clone)]
pub struct LocalTransport {
    domain: Shared,
}

impl LocalTransport {
    pub fn new(domain: &crate::domain::Domain) -> LocalTransport {
        let mut all = registry().lock().unwrap_or_else(|p| p.into_inner());
        let domain = all.entry(domain.name().to_owned()).or_default().clone();
        LocalTransport { domain }
    }

    /// The channels and wake-ups of the domain (see [`crate::channels`]).
    pub fn channels(&self) -> LocalChannels {
        LocalChannels::new(lock(&self.domain).channels.clone())
    }

    /// Marks module `addr` dead, as if its process had been killed.
    pub fn kill(&self, addr: Addr) {
        if let Some(slot) = lock(&self.domain).slots.get_mut(&addr.0) {
            slot.alive = false;
        }
    }
}

impl Transport for LocalTransport {
    fn open_checked(&self, module: Opening<'_>) -> Result<Endpoint, TransportError> {
        let Opening { addr, name, .. } = module;
        let mut d = lock(&self.domain);
        if let Some(s) = d.slots.get(&addr.0).filter(|s| s.alive) {
            return Err(TransportError::AddressTaken {
                addr,
                holder: s.name.clone(),
                pid: std::process::id(),
            });
        }
        if let Some((a, _)) = d.slots.iter().find(|(_, s)| s.alive && s.name == name) {
            return Err(TransportError::NameTaken {
                name: name.to_owned(),
                addr: Addr(*a),
                pid: std::process::id(),
            });
        }
        let (tx, rx) = bounded(INBOX_DEPTH);
        static NEXT_ID: AtomicU64 = AtomicU64::new(0);
        let id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
        d.slots.insert(
            addr.0,
            Slot {
                id,
                name: name.to_owned(),
                mode: module.mode,
                alive: true,
                inbox: tx,
                groups: module.joins.groups.to_vec(),
                broadcast: module.joins.broadcast,
            },
        );
        drop(d);
        Ok(Endpoint {
            addr,
            rx: Box::new(LocalRx {
                domain: self.domain.clone(),
                me: addr,
                id,
                inbox: rx,
                pending: None,
            }),
            tx: Box::new(LocalTx {
                domain: self.domain.clone(),
                me: addr,
                dropped: 0,
            }),
            snapshots: Box::new(LocalSnapshots {
                domain: self.domain.clone(),
                me: addr,
                held: HashMap::new(),
            }),
            directory: Box::new(LocalDirectory {
                domain: self.domain.clone(),
            }),
        })
    }

    fn directory(&self) -> Result<Box<dyn Directory>, TransportError> {
        Ok(Box::new(LocalDirectory {
            domain: self.domain.clone(),
        }))
    }

    fn sweep_if_empty(&self) -> bool {
        let mut d = lock(&self.domain);
        if d.slots.values().any(|s| s.alive) {
            return false;
        }
        d.slots.clear();
        d.snapshots.clear();
        true
    }
}

struct LocalDirectory {
    domain: Shared,
}

impl Directory for LocalDirectory {
    fn list(&self, f: &mut dyn FnMut(PeerInfo)) -> Result<(), TransportError> {
        let d = lock(&self.domain);
        for (addr, s) in &d.slots {
            f(PeerInfo {
                addr: Addr(*addr),
                name: s.name.clone(),
                pid: std::process::id(),
                mode: s.mode,
                alive: s.alive,
                methods_digest: 0,
                upgrades: 0,
            });
        }
        Ok(())
    }

    fn reap_dead(&self) -> usize {
        let mut d = lock(&self.domain);
        let before = d.slots.len();
        d.slots.retain(|_, s| s.alive);
        before - d.slots.len()
    }
}

struct LocalRx {
    domain: Shared,
    me: Addr,
    /// The id of this endpoint's slot.
    id: u64,
    inbox: Receiver<Vec<u8>>,
    pending: Option<Vec<u8>>,
}

impl Drop for LocalRx {
    fn drop(&mut self) {
        let mut d = lock(&self.domain);
        // The address may belong to a newer module by now (this one was killed and another
        // opened in its place): leave that one's slot and snapshot alone.
        let newer = d.slots.get(&self.me.0).is_some_and(|s| s.id != self.id);
        if !newer {
            d.slots.remove(&self.me.0);
            d.snapshots.remove(&self.me.0);
        }
    }
}

impl Rx for LocalRx {
    fn try_receive(&mut self, on_frame: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError> {
        let frame = match self.pending.take() {
            Some(f) => Some(f),
            None => self.inbox.try_recv().ok(),
        };
        Ok(frame.map(|f| on_frame(&f)).is_some())
    }

    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        if self.pending.is_none() {
            match self.inbox.recv_timeout(timeout) {
                Ok(f) => self.pending = Some(f),
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => {}
            }
        }
        Ok(())
    }
}

struct LocalTx {
    domain: Shared,
    me: Addr,
    dropped: u64,
}

impl Tx for LocalTx {
    fn send(
        &mut self,
        to: Dest<'_>,
        len: usize,
        fill: &mut dyn FnMut(&mut [u8]),
    ) -> Result<(), SendError> {
        let mut frame = vec![0u8; len];
        fill(&mut frame);
        let d = lock(&self.domain);
        match to {
            Dest::Module(addr) => {
                let Some(slot) = d.slots.get(&addr.0).filter(|s| s.alive) else {
                    self.dropped += 1;
                    return Err(SendError::NoReceiver(addr));
                };
                match slot.inbox.try_send(frame) {
                    Ok(()) => Ok(()),
                    Err(TrySendError::Full(_)) => {
                        self.dropped += 1;
                        Err(SendError::InboxFull(addr))
                    }
                    Err(TrySendError::Disconnected(_)) => {
                        self.dropped += 1;
                        Err(SendError::NoReceiver(addr))
                    }
                }
            }
            Dest::Broadcast | Dest::Group(_) => {
                for (addr, slot) in &d.slots {
                    let member = match to {
                        Dest::Group(g) => slot.groups.iter().any(|m| m == g),
                        _ => slot.broadcast,
                    };
                    if *addr != self.me.0
                        && slot.alive
                        && member
                        && slot.inbox.try_send(frame.clone()).is_err()
                    {
                        self.dropped += 1;
                    }
                }
                Ok(())
            }
        }
    }

    fn connect(&mut self, _to: Addr) -> Result<(), SendError> {
        Ok(())
    }

    fn disconnect(&mut self, _to: Addr) {}

    fn dropped(&self) -> u64 {
        self.dropped
    }
}

struct LocalSnapshots {
    domain: Shared,
    me: Addr,
    held: HashMap<Addr, Arc<AlignedBytes>>,
}

/// A snapshot's bytes, starting 64-byte aligned as in a shared-memory sample (readers view
/// bulk items in place).
struct AlignedBytes {
    lines: Vec<Line>,
    len: usize,
}

#[derive(Clone, Copy, bytemuck::Zeroable, bytemuck::Pod)]
#[repr(C, align(64))]
struct Line([u8; modbot_ipc_schema::snapshot::BULK_ALIGN]);

const _: () = assert!(core::mem::align_of::<Line>() == modbot_ipc_schema::snapshot::BULK_ALIGN);

impl AlignedBytes {
    fn zeroed(len: usize) -> AlignedBytes {
        let lines = vec![Line([0; modbot_ipc_schema::snapshot::BULK_ALIGN]); len.div_ceil(64)];
        AlignedBytes { lines, len }
    }

    fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice(&self.lines)[..self.len]
    }

    fn bytes_mut(&mut self) -> &mut [u8] {
        &mut bytemuck::cast_slice_mut(&mut self.lines)[..self.len]
    }
}

impl Snapshots for LocalSnapshots {
    fn publish(
        &mut self,
        len: usize,
        fill: &mut dyn FnMut(&mut [u8]),
    ) -> Result<(), TransportError> {
        let mut snap = AlignedBytes::zeroed(len);
        fill(snap.bytes_mut());
        lock(&self.domain)
            .snapshots
            .insert(self.me.0, Arc::new(snap));
        Ok(())
    }

    fn read_latest(
        &mut self,
        of: Addr,
        read: &mut dyn FnMut(&[u8]),
    ) -> Result<bool, TransportError> {
        if let Some(s) = lock(&self.domain).snapshots.get(&of.0) {
            self.held.insert(of, s.clone());
        }
        Ok(self.held.get(&of).map(|s| read(s.bytes())).is_some())
    }
}
