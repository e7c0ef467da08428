//! The time grid's iceoryx2 services, per domain:
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
//! - `grid.assembly`: the assembly being prepared ([`modbot_ipc_schema::grid::Prepare`]), from
//!   the coordinator to the hosts of the system's own components, with history 1.
//!
//! Only small notices pass through the coordinator; data moves host to host.

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::Service;

use modbot_core::transport::TransportError;

/// The coordinator's grid ports: shareable between threads, so links to an assembly's hosts
/// can be opened off the tick thread and handed to it. The services are the same as the
/// hosts' (`ipc::Service`): the two differ only in how a process guards its own ports.
pub type Threadsafe = ipc_threadsafe::Service;

pub type Pub<S = ipc::Service> = Publisher<S, [u8], ()>;
pub type Sub<S = ipc::Service> = Subscriber<S, [u8], ()>;
type PubSubFactory<S> =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<S, [u8], ()>;

/// Nodes (processes) a grid service serves at most.
const MAX_NODES: usize = 256;
/// Samples a subscriber keeps before the oldest is dropped.
pub const OUT_DEPTH: usize = 64;

fn err(op: &'static str) -> impl Fn(&dyn core::fmt::Debug) -> TransportError {
    move |e| TransportError::Ipc {
        op,
        detail: format!("{e:?}"),
    }
}

fn name(text: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(text).map_err(|e| err("grid service name")(&e))
}

fn pubsub<S: Service>(
    node: &Node<S>,
    service: &str,
    depth: usize,
    publishers: usize,
    subscribers: usize,
) -> Result<PubSubFactory<S>, TransportError> {
    node.service_builder(&name(service)?)
        .publish_subscribe::<[u8]>()
        .max_publishers(publishers)
        .max_subscribers(subscribers)
        .max_nodes(MAX_NODES)
        .history_size(0)
        .subscriber_max_buffer_size(depth)
        .subscriber_max_borrowed_samples(2)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| err("open grid service")(&e))
}

fn publisher<S: Service>(factory: &PubSubFactory<S>, len: usize) -> Result<Pub<S>, TransportError> {
    factory
        .publisher_builder()
        .initial_max_slice_len(len.max(1))
        .allocation_strategy(AllocationStrategy::Static)
        .max_loaned_samples(2)
        .create()
        .map_err(|e| err("grid publisher")(&e))
}

fn subscriber<S: Service>(
    factory: &PubSubFactory<S>,
    depth: usize,
) -> Result<Sub<S>, TransportError> {
    factory
        .subscriber_builder()
        .buffer_size(depth)
        .create()
        .map_err(|e| err("grid subscriber")(&e))
}

/// The publisher of a component's outputs (`service`: [`super::GridSpec::out_service`]),
/// for records of `len` bytes (header included).
pub fn out_publisher<S: Service>(
    node: &Node<S>,
    service: &str,
    len: usize,
) -> Result<Pub<S>, TransportError> {
    publisher(&pubsub(node, service, OUT_DEPTH, 2, 64)?, len)
}

/// A reader of a component's outputs.
pub fn out_subscriber<S: Service>(node: &Node<S>, service: &str) -> Result<Sub<S>, TransportError> {
    subscriber(&pubsub(node, service, OUT_DEPTH, 2, 64)?, OUT_DEPTH)
}

/// How many publishers a component's outputs have (0 or 1: its host, once started).
pub fn out_publishers<S: Service>(node: &Node<S>, service: &str) -> Result<usize, TransportError> {
    Ok(pubsub(node, service, OUT_DEPTH, 2, 64)?
        .dynamic_config()
        .number_of_publishers())
}

/// The coordinator's side of a host's release notices ([`super::GridSpec::release_service`]),
/// in batches of at most `most`.
pub fn release_publisher<S: Service>(
    node: &Node<S>,
    service: &str,
    most: usize,
) -> Result<Pub<S>, TransportError> {
    let len = core::mem::size_of::<modbot_ipc_schema::grid::Release>() * most.max(1);
    publisher(&pubsub(node, service, 256, 2, 2)?, len)
}

/// A host's side of its release notices.
pub fn release_subscriber<S: Service>(
    node: &Node<S>,
    service: &str,
) -> Result<Sub<S>, TransportError> {
    subscriber(&pubsub(node, service, 256, 2, 2)?, 256)
}

/// The coordinator's side of the assembly notices.
pub fn prepare_publisher<S: Service>(node: &Node<S>) -> Result<Pub<S>, TransportError> {
    let len = core::mem::size_of::<modbot_ipc_schema::grid::Prepare>();
    publisher(&prepare_service(node)?, len)
}

