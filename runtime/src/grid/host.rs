//! A component host: the process that steps some of the grid's components.
//!
//! It waits for release notices. Released at n, a component reads each input as valid at n —
//! the version of its source's outputs that the notice names, taken from the samples that source
//! published — steps, publishes its outputs stamped valid from n + period, and sends a done
//! notice with its execution time. A host steps its components one after another, in the
//! order they were released.

use core::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::*;
use modbot_ipc_schema::grid::{
    read_record, record_len, write_record, Done, OutHeader, PortValue, Release, OUT_HEADER_LEN,
};
use zerocopy::{FromBytes, IntoBytes};

use super::component::{Component, Registry};
use super::spec::GridSpec;
use super::wire::{self, Pub, Sub};
use crate::transport::TransportError;

/// Versions kept per source: LET only ever reads one of the newest two.
const KEPT: usize = 4;

/// The outputs of one source component, as one consumer reads them.
struct Source {
    sub: Sub,
    ring: Vec<(u64, Vec<PortValue>)>,
    next: usize,
    zeros: Vec<PortValue>,
}

impl Source {
    /// Takes what arrived, then lends the version `want` (0: the initial zeros); `None` if it
    /// never arrived.
    fn version(&mut self, want: u64) -> Option<&[PortValue]> {
        while let Ok(Some(sample)) = self.sub.receive() {
            let bytes = sample.payload();
            let Ok((header, record)) = OutHeader::ref_from_prefix(bytes) else {
                continue;
            };
            let slot = &mut self.ring[self.next];
            if read_record(record, &mut slot.1).is_ok() {
                slot.0 = header.valid_from.get();
                self.next = (self.next + 1) % KEPT;
            }
        }
        if want == 0 {
            return Some(&self.zeros);
        }
        self.ring
            .iter()
            .find(|(from, _)| *from == want)
            .map(|(_, v)| v.as_slice())
    }
}

struct Hosted {
    index: usize,
    period: u64,
    component: Box<dyn Component>,
    inputs: Vec<PortValue>,
    outputs: Vec<PortValue>,
    sources: Vec<Source>,
    /// For each input: (source position, output port of that source).
    bindings: Vec<(usize, usize)>,
    out: Pub,
    out_len: usize,
}

/// The components of one host, and its notice channels.
pub struct Host {
    name: String,
    hosted: Vec<Hosted>,
    releases: Sub,
    done: Pub,
    wake: Listener<ipc::Service>,
    /// Inputs that were not found in the version the notice named.
    pub missing: u64,
}

