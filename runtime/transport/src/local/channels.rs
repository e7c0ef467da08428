//! [`Channels`] inside one process: a channel is a set of bounded queues, one per subscriber,
//! a wake-up a flag and a condition variable per listener; both are found by name in the
//! domain. Samples are copied into heap buffers: for tests (the grid's LET semantics run here
//! on threads), not for real runs.

use core::time::Duration;
use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, Weak};
use std::time::Instant;

use crate::channels::{
    BytePublisher, ByteSubscriber, ChannelSpec, Channels, WakeListener, WakeNotifier,
};
use crate::TransportError;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The channels and wake-ups of one domain, by name.
#[derive(Default)]
pub(super) struct LocalChannelSet {
    channels: Mutex<HashMap<String, Arc<Channel>>>,
    wakeups: Mutex<HashMap<String, Arc<Wakeup>>>,
}

struct Channel {
    spec: ChannelSpec,
    state: Mutex<ChannelState>,
}

#[derive(Default)]
struct ChannelState {
    publishers: usize,
    subscribers: Vec<Weak<Queue>>,
    /// The last samples sent, for subscribers that join late.
    history: VecDeque<Vec<u8>>,
}

type Queue = Mutex<VecDeque<Vec<u8>>>;

#[derive(Default)]
struct Wakeup {
    listeners: Mutex<Vec<Weak<Flag>>>,
}

#[derive(Default)]
struct Flag {
    set: Mutex<bool>,
    changed: Condvar,
}

/// One user's access to a domain's [`LocalChannelSet`].
#[derive(Clone)]
pub struct LocalChannels {
    set: Arc<LocalChannelSet>,
}

impl LocalChannels {
    pub(super) fn new(set: Arc<LocalChannelSet>) -> LocalChannels {
        LocalChannels { set }
    }

    fn channel(&self, name: &str, spec: &ChannelSpec) -> Result<Arc<Channel>, TransportError> {
        let mut all = lock(&self.set.channels);
        let channel = all.entry(name.to_owned()).or_insert_with(|| {
            Arc::new(Channel {
                spec: *spec,
                state: Mutex::default(),
            })
        });
        if channel.spec != *spec {
            return Err(TransportError::ChannelSpecDiffers {
                name: name.to_owned(),
                have: channel.spec,
                asked: *spec,
            });
        }
        Ok(channel.clone())
    }

    fn wakeup(&self, name: &str) -> Arc<Wakeup> {
        lock(&self.set.wakeups)
            .entry(name.to_owned())
            .or_default()
            .clone()
    }
}

impl Channels for LocalChannels {
    fn publisher(
        &self,
        name: &str,
        spec: &ChannelSpec,
        max_len: usize,
    ) -> Result<Box<dyn BytePublisher>, TransportError> {
        let channel = self.channel(name, spec)?;
        let mut state = lock(&channel.state);
        if state.publishers >= spec.publishers {
            return Err(TransportError::ChannelPublishersTaken {
                name: name.to_owned(),
                max: spec.publishers,
            });
        }
        state.publishers += 1;
        drop(state);
        Ok(Box::new(LocalPublisher { channel, max_len }))
    }

    fn subscriber(
        &self,
        name: &str,
        spec: &ChannelSpec,
    ) -> Result<Box<dyn ByteSubscriber>, TransportError> {
        let channel = self.channel(name, spec)?;
        let mut state = lock(&channel.state);
        state.subscribers.retain(|q| q.strong_count() > 0);
        if state.subscribers.len() >= spec.subscribers {
            return Err(TransportError::ChannelSubscribersTaken {
                name: name.to_owned(),
                max: spec.subscribers,
            });
        }
        let queue: Arc<Queue> = Arc::new(Mutex::new(state.history.iter().cloned().collect()));
        state.subscribers.push(Arc::downgrade(&queue));
        Ok(Box::new(LocalSubscriber { queue }))
    }

    fn publishers(&self, name: &str, spec: &ChannelSpec) -> Result<usize, TransportError> {
        Ok(lock(&self.channel(name, spec)?.state).publishers)
    }

    fn notifier(&self, name: &str, _: usize) -> Result<Box<dyn WakeNotifier>, TransportError> {
        Ok(Box::new(LocalNotifier(self.wakeup(name))))
    }

    fn listener(&self, name: &str, _: usize) -> Result<Box<dyn WakeListener>, TransportError> {
        let flag = Arc::new(Flag::default());
        lock(&self.wakeup(name).listeners).push(Arc::downgrade(&flag));
        Ok(Box::new(LocalListener(flag)))
    }
}

struct LocalPublisher {
    channel: Arc<Channel>,
    max_len: usize,
}

impl BytePublisher for LocalPublisher {
    fn send(&self, len: usize, fill: &mut dyn FnMut(&mut [u8])) -> Result<(), TransportError> {
        if len > self.max_len {
            return Err(TransportError::FrameTooLarge {
                len,
                max: self.max_len,
            });
        }
        let mut sample = vec![0u8; len];
        fill(&mut sample);
        let mut state = lock(&self.channel.state);
        let depth = self.channel.spec.depth.max(1);
        state.subscribers.retain(|q| q.strong_count() > 0);
        for queue in state.subscribers.iter().filter_map(Weak::upgrade) {
            let mut q = lock(&queue);
            if q.len() == depth {
                q.pop_front();
            }
            q.push_back(sample.clone());
        }
        if self.channel.spec.history > 0 {
            if state.history.len() == self.channel.spec.history {
                state.history.pop_front();
            }
            state.history.push_back(sample);
        }
        Ok(())
    }
}

impl Drop for LocalPublisher {
    fn drop(&mut self) {
        let mut state = lock(&self.channel.state);
        state.publishers = state.publishers.saturating_sub(1);
    }
}

struct LocalSubscriber {
    queue: Arc<Queue>,
}

impl ByteSubscriber for LocalSubscriber {
    fn receive(&self, read: &mut dyn FnMut(&[u8])) -> Result<bool, TransportError> {
        let sample = lock(&self.queue).pop_front();
        match sample {
            Some(sample) => {
                read(&sample);
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// Nothing to map in one process.
    fn connect(&self) {}
}

struct LocalNotifier(Arc<Wakeup>);

impl WakeNotifier for LocalNotifier {
    fn notify(&self) -> Result<(), TransportError> {
        let mut listeners = lock(&self.0.listeners);
        listeners.retain(|l| l.strong_count() > 0);
        for flag in listeners.iter().filter_map(Weak::upgrade) {
            *lock(&flag.set) = true;
            flag.changed.notify_all();
        }
        Ok(())
    }
}

struct LocalListener(Arc<Flag>);

impl WakeListener for LocalListener {
    fn wait(&self, timeout: Option<Duration>) -> bool {
        let deadline = timeout.map(|t| Instant::now() + t);
        let mut set = lock(&self.0.set);
        while !*set {
            match deadline {
                None => {
                    set = self
                        .0
                        .changed
                        .wait(set)
                        .unwrap_or_else(|poisoned| poisoned.into_inner());
                }
                Some(deadline) => {
                    let left = deadline.saturating_duration_since(Instant::now());
                    if left.is_zero() {
                        return false;
                    }
                    set = self
                        .0
                        .changed
                        .wait_timeout(set, left)
                        .unwrap_or_else(|poisoned| poisoned.into_inner())
                        .0;
                }
            }
        }
        true
    }

    fn drain(&self) {
        *lock(&self.0.set) = false;
    }
}
