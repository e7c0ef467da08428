//! The master's frames, moved on the calling thread: ethercrab's futures polled in place, the
//! frames they queue sent on the [`RawLink`], the replies handed back, until the future is done.
//!
//! ethercrab's own loop (`ethercrab::std::tx_rx_task`) runs in a thread of its own and dies on
//! the first reply that comes after its frame timed out (`Error::ReceiveFrame`, and every frame
//! after it times out). Here nothing crosses a thread: the bus bridge's real-time thread sends
//! the cycle's frame and waits for its reply itself (no wake-up of another thread in between),
//! and a late or stray reply is counted and dropped. Polling uses a no-op waker: the loop polls
//! again after every send and every received frame, and at least every [`POLL_EVERY`] (ethercrab's
//! timeouts are timers that are checked when polled). Nothing here allocates.

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};
use std::time::Duration;

use ethercrab::{PduRx, PduTx};
use modbot_bus::link::RawLink;

/// The longest the pump waits for a frame before it polls the future again.
pub const POLL_EVERY: Duration = Duration::from_micros(500);

/// The largest Ethernet frame a reply may be.
const FRAME_MAX: usize = 1536;

/// ethercrab's side of the link (its frame queue) and the socket.
pub struct Pump {
    link: RawLink,
    tx: PduTx<'static>,
    rx: PduRx<'static>,
    buf: [u8; FRAME_MAX],
    /// Replies that matched no frame waiting for one (late, duplicated, or not ours).
    pub stray_replies: u64,
    /// Frames the link refused to send (the interface down, say); ethercrab times them out.
    pub send_failures: u64,
}

impl Pump {
    pub fn new(link: RawLink, tx: PduTx<'static>, rx: PduRx<'static>) -> Pump {
        Pump {
            link,
            tx,
            rx,
            buf: [0; FRAME_MAX],
            stray_replies: 0,
            send_failures: 0,
        }
    }

    /// The interface the master talks on.
    pub fn interface(&self) -> &str {
        self.link.interface()
    }

    /// Runs `future` (an ethercrab operation) to its end, moving its frames. It ends by itself:
    /// every ethercrab operation has its timeout.
    pub fn run<F: Future>(&mut self, future: F) -> F::Output {
        let mut future = pin!(future);
        let mut cx = Context::from_waker(Waker::noop());
        loop {
            if let Poll::Ready(out) = future.as_mut().poll(&mut cx) {
                return out;
            }
            self.send_queued();
            // Wait for a reply (or the poll interval), then take every reply that is waiting.
            match self.link.wait(POLL_EVERY) {
                Ok(_) => self.receive_waiting(),
                Err(e) => tracing::warn!("EtherCAT link '{}': {e}", self.link.interface()),
            }
        }
    }

    /// Runs `main` to its end as [`Pump::run`] does, with `side` beside it: both frames go
    /// out together, so `side` costs no round trip of its own. `side` is polled first (its
    /// frame queued first); its output, if it ended by the time `main` did (else it is
    /// dropped: ethercrab frees its frame, and a late reply counts as stray).
    pub fn run_beside<S: Future, F: Future>(
        &mut self,
        side: S,
        main: F,
    ) -> (Option<S::Output>, F::Output) {
        let mut side = pin!(side);
        let mut main = pin!(main);
        let mut side_out = None;
        let mut cx = Context::from_waker(Waker::noop());
        loop {
            if side_out.is_none() {
                if let Poll::Ready(out) = side.as_mut().poll(&mut cx) {
                    side_out = Some(out);
                }
            }
            if let Poll::Ready(out) = main.as_mut().poll(&mut cx) {
                return (side_out, out);
            }
            self.send_queued();
            match self.link.wait(POLL_EVERY) {
                Ok(_) => self.receive_waiting(),
                Err(e) => tracing::warn!("EtherCAT link '{}': {e}", self.link.interface()),
            }
        }
    }

    fn send_queued(&mut self) {
        while let Some(frame) = self.tx.next_sendable_frame() {
            let link = &self.link;
            let sent = frame.send_blocking(|bytes| match link.send(bytes) {
                Ok(()) => Ok(bytes.len()),
                Err(_) => Err(ethercrab::error::Error::SendFrame),
            });
            if sent.is_err() {
                self.send_failures += 1;
                // The frame stays queued; do not spin on a link that refuses it.
                break;
            }
        }
    }

    fn receive_waiting(&mut self) {
        loop {
            match self.link.try_recv(&mut self.buf) {
                Ok(Some(n)) => {
                    if self.rx.receive_frame(&self.buf[..n]).is_err() {
                        self.stray_replies += 1;
                    }
                }
                Ok(None) => return,
                Err(e) => {
                    tracing::warn!("EtherCAT link '{}': {e}", self.link.interface());
                    return;
                }
            }
        }
    }
}