/// A system host's side of the assembly notices: the newest one arrives even if it was sent
/// before the host subscribed.
pub fn prepare_subscriber<S: Service>(node: &Node<S>) -> Result<Sub<S>, TransportError> {
    prepare_service(node)?
        .subscriber_builder()
        .buffer_size(4)
        .create()
        .map_err(|e| err("grid subscriber")(&e))
}

fn prepare_service<S: Service>(node: &Node<S>) -> Result<PubSubFactory<S>, TransportError> {
    node.service_builder(&name("grid.assembly")?)
        .publish_subscribe::<[u8]>()
        .max_publishers(2)
        .max_subscribers(64)
        .max_nodes(MAX_NODES)
        .history_size(1)
        .subscriber_max_buffer_size(4)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| err("open grid service")(&e))
}

/// Done notices a host sends in one sample at most.
pub const DONE_BATCH: usize = 64;

/// A host's side of the done notices, in batches of at most [`DONE_BATCH`].
pub fn done_publisher<S: Service>(node: &Node<S>) -> Result<Pub<S>, TransportError> {
    let len = core::mem::size_of::<modbot_ipc_schema::grid::Done>() * DONE_BATCH;
    publisher(&pubsub(node, "grid.done", 256, MAX_NODES, 2)?, len)
}

/// The coordinator's side of the done notices.
pub fn done_subscriber<S: Service>(node: &Node<S>) -> Result<Sub<S>, TransportError> {
    subscriber(&pubsub(node, "grid.done", 256, MAX_NODES, 2)?, 256)
}

fn wake<S: Service>(
    node: &Node<S>,
    service: &str,
    notifiers: usize,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<S>, TransportError> {
    node.service_builder(&name(service)?)
        .event()
        .max_nodes(MAX_NODES)
        .max_notifiers(notifiers)
        .max_listeners(4)
        .open_or_create()
        .map_err(|e| err("open grid wake-up")(&e))
}

/// A host's side of the done wake-up.
pub fn done_wake_notifier<S: Service>(node: &Node<S>) -> Result<Notifier<S>, TransportError> {
    wake(node, "grid.done.wake", MAX_NODES)?
        .notifier_builder()
        .create()
        .map_err(|e| err("grid wake notifier")(&e))
}

/// The coordinator's side of the done wake-up.
pub fn done_wake_listener<S: Service>(node: &Node<S>) -> Result<Listener<S>, TransportError> {
    wake(node, "grid.done.wake", MAX_NODES)?
        .listener_builder()
        .create()
        .map_err(|e| err("grid wake listener")(&e))
}

/// The coordinator's side of a host's wake-up ([`super::GridSpec::wake_service`]).
pub fn wake_notifier<S: Service>(
    node: &Node<S>,
    service: &str,
) -> Result<Notifier<S>, TransportError> {
    wake(node, service, 2)?
        .notifier_builder()
        .create()
        .map_err(|e| err("grid wake notifier")(&e))
}

/// A host's wake-up.
pub fn wake_listener<S: Service>(
    node: &Node<S>,
    service: &str,
) -> Result<Listener<S>, TransportError> {
    wake(node, service, 2)?
        .listener_builder()
        .create()
        .map_err(|e| err("grid wake listener")(&e))
}

/// Sends a copy of `bytes` (a notice or a batch of them) on `publisher`.
pub fn send_bytes<S: Service>(publisher: &Pub<S>, bytes: &[u8]) -> Result<(), TransportError> {
    send(publisher, bytes.len(), |buf| buf.copy_from_slice(bytes))
}

/// Sends `bytes` on `publisher`, written in place.
pub fn send<S: Service>(
    publisher: &Pub<S>,
    len: usize,
    fill: impl FnOnce(&mut [u8]),
) -> Result<(), TransportError> {
    let mut sample = publisher
        .loan_slice_uninit(len)
        .map_err(|e| err("grid loan")(&e))?;
    let payload = sample.payload_mut();
    // SAFETY: the payload is `len` bytes of shared memory that iceoryx2 mapped zero-filled and
    // that only ever held bytes of earlier samples, so every byte is initialised; `u8` and
    // `MaybeUninit<u8>` have the same layout. `fill` writes the whole record before it is sent.
    let bytes = unsafe {
        core::slice::from_raw_parts_mut(payload.as_mut_ptr().cast::<u8>(), payload.len())
    };
    fill(bytes);
    // SAFETY: see above; every byte is initialised.
    let sample = unsafe { sample.assume_init() };
    sample.send().map_err(|e| err("grid send")(&e))?;
    Ok(())
}
