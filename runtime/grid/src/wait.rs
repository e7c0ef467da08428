//! Sleeping on an iceoryx2 wake-up with a deadline to the microsecond.
//!
//! `Listener::timed_wait` waits on its socket with a receive timeout of millisecond
//! granularity; the grid needs better: the coordinator waits for a late done notice for a
//! fraction of a tick, the bus bridge for its release until its watchdog's deadline. So the
//! grid polls the listener's file descriptor with `ppoll` (a nanosecond timeout) and drains
//! the listener once it is readable. Draining resets iceoryx2's notification state, so a
//! notifier whose listener was not drained since its last notification pays no system call.

use std::os::fd::{AsRawFd, BorrowedFd};
use std::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::FileDescriptorBased;
use nix::poll::{PollFd, PollFlags};
use nix::sys::time::TimeSpec;

use super::wire::Threadsafe;

/// The listener's socket.
fn fd(listener: &Listener<Threadsafe>) -> BorrowedFd<'_> {
    // SAFETY: the descriptor is the listener's socket, open for as long as the listener
    // lives, which outlives the borrow; it is only polled and read, never closed here.
    unsafe { BorrowedFd::borrow_raw(listener.file_descriptor().native_handle()) }
}

/// Sleeps until `listener` has a notification waiting or `timeout` passed (`None`: no
/// limit); returns whether one is waiting. It takes nothing: call [`drain`] before looking
/// for the work the notification announces. An interrupted wait (a signal) returns `false`,
/// so the caller looks at its termination flag.
pub fn wait(listener: &Listener<Threadsafe>, timeout: Option<Duration>) -> bool {
    let mut fds = [PollFd::new(fd(listener), PollFlags::POLLIN)];
    match nix::poll::ppoll(&mut fds, timeout.map(TimeSpec::from), None) {
        Ok(n) => n > 0,
        Err(_) => false,
    }
}

/// Takes every notification that arrived, without waiting. Call it before looking for work:
/// a notification sent after it wakes the next [`wait`].
///
/// iceoryx2 reads one datagram per take, and a notifier whose listener counts as notified
/// sends none; datagrams of racing notifiers can pile up (the socket holds 10 here) or the
/// state can say "notified" with none left. So the socket is emptied first, then iceoryx2's
/// state is reset: whatever came in between is still seen by the look for work that follows.
pub fn drain(listener: &Listener<Threadsafe>) {
    let mut byte = [0u8; 32];
    while let Ok(n) = nix::sys::socket::recv(
        fd(listener).as_raw_fd(),
        &mut byte,
        nix::sys::socket::MsgFlags::MSG_DONTWAIT,
    ) {
        if n == 0 {
            break;
        }
    }
    if let Err(e) = listener.try_wait(|_| {}) {
        tracing::debug!("wake-up not taken: {e:?}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use iceoryx2::config::Config;
    use iceoryx2::prelude::*;

    #[test]
    fn a_notification_wakes_the_waiter_and_a_silent_listener_times_out() {
        let domain = modbot_testkit::TestDomain::new("wait", "notification");
        let mut cfg = Config::default();
        cfg.global.prefix = FileName::new(domain.prefix().as_bytes()).unwrap();
        let node = NodeBuilder::new()
            .config(&cfg)
            .create::<Threadsafe>()
            .unwrap();
        let svc = node
            .service_builder(&"wake".try_into().unwrap())
            .event()
            .open_or_create()
            .unwrap();
        let listener = svc.listener_builder().create().unwrap();
        let notifier = svc.notifier_builder().create().unwrap();
        assert!(!wait(&listener, Some(Duration::from_micros(300))));
        notifier.notify().unwrap();
        assert!(wait(&listener, Some(Duration::from_secs(10))));
        drain(&listener);
        assert!(
            !wait(&listener, Some(Duration::ZERO)),
            "the notification was taken"
        );
        for _ in 0..3 {
            notifier.notify().unwrap();
            assert!(
                wait(&listener, None),
                "each notification after a drain wakes"
            );
            drain(&listener);
        }
        // The domain's files go with `domain`.
        drop((listener, notifier, svc, node, domain));
    }
}
