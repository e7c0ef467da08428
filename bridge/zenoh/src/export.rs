//! The exported side: calls and reports that remote domains send to this domain's modules.
//! The bridge's own module (its name and address in the local domain) makes each call it is
//! asked for, as any caller would — sequence numbers, retransmission, the timeout — and
//! answers the remote bridge with the answer's kind, NAK code and payload as they came. A call
//! of a module or method the description does not export is refused without reaching it.
//!
//! Zenoh hands queries and reports over on its own threads; they come here through a channel,
//! and one thread serves them in order, beside the bridge module's own inbox and the exported
//! modules' snapshots ([`super::mirror`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::Duration;

use modbot_core::transport::Dest;
use modbot_core::{CallError, CallOptions, Module};
use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::{Args, FrameKind, FrameSpec, NakCode, Seq};
use zenoh::query::Query;
use zenoh::{Session, Wait};

use super::config::{Export, Import};
use super::keys;
use super::mirror;
use super::remote::Answer;
use super::wire;

/// What Zenoh's threads hand the exporting thread.
pub enum Work {
    /// A remote caller's query.
    Call(Query),
    /// A report to local module `to` from the remote module `from` of domain `domain`.
    Report {
        domain: String,
        to: String,
        from: String,
        bytes: Vec<u8>,
    },
}

/// The exporting side of a bridge.
pub struct Exporter {
    pub domain: String,
    pub exports: Vec<Export>,
    /// The imports, to name a report's sender by its local proxy.
    pub imports: Vec<Import>,
    /// How long a call of a local module may take.
    pub call_timeout: Duration,
    /// How often the exported modules' blackboard snapshots are put (0: never).
    pub snapshot_hz: f64,
}

impl Exporter {
    /// Serves `work` and the bridge module's own inbox, and puts the exported modules'
    /// snapshots on `session`, until `stop` (or SIGTERM).
    pub fn run(
        &self,
        module: &mut Module<()>,
        work: &Receiver<Work>,
        session: &Session,
        stop: &AtomicBool,
    ) -> Result<(), modbot_core::transport::TransportError> {
        let mut out = Vec::new();
        let mut snapshots = mirror::Publisher::new(self.snapshot_hz);
        while !stop.load(Ordering::Relaxed) && !modbot_core::signals::termination_requested() {
            while module.poll_once()? {}
            module.housekeeping();
            snapshots.publish_due(module, session, &self.domain, &self.exports);
            match work.recv_timeout(Duration::from_millis(5)) {
                Ok(Work::Call(query)) => self.call(module, &query, &mut out),
                Ok(Work::Report {
                    domain,
                    to,
                    from,
                    bytes,
                }) => self.report(module, &domain, &to, &from, &bytes),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        Ok(())
    }

    /// Serves a remote caller's query.
    fn call(&self, module: &mut Module<()>, query: &Query, out: &mut Vec<u8>) {
        let answer = self.answer(module, query);
        wire::put_answer(answer.kind, &answer.payload, out);
        if let Err(e) = query.reply(query.key_expr().clone(), out.clone()).wait() {
            tracing::debug!("answer to a remote call not sent: {e}");
        }
    }

    fn answer(&self, module: &mut Module<()>, query: &Query) -> Answer {
        let refuse = |detail: String| Answer::nak(NakCode::UNKNOWN_METHOD, &detail);
        let Some(name) = keys::call_module(&self.domain, query.key_expr().as_str()) else {
            return refuse(format!(
                "'{}' is no call of domain '{}'",
                query.key_expr(),
                self.domain
            ));
        };
        let payload = query.payload().map(|p| p.to_bytes()).unwrap_or_default();
        let call = match wire::call(&payload) {
            Ok(c) => c,
            Err(e) => return Answer::nak(NakCode::BAD_ARGUMENTS, &format!("malformed call: {e}")),
        };
        let Some(export) = self.exports.iter().find(|e| e.module == name) else {
            return refuse(format!(
                "module '{name}' of domain '{}' is not exported (the description's bridge \
                 exports: {})",
                self.domain,
                self.exported()
            ));
        };
        if !export.allows(call.method) {
            let list = export.methods.as_deref().unwrap_or_default().join(", ");
            return refuse(format!(
                "method '{}' of '{name}' is not exported by domain '{}' (exported: {list})",
                call.method, self.domain
            ));
        }
        let args = match Args::decode(Values::new(call.args, 0)) {
            Ok(a) => a,
            Err(e) => return Answer::nak(NakCode::BAD_ARGUMENTS, &e.to_string()),
        };
        let opts = CallOptions {
            timeout: self.call_timeout,
            ..CallOptions::default()
        };
        module.call_blocking(name, call.method, args.as_slice(), opts, |r| match r {
            Ok(values) => {
                let mut payload = Vec::new();
                for v in values.as_slice() {
                    let _ = v.encode_to_vec(&mut payload);
                }
                Answer {
                    kind: if values.is_empty() {
                        FrameKind::Ack
                    } else {
                        FrameKind::Reply
                    },
                    payload,
                }
            }
            Err(CallError::Nak { code, detail, .. }) => Answer::nak(*code, detail),
            Err(e @ CallError::UnknownMethod { .. }) => {
                Answer::nak(NakCode::UNKNOWN_METHOD, &e.to_string())
            }
            Err(e @ (CallError::UnknownModule(_) | CallError::NotAvailable { .. })) => Answer::nak(
                NakCode::NOT_READY,
                &format!("in domain '{}': {e}", self.domain),
            ),
            Err(e) => Answer::nak(
                NakCode::FAILED,
                &format!("in domain '{}': {e}", self.domain),
            ),
        })
    }

    fn exported(&self) -> String {
        self.exports
            .iter()
            .map(|e| e.module.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Delivers a remote module's report to local module `to`: from that module's proxy here
    /// if this bridge imports it, else from the bridge itself.
    fn report(&self, module: &mut Module<()>, domain: &str, to: &str, from: &str, bytes: &[u8]) {
        if !self.exports.iter().any(|e| e.module == to) {
            tracing::debug!("report to '{to}', which is not exported, dropped");
            return;
        }
        let Some((&topic, values)) = bytes.split_first() else {
            return;
        };
        let peers = match module.list_modules() {
            Ok(p) => p,
            Err(e) => {
                tracing::warn!("report to '{to}' not delivered: {e}");
                return;
            }
        };
        let Some(dst) = peers
            .iter()
            .find(|p| p.alive && p.name == to)
            .map(|p| p.addr)
        else {
            tracing::debug!("report to '{to}', which is not running, dropped");
            return;
        };
        let src = self
            .imports
            .iter()
            .find(|i| i.domain == domain && i.module == from)
            .map(|i| i.addr)
            .unwrap_or(module.addr());
        let spec = FrameSpec {
            dst,
            src,
            seq: Seq::new(0).expect("0 is a sequence number"),
            kind: FrameKind::Report { topic },
        };
        let mut frame = vec![0; spec.encoded_len(values.len())];
        if spec.encode(values, &mut frame).is_ok() {
            if let Err(e) = module.ctx().send_bytes(Dest::Module(dst), &frame) {
                tracing::debug!("report to '{to}' not delivered: {e}");
            }
        }
    }
}
