//! The domain's directory as the supervisor keeps it, published to every module.
//!
//! The supervisor knows its own modules (their slots: pid from `fork`, running from the first
//! heartbeat, gone from `waitpid`) and learns of any other module of the domain (a tool, a
//! module started by hand) from its heartbeats: a beat from an address it does not know makes
//! it read the node directory once for that module's name. Another module leaves the roster
//! when it says it stops, or when its heartbeats stop and its process is gone.
//!
//! Whatever changes, the next [`Roster::publish`] writes a new generation of the directory;
//! modules read it when its generation changes, and never scan the node directory themselves.
//! Cleaning up after a dead process (its node, its ports) is the supervisor's too:
//! [`Roster::reap`].

use std::collections::BTreeMap;

use iceoryx2::prelude::*;
use modbot_ipc_schema::directory::Listing;
use modbot_ipc_schema::heartbeat::ModuleState;
use modbot_ipc_schema::Addr;
use nix::sys::signal::kill;
use nix::unistd::Pid;

use modbot_core::transport::ipc::{DirectoryWriter, IpcTransport};
use modbot_core::transport::{Directory, TransportError};

/// How often at most the node directory is read to learn an unknown module's name.
const SCAN_EVERY_NS: u64 = 50_000_000;

/// A module of the domain that is not one of the supervisor's.
#[derive(Debug, Clone)]
struct Other {
    listing: Listing,
    last_beat_ns: u64,
}

/// The directory's content and its publisher.
pub(super) struct Roster {
    writer: DirectoryWriter,
    _node: Node<ipc::Service>,
    scan: Box<dyn Directory>,
    others: BTreeMap<u8, Other>,
    /// Heartbeats of modules not known yet (address, pid): the next scan learns their names.
    unknown: Vec<(Addr, u32, u32)>,
    last_scan_ns: u64,
    published: Vec<Listing>,
    /// The others changed since the last publication.
    changed: bool,
}

impl Roster {
    /// Creates the domain's directory (empty until the first [`Roster::publish`]).
    pub(super) fn new(transport: &IpcTransport) -> Result<Roster, TransportError> {
        let node = transport.node(&format!("directory.{}", std::process::id()))?;
        let writer = DirectoryWriter::create(&node)?;
        Ok(Roster {
            writer,
            _node: node,
            scan: transport.scanned_directory(),
            others: BTreeMap::new(),
            unknown: Vec::new(),
            last_scan_ns: 0,
            published: Vec::new(),
            changed: false,
        })
    }

    /// Removes what dead processes left in the domain (their nodes and ports).
    pub(super) fn reap(&self) -> usize {
        self.scan.reap_dead()
    }

    /// A heartbeat of a module at `addr` that is not one of the supervisor's.
    pub(super) fn beat_of_other(
        &mut self,
        addr: Addr,
        pid: u32,
        state: ModuleState,
        methods_digest: u32,
        now_ns: u64,
    ) {
        if state == ModuleState::Stopping {
            self.changed |= self.others.remove(&addr.0).is_some();
            self.unknown.retain(|u| u.0 != addr);
            return;
        }
        match self.others.get_mut(&addr.0) {
            Some(o) if o.listing.pid == pid => {
                o.last_beat_ns = now_ns;
                self.changed |= o.listing.methods_digest != methods_digest;
                o.listing.methods_digest = methods_digest;
            }
            _ => {
                if !self.unknown.iter().any(|u| u.0 == addr && u.1 == pid) {
                    self.unknown.push((addr, pid, methods_digest));
                }
            }
        }
    }

    /// Learns the names of modules first heard of, and drops the others whose heartbeats
    /// stopped for `silent_ns` and whose process is gone.
    pub(super) fn check_others(&mut self, now_ns: u64, silent_ns: u64) {
        if !self.unknown.is_empty() && now_ns.saturating_sub(self.last_scan_ns) >= SCAN_EVERY_NS {
            self.last_scan_ns = now_ns;
            let unknown = std::mem::take(&mut self.unknown);
            let mut found = Vec::new();
            let listed = self.scan.list(&mut |p| {
                if let Some(&(_, _, digest)) = unknown
                    .iter()
                    .find(|u| u.0 == p.addr && u.1 == p.pid && p.alive)
                {
                    found.push(Listing {
                        addr: p.addr,
                        mode: p.mode.code() as u8,
                        state: ModuleState::Running,
                        pid: p.pid,
                        methods_digest: digest,
                        upgrades: 0,
                        name: p.name,
                    });
                }
            });
            if let Err(e) = listed {
                tracing::debug!("node directory: {e}");
            }
            for listing in found {
                tracing::debug!(
                    "module {} ({}, pid {}) joined the domain",
                    listing.name,
                    listing.addr,
                    listing.pid
                );
                self.changed = true;
                self.others.insert(
                    listing.addr.0,
                    Other {
                        listing,
                        last_beat_ns: now_ns,
                    },
                );
            }
        }
        let gone: Vec<u8> = self
            .others
            .iter()
            .filter(|(_, o)| {
                now_ns.saturating_sub(o.last_beat_ns) >= silent_ns
                    && kill(Pid::from_raw(o.listing.pid as i32), None).is_err()
            })
            .map(|(a, _)| *a)
            .collect();
        if !gone.is_empty() {
            self.changed = true;
            for a in gone {
                self.others.remove(&a);
            }
            self.reap();
        }
    }

    /// Whether the other modules changed since the last publication.
    pub(super) fn changed(&self) -> bool {
        self.changed
    }

    /// Publishes the supervisor's modules (`own`) and the others if anything changed since the
    /// last publication. The supervisor's own modules win an address both claim.
    pub(super) fn publish(&mut self, own: Vec<Listing>) {
        self.changed = false;
        let mut all = own;
        for o in self.others.values() {
            if !all.iter().any(|l| l.addr == o.listing.addr) {
                all.push(o.listing.clone());
            }
        }
        all.sort_by_key(|l| l.addr);
        if all == self.published && self.writer.generation() > 0 {
            return;
        }
        match self.writer.publish(&all) {
            Ok(_) => self.published = all,
            Err(e) => tracing::warn!("directory not published: {e}"),
        }
    }
}
