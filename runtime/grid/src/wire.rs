//! The time grid's links, per domain: channels and wake-ups of the transport layer
//! ([`modbot_core::transport::channels`]: iceoryx2 in real runs, in-process in tests).
//! Services of an assembly's components and hosts carry its generation (`grid.out.g3.<name>`,
//! `grid.release.g3.<host>`, `grid.wake.g3.<host>`; see [`super::GridSpec::out_service`]), so
//! an assembly being prepared never meets the one that runs.
//!
//! - `grid.out.<component>`: publish-subscribe `[u8]`, the component's output samples (an
//!   [`modbot_ipc_schema::grid::OutHeader`] and the packed outputs), one publisher (its host),
//!   subscribers where they are read (consumer hosts, the coordinator's recorder). A subscriber
//!   keeps the newest 64 samples: LET only ever reads one of the newest two.
//! - `grid.release.<host>`: release notices from the coordinator to one host, a batch per tick;
//! - `grid.done`: done notices from every host to the coordinator, a batch per wake-up;
//! - `grid.done.wake`: an event each host notifies once per batch of done notices, so the
//!   coordinator can sleep while it waits for a late one (a notification the coordinator has
//!   not taken yet makes the next one free: iceoryx2 sends nothing then);
//! - `grid.wake.<host>`: an event, so a blocking host sleeps until it is released;
//! - `grid.handover.<host>` and `.verdict`: a live upgrade's handover between the running
//!   process of a host and its new one (the components' state, the new one's answer);
//! - `grid.assembly`: the assembly being prepared ([`modbot_ipc_schema::grid::Prepare`]), from
//!   the coordinator to the hosts of the system's own components, with history 1.
//!
//! Only small notices pass through the coordinator; data moves host to host.

use modbot_core::transport::channels::{
    BytePublisher, ByteSubscriber, ChannelSpec, Channels, WakeListener, WakeNotifier,
};
use modbot_core::transport::TransportError;

pub type Pub = Box<dyn BytePublisher>;
pub type Sub = Box<dyn ByteSubscriber>;
pub type Notifier = Box<dyn WakeNotifier>;
pub type Listener = Box<dyn WakeListener>;

/// Nodes (processes) a grid service serves at most.
const MAX_NODES: usize = 256;
/// Samples a subscriber keeps before the oldest is dropped.
pub const OUT_DEPTH: usize = 64;

/// A component's outputs: one publisher (its host), readers where they are read.
const OUT: ChannelSpec = ChannelSpec {
    depth: OUT_DEPTH,
    history: 0,
    publishers: 2,
    subscribers: 64,
};
/// A host's release notices: the coordinator to the host.
const RELEASE: ChannelSpec = ChannelSpec {
    depth: 256,
    history: 0,
    publishers: 2,
    subscribers: 2,
};
/// The done notices: every host to the coordinator.
const DONE: ChannelSpec = ChannelSpec {
    depth: 256,
    history: 0,
    publishers: MAX_NODES,
    subscribers: 2,
};
/// The assembly notices: the newest one reaches a host that subscribes after it was sent.
const PREPARE: ChannelSpec = ChannelSpec {
    depth: 4,
    history: 1,
    publishers: 2,
    subscribers: 64,
};
/// A host's handover in a live upgrade: the running process's state to the new one, and the
/// new one's verdict back (a sample each; the newest reaches a reader that comes late).
const HANDOVER: ChannelSpec = ChannelSpec {
    depth: 2,
    history: 1,
    publishers: 2,
    subscribers: 2,
};
/// The assembly notices' channel.
const PREPARE_CHANNEL: &str = "grid.assembly";
/// The done notices' channel and wake-up.
const DONE_CHANNEL: &str = "grid.done";
const DONE_WAKE: &str = "grid.done.wake";

/// The publisher of a component's outputs (`service`: [`super::GridSpec::out_service`]),
/// for records of `len` bytes (header included).
pub fn out_publisher(ch: &dyn Channels, service: &str, len: usize) -> Result<Pub, TransportError> {
    ch.publisher(service, &OUT, len)
}

