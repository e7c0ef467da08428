//! Both sides of a live upgrade ([`crate::upgrade`]): the running process handing over
//! (`handover_step`, from housekeeping) and the new process taking over (`take_over`, from
//! [`super::ModuleBuilder::open`]). Neither is on a hot path: a module that is not being
//! upgraded pays one `is_some` per frame and per housekeeping.

use std::path::Path;
use std::time::Instant;

use super::{Closed, Module};
use crate::clock::{Clock, MonotonicClock};
use crate::error::ModuleError;
use crate::manager;
use crate::served::ServedLog;
use crate::upgrade::{self, Handover, ABORT, READY, STATE, SUBSCRIBE, SUBSCRIBED};

/// How often the new process looks for the handover's files while it waits for the other
/// side (a stat each time: every call to the module waits for the handover meanwhile).
const POLL: core::time::Duration = core::time::Duration::from_micros(100);

impl<S> Module<S> {
    /// The running process, handing over: gives up when the supervisor called the upgrade off
    /// (or nothing happened for [`upgrade::STEP_LIMIT_NS`]); hands over once the new process
    /// receives the module's frames and this one's calls are answered (at most
    /// [`upgrade::CALLS_LIMIT_NS`] later). `may_finish` is false inside a blocking call.
    pub(super) fn handover_step(&mut self, now: u64, may_finish: bool) {
        let Some(out) = self.ctx.serving.handover.as_mut() else {
            return;
        };
        if upgrade::exists(&out.dir, ABORT) {
            self.resume("the supervisor called it off");
            return;
        }
        if now.saturating_sub(out.began_ns) > upgrade::STEP_LIMIT_NS && out.subscribed_ns.is_none()
        {
            self.resume("the new process did not take the inbox within 30 s");
            return;
        }
        if out.subscribed_ns.is_none() && upgrade::exists(&out.dir, SUBSCRIBED) {
            out.subscribed_ns = Some(now);
        }
        let Some(since) = out.subscribed_ns else {
            return;
        };
        let calls_done = self.ctx.out.calls.waiting() == 0 && self.ctx.out.pending.is_empty();
        if may_finish && (calls_done || now.saturating_sub(since) > upgrade::CALLS_LIMIT_NS) {
            self.hand_over();
        }
    }

    /// Serves on after a called-off upgrade: the requests and reports kept for the new process
    /// are served here.
    fn resume(&mut self, why: &str) {
        let Some(out) = self.ctx.serving.handover.take() else {
            return;
        };
        tracing::warn!(
            "module {}: the live upgrade was called off ({why}); it serves on, first the {} \
             frame(s) it kept meanwhile",
            self.ctx.name,
            out.kept.len()
        );
        for frame in &out.kept {
            self.serve_bytes(frame);
        }
    }

    /// Takes what is left in the inbox (dropping requests, keeping reports), writes the state
    /// for the new process, gives the inbox up and asks the module to stop.
    fn hand_over(&mut self) {
        while let Ok(true) = self.poll_with(&mut None) {}
        let Some(out) = self.ctx.serving.handover.take() else {
            return;
        };
        let items: Vec<_> = self
            .ctx
            .bb
            .values()
            .map(|(name, v)| (name.to_owned(), v.to_owned_value()))
            .collect();
        let state = self.def.upgrade_out.map(|(v, f)| (v, f(&self.state)));
        let handover = Handover {
            from_pid: std::process::id(),
            stopped_ns: out.began_mono_ns,
            active: self.ctx.liveness.active,
            items,
            state,
            served: self.ctx.serving.served.encode(),
            frames: out.kept,
        };
        if let Err(e) = upgrade::write_file(&out.dir, STATE, &handover.encode()) {
            // The new process waits for the state in vain and gives up; this one serves on.
            let _ = upgrade::write_file(&out.dir, ABORT, b"");
            self.ctx.serving.handover = Some(crate::upgrade::Outgoing {
                kept: handover.frames,
                ..out
            });
            self.resume(&format!("its state could not be written: {e}"));
            return;
        }
        // Frames that come from now on reach the new process, which subscribed.
        self.rx = Box::new(Closed);
        self.ctx.liveness.stop = true;
        let to = upgrade::read_file(&out.dir, READY)
            .ok()
            .and_then(|b| String::from_utf8(b).ok())
            .and_then(|t| t.lines().next().map(str::to_owned))
            .unwrap_or_else(|| "?".into());
        tracing::info!(
            "module {} handed over to pid {to}: {} blackboard item(s), {}, {} frame(s) kept",
            self.ctx.name,
            handover.items.len(),
            match &handover.state {
                Some((v, b)) => format!("its own state (version {v}, {} bytes)", b.len()),
                None => "no state of its own (no on_upgrade_out)".into(),
            },
            handover.frames.len()
        );
    }

    /// Serves a frame that did not come from the inbox (kept during a handover).
    fn serve_bytes(&mut self, bytes: &[u8]) {
        let (def, state, ctx, reply) = (&self.def, &mut self.state, &mut self.ctx, &mut self.reply);
        manager::dispatch(def, state, ctx, reply, bytes, &mut None);
    }

