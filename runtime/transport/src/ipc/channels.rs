//! [`Channels`] on iceoryx2: a channel is a publish-subscribe service of `[u8]` samples,
//! opened through one node whose ports may move between threads (a coordinator opens an
//! assembly's links off its tick thread and hands them over). A wake-up is a futex word of the
//! domain's wake-up table ([`super::wake`]), found by its name.
//!
//! # Waiting to the microsecond
//! The grid waits with deadlines finer than a millisecond: the coordinator for a late done
//! notice for a fraction of a tick, the bus bridge for its release until its watchdog's
//! deadline. A listener sleeps in `futex` with a nanosecond timeout; a notifier counts on the
//! word and makes a system call only when a listener sleeps; a listener takes a notification
//! by remembering the count (nothing to read or drain in the kernel). iceoryx2's own event, a
//! Unix datagram socket, cost a `ppoll`, a `recv` and a `sendto` per wake-up.

use core::sync::atomic::{AtomicU32, Ordering};
use core::time::Duration;
use std::sync::Arc;

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use super::wake::{WakeTable, Word};
use crate::channels::{
    BytePublisher, ByteSubscriber, ChannelSpec, Channels, WakeListener, WakeNotifier,
};
use crate::{IpcResult, TransportError};

/// The service type of the channels: ports that may move between threads.
type Service = ipc_threadsafe::Service;
type Factory = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Service, [u8], ()>;

/// Nodes (processes) a channel serves at most.
const MAX_NODES: usize = 256;

/// The channels of one node.
pub struct IpcChannels {
    node: Node<Service>,
    /// The domain's wake-up table.
    wake: Arc<WakeTable>,
}

impl IpcChannels {
    pub(super) fn new(node: Node<Service>, wake: Arc<WakeTable>) -> IpcChannels {
        IpcChannels { node, wake }
    }

    fn service(&self, name: &str, spec: &ChannelSpec) -> Result<Factory, TransportError> {
        let name = ServiceName::new(name).ipc("channel name")?;
        self.node
            .service_builder(&name)
            .publish_subscribe::<[u8]>()
            .max_publishers(spec.publishers)
            .max_subscribers(spec.subscribers)
            .max_nodes(MAX_NODES)
            .history_size(spec.history)
            .subscriber_max_buffer_size(spec.depth)
            .subscriber_max_borrowed_samples(2)
            .enable_safe_overflow(true)
            .open_or_create()
            .ipc("open channel")
    }
}

impl Channels for IpcChannels {
    fn publisher(
        &self,
        name: &str,
        spec: &ChannelSpec,
        max_len: usize,
    ) -> Result<Box<dyn BytePublisher>, TransportError> {
        let port = self
            .service(name, spec)?
            .publisher_builder()
            .initial_max_slice_len(max_len.max(1))
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_samples(2)
            .create()
            .ipc("channel publisher")?;
        Ok(Box::new(IpcPublisher(port)))
    }

    fn subscriber(
        &self,
        name: &str,
        spec: &ChannelSpec,
    ) -> Result<Box<dyn ByteSubscriber>, TransportError> {
        let port = self
            .service(name, spec)?
            .subscriber_builder()
            .buffer_size(spec.depth)
            .create()
            .ipc("channel subscriber")?;
        Ok(Box::new(IpcSubscriber(port)))
    }

    fn publishers(&self, name: &str, spec: &ChannelSpec) -> Result<usize, TransportError> {
        Ok(self
            .service(name, spec)?
            .dynamic_config()
            .number_of_publishers())
    }

    fn notifier(
        &self,
        name: &str,
        _notifiers: usize,
    ) -> Result<Box<dyn WakeNotifier>, TransportError> {
        Ok(Box::new(FutexNotifier {
            table: self.wake.clone(),
            word: Word::named(name),
        }))
    }

    fn listener(
        &self,
        name: &str,
        _notifiers: usize,
    ) -> Result<Box<dyn WakeListener>, TransportError> {
        let word = Word::named(name);
        // A notification sent before the listener existed is not its to take.
        let taken = AtomicU32::new(self.wake.count(word));
        Ok(Box::new(FutexListener {
            table: self.wake.clone(),
            word,
            taken,
        }))
    }
}

struct IpcPublisher(Publisher<Service, [u8], ()>);

impl BytePublisher for IpcPublisher {
    fn send(&self, len: usize, fill: &mut dyn FnMut(&mut [u8])) -> Result<(), TransportError> {
        let mut sample = self.0.loan_slice_uninit(len).ipc("channel loan")?;
        let payload = sample.payload_mut();
        // SAFETY: the payload is `len` bytes of shared memory that iceoryx2 mapped zero-filled
        // and that only ever held bytes of earlier samples, so every byte is initialised; `u8`
        // and `MaybeUninit<u8>` have the same layout. `fill` writes the whole sample before it
        // is sent.
        let bytes = unsafe {
            core::slice::from_raw_parts_mut(payload.as_mut_ptr().cast::<u8>(), payload.len())
        };
        fill(bytes);
        // SAFETY: see above; every byte is initialised.
        let sample = unsafe { sample.assume_init() };
        sample.send().ipc("channel send")?;
        Ok(())
    }
}

struct IpcSubscriber(Subscriber<Service, [u8], ()>);

impl ByteSubscriber for IpcSubscriber {
    fn receive(&self, read: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError> {
        match self.0.receive().ipc("channel receive")? {
            Some(sample) => {
                read(sample.payload());
                Ok(true)
            }
            None => Ok(false),
        }
    }

    fn connect(&self) {
        let _ = self.0.has_samples();
    }
}

struct FutexNotifier {
    table: Arc<WakeTable>,
    word: Word,
}

impl WakeNotifier for FutexNotifier {
    fn notify(&self) -> Result<(), TransportError> {
        self.table.notify_counted(self.word);
        Ok(())
    }
}

struct FutexListener {
    table: Arc<WakeTable>,
    word: Word,
    /// The count of the word when notifications were last taken.
    taken: AtomicU32,
}

impl WakeListener for FutexListener {
    fn wait(&self, timeout: Option<Duration>) -> bool {
        self.table
            .wait_for_count(self.word, self.taken.load(Ordering::Relaxed), timeout)
    }

    /// Whatever is counted after this wakes the next wait: the look for work that follows
    /// sees what came before.
    fn drain(&self) {
        self.taken
            .store(self.table.count(self.word), Ordering::Relaxed);
    }
}
