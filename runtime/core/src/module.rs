//! A module: its name, address, method table and hooks, and the message manager that serves
//! them.
//!
//! - `builder`: [`ModuleBuilder`], declaring a module and opening it in a domain;
//! - this file: [`Module`], a running module (serving, housekeeping, calls, heartbeats);
//! - `closed`: what stands in for the endpoint after the module released it;
//! - `look`: looking for a frame before sleeping (blocking calls, lingering after serving);
//! - `handover`: both sides of a live upgrade ([`crate::upgrade`]).

mod builder;
mod closed;
mod handover;
mod look;

pub use builder::ModuleBuilder;
use closed::Closed;
use look::{realtime_thread, Look};

use core::time::Duration;

use modbot_ipc_schema::heartbeat::ModuleState;
use modbot_ipc_schema::{Addr, Args, OwnedValue, Value};

use crate::calls::{owned_answer, CallOptions, Purpose};
use crate::ctx::Ctx;
use crate::error::{CallError, ModuleError};
pub use crate::hooks::{
    ActivationFn, DoneFn, MethodFn, Reply, Report, ReportFn, TaskFn, UpgradeInFn, UpgradeOutFn,
};
pub(crate) use crate::hooks::{Definition, Waiter};
use crate::manager;
use crate::transport::{PeerInfo, ReceiveMode, Rx, Transport, TransportError};

/// A running module: its state, its context and its endpoint.
pub struct Module<S> {
    def: Definition<S>,
    state: S,
    ctx: Ctx,
    rx: Box<dyn Rx>,
    transport: Box<dyn Transport>,
    next_task_ns: Vec<u64>,
    next_refresh_ns: u64,
    last_snapshot_ns: u64,
    reply: Reply,
    /// The generation of the published directory the phone book last took in.
    book_generation: u64,
    /// How blocking calls' looks for their answers fared ([`CallOptions::spin`]).
    answer_look: Look,
    /// How lingering after a served frame fared ([`ModuleBuilder::linger`]), and how long.
    linger: Look,
    linger_span: Duration,
    /// Whether the module's thread ran under SCHED_FIFO or SCHED_RR at its last heartbeat (the
    /// supervisor may set the policy after the module started): it never looks.
    realtime: bool,
}

/// [`ModuleBuilder::linger`] by default: the same as a blocking call's look for its answer
/// ([`crate::calls::DEFAULT_CALL_SPIN`]), about one wake-up of a halted core on the machines
/// modbot is measured on.
pub const DEFAULT_LINGER: Duration = crate::calls::DEFAULT_CALL_SPIN;

/// The longest a module in blocking mode sleeps without a frame or a due deadline.
const MAX_IDLE_NS: u64 = 1_000_000_000;

/// How often the phone book re-reads a scanned directory (liveness, new modules); a published
/// one is read when it changes.
const REFRESH_NS: u64 = 200_000_000;

impl<S> Module<S> {
    pub fn state(&self) -> &S {
        &self.state
    }

    pub fn state_mut(&mut self) -> &mut S {
        &mut self.state
    }

    pub fn ctx(&mut self) -> &mut Ctx {
        &mut self.ctx
    }

    pub fn addr(&self) -> Addr {
        self.ctx.addr
    }

    pub fn mode(&self) -> ReceiveMode {
        self.ctx.mode
    }

    /// The digest of this module's method names (in its heartbeats and the directory).
    pub fn methods_digest(&self) -> u32 {
        self.ctx.liveness.heartbeats.methods_digest
    }

    /// Every module of the domain as the directory sees it now.
    pub fn list_modules(&self) -> Result<Vec<PeerInfo>, TransportError> {
        let mut out = Vec::new();
        self.ctx.link.directory.list(&mut |p| out.push(p))?;
        out.sort_by_key(|p| (p.addr, !p.alive));
        Ok(out)
    }

    /// Removes resources left by dead modules.
    pub fn reap_dead(&self) -> usize {
        self.ctx.link.directory.reap_dead()
    }

