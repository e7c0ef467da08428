//! An imported module: a remote domain's module in the local phone book. The proxy holds an
//! address and an inbox here, under the import's local name, beats like a module, and forwards
//! every request it takes to the remote domain's bridge, one at a time, answering the caller
//! with what came back — or, when nothing can come back, with a NAK `UNREACHABLE` that says
//! since when the link is down. A retransmitted request it answered already is answered again
//! from its log, never forwarded twice; reports to the module are forwarded as they come.
//! The remote module's blackboard snapshots, as its bridge puts them, are published here as
//! the proxy's own ([`super::mirror`]).
//!
//! The remote module's method ids are those of its own table (learned with a `describe`
//! through the link, again after each time the link came back), so a request's method id maps
//! to the name the remote bridge calls.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use modbot_core::served::{Replay, ServedLog};
use modbot_core::transport::{Dest, Endpoint, Joins, ReceiveMode, Transport};
use modbot_core::{Domain, IpcTransport};
use modbot_ipc_schema::directory::methods_digest;
use modbot_ipc_schema::heartbeat::{Counters, Heartbeat, ModuleState};
use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::{sysmethod, Addr, Args, Frame, FrameKind, FrameSpec, NakCode};
use zenoh::{Session, Wait};
use zerocopy::IntoBytes;

use super::config::Import;
use super::keys;
use super::link::Link;
use super::mirror::{self, Received};
use super::remote::{self, Answer};

/// What a proxy needs besides its import.
pub struct ProxyContext {
    pub domain: Domain,
    pub session: Session,
    pub link: Arc<Link>,
    /// How long a forwarded call may take before the caller is told it got no answer.
    pub call_timeout: Duration,
    pub heartbeat: Duration,
    pub stop: Arc<AtomicBool>,
}

/// The remote module's method table, as last learned.
struct Table {
    methods: Vec<String>,
    /// The link's epoch it was learned in ([`Link::epoch`]).
    epoch: u64,
}

/// Serves the import `import` until `cx.stop`; says once on `ready` whether its endpoint
/// opened.
pub fn serve(import: Import, cx: ProxyContext, ready: std::sync::mpsc::Sender<Result<(), String>>) {
    let transport = match IpcTransport::new(&cx.domain) {
        Ok(t) => t,
        Err(e) => {
            let _ = ready.send(Err(format!("import '{}': {e}", import.local)));
            return;
        }
    };
    let endpoint = match transport.open(
        import.addr,
        &import.local,
        ReceiveMode::Blocking,
        &Joins::NONE,
    ) {
        Ok(ep) => ep,
        Err(e) => {
            let _ = ready.send(Err(format!(
                "import '{}' at address {}: {e}",
                import.local, import.addr
            )));
            return;
        }
    };
    let snapshots = Arc::new(Received::default());
    let _subscriber = match mirror::subscribe(
        &cx.session,
        &import.domain,
        &import.module,
        snapshots.clone(),
    ) {
        Ok(s) => s,
        Err(why) => {
            let _ = ready.send(Err(format!("import '{}': {why}", import.local)));
            return;
        }
    };
    let _ = ready.send(Ok(()));
    let mut proxy = Proxy {
        snapshots,
        key: keys::call(&import.domain, &import.module),
        import,
        ep: endpoint,
        served: ServedLog::default(),
        table: None,
        beats: 0,
        frame: Vec::new(),
        out: Vec::new(),
        cx,
    };
    proxy.run();
}

struct Proxy {
    import: Import,
    /// The remote module's newest snapshot, until published here.
    snapshots: Arc<Received>,
    key: String,
    ep: Endpoint,
    served: ServedLog,
    table: Option<Table>,
    beats: u64,
    /// The frame being served (copied out of the inbox: serving it waits on the network).
    frame: Vec<u8>,
    out: Vec<u8>,
    cx: ProxyContext,
}

impl Proxy {
    fn run(&mut self) {
        let mut next_beat = Instant::now();
        while !self.cx.stop.load(Ordering::Relaxed) {
            if Instant::now() >= next_beat {
                self.beat(ModuleState::Running);
                next_beat = Instant::now() + self.cx.heartbeat;
            }
            self.publish_snapshot();
            let mut frame = std::mem::take(&mut self.frame);
            let got = self.ep.rx.try_receive(&mut |bytes| {
                frame.clear();
                frame.extend_from_slice(bytes);
            });
            match got {
                Ok(true) => {
                    self.serve(&frame);
                    self.frame = frame;
                    continue;
                }
                Ok(false) => self.frame = frame,
                Err(e) => {
                    tracing::warn!("import '{}': inbox: {e}", self.import.local);
                    self.frame = frame;
                }
            }
            let until_beat = next_beat.saturating_duration_since(Instant::now());
            // Woken by frames; snapshots are looked for at least every 20 ms.
            if let Err(e) = self.ep.rx.wait(until_beat.min(Duration::from_millis(20))) {
                tracing::warn!("import '{}': wait: {e}", self.import.local);
                std::thread::sleep(Duration::from_millis(10));
            }
        }
        self.beat(ModuleState::Stopping);
    }

    /// Publishes the remote module's snapshot received since, as this proxy's.
    fn publish_snapshot(&mut self) {
        let local = &self.import.local;
        let Some(bytes) = self.snapshots.take_for(self.import.addr, local) else {
            return;
        };
        if let Err(e) = self
            .ep
            .snapshots
            .publish(bytes.len(), &mut |buf| buf.copy_from_slice(&bytes))
        {
            tracing::debug!("import '{local}': snapshot not published: {e}");
        }
    }