/// Why a host could not start.
#[derive(Debug, thiserror::Error)]
pub enum HostError {
    #[error("host '{0}' has no components in this grid")]
    NoComponents(String),
    #[error("component '{name}' cannot be instantiated: {why}")]
    Instantiate { name: String, why: String },
    #[error(transparent)]
    Transport(#[from] TransportError),
}

impl Host {
    /// Instantiates and initialises the components of `host` and opens their channels.
    pub fn new(
        node: &Node<ipc::Service>,
        spec: &GridSpec,
        registry: &Registry,
        host: &str,
    ) -> Result<Host, HostError> {
        let mine = spec.components_of(host);
        if mine.is_empty() {
            return Err(HostError::NoComponents(host.to_owned()));
        }
        let mut hosted = Vec::new();
        for c in mine {
            let cs = &spec.components[c];
            let component = registry
                .instantiate(&cs.type_name, &cs.params)
                .map_err(|why| HostError::Instantiate {
                    name: cs.name.clone(),
                    why,
                })?;
            let out_types = spec.output_types(c);
            let sources = spec
                .sources(c)
                .into_iter()
                .map(|s| {
                    let zeros: Vec<PortValue> =
                        spec.output_types(s).iter().map(|t| t.zero()).collect();
                    Ok(Source {
                        sub: wire::out_subscriber(node, &spec.components[s].name)?,
                        ring: (0..KEPT).map(|_| (u64::MAX, zeros.clone())).collect(),
                        next: 0,
                        zeros,
                    })
                })
                .collect::<Result<Vec<_>, TransportError>>()?;
            let out_len = OUT_HEADER_LEN + record_len(&out_types);
            hosted.push(Hosted {
                index: c,
                period: cs.period.max(1),
                component,
                inputs: cs.info.inputs.iter().map(|p| p.ty.zero()).collect(),
                outputs: out_types.iter().map(|t| t.zero()).collect(),
                bindings: (0..cs.info.inputs.len())
                    .map(|i| spec.input_binding(c, i))
                    .collect(),
                sources,
                out: wire::out_publisher(node, &cs.name, out_len)?,
                out_len,
            });
        }
        Ok(Host {
            name: host.to_owned(),
            hosted,
            releases: wire::release_subscriber(node, host)?,
            done: wire::done_publisher(node)?,
            wake: wire::wake_listener(node, host)?,
            missing: 0,
        })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Sleeps until released or `timeout` passed, then serves every release waiting.
    pub fn wait_and_serve(
        &mut self,
        timeout: Duration,
        now: &dyn Fn() -> u64,
    ) -> Result<usize, TransportError> {
        if let Err(e) = self.wake.timed_wait(|_| {}, timeout) {
            tracing::debug!("host wait: {e:?}");
        }
        self.serve(now)
    }

    /// Serves every release notice waiting; returns how many.
    pub fn serve(&mut self, now: &dyn Fn() -> u64) -> Result<usize, TransportError> {
        let mut served = 0;
        while let Some(sample) = self.releases.receive().map_err(|e| TransportError::Ipc {
            op: "receive release",
            detail: format!("{e:?}"),
        })? {
            let Ok(release) = Release::parse(sample.payload()) else {
                continue;
            };
            let release = *release;
            drop(sample);
            self.step(&release, now)?;
            served += 1;
        }
        Ok(served)
    }

    fn step(&mut self, release: &Release, now: &dyn Fn() -> u64) -> Result<(), TransportError> {
        let n = release.tick.get();
        if release.component.get() == modbot_ipc_schema::grid::PING {
            let done = Done::new(n, modbot_ipc_schema::grid::PING, Done::OK, 0, 0);
            return wire::send(&self.done, done.as_bytes().len(), |buf| {
                buf.copy_from_slice(done.as_bytes())
            });
        }
        let c = usize::from(release.component.get());
        let Some(h) = self.hosted.iter_mut().find(|h| h.index == c) else {
            tracing::warn!(
                "release of component {c}, which is not on host {}",
                self.name
            );
            return Ok(());
        };
        let mut versions = [0u64; modbot_ipc_schema::grid::MAX_SOURCES];
        for (slot, v) in versions.iter_mut().zip(release.versions()) {
            *slot = v;
        }
        for (i, &(s, port)) in h.bindings.iter().enumerate() {
            match h.sources[s].version(versions[s]) {
                Some(values) => h.inputs[i].assign(&values[port]),
                None => {
                    self.missing += 1;
                    tracing::warn!(
                        "component {c} at tick {n}: input {i} version {} missing",
                        versions[s]
                    );
                }
            }
        }
        let start = now();
        h.component.step(n, &h.inputs, &mut h.outputs);
        let end = now();
        let outputs = &h.outputs;
        wire::send(&h.out, h.out_len, |buf| {
            let header = OutHeader {
                valid_from: (n + h.period).into(),
                release: n.into(),
            };
            buf[..OUT_HEADER_LEN].copy_from_slice(header.as_bytes());
            if let Err(e) = write_record(outputs, &mut buf[OUT_HEADER_LEN..]) {
                tracing::error!("outputs of component {c} not written: {e}");
            }
        })?;
        let done = Done::new(
            n,
            c as u16,
            Done::OK,
            end.saturating_sub(start),
            start.saturating_sub(release.released_ns.get()),
        );
        wire::send(&self.done, done.as_bytes().len(), |buf| {
            buf.copy_from_slice(done.as_bytes())
        })
    }
}

impl Drop for Host {
    fn drop(&mut self) {
        for h in &mut self.hosted {
            h.component.terminate();
        }
    }
}
