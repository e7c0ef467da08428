//! [`Channels`] on iceoryx2: a channel is a publish-subscribe service of `[u8]` samples, a
//! wake-up an event service, all opened through one node whose ports may move between threads
//! (a coordinator opens an assembly's links off its tick thread and hands them over).
//!
//! # Waiting to the microsecond
//! `Listener::timed_wait` waits on its socket with a receive timeout of millisecond
//! granularity; the grid needs better: the coordinator waits for a late done notice for a
//! fraction of a tick, the bus bridge for its release until its watchdog's deadline. So a
//! listener polls its file descriptor with `ppoll` (a nanosecond timeout), and draining it
//! empties the socket, then resets iceoryx2's notification state (a notifier whose listener
//! was not drained since its last notification pays no system call).

use core::time::Duration;
use std::os::fd::{AsRawFd, BorrowedFd};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use nix::poll::{PollFd, PollFlags};
use nix::sys::time::TimeSpec;

use super::ipc_err;
use crate::channels::{
    BytePublisher, ByteSubscriber, ChannelSpec, Channels, WakeListener, WakeNotifier,
};
use crate::TransportError;

/// The service type of the channels: ports that may move between threads.
type Service = ipc_threadsafe::Service;
type Factory = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Service, [u8], ()>;

/// Nodes (processes) a channel or wake-up serves at most.
const MAX_NODES: usize = 256;
/// Listeners a wake-up admits.
const MAX_LISTENERS: usize = 4;

/// The channels of one node.
pub struct IpcChannels {
    node: Node<Service>,
}

impl IpcChannels {
    pub(super) fn new(node: Node<Service>) -> IpcChannels {
        IpcChannels { node }
    }

    fn service(&self, name: &str, spec: &ChannelSpec) -> Result<Factory, TransportError> {
        let name = ServiceName::new(name).map_err(|e| ipc_err("channel name")(&e))?;
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
            .map_err(|e| ipc_err("open channel")(&e))
    }

    fn event(
        &self,
        name: &str,
        notifiers: usize,
    ) -> Result<iceoryx2::service::port_factory::event::PortFactory<Service>, TransportError> {
        let name = ServiceName::new(name).map_err(|e| ipc_err("wake-up name")(&e))?;
        self.node
            .service_builder(&name)
            .event()
            .max_nodes(MAX_NODES)
            .max_notifiers(notifiers)
            .max_listeners(MAX_LISTENERS)
            .open_or_create()
            .map_err(|e| ipc_err("open wake-up")(&e))
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
            .map_err(|e| ipc_err("channel publisher")(&e))?;
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
            .map_err(|e| ipc_err("channel subscriber")(&e))?;
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
        notifiers: usize,
    ) -> Result<Box<dyn WakeNotifier>, TransportError> {
        let port = self
            .event(name, notifiers)?
            .notifier_builder()
            .create()
            .map_err(|e| ipc_err("wake-up notifier")(&e))?;
        Ok(Box::new(IpcNotifier(port)))
    }

    fn listener(
        &self,
        name: &str,
        notifiers: usize,
    ) -> Result<Box<dyn WakeListener>, TransportError> {
        let port = self
            .event(name, notifiers)?
            .listener_builder()
            .create()
            .map_err(|e| ipc_err("wake-up listener")(&e))?;
        Ok(Box::new(IpcListener(port)))
    }
}

struct IpcPublisher(Publisher<Service, [u8], ()>);

impl BytePublisher for IpcPublisher {
    fn send(&self, len: usize, fill: &mut dyn FnMut(&mut [u8])) -> Result<(), TransportError> {
        let mut sample = self
            .0
            .loan_slice_uninit(len)
            .map_err(|e| ipc_err("channel loan")(&e))?;
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
        sample.send().map_err(|e| ipc_err("channel send")(&e))?;
        Ok(())
    }
}

struct IpcSubscriber(Subscriber<Service, [u8], ()>);

impl ByteSubscriber for IpcSubscriber {
    fn receive(&self, read: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError> {
        match self
            .0
            .receive()
            .map_err(|e| ipc_err("channel receive")(&e))?
        {
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

struct IpcNotifier(Notifier<Service>);

impl WakeNotifier for IpcNotifier {
    fn notify(&self) -> Result<(), TransportError> {
        self.0
            .notify()
            .map(|_| ())
            .map_err(|e| ipc_err("wake-up notify")(&e))
    }
}

struct IpcListener(Listener<Service>);

impl IpcListener {
    /// The listener's socket.
    fn fd(&self) -> BorrowedFd<'_> {
        // SAFETY: the descriptor is the listener's socket, open for as long as the listener
        // lives, which outlives the borrow; it is only polled and read, never closed here.
        unsafe { BorrowedFd::borrow_raw(self.0.file_descriptor().native_handle()) }
    }
}

impl WakeListener for IpcListener {
    fn wait(&self, timeout: Option<Duration>) -> bool {
        let mut fds = [PollFd::new(self.fd(), PollFlags::POLLIN)];
        match nix::poll::ppoll(&mut fds, timeout.map(TimeSpec::from), None) {
            Ok(n) => n > 0,
            Err(_) => false,
        }
    }

    /// iceoryx2 reads one datagram per take, and a notifier whose listener counts as notified
    /// sends none; datagrams of racing notifiers can pile up (the socket holds 10 here) or the
    /// state can say "notified" with none left. So the socket is emptied first, then
    /// iceoryx2's state is reset: whatever came in between is still seen by the look for work
    /// that follows.
    fn drain(&self) {
        let mut byte = [0u8; 32];
        while let Ok(n) = nix::sys::socket::recv(
            self.fd().as_raw_fd(),
            &mut byte,
            nix::sys::socket::MsgFlags::MSG_DONTWAIT,
        ) {
            if n == 0 {
                break;
            }
        }
        if let Err(e) = self.0.try_wait(|_| {}) {
            tracing::debug!("wake-up not taken: {e:?}");
        }
    }
}
