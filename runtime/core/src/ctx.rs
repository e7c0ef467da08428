//! What a module's code can do: call, report, read snapshots, use its blackboard.

use core::time::Duration;
use std::sync::Arc;

use modbot_ipc_schema::heartbeat::{Counters, ModuleState};
use modbot_ipc_schema::{sysmethod, value, Addr, FrameKind, FrameSpec, Seq, SnapshotView, Value};

use crate::beat::Heartbeats;
use crate::blackboard::Blackboard;
use crate::calls::{CallHandle, CallOptions, MethodQueue, Purpose, Resend};
use crate::clock::Clock;
use crate::error::CallError;
use crate::phonebook::PhoneBook;
use crate::served::ServedLog;
use crate::stats::Stats;
use crate::transport::{Dest, Directory, ReceiveMode, SendError, Snapshots, Tx};

/// A call that waits to be sent: its peer's method table is not learned yet, or the peer is
/// down and the caller chose to wait for it.
#[derive(Debug)]
pub(crate) struct PendingCall {
    pub handle: CallHandle,
    pub addr: Addr,
    pub seq: Seq,
    pub method: String,
    pub payload: Vec<u8>,
    pub wait_for_peer: bool,
    /// Whether the payload is kept for retransmission once sent.
    pub keep: bool,
}

/// The calls a module makes: the method queue and what waits beside it.
pub(crate) struct Outgoing {
    pub(crate) calls: MethodQueue,
    /// Calls not sent yet: their peer's method table is not learned, or the peer is down.
    pub(crate) pending: Vec<PendingCall>,
    /// Calls that ended without an answer, to hand to the application.
    pub(crate) failures: Vec<(CallHandle, CallError)>,
    /// Peers whose `describe` is in flight.
    pub(crate) describing: [bool; 256],
    /// Answers that matched no waiting call (late, after a timeout).
    pub(crate) stale: u64,
}

impl Default for Outgoing {
    fn default() -> Self {
        Outgoing {
            calls: MethodQueue::default(),
            pending: Vec::new(),
            failures: Vec::new(),
            describing: [false; 256],
            stale: 0,
        }
    }
}

/// The frames a module serves: whose frame is being served, what was served lately, and what
/// was refused.
pub(crate) struct Serving {
    /// The module whose frame is being served.
    pub(crate) caller: Addr,
    /// The requests served lately, to answer their retransmissions.
    pub(crate) served: ServedLog,
    /// Retransmitted requests answered from that record.
    pub(crate) replayed: u64,
    /// Malformed or misrouted frames received and dropped.
    pub(crate) rejected: u64,
    /// Handing over to the process of a live upgrade ([`crate::upgrade`]).
    pub(crate) handover: Option<crate::upgrade::Outgoing>,
}

impl Default for Serving {
    fn default() -> Self {
        Serving {
            caller: Addr::NONE,
            served: ServedLog::default(),
            replayed: 0,
            rejected: 0,
            handover: None,
        }
    }
}

/// A module's side of the runtime, lent to its methods and tasks.
pub struct Ctx {
    /// Its address in the domain.
    pub(crate) addr: Addr,
    /// Its name in the phone book.
    pub(crate) name: String,
    /// How it waits for frames (blocking or busy).
    pub(crate) mode: ReceiveMode,
    /// Its endpoint's sending side, snapshots and directory.
    pub(crate) link: Link,
    /// This module's blackboard.
    pub bb: Blackboard,
    /// The calls this module makes.
    pub(crate) out: Outgoing,
    /// The other modules it knows: addresses, liveness, method tables.
    pub(crate) book: PhoneBook,
    /// Its time (injected, so tests control it).
    pub(crate) clock: Arc<dyn Clock>,
    /// The frames it serves.
    pub(crate) serving: Serving,
    /// Traffic and call counters and the call latency histogram (the `stats` system method).
    pub(crate) stats: Stats,
    /// Whether it goes on, is active, and beats.
    pub(crate) liveness: Liveness,
}

/// What a module reaches the domain through: its endpoint's parts.
pub(crate) struct Link {
    /// Sends frames to other modules' inboxes.
    pub(crate) tx: Box<dyn Tx>,
    /// Publishes its blackboard and reads others'.
    pub(crate) snapshots: Box<dyn Snapshots>,
    /// The domain's directory of modules.
    pub(crate) directory: Box<dyn Directory>,
}

