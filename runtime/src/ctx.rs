//! What a module's code can do: call, report, read snapshots, use its blackboard.

use core::time::Duration;
use std::sync::Arc;

use modbot_ipc_schema::{sysmethod, value, Addr, FrameKind, FrameSpec, Seq, SnapshotView, Value};

use crate::blackboard::Blackboard;
use crate::calls::{CallHandle, CallOptions, MethodQueue, Purpose};
use crate::clock::Clock;
use crate::error::CallError;
use crate::phonebook::PhoneBook;
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
}

/// A module's side of the runtime, lent to its methods and tasks.
pub struct Ctx {
    pub(crate) addr: Addr,
    pub(crate) name: String,
    pub(crate) mode: ReceiveMode,
    pub(crate) tx: Box<dyn Tx>,
    pub(crate) snapshots: Box<dyn Snapshots>,
    pub(crate) directory: Box<dyn Directory>,
    /// This module's blackboard.
    pub bb: Blackboard,
    pub(crate) calls: MethodQueue,
    pub(crate) book: PhoneBook,
    pub(crate) clock: Arc<dyn Clock>,
    pub(crate) pending: Vec<PendingCall>,
    /// Calls that ended without an answer, to hand to the application.
    pub(crate) failures: Vec<(CallHandle, CallError)>,
    /// Peers whose `describe` is in flight.
    pub(crate) describing: [bool; 256],
    /// Malformed or misrouted frames received and dropped.
    pub(crate) rejected: u64,
    /// Answers that matched no waiting call (late, after a timeout).
    pub(crate) stale: u64,
    pub(crate) stop: bool,
    /// The module whose frame is being served.
    pub(crate) caller: Addr,
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
        self.caller
    }

    pub fn now_ns(&self) -> u64 {
        self.clock.now_ns()
    }

    /// Asks the main loop to stop after this step.
    pub fn stop(&mut self) {
        self.stop = true;
    }

    pub fn phone_book(&self) -> &PhoneBook {
        &self.book
    }

    /// Frames received malformed or misrouted, and dropped.
    pub fn rejected(&self) -> u64 {
        self.rejected
    }

    /// Frames this module could not deliver.
    pub fn dropped(&self) -> u64 {
        self.tx.dropped()
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
        let addr = match self.book.lookup(module) {
            Ok(e) => e.addr,
            Err(_) => {
                self.refresh_book();
                match self.book.lookup(module) {
                    Ok(e) => e.addr,
                    Err(e) => return Err(e),
                }
            }
        };
        let now = self.now_ns();
        let (handle, seq) = self.calls.begin(addr, now, opts.timeout, Purpose::User)?;
        match self.book.method_id(addr, method) {
            Some(Ok(id)) => {
                let spec = FrameSpec {
                    dst: addr,
                    src: self.addr,
                    seq,
                    kind: FrameKind::Exec { method: id },
                };
                match self.send_values(Dest::Module(addr), spec, args) {
                    Ok(()) => Ok(handle),
                    Err(CallError::Send(SendError::NoReceiver(_) | SendError::InboxFull(_)))
                        if opts.wait_for_peer =>
                    {
                        self.park(handle, addr, seq, method, args, true)?;
                        Ok(handle)
                    }
                    Err(e) => {
                        self.calls.cancel(handle);
                        Err(self.explain(addr, e))
                    }
                }
            }
            Some(Err(e)) => {
                self.calls.cancel(handle);
                Err(e)
            }
            None => {
                self.park(handle, addr, seq, method, args, opts.wait_for_peer)?;
                self.describe(addr);
                Ok(handle)
            }
        }
    }

    fn park(
        &mut self,
        handle: CallHandle,
        addr: Addr,
        seq: Seq,
        method: &str,
        args: &[Value<'_>],
        wait_for_peer: bool,
    ) -> Result<(), CallError> {
        let mut payload = Vec::with_capacity(value::encoded_len(args));
        for a in args {
            a.encode_to_vec(&mut payload)
                .map_err(|e| CallError::Encode(e.to_string()))?;
        }
        self.pending.push(PendingCall {
            handle,
            addr,
            seq,
            method: method.to_owned(),
            payload,
            wait_for_peer,
        });
        Ok(())
    }

    /// Turns a send failure into what the caller should read.
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
        if self.describing[usize::from(addr.0)] {
            return;
        }
        let now = self.now_ns();
        let Ok((handle, seq)) =
            self.calls
                .begin(addr, now, Duration::from_millis(1000), Purpose::Describe)
        else {
            return;
        };
        let spec = FrameSpec {
            dst: addr,
            src: self.addr,
            seq,
            kind: FrameKind::Exec {
                method: sysmethod::DESCRIBE,
            },
        };
        match self.send_values(Dest::Module(addr), spec, &[]) {
            Ok(()) => self.describing[usize::from(addr.0)] = true,
            Err(_) => self.calls.cancel(handle),
        }
    }

    /// Re-reads the directory now.
    pub(crate) fn refresh_book(&mut self) -> crate::phonebook::Changes {
        match self.book.refresh(self.directory.as_ref()) {
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
        let payload_len = value::encoded_len(values);
        let len = spec.encoded_len(payload_len);
        let mut result = Ok(0);
        self.tx
            .send(to, len, &mut |buf| result = spec.encode_values(values, buf))?;
        result
            .map(|_| ())
            .map_err(|e| CallError::Encode(e.to_string()))
    }

    /// Sends a frame whose payload is already encoded.
    pub(crate) fn send_raw(
        &mut self,
        to: Dest<'_>,
        spec: FrameSpec,
        payload: &[u8],
    ) -> Result<(), CallError> {
        let len = spec.encoded_len(payload.len());
        let mut result = Ok(0);
        self.tx
            .send(to, len, &mut |buf| result = spec.encode(payload, buf))?;
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
        self.snapshots
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

    /// Sends the calls that wait for a method table or for their peer, where they now can go.
    pub(crate) fn flush_pending(&mut self) {
        if self.pending.is_empty() {
            return;
        }
        let mut i = 0;
        while i < self.pending.len() {
            let p = &self.pending[i];
            if !self.calls.is_waiting(p.handle) {
                self.pending.swap_remove(i); // expired meanwhile; already reported
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
                    let p = self.pending.swap_remove(i);
                    self.calls.cancel(p.handle);
                    self.failures.push((p.handle, e));
                    continue;
                }
                Some(Ok(id)) => id,
            };
            let p = self.pending.swap_remove(i);
            let spec = FrameSpec {
                dst: p.addr,
                src: self.addr,
                seq: p.seq,
                kind: FrameKind::Exec { method: id },
            };
            match self.send_raw(Dest::Module(p.addr), spec, &p.payload) {
                Ok(()) => {}
                Err(CallError::Send(SendError::NoReceiver(_) | SendError::InboxFull(_)))
                    if p.wait_for_peer =>
                {
                    self.pending.push(p);
                    i += 1;
                }
                Err(e) => {
                    self.calls.cancel(p.handle);
                    let e = self.explain(p.addr, e);
                    self.failures.push((p.handle, e));
                }
            }
        }
    }
}