    /// Sleeps until a frame arrives in the inbox or `timeout` passed (a loop that also waits
    /// for other things calls this instead of sleeping, so calls are answered at once).
    pub fn wait_for_frame(&mut self, timeout: Duration) -> Result<(), TransportError> {
        self.rx.wait(timeout)
    }

    /// Serves at most one waiting frame; returns whether there was one.
    pub fn poll_once(&mut self) -> Result<bool, TransportError> {
        self.poll_with(&mut None)
    }

    fn poll_with(&mut self, waiter: &mut Waiter<'_>) -> Result<bool, TransportError> {
        let (def, state, ctx, reply) = (&self.def, &mut self.state, &mut self.ctx, &mut self.reply);
        self.rx.try_receive(&mut |bytes| {
            if let Some(out) = ctx.serving.handover.as_mut() {
                if let crate::upgrade::Route::Done = crate::upgrade::route(out, bytes) {
                    return;
                }
            }
            manager::dispatch(def, state, ctx, reply, bytes, waiter)
        })
    }

    /// Periodic work: due tasks, call deadlines, liveness, pending sends, snapshots.
    pub fn housekeeping(&mut self) {
        self.housekeeping_with(&mut None);
    }

    fn housekeeping_with(&mut self, waiter: &mut Waiter<'_>) {
        let now = self.ctx.now_ns();
        if self.ctx.serving.handover.is_some() {
            // Not inside a blocking call: the handover ends with the inbox given up.
            self.handover_step(now, waiter.is_none());
        }
        let handing_over = self.ctx.serving.handover.is_some() || self.ctx.liveness.stop;
        for i in 0..self.def.tasks.len() {
            if now >= self.next_task_ns[i] {
                let (period, f) = self.def.tasks[i];
                let period = period.as_nanos() as u64;
                self.next_task_ns[i] = if now - self.next_task_ns[i] > period {
                    now + period
                } else {
                    self.next_task_ns[i] + period
                };
                // Deactivated: the beat is skipped, so the task resumes on its grid. Handing
                // over: the new process runs the tasks from now on.
                if self.ctx.liveness.active && !handing_over {
                    f(&mut self.state, &mut self.ctx);
                }
            }
        }
        let ctx = &mut self.ctx;
        let (failures, book, describing) =
            (&mut ctx.out.failures, &ctx.book, &mut ctx.out.describing);
        let (tx, me, sent) = (&mut ctx.link.tx, ctx.addr, &mut ctx.stats.frames_sent);
        ctx.out.calls.expire(
            now,
            |e| {
                let name = book
                    .get(e.peer)
                    .map(|x| x.name.clone())
                    .unwrap_or_else(|| format!("module {}", e.peer));
                match e.purpose {
                    Purpose::User => failures.push((
                        e.handle,
                        CallError::Timeout {
                            module: name,
                            timeout_ms: e.timeout.as_millis() as u64,
                            sends: e.sends,
                        },
                    )),
                    Purpose::Describe => describing[usize::from(e.peer.0)] = false,
                }
            },
            |r| {
                let peer = r.peer;
                match crate::ctx::send_retry(tx.as_mut(), me, r) {
                    Ok(()) => *sent += 1,
                    Err(e) => tracing::debug!("retransmission to {peer} not delivered: {e}"),
                }
            },
        );
        // A published directory says when it changed; a scanned one is read on a timer.
        let directory_due = if self.ctx.link.directory.published() {
            let generation = self.ctx.link.directory.generation();
            let due = generation != self.book_generation;
            self.book_generation = generation;
            due
        } else {
            now >= self.next_refresh_ns
        };
        if directory_due {
            self.next_refresh_ns = now + REFRESH_NS;
            let changes = self.ctx.refresh_book();
            if !changes.died.is_empty() {
                self.ctx.link.directory.reap_dead();
            }
            for addr in changes.died {
                let name = self
                    .ctx
                    .book
                    .get(addr)
                    .map(|e| e.name.clone())
                    .unwrap_or_default();
                if self.def.peers.contains(&name) {
                    tracing::warn!("peer {name} ({addr}) died");
                } else {
                    tracing::debug!("module {name} ({addr}) died");
                }
                self.ctx.out.describing[usize::from(addr.0)] = false;
                // The next process at this address may use a new inbox (its files were swept
                // while it started, say): open the link again rather than keep sending into
                // the dead one's.
                self.ctx.link.tx.disconnect(addr);
                let failures = &mut self.ctx.out.failures;
                self.ctx.out.calls.fail_peer(addr, |e| {
                    if e.purpose == Purpose::User {
                        failures.push((
                            e.handle,
                            CallError::NotAvailable {
                                name: name.clone(),
                                why: "its process died".into(),
                            },
                        ));
                    }
                });
            }
            for &addr in &changes.appeared {
                // A new process at `addr`: what it was served before died with the old one,
                // and calls that wait for it go out again.
                let ctx = &mut self.ctx;
                ctx.serving.served.forget(addr);
                let (tx, me, sent) = (&mut ctx.link.tx, ctx.addr, &mut ctx.stats.frames_sent);
                if changes.upgraded.contains(&addr) {
                    // A live upgrade: the new process got every request on its way (nothing
                    // to send again), and its own calls' sequence numbers start over.
                    continue;
                }
                ctx.out.calls.resend_to(addr, |r| {
                    match crate::ctx::send_retry(tx.as_mut(), me, r) {
                        Ok(()) => *sent += 1,
                        Err(e) => tracing::debug!("resend to {addr} not delivered: {e}"),
                    }
                });
            }
            if !changes.appeared.is_empty() {
                self.look_up_peers();
            }
        }
        self.ctx.flush_pending();
        self.deliver_failures(waiter);
        if self.ctx.liveness.heartbeats.due(now) {
            self.ctx.beat(ModuleState::Running);
            self.realtime = realtime_thread();
        }
        let since = now.saturating_sub(self.last_snapshot_ns);
        if !self.ctx.bb.is_empty()
            && ((self.ctx.bb.changed() && since >= 1_000_000)
                || since >= self.def.snapshot_period_ns)
        {
            self.publish_snapshot(now);
        }
    }

