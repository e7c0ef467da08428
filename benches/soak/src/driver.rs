//! The soak's caller: a tool endpoint of this process, on a thread of its own, that calls
//! `journal.record(seq)` every [`PERIOD`] with a sequence number of its own, and keeps the
//! numbers whose reply came back.
//!
//! The calls use what a caller uses for a call that must not be lost ([`options`]): it waits
//! for the journal while it is down (the call is sent when the module is back, and sent again
//! if the module died with it), and retransmits an unanswered request (the receiver answers a
//! RETRY of a request it served from its record, so that is not executed twice).

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::Context;
use modbot_core::{
    Args, CallError, CallHandle, CallOptions, Ctx, Domain, IpcTransport, ModuleBuilder,
    ReceiveMode, RetryPolicy, Value,
};

use crate::system::JOURNAL;

/// One call this often.
pub const PERIOD: Duration = Duration::from_millis(5);

/// How long a call waits for its reply, retransmissions and the journal's restarts included.
const TIMEOUT: Duration = Duration::from_secs(5);

/// The options of every call: wait for the journal across its restarts, retransmit four times
/// (once a second) while no reply comes.
pub fn options() -> CallOptions {
    CallOptions::timeout(TIMEOUT)
        .waiting_for_peer()
        .with_retry(RetryPolicy { retries: 4 })
}

/// What the driver saw.
#[derive(Debug, Default)]
pub struct Outcome {
    /// Calls made: sequence numbers 1 to this.
    pub issued: u64,
    /// The sequence numbers whose reply came back (with their own number in it).
    pub acknowledged: Vec<u64>,
    /// Calls the runtime refused before sending them, by reason (32 calls outstanding to the
    /// journal while it was stalled, say).
    pub refused: BTreeMap<&'static str, u64>,
    /// Calls sent that ended without a reply, by reason.
    pub failed: BTreeMap<&'static str, u64>,
    /// Replies that carried another call's number: (the call's number, the number in the
    /// reply). The runtime matched another call's answer to this call (0 expected).
    pub misanswered: Vec<(u64, Option<i64>)>,
    /// Calls still waiting when the driver stopped waiting for them.
    pub unfinished: u64,
    /// The longest time from a call to its reply.
    pub slowest: Duration,
}

/// The calls in flight and what came back, kept by the tool endpoint's hook.
#[derive(Default)]
struct State {
    /// Handle → (sequence number, when it was called).
    in_flight: HashMap<u64, (u64, Instant)>,
    outcome: Outcome,
}

/// The driver thread; stopped and joined by [`Driver::finish`] (or on drop).
pub struct Driver {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<anyhow::Result<Outcome>>>,
}

impl Driver {
    /// Starts calling into `domain`'s journal module.
    pub fn start(domain: &Domain) -> anyhow::Result<Driver> {
        let stop = Arc::new(AtomicBool::new(false));
        let (domain, flag) = (domain.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name("soak-driver".into())
            .spawn(move || drive(&domain, &flag))
            .context("cannot start the driver thread")?;
        Ok(Driver {
            stop,
            thread: Some(thread),
        })
    }

    /// Whether the thread ended early (its error comes with [`Driver::finish`]).
    pub fn has_ended(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Stops calling, waits for the calls in flight (up to their timeout) and returns what
    /// the driver saw.
    pub fn finish(mut self) -> anyhow::Result<Outcome> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(outcome)) => outcome,
            Some(Err(_)) => anyhow::bail!("the driver thread panicked"),
            None => anyhow::bail!("the driver was finished before"),
        }
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn drive(domain: &Domain, stop: &AtomicBool) -> anyhow::Result<Outcome> {
    let mut tool = ModuleBuilder::new("soak_driver", 0)
        .mode(ReceiveMode::Blocking)
        .on_done(done)
        .open_tool(IpcTransport::new(domain)?, State::default())
        .context("the driver cannot join the system's domain")?;
    let opts = options();
    let mut next = Instant::now();
    let mut drain_until = None;
    loop {
        let now = Instant::now();
        if drain_until.is_none() && stop.load(Ordering::Relaxed) {
            drain_until = Some(now + TIMEOUT + Duration::from_secs(1));
        }
        if drain_until.is_none() && now >= next {
            let state = tool.state_mut();
            state.outcome.issued += 1;
            let seq = state.outcome.issued;
            let arg = [Value::I64(i64::try_from(seq).unwrap_or(i64::MAX))];
            match tool.ctx().call_with(JOURNAL, "record", &arg, opts) {
                Ok(h) => {
                    tool.state_mut().in_flight.insert(h.id(), (seq, now));
                }
                Err(e) => {
                    *tool
                        .state_mut()
                        .outcome
                        .refused
                        .entry(reason(&e))
                        .or_default() += 1
                }
            }
            // After a stall of this thread, go on at the period rather than catch up at once.
            next = (next + PERIOD).max(now);
        }
        while tool.poll_once()? {}
        tool.housekeeping();
        if let Some(until) = drain_until {
            let waiting = tool.state().in_flight.len() as u64;
            if waiting == 0 || Instant::now() >= until {
                tool.state_mut().outcome.unfinished = waiting;
                break;
            }
        }
        let wait = next.saturating_duration_since(Instant::now()).min(PERIOD);
        tool.wait(wait)?;
    }
    let mut outcome = std::mem::take(&mut tool.state_mut().outcome);
    outcome.acknowledged.sort_unstable();
    Ok(outcome)
}

/// The answer to a call (or its failure): acknowledged when the reply carries the call's own
/// number; a reply with another number is kept apart (it is not this call's answer).
fn done(s: &mut State, _: &mut Ctx, h: CallHandle, answer: Result<&Args<'_>, &CallError>) {
    let Some((seq, called)) = s.in_flight.remove(&h.id()) else {
        return;
    };
    match answer {
        Ok(args) => {
            let got = args.i64(0).ok();
            if got.and_then(|v| u64::try_from(v).ok()) == Some(seq) {
                s.outcome.acknowledged.push(seq);
                s.outcome.slowest = s.outcome.slowest.max(called.elapsed());
            } else {
                s.outcome.misanswered.push((seq, got));
            }
        }
        Err(e) => *s.outcome.failed.entry(reason(e)).or_default() += 1,
    }
}

/// A short name for why a call failed, for the report.
fn reason(e: &CallError) -> &'static str {
    match e {
        CallError::Timeout { .. } => "timeout",
        CallError::NotAvailable { .. } => "not available",
        CallError::UnknownModule(_) => "unknown module",
        CallError::TooManyOutstanding(_) => "32 outstanding",
        CallError::QueueFull(_) => "queue full",
        CallError::Nak { .. } => "refused (NAK)",
        CallError::Send(_) | CallError::Transport(_) => "transport",
        _ => "other",
    }
}
