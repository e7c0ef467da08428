//! Blackboard snapshots across hosts. The exporting bridge reads the newest snapshot each
//! exported module publishes in shared memory and puts it on `modbot/D/M/bb` at the rate the
//! description gives (`snapshot_hz`; only a snapshot newer than the last put goes); the
//! importing bridge's proxy publishes each one it receives as its own — the snapshot's
//! address rewritten to the proxy's — so a local module reads a remote module's blackboard
//! with `snapshot_of` as it reads a local one's, and `modbot bb --shared` shows it.
//!
//! A snapshot from the network is checked before it is published here: a malformed one is
//! dropped with a warning, never passed on.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use modbot_core::Module;
use modbot_ipc_schema::snapshot::SnapshotHeader;
use modbot_ipc_schema::{Addr, SnapshotView};
use zenoh::{Session, Wait};
use zerocopy::FromBytes;

use super::config::Export;
use super::keys;

/// The exporting side: puts the exported modules' snapshots at a rate.
pub struct Publisher {
    period: Option<Duration>,
    next: Instant,
    /// The sequence number of the last snapshot put, per module.
    sent: HashMap<String, u64>,
}

impl Publisher {
    /// Puts snapshots `hz` times a second (0: never).
    pub fn new(hz: f64) -> Publisher {
        Publisher {
            period: (hz > 0.0 && hz.is_finite()).then(|| Duration::from_secs_f64(1.0 / hz)),
            next: Instant::now(),
            sent: HashMap::new(),
        }
    }

    /// Puts the snapshots that are new since the last time, if it is time.
    pub fn publish_due(
        &mut self,
        module: &mut Module<()>,
        session: &Session,
        domain: &str,
        exports: &[Export],
    ) {
        let Some(period) = self.period else {
            return;
        };
        let now = Instant::now();
        if now < self.next {
            return;
        }
        self.next = now + period;
        for e in exports {
            let last = self.sent.get(&e.module).copied();
            let put = module.ctx().snapshot_of(&e.module, |v| {
                if last == Some(v.seq()) {
                    return None;
                }
                let sent = session
                    .put(keys::snapshot(domain, &e.module), v.as_bytes().to_vec())
                    .wait();
                Some((v.seq(), sent))
            });
            match put {
                Ok(Some(Some((seq, Ok(()))))) => {
                    self.sent.insert(e.module.clone(), seq);
                }
                Ok(Some(Some((_, Err(why))))) => {
                    tracing::debug!("snapshot of '{}' not put: {why}", e.module)
                }
                // Nothing new, none published yet (a module without a blackboard never
                // publishes one), or the module is not running.
                Ok(_) | Err(_) => {}
            }
        }
    }
}

/// The importing side: the newest snapshot received for one proxy, until it publishes it.
#[derive(Default)]
pub struct Received {
    latest: Mutex<Option<Vec<u8>>>,
}

impl Received {
    /// Keeps `bytes` (a Zenoh thread calls this), replacing one not yet published.
    pub fn put(&self, bytes: Vec<u8>) {
        if let Ok(mut latest) = self.latest.lock() {
            *latest = Some(bytes);
        }
    }

    /// The snapshot received since the last call, checked and readdressed to `addr` (import
    /// `local`'s); `None` if none came (or the one that came was malformed: said here).
    pub fn take_for(&self, addr: Addr, local: &str) -> Option<Vec<u8>> {
        let mut bytes = self.latest.lock().ok()?.take()?;
        if let Err(e) = SnapshotView::parse(&bytes) {
            tracing::warn!(
                "import '{local}': a malformed snapshot came through the link, dropped: {e}"
            );
            return None;
        }
        let (header, _) = SnapshotHeader::mut_from_prefix(&mut bytes).ok()?;
        header.addr = addr.0;
        Some(bytes)
    }
}

/// Subscribes `received` to the snapshots of module `module` of domain `domain`.
pub fn subscribe(
    session: &Session,
    domain: &str,
    module: &str,
    received: Arc<Received>,
) -> Result<zenoh::pubsub::Subscriber<()>, String> {
    session
        .declare_subscriber(keys::snapshot(domain, module))
        .callback(move |s| received.put(s.payload().to_bytes().into_owned()))
        .wait()
        .map_err(|e| format!("Zenoh subscriber for {domain}/{module}'s snapshots: {e}"))
}

#[cfg(test)]
mod tests {
    use modbot_core::blackboard::Blackboard;
    use modbot_ipc_schema::{OwnedValue, Value};

    use super::*;

    fn snapshot(addr: Addr) -> Vec<u8> {
        let mut bb = Blackboard::builder()
            .item("recorded", OwnedValue::I64(0))
            .build()
            .unwrap();
        bb.write("recorded", Value::I64(41)).unwrap();
        let mut out = vec![0; bb.snapshot_len()];
        bb.write_snapshot(&mut out, addr, 7);
        out
    }

    #[test]
    fn a_received_snapshot_is_published_under_the_proxys_address_once() {
        let sut = Received::default();
        sut.put(snapshot(Addr(5)));
        let mine = sut.take_for(Addr(40), "target").expect("one came");
        let view = SnapshotView::parse(&mine).unwrap();
        assert_eq!(view.addr(), Addr(40));
        assert_eq!(view.value("recorded").unwrap(), Value::I64(41));
        assert_eq!(sut.take_for(Addr(40), "target"), None);
    }

    #[test]
    fn a_malformed_snapshot_from_the_link_is_dropped() {
        let sut = Received::default();
        let mut bad = snapshot(Addr(5));
        bad.truncate(bad.len() - 3);
        sut.put(bad);
        assert_eq!(sut.take_for(Addr(40), "target"), None);
        sut.put(b"MBBB".to_vec());
        assert_eq!(sut.take_for(Addr(40), "target"), None);
    }
}
