//! Named byte channels and wake-ups: the links of the time grid, which are not module frames.
//!
//! A [`Channels`] is one process's access to them (an iceoryx2 node, or the in-process
//! backend). A channel carries byte samples from its publishers to every subscriber, each of
//! which buffers up to [`ChannelSpec::depth`] of them (the oldest is dropped when it is full:
//! readers of a channel want the newest), and may lend a late subscriber the last
//! [`ChannelSpec::history`] ones. A wake-up is an event: a listener sleeps until a notifier
//! notifies, with a deadline to the microsecond.
//!
//! Every operation on a port borrows what it needs: a publisher lends its sample to a closure
//! that writes it in place, a subscriber lends a received sample to a closure that reads it.
//! Nothing is allocated on a real-time path by the iceoryx2 backend ([`crate::ipc`]); the
//! in-process backend ([`crate::local`]) copies into heap buffers and is for tests.

use core::time::Duration;

use crate::TransportError;

pub use crate::channel_spec::ChannelSpec;

/// One process's access to the channels and wake-ups of a domain.
pub trait Channels: Send + Sync {
    /// A publisher on channel `name`, for samples of up to `max_len` bytes.
    fn publisher(
        &self,
        name: &str,
        spec: &ChannelSpec,
        max_len: usize,
    ) -> Result<Box<dyn BytePublisher>, TransportError>;

    /// A subscriber of channel `name`.
    fn subscriber(
        &self,
        name: &str,
        spec: &ChannelSpec,
    ) -> Result<Box<dyn ByteSubscriber>, TransportError>;

    /// How many publishers channel `name` has now.
    fn publishers(&self, name: &str, spec: &ChannelSpec) -> Result<usize, TransportError>;

    /// A notifier of wake-up `name`, which admits `notifiers` of them.
    fn notifier(
        &self,
        name: &str,
        notifiers: usize,
    ) -> Result<Box<dyn WakeNotifier>, TransportError>;

    /// A listener of wake-up `name`, which admits `notifiers` notifiers.
    fn listener(
        &self,
        name: &str,
        notifiers: usize,
    ) -> Result<Box<dyn WakeListener>, TransportError>;
}

/// Sends samples on a channel.
pub trait BytePublisher: Send {
    /// Sends a sample of `len` bytes, written in place by `fill` (the bytes it finds are
    /// those of an earlier sample, or zeros: it writes all of them).
    fn send(&self, len: usize, fill: &mut dyn FnMut(&mut [u8])) -> Result<(), TransportError>;

    /// Sends a copy of `bytes`.
    fn send_bytes(&self, bytes: &[u8]) -> Result<(), TransportError> {
        self.send(bytes.len(), &mut |buf| buf.copy_from_slice(bytes))
    }
}

/// Receives the samples of a channel, oldest first.
pub trait ByteSubscriber: Send {
    /// Lends the oldest sample waiting to `read`, if there is one; whether there was.
    fn receive(&self, read: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError>;

    /// Maps what the publishers share now, so that the first receive on a real-time thread
    /// does not.
    fn connect(&self);
}

/// Wakes the listeners of a wake-up.
pub trait WakeNotifier: Send {
    fn notify(&self) -> Result<(), TransportError>;
}

/// Sleeps until woken.
pub trait WakeListener: Send {
    /// Sleeps until a notification is waiting or `timeout` passed (`None`: no limit);
    /// whether one is waiting. It takes nothing: call [`WakeListener::drain`] before looking
    /// for the work the notification announces. An interrupted wait (a signal) returns
    /// `false`, so the caller looks at its termination flag.
    fn wait(&self, timeout: Option<Duration>) -> bool;

    /// Takes every notification that arrived, without waiting: one sent after this wakes the
    /// next [`WakeListener::wait`].
    fn drain(&self);
}