    fn deliver_failures(&mut self, waiter: &mut Waiter<'_>) {
        while let Some((handle, err)) = self.ctx.out.failures.pop() {
            tracing::debug!("a call failed: {err}");
            self.ctx.stats.failed += 1;
            match waiter {
                Some((h, f)) if *h == handle => f(Err(&err)),
                _ => match self.def.on_done {
                    Some(done) => done(&mut self.state, &mut self.ctx, handle, Err(&err)),
                    None => tracing::warn!("call failed: {err}"),
                },
            }
        }
    }

    fn look_up_peers(&mut self) {
        for name in &self.def.peers {
            if let Ok(e) = self.ctx.book.lookup(name) {
                let addr = e.addr;
                if e.methods.is_none() {
                    let _ = self.ctx.link.tx.connect(addr);
                    self.ctx.describe(addr);
                }
            }
        }
    }

    /// Publishes the blackboard now.
    pub fn publish_snapshot(&mut self, now: u64) {
        if self.ctx.bb.is_empty() {
            return;
        }
        self.last_snapshot_ns = now;
        let len = self.ctx.bb.snapshot_len();
        let (bb, addr) = (&mut self.ctx.bb, self.ctx.addr);
        if let Err(e) = self
            .ctx
            .link
            .snapshots
            .publish(len, &mut |buf| bb.write_snapshot(buf, addr, now))
        {
            tracing::warn!("snapshot not published: {e}");
        }
    }