/// Whether a module goes on, whether the operator left it active, and its heartbeats.
pub(crate) struct Liveness {
    /// Its code asked it to stop ([`Ctx::stop`]).
    pub(crate) stop: bool,
    /// Whether the operator left the module active (`activate`/`deactivate`): while not, its
    /// own methods answer NAK not-ready and its tasks do not run.
    pub(crate) active: bool,
    /// Its heartbeats.
    pub(crate) heartbeats: Heartbeats,
}

impl Ctx {
    pub fn addr(&self) -> Addr {
        self.addr
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// The address of the module whose call or report is being served.
    pub fn caller(&self) -> Addr {
        self.serving.caller
    }

    pub fn now_ns(&self) -> u64 {
        self.clock.now_ns()
    }

    /// Sends a heartbeat if one is due. The message manager beats between the frames it serves;
    /// a method that waits long (for a file to close, a device to answer) calls this while it
    /// waits, or the supervisor, hearing nothing for the heartbeat timeout, judges the module
    /// hung and kills it.
    pub fn keep_alive(&mut self) {
        if self.liveness.heartbeats.due(self.now_ns()) {
            self.beat(ModuleState::Running);
        }
    }

    /// Publishes a heartbeat now.
    pub(crate) fn beat(&mut self, state: ModuleState) {
        let counters = Counters {
            dropped: self.link.tx.dropped(),
            rejected: self.serving.rejected,
            replayed: self.serving.replayed,
        };
        self.liveness
            .heartbeats
            .send(self.link.tx.as_mut(), self.addr, state, counters);
    }

    /// Asks the main loop to stop after this step.
    pub fn stop(&mut self) {
        self.liveness.stop = true;
    }

    pub fn phone_book(&self) -> &PhoneBook {
        &self.book
    }

    /// Frames received malformed or misrouted, and dropped.
    pub fn rejected(&self) -> u64 {
        self.serving.rejected
    }

    /// Frames this module could not deliver.
    pub fn dropped(&self) -> u64 {
        self.link.tx.dropped()
    }

    /// This module's traffic and call counters and its call latencies, as the `stats` system
    /// method answers them.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Whether the module is active: an operator can deactivate it (the `deactivate` system
    /// method), and then it refuses its own methods and pauses its periodic tasks.
    pub fn is_active(&self) -> bool {
        self.liveness.active
    }

    /// Calls `method` of `module` with the default options; the answer comes to the module's
    /// `on_done` hook (or to [`crate::Module::call_blocking`]).
    pub fn call(
        &mut self,
        module: &str,
        method: &str,
        args: &[Value<'_>],
    ) -> Result<CallHandle, CallError> {
        self.call_with(module, method, args, CallOptions::default())
    }

    /// Calls `method` of `module`.
    pub fn call_with(
        &mut self,
        module: &str,
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
    ) -> Result<CallHandle, CallError> {
        // The same method as last time, and the book has not changed since: nothing to look up.
        let resolved = self.book.resolved(module, method);
        let addr = match resolved {
            Some((addr, _)) => addr,
            None => self.address_of(module, opts)?,
        };
        let (handle, seq) = self.out.calls.begin(addr, opts, Purpose::User)?;
        let id = match resolved {
            Some((_, id)) => Some(Ok(id)),
            None => self.book.method_id(addr, method),
        };
        let started = match id {
            Some(Ok(id)) => {
                let sent = self.send_call(handle, (addr, seq, id), method, args, opts);
                let learnt = resolved.is_none() && sent.is_ok();
                if learnt && self.book.get(addr).is_some_and(|e| e.alive) {
                    self.book.remember(module, method, addr, id);
                }
                sent
            }
            Some(Err(e)) => {
                self.out.calls.cancel(handle);
                Err(e)
            }
            None => {
                self.park(handle, addr, seq, method, args, opts)?;
                self.describe(addr);
                Ok(handle)
            }
        };
        if started.is_ok() {
            self.stats.calls += 1;
        }
        started
    }

    /// The address of `module`, from the book (read again if it does not know the module);
    /// with `opts.wait_for_peer`, that of a module that is down but known.
    fn address_of(&mut self, module: &str, opts: CallOptions) -> Result<Addr, CallError> {
        if let Ok(e) = self.book.lookup(module) {
            return Ok(e.addr);
        }
        self.refresh_book();
        match self.book.lookup(module) {
            Ok(e) => Ok(e.addr),
            // Down, but known: a caller that waits for it sends to its address, where it comes
            // back.
            Err(CallError::NotAvailable { .. }) if opts.wait_for_peer => {
                match self.book.entries().find(|e| e.name == module) {
                    Some(e) => Ok(e.addr),
                    None => Err(CallError::UnknownModule(module.to_owned())),
                }
            }
            Err(e) => Err(e),
        }
    }

    /// Sends call `handle`; a peer that is down or full parks it if the caller waits for the
    /// peer, any other failure ends it.
    fn send_call(
        &mut self,
        handle: CallHandle,
        (addr, seq, id): (Addr, Seq, u8),
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
    ) -> Result<CallHandle, CallError> {
        match self.send_exec(handle, (addr, seq, id), args, opts.keeps_payload()) {
            Ok(()) => Ok(handle),
            Err(CallError::Send(SendError::NoReceiver(_) | SendError::InboxFull(_)))
                if opts.wait_for_peer =>
            {
                self.park(handle, addr, seq, method, args, opts)?;
                Ok(handle)
            }
            Err(e) => {
                self.out.calls.cancel(handle);
                Err(self.explain(addr, e))
            }
        }
    }

    /// Sends call `handle` to `addr` as an EXEC of method `id` with `args`, encoded straight
    /// into the sample. What the answer does not wait for comes after the send: the clock read
    /// that starts the call's timeout, and with `keep` the payload encoded again into the call's
    /// retransmission buffer (the caller's next step is to wait for the answer, which takes
    /// longer than either).
    fn send_exec(
        &mut self,
        handle: CallHandle,
        (addr, seq, id): (Addr, Seq, u8),
        args: &[Value<'_>],
        keep: bool,
    ) -> Result<(), CallError> {
        let spec = FrameSpec {
            dst: addr,
            src: self.addr,
            seq,
            kind: FrameKind::Exec { method: id },
        };
        self.send_values(Dest::Module(addr), spec, args)?;
        let now = self.now_ns();
        let kept = keep
            && match self.out.calls.payload_buffer(handle) {
                // It was encoded once into the sample: it encodes again.
                Some(buf) => encode_into(args, buf).is_ok(),
                None => false,
            };
        self.out.calls.sent(handle, id, now, kept);
        Ok(())
    }

    fn park(
        &mut self,
        handle: CallHandle,
        addr: Addr,
        seq: Seq,
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
    ) -> Result<(), CallError> {
        let mut payload = Vec::with_capacity(value::encoded_len(args));
        if let Err(e) = encode_into(args, &mut payload) {
            self.out.calls.cancel(handle);
            return Err(e);
        }
        // Its timeout runs while it waits to be sent.
        let now = self.now_ns();
        self.out.calls.start(handle, now);
        self.out.pending.push(PendingCall {
            handle,
            addr,
            seq,
            method: method.to_owned(),
            payload,
            wait_for_peer: opts.wait_for_peer,
            keep: opts.keeps_payload(),
        });
        Ok(())
    }

    /// Turns a send failure into what the caller should read.
    /// Opens the link to module `addr` now rather than at the first frame sent to it (a
    /// supervisor connects to its modules ahead of its first call).
    pub fn connect(&mut self, addr: Addr) -> Result<(), crate::transport::SendError> {
        self.link.tx.connect(addr)
    }

    pub(crate) fn explain(&self, addr: Addr, e: CallError) -> CallError {
        let name = self
            .book
            .get(addr)
            .map(|e| e.name.clone())
            .unwrap_or_else(|| format!("module {addr}"));
        match e {
            CallError::Send(SendError::NoReceiver(_)) => CallError::NotAvailable {
                name,
                why: "it is not running".into(),
            },
            CallError::Send(SendError::InboxFull(_)) => CallError::NotAvailable {
                name,
                why: "its inbox is full".into(),
            },
            other => other,
        }
    }

    /// Sends `describe` to `addr` unless one is in flight.
    pub(crate) fn describe(&mut self, addr: Addr) {
        if self.out.describing[usize::from(addr.0)] {
            return;
        }
        let opts = CallOptions::timeout(Duration::from_millis(1000));
        let Ok((handle, seq)) = self.out.calls.begin(addr, opts, Purpose::Describe) else {
            return;
        };
        match self.send_exec(handle, (addr, seq, sysmethod::DESCRIBE), &[], true) {
            Ok(()) => self.out.describing[usize::from(addr.0)] = true,
            Err(e) => {
                tracing::debug!("cannot ask module {addr} for its methods: {e}");
                self.out.calls.cancel(handle);
            }
        }
    }

    /// The directory entry of the caller being served (its name and pid), the directory read
    /// again if the caller is new to this module's phone book; `None` for a caller the
    /// directory does not have alive. A caller that took the address of one that ended since
    /// the book was last read is seen as that one until it is read again: what must be sure of
    /// the caller's process asks the caller (the coordinator's gate takes the pid it is given).
    pub fn caller_entry(&mut self) -> Option<&crate::phonebook::Entry> {
        let caller = self.caller();
        if !self.book.get(caller).is_some_and(|e| e.alive) {
            self.refresh_book();
        }
        self.book.get(caller).filter(|e| e.alive)
    }

    /// Re-reads the directory now.
    pub(crate) fn refresh_book(&mut self) -> crate::phonebook::Changes {
        match self.book.refresh(self.link.directory.as_ref()) {
            Ok(c) => c,
            Err(e) => {
                tracing::warn!("phone book refresh failed: {e}");
                Default::default()
            }
        }
    }

    /// Sends a REPORT to `to` (a module, every module, or a group).
    pub fn report(
        &mut self,
        to: Dest<'_>,
        topic: u8,
        values: &[Value<'_>],
    ) -> Result<(), CallError> {
        let dst = match to {
            Dest::Module(a) => a,
            Dest::Broadcast | Dest::Group(_) => Addr::BROADCAST,
        };
        let spec = FrameSpec {
            dst,
            src: self.addr,
            seq: Seq::default(),
            kind: FrameKind::Report { topic },
        };
        self.send_values(to, spec, values)
    }

    /// Sends `bytes` to `to` exactly as they are, unchecked: for tools and fault injection
    /// (a receiver must count and drop what is malformed).
    pub fn send_bytes(&mut self, to: Dest<'_>, bytes: &[u8]) -> Result<(), SendError> {
        self.link
            .tx
            .send(to, bytes.len(), &mut |buf| buf.copy_from_slice(bytes))?;
        self.stats.frames_sent += 1;
        Ok(())
    }

    /// Resolves a module name to its address through the phone book.
    pub fn resolve(&mut self, module: &str) -> Result<Addr, CallError> {
        match self.book.lookup(module) {
            Ok(e) => Ok(e.addr),
            Err(_) => {
                self.refresh_book();
                Ok(self.book.lookup(module)?.addr)
            }
        }
    }

    /// Sends a REPORT to the module named `module`.
    pub fn report_to(
        &mut self,
        module: &str,
        topic: u8,
        values: &[Value<'_>],
    ) -> Result<(), CallError> {
        let addr = self.book.lookup(module).map(|e| e.addr);
        let addr = match addr {
            Ok(a) => a,
            Err(_) => {
                self.refresh_book();
                self.book.lookup(module)?.addr
            }
        };
        self.report(Dest::Module(addr), topic, values)
            .map_err(|e| self.explain(addr, e))
    }

    /// Encodes a frame with `values` straight into the transport's buffer and sends it.
    pub(crate) fn send_values(
        &mut self,
        to: Dest<'_>,
        spec: FrameSpec,
        values: &[Value<'_>],
    ) -> Result<(), CallError> {
        let len = spec.encoded_len(value::encoded_len(values));
        self.send_frame(to, len, &mut |buf| spec.encode_values(values, buf))
    }

    /// Sends a frame whose payload is already encoded.
    pub(crate) fn send_raw(
        &mut self,
        to: Dest<'_>,
        spec: FrameSpec,
        payload: &[u8],
    ) -> Result<(), CallError> {
        let len = spec.encoded_len(payload.len());
        self.send_frame(to, len, &mut |buf| spec.encode(payload, buf))
    }

    /// Sends a frame of `len` bytes that `encode` writes in place, and counts it.
    fn send_frame<E: core::fmt::Display>(
        &mut self,
        to: Dest<'_>,
        len: usize,
        encode: &mut dyn FnMut(&mut [u8]) -> Result<usize, E>,
    ) -> Result<(), CallError> {
        let mut result = Ok(0);
        self.link
            .tx
            .send(to, len, &mut |buf| result = encode(buf))?;
        self.stats.frames_sent += 1;
        result
            .map(|_| ())
            .map_err(|e| CallError::Encode(e.to_string()))
    }

    /// Reads the newest blackboard snapshot of `module`, in place.
    ///
    /// Returns `Ok(None)` if none has arrived yet.
    pub fn snapshot_of<R>(
        &mut self,
        module: &str,
        read: impl FnOnce(SnapshotView<'_>) -> R,
    ) -> Result<Option<R>, CallError> {
        let addr = match self.book.lookup(module) {
            Ok(e) => e.addr,
            Err(_) => {
                self.refresh_book();
                self.book.lookup(module)?.addr
            }
        };
        let mut read = Some(read);
        let mut out = None;
        let mut bad = None;
        self.link
            .snapshots
            .read_latest(addr, &mut |bytes| match SnapshotView::parse(bytes) {
                Ok(view) => out = read.take().map(|f| f(view)),
                Err(e) => bad = Some(e.to_string()),
            })?;
        if let Some(detail) = bad {
            return Err(CallError::BadAnswer {
                module: module.to_owned(),
                detail,
            });
        }
        Ok(out)
    }

    /// Fails every call waiting for the method table of `addr` with `err`.
    pub(crate) fn fail_pending(&mut self, addr: Addr, err: &CallError) {
        let mut i = 0;
        while i < self.out.pending.len() {
            if self.out.pending[i].addr != addr {
                i += 1;
                continue;
            }
            let p = self.out.pending.swap_remove(i);
            if self.out.calls.is_waiting(p.handle) {
                self.out.calls.cancel(p.handle);
                self.out.failures.push((p.handle, err.clone()));
            }
        }
    }

    /// Sends the calls that wait for a method table or for their peer, where they now can go.
    pub(crate) fn flush_pending(&mut self) {
        if self.out.pending.is_empty() {
            return;
        }
        let mut i = 0;
        while i < self.out.pending.len() {
            let p = &self.out.pending[i];
            if !self.out.calls.is_waiting(p.handle) {
                self.out.pending.swap_remove(i); // expired meanwhile; already reported
                continue;
            }
            let id = match self.book.method_id(p.addr, &p.method) {
                None => {
                    let addr = p.addr;
                    if self.book.get(addr).is_some_and(|e| e.alive) {
                        self.describe(addr);
                    }
                    i += 1;
                    continue;
                }
                Some(Err(e)) => {
                    let p = self.out.pending.swap_remove(i);
                    self.out.calls.cancel(p.handle);
                    self.out.failures.push((p.handle, e));
                    continue;
                }
                Some(Ok(id)) => id,
            };
            let p = self.out.pending.swap_remove(i);
            let spec = FrameSpec {
                dst: p.addr,
                src: self.addr,
                seq: p.seq,
                kind: FrameKind::Exec { method: id },
            };
            match self.send_raw(Dest::Module(p.addr), spec, &p.payload) {
                Ok(()) => {
                    let now = self.now_ns();
                    self.out.calls.sent(p.handle, id, now, p.keep);
                    if p.keep {
                        if let Some(slot) = self.out.calls.payload_buffer(p.handle) {
                            *slot = p.payload;
                        }
                    }
                }
                Err(CallError::Send(SendError::NoReceiver(_) | SendError::InboxFull(_)))
                    if p.wait_for_peer =>
                {
                    self.out.pending.push(p);
                    i += 1;
                }
                Err(e) => {
                    self.out.calls.cancel(p.handle);
                    let e = self.explain(p.addr, e);
                    self.out.failures.push((p.handle, e));
                }
            }
        }
    }
}

/// Encodes `args` at the end of `out`.
fn encode_into(args: &[Value<'_>], out: &mut Vec<u8>) -> Result<(), CallError> {
    for a in args {
        a.encode_to_vec(out)
            .map_err(|e| CallError::Encode(e.to_string()))?;
    }
    Ok(())
}

/// Sends a request again, as a RETRY frame.
pub(crate) fn send_retry(tx: &mut dyn Tx, me: Addr, r: Resend<'_>) -> Result<(), SendError> {
    let spec = FrameSpec {
        dst: r.peer,
        src: me,
        seq: r.seq,
        kind: FrameKind::Retry { method: r.method },
    };
    let len = spec.encoded_len(r.payload.len());
    tx.send(Dest::Module(r.peer), len, &mut |buf| {
        // The buffer is exactly `len` bytes and `me` is this module's address: encoding
        // an already encoded payload cannot fail here.
        if let Err(e) = spec.encode(r.payload, buf) {
            tracing::warn!("retry to {} not encoded: {e}", r.peer);
        }
    })
}