/// A reader of a component's outputs.
pub fn out_subscriber(ch: &dyn Channels, service: &str) -> Result<Sub, TransportError> {
    ch.subscriber(service, &OUT)
}

/// How many publishers a component's outputs have (0 or 1: its host, once started).
pub fn out_publishers(ch: &dyn Channels, service: &str) -> Result<usize, TransportError> {
    ch.publishers(service, &OUT)
}

/// The coordinator's side of a host's release notices ([`super::GridSpec::release_service`]),
/// in batches of at most `most`.
pub fn release_publisher(
    ch: &dyn Channels,
    service: &str,
    most: usize,
) -> Result<Pub, TransportError> {
    let len = core::mem::size_of::<modbot_ipc_schema::grid::Release>() * most.max(1);
    ch.publisher(service, &RELEASE, len)
}

/// A host's side of its release notices.
pub fn release_subscriber(ch: &dyn Channels, service: &str) -> Result<Sub, TransportError> {
    ch.subscriber(service, &RELEASE)
}

/// The coordinator's side of the assembly notices.
pub fn prepare_publisher(ch: &dyn Channels) -> Result<Pub, TransportError> {
    let len = core::mem::size_of::<modbot_ipc_schema::grid::Prepare>();
    ch.publisher(PREPARE_CHANNEL, &PREPARE, len)
}

/// A system host's side of the assembly notices: the newest one arrives even if it was sent
/// before the host subscribed.
pub fn prepare_subscriber(ch: &dyn Channels) -> Result<Sub, TransportError> {
    ch.subscriber(PREPARE_CHANNEL, &PREPARE)
}

/// Done notices a host sends in one sample at most.
pub const DONE_BATCH: usize = 64;

/// A host's side of the done notices, in batches of at most [`DONE_BATCH`].
pub fn done_publisher(ch: &dyn Channels) -> Result<Pub, TransportError> {
    let len = core::mem::size_of::<modbot_ipc_schema::grid::Done>() * DONE_BATCH;
    ch.publisher(DONE_CHANNEL, &DONE, len)
}

/// The coordinator's side of the done notices.
pub fn done_subscriber(ch: &dyn Channels) -> Result<Sub, TransportError> {
    ch.subscriber(DONE_CHANNEL, &DONE)
}

/// A host's side of the done wake-up.
pub fn done_wake_notifier(ch: &dyn Channels) -> Result<Notifier, TransportError> {
    ch.notifier(DONE_WAKE, MAX_NODES)
}

/// The coordinator's side of the done wake-up.
pub fn done_wake_listener(ch: &dyn Channels) -> Result<Listener, TransportError> {
    ch.listener(DONE_WAKE, MAX_NODES)
}

/// The coordinator's side of a host's wake-up ([`super::GridSpec::wake_service`]).
pub fn wake_notifier(ch: &dyn Channels, service: &str) -> Result<Notifier, TransportError> {
    ch.notifier(service, 2)
}

/// A host's wake-up.
pub fn wake_listener(ch: &dyn Channels, service: &str) -> Result<Listener, TransportError> {
    ch.listener(service, 2)
}

/// The running process's end of a host's handover (`service`:
/// [`super::GridSpec::handover_service`]): its state out (`len` bytes), the verdict in.
pub fn handover_out(
    ch: &dyn Channels,
    service: &str,
    len: usize,
) -> Result<(Pub, Sub), TransportError> {
    Ok((
        ch.publisher(service, &HANDOVER, len)?,
        ch.subscriber(&format!("{service}.verdict"), &HANDOVER)?,
    ))
}

/// The new process's end of a host's handover: the state in, its verdict out.
pub fn handover_in(ch: &dyn Channels, service: &str) -> Result<(Sub, Pub), TransportError> {
    Ok((
        ch.subscriber(service, &HANDOVER)?,
        ch.publisher(&format!("{service}.verdict"), &HANDOVER, 1)?,
    ))
}