    /// Calls `method` of `module` and waits for the answer, serving incoming frames meanwhile.
    /// `on_answer` reads the answer in place.
    pub fn call_blocking<R>(
        &mut self,
        module: &str,
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
        on_answer: impl FnOnce(Result<&Args<'_>, &CallError>) -> R,
    ) -> R {
        let handle = match self.ctx.call_with(module, method, args, opts) {
            Ok(h) => h,
            Err(e) => return on_answer(Err(&e)),
        };
        let mut on_answer = Some(on_answer);
        let mut out = None;
        let mut cb = |r: Result<&Args<'_>, &CallError>| {
            if let Some(f) = on_answer.take() {
                out = Some(f(r));
            }
        };
        let mut waiter: Waiter<'_> = Some((handle, &mut cb));
        // Read at the first housekeeping, not before the call: a call answered within 64 looks
        // at the inbox reads the clock only twice (sent, answered).
        let mut deadline = None;
        let mut spins = 0u32;
        // A blocking module looks without sleeping until `opts.spin` after its first
        // housekeeping, then sleeps between looks.
        let blocking = self.ctx.mode == ReceiveMode::Blocking;
        let mut spin_until = None;
        // Not under a real-time policy (there the callee may wait for this very core), and not
        // right after a look that missed.
        let look = blocking && self.answer_look.begin(opts.spin, self.realtime);
        let mut sleeping = blocking && !look;
        loop {
            match self.poll_with(&mut waiter) {
                Ok(true) => {
                    spins = 0;
                    self.deliver_failures(&mut waiter);
                    if !self.ctx.out.calls.is_waiting(handle)
                        && !self.ctx.out.pending.iter().any(|p| p.handle == handle)
                    {
                        break;
                    }
                    continue;
                }
                Ok(false) => {}
                Err(e) => {
                    let err = CallError::Transport(e);
                    if let Some((_, f)) = waiter.as_mut() {
                        f(Err(&err));
                    }
                    break;
                }
            }
            spins += 1;
            if spins.is_multiple_of(64) || sleeping {
                self.housekeeping_with(&mut waiter);
                if !self.ctx.out.calls.is_waiting(handle)
                    && !self.ctx.out.pending.iter().any(|p| p.handle == handle)
                {
                    break;
                }
                let now = self.ctx.now_ns();
                if now > *deadline.get_or_insert(now + opts.timeout.as_nanos() as u64 + 50_000_000)
                {
                    break;
                }
                if !sleeping
                    && blocking
                    && now >= *spin_until.get_or_insert(now + opts.spin.as_nanos() as u64)
                {
                    sleeping = true;
                    self.answer_look.missed();
                }
            }
            if sleeping {
                let _ = self.rx.wait(Duration::from_millis(5));
            } else {
                core::hint::spin_loop();
            }
        }
        match out {
            Some(r) => r,
            None => {
                let e = CallError::Timeout {
                    module: module.to_owned(),
                    timeout_ms: opts.timeout.as_millis() as u64,
                    sends: 1 + opts.retry.retries,
                };
                (on_answer.take().expect("not called"))(Err(&e))
            }
        }
    }

    /// Like [`Module::call_blocking`], returning owned values.
    pub fn call_owned(
        &mut self,
        module: &str,
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
    ) -> Result<Vec<OwnedValue>, CallError> {
        self.call_blocking(module, method, args, opts, owned_answer)
    }

