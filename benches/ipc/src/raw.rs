//! The raw iceoryx2 baseline: a `[u8]` publish-subscribe ping-pong without modbot, in the
//! benchmark's domain (the same prefix, so the same cleanup). Either side spins on its
//! subscriber (busy) or sleeps on an Event listener that the sender notifies after each
//! sample (event).
//!
//! Child role `raw-echo DOMAIN MAX MODE CORE PRIO`: sends every sample back, copied out and in;
//! MODE is `busy` or `event`.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use modbot_bench_kit::procs::{self, Proc};
use modbot_core::Domain;

type RawPub = iceoryx2::port::publisher::Publisher<ipc::Service, [u8], ()>;
type RawSub = iceoryx2::port::subscriber::Subscriber<ipc::Service, [u8], ()>;

/// How a side waits for the next sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wait {
    /// Spin on the subscriber.
    Busy,
    /// Sleep on an Event listener; the sender notifies after each sample.
    Event,
}

impl Wait {
    pub fn arg(self) -> &'static str {
        match self {
            Wait::Busy => "busy",
            Wait::Event => "event",
        }
    }

    fn parse(text: &str) -> anyhow::Result<Wait> {
        match text {
            "busy" => Ok(Wait::Busy),
            "event" => Ok(Wait::Event),
            _ => bail!("wait mode '{text}': expected busy or event"),
        }
    }
}

/// One side of a raw ping-pong: publishes on `out`, subscribes to `inp`.
pub struct RawPorts {
    publisher: RawPub,
    subscriber: RawSub,
    /// Event mode: wakes the other side after a send.
    notifier: Option<Notifier<ipc::Service>>,
    /// Event mode: where this side sleeps.
    listener: Option<Listener<ipc::Service>>,
    /// Held for the ports' life.
    _node: Node<ipc::Service>,
}

