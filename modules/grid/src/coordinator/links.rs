//! The coordinator's links to its hosts: a host's release notices and wake-up, and the batch
//! of one tick's releases each host gets as one sample.

use modbot_core::transport::channels::Channels;
use modbot_core::transport::TransportError;
use modbot_ipc_schema::grid::{Generation, Release, MAX_SOURCES};
use zerocopy::IntoBytes;

use super::Comp;
use modbot_grid::wire::{self, Notifier, Pub};
use modbot_grid::GridSpec;

/// The coordinator's link to one host: its release notices and its wake-up. Opened on any
/// thread (an assembly's links are opened off the tick thread) and handed to the coordinator.
pub struct HostLink {
    /// The host's name and the generation of its components (0: the system's own).
    pub(super) name: String,
    pub(super) generation: Generation,
    pub(super) release: Pub,
    pub(super) wake: Notifier,
    /// The releases of this tick, sent as one sample with one wake-up when the tick's releases
    /// are made.
    pub(super) batch: Vec<u8>,
}

/// The coordinator's link to `host` of `spec`. Opening one takes milliseconds (files, maps):
/// never do it on the tick thread while the grid runs; hand it over with
/// [`Coordinator::add_incoming_link`].
pub fn link(node: &dyn Channels, spec: &GridSpec, host: &str) -> Result<HostLink, TransportError> {
    // A tick's batch holds a release of each of its components, and a warm-up release or a
    // live upgrade's notice (UPGRADE, then HANDOVER).
    let most = spec.components_of(host).len() + 2;
    Ok(HostLink {
        name: host.to_owned(),
        generation: spec.host_generation(host),
        release: wire::release_publisher(node, &spec.release_service(host), most)?,
        wake: wire::wake_notifier(node, &spec.wake_service(host))?,
        batch: Vec::with_capacity(most * core::mem::size_of::<Release>()),
    })
}

/// What every release of one tick and assembly shares.
pub(super) struct ReleaseAt {
    pub(super) n: u64,
    pub(super) now_ns: u64,
    pub(super) generation: Generation,
    pub(super) flags: u16,
    /// The grid's state hash at `n`.
    pub(super) state_hash: u64,
}

/// Releases component `c` at `at`, reading the source versions `versions` (in its sources'
/// order): the notice goes into its host's batch, and the release is pending until done.
pub(super) fn release(
    comp: &mut Comp,
    c: usize,
    at: &ReleaseAt,
    versions: &[u64],
    hosts: &mut [HostLink],
) {
    let k = comp.sources.len().min(MAX_SOURCES);
    let Ok(notice) = Release::new(at.n, at.now_ns, c as u16, &versions[..k]) else {
        return;
    };
    let notice = notice
        .with(at.generation.0, at.flags)
        .with_state_hash(at.state_hash);
    if send_release(&mut hosts[comp.host], &notice) {
        comp.pending = Some(at.n);
        comp.releases += 1;
    }
}

/// Adds `notice` to the batch `link` sends (and wakes) at the end of the tick; false if the
/// batch is full (it holds a release of each of the host's components and a warm-up).
pub(super) fn send_release(link: &mut HostLink, notice: &Release) -> bool {
    let bytes = notice.as_bytes();
    if link.batch.len() + bytes.len() > link.batch.capacity() {
        tracing::warn!(
            "release batch of host {} is full: a release is not sent",
            link.name
        );
        return false;
    }
    link.batch.extend_from_slice(bytes);
    true
}