    /// Runs the default application controller until SIGTERM/SIGINT or [`Ctx::stop`].
    pub fn run(mut self) -> Result<(), ModuleError> {
        if let Err(e) = crate::signals::install_termination_handler() {
            tracing::warn!("cannot handle SIGTERM/SIGINT: {e}");
        }
        crate::transport::launch::apply_mlockall();
        let mut idle_spins = 0u32;
        let blocking = self.mode() == ReceiveMode::Blocking;
        // Blocking mode: after serving, the module looks on without sleeping (it lingers)
        // until `linger_span` after its first housekeeping.
        let mut lingering = false;
        let mut linger_until = None;
        while !self.should_stop() {
            let mut served = 0;
            while served < 64 && self.poll_once()? {
                served += 1;
            }
            if served > 0 && blocking {
                lingering = self.linger.begin(self.linger_span, self.realtime);
                linger_until = None;
            }
            // A spinning module looks at its inbox between two housekeepings 64 times: a
            // frame that arrives is found within one look at the inbox, not after a
            // housekeeping (which reads the clock), and its tasks still run within
            // microseconds of their time.
            let spinning = served == 0 && (!blocking || lingering);
            if spinning {
                idle_spins = idle_spins.wrapping_add(1);
            }
            if !spinning || idle_spins.is_multiple_of(64) {
                self.housekeeping();
                if lingering {
                    let now = self.ctx.now_ns();
                    let until =
                        *linger_until.get_or_insert(now + self.linger_span.as_nanos() as u64);
                    if now >= until {
                        lingering = false;
                        self.linger.missed();
                    }
                }
            }
            if served == 0 {
                if spinning {
                    core::hint::spin_loop();
                } else {
                    let budget = self.idle_budget();
                    self.wait(budget)?;
                }
            }
        }
        tracing::info!("module {} stops", self.ctx().name());
        Ok(())
    }

    /// Whether the module is done: stopped (`Ctx::stop`, or handed over to a new process in a
    /// live upgrade) or asked to terminate.
    pub fn should_stop(&self) -> bool {
        self.ctx.liveness.stop || crate::signals::termination_requested()
    }

    /// Time until housekeeping has work next (blocking mode sleeps at most this long, unless a
    /// frame wakes it): a task, a heartbeat, a call's deadline or retransmission, a snapshot, a
    /// scanned directory's refresh, or a call waiting to be sent.
    pub(crate) fn idle_budget(&self) -> Duration {
        let now = self.ctx.now_ns();
        // A published directory is looked at on every wake-up, at least once a heartbeat.
        let refresh = if self.ctx.link.directory.published() {
            u64::MAX
        } else {
            self.next_refresh_ns
        };
        let snapshot = if self.ctx.bb.is_empty() {
            u64::MAX
        } else if self.ctx.bb.changed() {
            self.last_snapshot_ns + 1_000_000
        } else {
            self.last_snapshot_ns + self.def.snapshot_period_ns
        };
        // Waiting for a call to be sent; handing over to a live upgrade's new process, whose
        // files it looks for at every housekeeping (every call to it waits meanwhile).
        let pending = if self.ctx.serving.handover.is_some() {
            now + 100_000
        } else if self.ctx.out.pending.is_empty() {
            u64::MAX
        } else {
            now + 1_000_000
        };
        let next = self
            .next_task_ns
            .iter()
            .copied()
            .chain([
                refresh,
                self.ctx.liveness.heartbeats.next_ns,
                self.ctx.out.calls.next_due_ns(),
                snapshot,
                pending,
            ])
            .min()
            .unwrap_or(u64::MAX);
        Duration::from_nanos(next.saturating_sub(now).clamp(100_000, MAX_IDLE_NS))
    }

    /// Sleeps until a frame or a wake-up arrives, or `timeout` passed (for a loop of its own,
    /// as the supervisor's; [`crate::run()`] does this for a module program).
    pub fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        self.rx.wait(timeout)
    }
}

impl<S> Drop for Module<S> {
    fn drop(&mut self) {
        // Tell the supervisor this is a clean stop, release every iceoryx2 resource of this
        // module, then clean the domain if it was the last one.
        self.ctx.beat(ModuleState::Stopping);
        self.rx = Box::new(Closed);
        self.ctx.link.tx = Box::new(Closed);
        self.ctx.link.snapshots = Box::new(Closed);
        // The directory too: a supervisor's published one is a service this module holds, and
        // whether anyone still holds it says whether this module may be the last to leave.
        self.ctx.link.directory = Box::new(Closed);
        if self.transport.sweep_if_empty() {
            tracing::debug!("last module of the domain left: its files are removed");
        }
    }
}