impl RawPorts {
    /// Opens the ports in `domain` for samples of up to `max` bytes.
    pub fn open(
        domain: &Domain,
        out: &str,
        inp: &str,
        max: usize,
        wait: Wait,
    ) -> anyhow::Result<RawPorts> {
        let mut cfg = iceoryx2::config::Config::default();
        cfg.global.prefix = FileName::new(domain.prefix().as_bytes())
            .map_err(|e| anyhow::anyhow!("prefix {}: {e:?}", domain.prefix()))?;
        let node = NodeBuilder::new()
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| anyhow::anyhow!("raw node: {e:?}"))?;
        let pubsub = |name: &str| -> anyhow::Result<_> {
            let sname = ServiceName::new(&format!("raw.{name}"))
                .map_err(|e| anyhow::anyhow!("service name raw.{name}: {e:?}"))?;
            node.service_builder(&sname)
                .publish_subscribe::<[u8]>()
                .subscriber_max_buffer_size(4)
                .open_or_create()
                .map_err(|e| anyhow::anyhow!("raw service raw.{name}: {e:?}"))
        };
        let event = |name: &str| -> anyhow::Result<_> {
            let sname = ServiceName::new(&format!("raw.{name}.wake"))
                .map_err(|e| anyhow::anyhow!("service name raw.{name}.wake: {e:?}"))?;
            node.service_builder(&sname)
                .event()
                .open_or_create()
                .map_err(|e| anyhow::anyhow!("raw event raw.{name}.wake: {e:?}"))
        };
        let publisher = pubsub(out)?
            .publisher_builder()
            .initial_max_slice_len(max.max(8))
            .create()
            .map_err(|e| anyhow::anyhow!("raw publisher: {e:?}"))?;
        let subscriber = pubsub(inp)?
            .subscriber_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("raw subscriber: {e:?}"))?;
        let (notifier, listener) = match wait {
            Wait::Busy => (None, None),
            Wait::Event => (
                Some(
                    event(out)?
                        .notifier_builder()
                        .create()
                        .map_err(|e| anyhow::anyhow!("raw notifier: {e:?}"))?,
                ),
                Some(
                    event(inp)?
                        .listener_builder()
                        .create()
                        .map_err(|e| anyhow::anyhow!("raw listener: {e:?}"))?,
                ),
            ),
        };
        Ok(RawPorts {
            publisher,
            subscriber,
            notifier,
            listener,
            _node: node,
        })
    }

    /// Sends a copy of `payload` (and wakes the other side in event mode).
    pub fn send(&self, payload: &[u8]) -> anyhow::Result<()> {
        let sample = self
            .publisher
            .loan_slice_uninit(payload.len())
            .map_err(|e| anyhow::anyhow!("raw loan of {} bytes: {e:?}", payload.len()))?;
        sample
            .write_from_slice(payload)
            .send()
            .map_err(|e| anyhow::anyhow!("raw send: {e:?}"))?;
        if let Some(n) = &self.notifier {
            n.notify()
                .map_err(|e| anyhow::anyhow!("raw notify: {e:?}"))?;
        }
        Ok(())
    }

    /// Takes the next sample, if one is there, and copies it into `sink` (grown as needed);
    /// returns its length.
    pub fn try_recv(&self, sink: &mut Vec<u8>) -> anyhow::Result<Option<usize>> {
        let Some(sample) = self
            .subscriber
            .receive()
            .map_err(|e| anyhow::anyhow!("raw receive: {e:?}"))?
        else {
            return Ok(None);
        };
        let len = sample.payload().len();
        if sink.len() < len {
            sink.resize(len, 0);
        }
        sink[..len].copy_from_slice(sample.payload());
        Ok(Some(len))
    }

    /// Waits for the next sample (spinning or sleeping as opened) until `deadline`.
    pub fn recv(&self, sink: &mut Vec<u8>, deadline: Instant) -> anyhow::Result<Option<usize>> {
        let mut spins = 0u32;
        loop {
            if let Some(len) = self.try_recv(sink)? {
                return Ok(Some(len));
            }
            // A spinning receiver looks at the clock once per 64 looks at its subscriber, as
            // modbot's do: a clock read per look would slow the baseline down.
            spins = spins.wrapping_add(1);
            if self.listener.is_none() && !spins.is_multiple_of(64) {
                core::hint::spin_loop();
                continue;
            }
            let now = Instant::now();
            if now >= deadline || procs::interrupted() {
                return Ok(None);
            }
            if let Some(l) = &self.listener {
                let left = (deadline - now).min(Duration::from_millis(100));
                if let Err(e) = l.timed_wait(|_| {}, left) {
                    // A signal ends the wait: SIGTERM is how this process is told to stop.
                    if procs::interrupted() {
                        return Ok(None);
                    }
                    bail!("raw wait: {e:?}");
                }
            } else {
                core::hint::spin_loop();
            }
        }
    }

    /// One round trip: sends `payload`, waits for the answer (copied into `sink`).
    pub fn round_trip(&self, payload: &[u8], sink: &mut Vec<u8>) -> anyhow::Result<usize> {
        self.send(payload)?;
        match self.recv(sink, Instant::now() + Duration::from_secs(5))? {
            Some(len) => Ok(len),
            None => {
                procs::check_interrupted()?;
                bail!("the raw echo process did not answer within 5 s")
            }
        }
    }

    /// Pings until the other side answers (its ports may not be connected yet), then drains
    /// what the extra pings brought back.
    pub fn handshake(&self, child: &mut Proc) -> anyhow::Result<()> {
        let end = Instant::now() + Duration::from_secs(10);
        let mut sink = Vec::new();
        loop {
            self.send(&[0])?;
            if self
                .recv(&mut sink, Instant::now() + Duration::from_millis(20))?
                .is_some()
            {
                break;
            }
            child.check_running().context("raw handshake")?;
            procs::check_interrupted()?;
            if Instant::now() > end {
                bail!("the raw echo process does not answer");
            }
        }
        let settle = Instant::now() + Duration::from_millis(50);
        while Instant::now() < settle {
            let _ = self.try_recv(&mut sink)?;
        }
        Ok(())
    }
}

/// The child role of this baseline.
pub fn child(role: &str, args: &[String]) -> Option<anyhow::Result<()>> {
    (role == "raw-echo").then(|| echo(args))
}

fn echo(args: &[String]) -> anyhow::Result<()> {
    let [domain, max, wait, core, prio] = args else {
        bail!("usage: child raw-echo DOMAIN MAX busy|event CORE PRIO");
    };
    let _pinned = procs::pin(procs::parse_core(core)?)?;
    let wait = Wait::parse(wait)?;
    let _fifo = procs::set_fifo(crate::uds::parse_prio(prio)?)?;
    let max: usize = max.parse().with_context(|| format!("max '{max}'"))?;
    let ports = RawPorts::open(&Domain::new(domain)?, "pong", "ping", max, wait)?;
    let mut buf = vec![0u8; max];
    while !procs::interrupted() {
        let deadline = Instant::now() + Duration::from_millis(100);
        if let Some(len) = ports.recv(&mut buf, deadline)? {
            ports.send(&buf[..len])?;
        }
    }
    Ok(())
}