    fn beat(&mut self, state: ModuleState) {
        self.beats += 1;
        let digest = self
            .table
            .as_ref()
            .map(|t| methods_digest(t.methods.iter().map(String::as_str)))
            .unwrap_or(0);
        let hb = Heartbeat::new(
            self.import.addr,
            std::process::id(),
            state,
            self.beats,
            Counters::default(),
        )
        .with_methods_digest(digest);
        if let Err(e) = self.ep.tx.heartbeat(hb.as_bytes()) {
            tracing::debug!("import '{}': heartbeat: {e}", self.import.local);
        }
    }

    fn serve(&mut self, bytes: &[u8]) {
        let frame = match Frame::decode(bytes) {
            Ok(f) => f,
            Err(e) => {
                tracing::debug!("import '{}': malformed frame: {e}", self.import.local);
                return;
            }
        };
        if frame.dst() != self.import.addr {
            return;
        }
        match frame.kind() {
            FrameKind::Exec { method } => self.request(&frame, method),
            FrameKind::Retry { method } => {
                match self.served.replay(frame.src(), frame.seq(), method) {
                    Some(Replay::Answer { kind, payload }) => {
                        let payload = payload.to_vec();
                        self.answer(&frame, kind, &payload);
                    }
                    Some(Replay::NotKept { .. }) => {
                        let a = Answer::nak(NakCode::DUPLICATE, "answered already");
                        self.answer(&frame, a.kind, &a.payload);
                    }
                    None => self.request(&frame, method),
                }
            }
            FrameKind::Report { topic } => self.report(&frame, topic),
            FrameKind::Ack | FrameKind::Reply | FrameKind::Nak { .. } => {}
        }
    }

    /// Forwards the request `frame` (method id `method`) and answers it.
    fn request(&mut self, frame: &Frame<'_>, method: u8) {
        let answer = match self.method_name(method) {
            Ok(name) => {
                let a = remote::call(
                    &self.cx.session,
                    &self.key,
                    &name,
                    frame.payload(),
                    self.cx.call_timeout,
                    &self.cx.link,
                );
                if method == sysmethod::DESCRIBE {
                    self.learn(&a);
                }
                a
            }
            Err(a) => a,
        };
        self.answer(frame, answer.kind, &answer.payload);
        self.served.record(
            frame.src(),
            frame.seq(),
            method,
            answer.kind,
            &answer.payload,
        );
    }

    /// The name of method `id` of the remote module, learning its table first if need be.
    fn method_name(&mut self, id: u8) -> Result<String, Answer> {
        if let Some(name) = sysmethod::name(id) {
            return Ok(name.to_owned());
        }
        if let Err(why) = self.cx.link.check() {
            return Err(Answer::nak(NakCode::UNREACHABLE, &why));
        }
        let stale = self
            .table
            .as_ref()
            .is_none_or(|t| t.epoch != self.cx.link.epoch());
        if stale {
            let a = remote::call(
                &self.cx.session,
                &self.key,
                "describe",
                &[],
                self.cx.call_timeout,
                &self.cx.link,
            );
            if !matches!(a.kind, FrameKind::Reply) {
                return Err(a);
            }
            self.learn(&a);
        }
        let table = self.table.as_ref().map(|t| &t.methods);
        match table.and_then(|m| m.get(usize::from(id))) {
            Some(name) => Ok(name.clone()),
            None => Err(Answer::nak(
                NakCode::UNKNOWN_METHOD,
                &format!(
                    "'{}' (module '{}' of remote domain '{}') has no method {id}",
                    self.import.local, self.import.module, self.import.domain
                ),
            )),
        }
    }

    /// Learns the method table from a `describe` answer.
    fn learn(&mut self, a: &Answer) {
        if !matches!(a.kind, FrameKind::Reply) {
            return;
        }
        let Ok(args) = Args::decode(Values::new(&a.payload, 0)) else {
            return;
        };
        if let Ok(methods) = args.text(3) {
            self.table = Some(Table {
                methods: methods
                    .split(',')
                    .filter(|m| !m.is_empty())
                    .map(str::to_owned)
                    .collect(),
                epoch: self.cx.link.epoch(),
            });
        }
    }

    fn answer(&mut self, to: &Frame<'_>, kind: FrameKind, payload: &[u8]) {
        let spec = FrameSpec {
            dst: to.src(),
            src: self.import.addr,
            seq: to.seq(),
            kind,
        };
        let len = spec.encoded_len(payload.len());
        let sent = self.ep.tx.send(Dest::Module(to.src()), len, &mut |buf| {
            let _ = spec.encode(payload, buf);
        });
        if let Err(e) = sent {
            tracing::debug!(
                "import '{}': answer to {}: {e}",
                self.import.local,
                to.src()
            );
        }
    }

    /// Forwards a report to the remote module, named by its sender's local name.
    fn report(&mut self, frame: &Frame<'_>, topic: u8) {
        let from = self.name_of(frame.src());
        let key = keys::report(
            &self.import.domain,
            &self.import.module,
            self.cx.domain.name(),
            &from,
        );
        self.out.clear();
        self.out.push(topic);
        self.out.extend_from_slice(frame.payload());
        if let Err(e) = self.cx.session.put(key, self.out.clone()).wait() {
            tracing::debug!("import '{}': report not forwarded: {e}", self.import.local);
        }
    }

    /// The local name of the module at `addr` (its address in words if the directory does not
    /// know it).
    fn name_of(&self, addr: Addr) -> String {
        let mut found = None;
        let _ = self.ep.directory.list(&mut |p| {
            if p.addr == addr && p.alive {
                found = Some(p.name);
            }
        });
        found.unwrap_or_else(|| format!("addr{}", addr.0))
    }
}