    /// The new process of a live upgrade: says it is ready, subscribes when the running
    /// process hands over, keeps what it receives until the state arrives, takes the state
    /// over and serves what it kept. Returns once the module is this process's.
    pub(super) fn take_over(&mut self, dir: &Path) -> Result<(), ModuleError> {
        let name = self.ctx.name.clone();
        let fail = |why: String| ModuleError::Upgrade {
            name: name.clone(),
            why,
        };
        let methods: Vec<&str> = self.def.methods.iter().map(|(n, _)| n.as_str()).collect();
        let ready = format!("{}\n{}\n", std::process::id(), methods.join(","));
        upgrade::write_file(dir, READY, ready.as_bytes()).map_err(|e| fail(e.to_string()))?;
        tracing::info!("module {name}: ready to take the running process over");
        let limit = core::time::Duration::from_nanos(upgrade::STEP_LIMIT_NS);
        let waiting = Instant::now();
        while !upgrade::exists(dir, SUBSCRIBE) {
            if upgrade::exists(dir, ABORT) {
                return Err(fail("the supervisor called the upgrade off".into()));
            }
            if waiting.elapsed() > limit || crate::signals::termination_requested() {
                return Err(fail(
                    "the running process did not hand over within 30 s".into(),
                ));
            }
            std::thread::sleep(POLL);
        }
        self.rx
            .attach()
            .map_err(|e| fail(format!("the inbox: {e}")))?;
        upgrade::write_file(dir, SUBSCRIBED, b"").map_err(|e| fail(e.to_string()))?;
        let mut received: Vec<Vec<u8>> = Vec::new();
        let waiting = Instant::now();
        loop {
            let mut take = |b: &[u8]| received.push(b.to_vec());
            while self
                .rx
                .try_receive(&mut take)
                .map_err(|e| fail(e.to_string()))?
            {}
            if upgrade::exists(dir, STATE) {
                // What came while the state was written.
                while self
                    .rx
                    .try_receive(&mut take)
                    .map_err(|e| fail(e.to_string()))?
                {}
                break;
            }
            if upgrade::exists(dir, ABORT) {
                return Err(fail("the running process gave the upgrade up".into()));
            }
            if waiting.elapsed() > limit || crate::signals::termination_requested() {
                return Err(fail("no state from the running process within 30 s".into()));
            }
            let _ = self.rx.wait(POLL);
        }
        let bytes = upgrade::read_file(dir, STATE).map_err(|e| fail(e.to_string()))?;
        let handover = Handover::decode(&bytes).map_err(|e| fail(e.to_string()))?;
        let mut restored = 0;
        for (item, value) in &handover.items {
            match self.ctx.bb.restore(item, value.as_value()) {
                Ok(()) => restored += 1,
                Err(e) => tracing::warn!("module {name}: blackboard item not carried over: {e}"),
            }
        }
        if !handover.active {
            // The operator's word stands: it refuses its methods and pauses its tasks.
            self.ctx.liveness.active = false;
            tracing::warn!("module {name} takes over deactivated, as the operator left it");
        }
        match ServedLog::decode(&handover.served) {
            Ok(log) => self.ctx.serving.served = log,
            Err(e) => tracing::warn!("module {name}: {e}; retransmissions are executed anew"),
        }
        let own = match (&handover.state, self.def.upgrade_in) {
            (Some((version, bytes)), Some(f)) => {
                match f(&mut self.state, &mut self.ctx, *version, bytes) {
                    Ok(()) => format!("its own state (version {version}, {} bytes)", bytes.len()),
                    Err(why) => {
                        tracing::warn!(
                            "module {name}: the state handed over (version {version}) is refused: \
                         {why}; it starts from its defaults"
                        );
                        "not its own state (refused)".into()
                    }
                }
            }
            (Some((version, _)), None) => {
                tracing::warn!(
                    "module {name}: the running program handed over its own state (version \
                     {version}), and this one takes none (no on_upgrade_in): it starts from its \
                     defaults"
                );
                "not its own state (no on_upgrade_in)".into()
            }
            (None, _) => {
                tracing::warn!(
                    "module {name}: the running program handed over no state of its own (no \
                     on_upgrade_out): it starts from its defaults"
                );
                "no state of its own".into()
            }
        };
        let frames = upgrade::merge(handover.frames, received);
        for frame in &frames {
            self.serve_bytes(frame);
        }
        // From the moment the old process stopped serving to now, when the frames that came
        // meanwhile are served: what a caller waited at most for the switch.
        let gap_us = Clock::now_ns(&MonotonicClock).saturating_sub(handover.stopped_ns) / 1000;
        tracing::info!(
            "module {name} took over from pid {}: {restored} of {} blackboard item(s), {own}, \
             {} frame(s) kept meanwhile served; handover {gap_us} us",
            handover.from_pid,
            handover.items.len(),
            frames.len()
        );
        Ok(())
    }
}
