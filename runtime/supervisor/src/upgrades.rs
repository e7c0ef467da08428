//! Live upgrades (`modbot upgrade`, the supervisor's `upgrade` method): a new process takes a
//! running module over — its address, blackboard, own state and the calls on their way — and
//! the old one leaves. The handover between the two is `modbot_core::upgrade`'s; this file is
//! the supervisor's part:
//!
//! 1. `upgrade(module[, program[, force]])` is asked: the supervisor makes a directory for the
//!    handover and starts the new program (the module's own, or `program`) with
//!    `MODBOT_UPGRADE_DIR` naming it; `upgrade_status(module)` says how it goes.
//! 2. Once the new process is ready (its `ready` file: pid and methods), the supervisor calls
//!    the old one's `upgrade_out`: a different method table is refused unless forced, and
//!    the old process serves on.
//! 3. It then writes `subscribe`; once the new process has subscribed (`subscribed`), the
//!    module's row and the directory name the new pid with the upgrade count one higher (the
//!    restart policy, heartbeats and `modbot ls` follow it) and the old process, which hands
//!    its state over and ends, is let go.
//! 4. The upgrade is done at the new process's first heartbeat.
//!
//! A new program that ends, or is not ready within the start timeout, is refused and killed,
//! the old process serving on (after `upgrade_out`, the supervisor writes `abort` and the old
//! process serves again what it had kept).
//!
//! A host of the time grid first hands its components over at a tick (`modbot_grid::host`'s
//! `handover`: the new process stands by, the coordinator names the tick, the state is carried
//! to the bit); its new process writes `grid` once it steps them, and only then does the
//! module follow as above (its method table is then taken as it is: the components are the
//! new process's already).

use std::path::PathBuf;
use std::process::Child;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use modbot_core::calls::CallOptions;
use modbot_core::ctx::Ctx;
use modbot_core::error::{CallError, MethodError};
use modbot_core::module::Reply;
use modbot_core::upgrade::{self as handover, ABORT, GRID, READY, SUBSCRIBE, SUBSCRIBED};
use modbot_grid::spec::GridRole;
use modbot_ipc_schema::{Args, Value};
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

use super::child;
use super::env;
use super::shared::{Shared, UpgradeRequest, UpgradeStatus};
use super::status::RunState;
use super::{reason_of, Supervisor};

/// Where an upgrade under way is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// The new process starts and opens in standby.
    Preparing,
    /// The old process hands over; the new one is told to subscribe.
    Subscribing,
    /// The new process has the module; waiting for its first heartbeat.
    Switched { at_ns: u64 },
}

/// An upgrade under way.
pub(super) struct Upgrade {
    slot: usize,
    dir: PathBuf,
    /// The new process until it takes the module (then the slot's).
    child: Option<Child>,
    pid: u32,
    log_readers: Vec<JoinHandle<()>>,
    old_pid: u32,
    phase: Phase,
    began: Instant,
    force: bool,
}

/// A process an upgrade replaced: it hands its state over and ends.
pub(super) struct Leaving {
    child: Child,
    pid: u32,
    since: Instant,
    log_readers: Vec<JoinHandle<()>>,
}

/// How long a replaced process may take to hand its state over and end before it is killed.
const LEAVE_LIMIT: Duration = Duration::from_secs(35);

/// How long the old process may take to answer `upgrade_out`.
const UPGRADE_OUT_TIMEOUT: Duration = Duration::from_secs(2);

impl Supervisor {
    /// Starts the upgrades asked for and moves those under way on.
    pub(super) fn handle_upgrades(&mut self) {
        let requests = std::mem::take(&mut self.endpoint.state_mut().upgrade_requests);
        for r in requests {
            if let Err(why) = self.start_upgrade(&r) {
                self.say(&format!("upgrade of {} refused: {why}", r.module));
                self.set_upgrade_status(&r.module, "refused", why);
            }
        }
        let mut i = 0;
        while i < self.upgrades.len() {
            match self.step_upgrade(i) {
                Ok(true) => {
                    self.upgrades.remove(i);
                }
                Ok(false) => i += 1,
                Err(why) => {
                    let mut u = self.upgrades.remove(i);
                    let name = self.spec.modules[u.slot].name.clone();
                    if u.phase == Phase::Subscribing {
                        let _ = handover::write_file(&u.dir, ABORT, b"");
                    }
                    // A grid host whose new process took the components over (`grid`) before
                    // the module's handover failed: the running process steps nothing any more,
                    // so it ends too, and the module's restart policy brings the host back.
                    let grid_taken = handover::exists(&u.dir, GRID)
                        && !matches!(u.phase, Phase::Switched { .. });
                    if grid_taken {
                        let _ = kill(Pid::from_raw(u.old_pid as i32), Signal::SIGKILL);
                    }
                    if let Some(mut c) = u.child.take() {
                        let _ = c.kill();
                        let _ = c.wait();
                    }
                    self.flush_readers(&mut u.log_readers);
                    self.domain.remove_temp_of(u.pid);
                    self.roster.reap();
                    let keeps = if matches!(u.phase, Phase::Switched { .. }) {
                        ""
                    } else if grid_taken {
                        "; the new process had taken the grid's components over: both ended, \
                         and the restart policy brings the host back"
                    } else {
                        "; the running process serves on"
                    };
                    self.say(&format!("upgrade of {name} refused: {why}{keeps}"));
                    self.set_upgrade_status(&name, "refused", format!("{why}{keeps}"));
                    // The old process has read `abort` or never saw the directory.
                    let dir = u.dir.clone();
                    self.remove_later.push((dir, Instant::now()));
                }
            }
        }
        // Directories of finished upgrades go once both processes are surely done with them.
        self.remove_later.retain(|(dir, at)| {
            if at.elapsed() < LEAVE_LIMIT {
                return true;
            }
            let _ = std::fs::remove_dir_all(dir);
            false
        });
    }

    fn set_upgrade_status(&mut self, module: &str, state: &'static str, detail: String) {
        self.endpoint
            .state_mut()
            .upgrade_status
            .insert(module.to_owned(), UpgradeStatus { state, detail });
    }

    fn start_upgrade(&mut self, r: &UpgradeRequest) -> Result<(), String> {
        let Some(slot) = self.spec.modules.iter().position(|m| m.name == r.module) else {
            return Err(format!("no module named {}", r.module));
        };
        if matches!(GridRole::of(&r.module), Some(GridRole::Coordinator)) {
            return Err(format!(
                "{} keeps the time grid's clock: it does not upgrade",
                r.module
            ));
        }
        if self.upgrades.iter().any(|u| u.slot == slot) {
            return Err(format!("an upgrade of {} is under way", r.module));
        }
        let s = &self.slots[slot];
        if s.child.is_none() || s.state != RunState::Running {
            return Err(format!(
                "{} is {}, not running: there is nothing to take over",
                r.module,
                s.state.name()
            ));
        }
        let old_pid = s.pid;
        let mut m = self.spec.modules[slot].clone();
        if let Some(p) = &r.program {
            m.program = PathBuf::from(p);
        }
        if !m.program.is_file() {
            return Err(format!("the program {} is not a file", m.program.display()));
        }
        let n = self.slots[slot].upgrades + 1;
        let dir = std::env::temp_dir().join(format!(
            "{}upgrade.{}.{n}.{}",
            self.domain.temp_prefix(std::process::id()),
            r.module,
            self.now_ns()
        ));
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        m.env
            .push((env::UPGRADE_DIR.to_owned(), dir.display().to_string()));
        let (child, log_readers) = child::spawn(
            slot,
            &m,
            &self.domain,
            &self.spec.supervision,
            &self.system,
            &self.logs.tx,
        )
        .map_err(|e| format!("cannot start {}: {e}", m.program.display()))?;
        let pid = child.id();
        self.say(&format!(
            "upgrading {} (pid {old_pid}): {} started as pid {pid}",
            r.module,
            m.program.display()
        ));
        self.set_upgrade_status(&r.module, "preparing", format!("new process pid {pid}"));
        self.upgrades.push(Upgrade {
            slot,
            dir,
            child: Some(child),
            pid,
            log_readers,
            old_pid,
            phase: Phase::Preparing,
            began: Instant::now(),
            force: r.force,
        });
        Ok(())
    }

    /// One look at upgrade `i`: `Ok(true)` when it is done, `Err` when it is refused.
    fn step_upgrade(&mut self, i: usize) -> Result<bool, String> {
        let limit = self.spec.supervision.start_timeout;
        let u = &mut self.upgrades[i];
        let slot = u.slot;
        let name = self.spec.modules[slot].name.clone();
        if let Some(c) = u.child.as_mut() {
            if let Ok(Some(status)) = c.try_wait() {
                u.child = None;
                return Err(format!(
                    "the new program ended before it took over ({})",
                    reason_of(status)
                ));
            }
        }
        // The old process ended meanwhile (a crash): the slot's restart policy has it.
        if u.phase != Phase::Preparing
            && !matches!(u.phase, Phase::Switched { .. })
            && self.slots[slot].pid != u.old_pid
        {
            return Err("the running process ended during the handover".into());
        }
        match u.phase {
            Phase::Preparing => {
                if !handover::exists(&u.dir, READY) {
                    if u.began.elapsed() > limit {
                        return Err(format!(
                            "the new program was not ready within {} ms",
                            limit.as_millis()
                        ));
                    }
                    return Ok(false);
                }
                // A host of the time grid: its new process takes the components over at a tick
                // first (it writes `grid` then); the module follows, whatever its methods (the
                // components are the new process's already).
                let grid_host = matches!(GridRole::of(&name), Some(GridRole::Host { .. }));
                if grid_host && !handover::exists(&u.dir, GRID) {
                    if u.began.elapsed() > limit + handover_limit() {
                        return Err("the new process did not take the grid's components over \
                                    in time (is the grid running?)"
                            .into());
                    }
                    return Ok(false);
                }
                let ready = handover::read_file(&u.dir, READY).map_err(|e| e.to_string())?;
                let ready = String::from_utf8_lossy(&ready).into_owned();
                let methods = ready.lines().nth(1).unwrap_or("").to_owned();
                let (dir, force) = (u.dir.display().to_string(), u.force || grid_host);
                let answer = self.endpoint.call_owned(
                    &name,
                    "upgrade_out",
                    &[Value::Text(&dir), Value::Text(&methods), Value::Bool(force)],
                    CallOptions::timeout(UPGRADE_OUT_TIMEOUT),
                );
                match answer {
                    Ok(_) => {}
                    Err(CallError::Nak { detail, .. }) => return Err(detail),
                    Err(e) => {
                        // It may have taken the request and lost the answer: call it off.
                        let _ = handover::write_file(&self.upgrades[i].dir, ABORT, b"");
                        return Err(format!("the running process did not hand over: {e}"));
                    }
                }
                let u = &mut self.upgrades[i];
                handover::write_file(&u.dir, SUBSCRIBE, b"").map_err(|e| e.to_string())?;
                u.phase = Phase::Subscribing;
                Ok(false)
            }
            Phase::Subscribing => {
                if !handover::exists(&u.dir, SUBSCRIBED) {
                    if u.began.elapsed() > limit + handover_limit() {
                        return Err("the new program did not subscribe in time".into());
                    }
                    return Ok(false);
                }
                self.switch_to_new(i);
                Ok(false)
            }
            Phase::Switched { at_ns } => {
                let s = &self.slots[slot];
                if s.pid != u.pid || s.child.is_none() {
                    // It ended after it took over: the slot's restart policy has it.
                    let dir = u.dir.clone();
                    self.remove_later.push((dir, Instant::now()));
                    self.set_upgrade_status(
                        &name,
                        "refused",
                        "the new process ended after it took over; its restart policy \
                         brings the module back"
                            .into(),
                    );
                    return Ok(true);
                }
                if s.last_beat_ns > at_ns {
                    let took = u.began.elapsed();
                    let (old, new, n) = (u.old_pid, u.pid, s.upgrades);
                    let dir = u.dir.clone();
                    self.remove_later.push((dir, Instant::now()));
                    let detail = format!(
                        "pid {old} -> {new}, upgrade {n}, in {} ms",
                        took.as_millis()
                    );
                    self.say(&format!("{name} upgraded: {detail}"));
                    self.set_upgrade_status(&name, "done", detail);
                    return Ok(true);
                }
                if u.began.elapsed() > limit + handover_limit() {
                    return Err("the new process did not beat after it took over".into());
                }
                Ok(false)
            }
        }
    }

    /// Before the end of slot `slot`'s process is handled as the module's: if it is the old
    /// process of an upgrade whose new process has subscribed, it ended because it handed over
    /// (it does so as soon as it sees `subscribed`, maybe before this loop did): the slot
    /// switches to the new process first, and the old one is let go.
    pub(super) fn switch_if_handed_over(&mut self, slot: usize) {
        let handed = self.upgrades.iter().position(|u| {
            u.slot == slot && u.phase == Phase::Subscribing && handover::exists(&u.dir, SUBSCRIBED)
        });
        if let Some(i) = handed {
            self.switch_to_new(i);
        }
    }

    /// The new process receives the module's frames: it is the module's from now on.
    fn switch_to_new(&mut self, i: usize) {
        let now = self.now_ns();
        let u = &mut self.upgrades[i];
        let slot = &mut self.slots[u.slot];
        let (child, readers) = (u.child.take(), std::mem::take(&mut u.log_readers));
        if let Some(old) = slot.child.take() {
            self.leaving.push(Leaving {
                child: old,
                pid: slot.pid,
                since: Instant::now(),
                log_readers: std::mem::take(&mut slot.log_readers),
            });
        }
        slot.child = child;
        slot.log_readers = readers;
        slot.pid = u.pid;
        slot.upgrades = slot.upgrades.saturating_add(1);
        slot.last_beat_ns = now;
        u.phase = Phase::Switched { at_ns: now };
        let m = &self.spec.modules[u.slot];
        for w in super::rt::apply(u.pid, &m.cpus, m.priority) {
            self.say(&format!("warning: {}: {w}", m.name));
        }
        self.shown.changed();
        self.publish_directory();
    }

    /// Lets go of the processes upgrades replaced once they ended (killed when they take too
    /// long to hand over).
    pub(super) fn watch_leaving(&mut self) {
        let mut i = 0;
        while i < self.leaving.len() {
            let l = &mut self.leaving[i];
            match l.child.try_wait() {
                Ok(Some(_)) | Err(_) => {
                    let mut l = self.leaving.remove(i);
                    self.domain.remove_temp_of(l.pid);
                    self.roster.reap();
                    // Its last lines (the handover) belong to the module's log.
                    self.flush_readers(&mut l.log_readers);
                }
                Ok(None) => {
                    if l.since.elapsed() > LEAVE_LIMIT {
                        let pid = l.pid;
                        let _ = kill(Pid::from_raw(pid as i32), Signal::SIGKILL);
                        self.problems.push(format!(
                            "a process replaced by an upgrade (pid {pid}) did not end within {} s; killed",
                            LEAVE_LIMIT.as_secs()
                        ));
                    }
                    i += 1;
                }
            }
        }
    }

    /// At shutdown: what upgrades started, and the processes they replaced, go too.
    pub(super) fn stop_upgrades(&mut self) {
        for mut u in std::mem::take(&mut self.upgrades) {
            if let Some(mut c) = u.child.take() {
                let _ = c.kill();
                let _ = c.wait();
            }
            self.domain.remove_temp_of(u.pid);
            let _ = std::fs::remove_dir_all(&u.dir);
        }
        for mut l in std::mem::take(&mut self.leaving) {
            let _ = kill(Pid::from_raw(l.pid as i32), Signal::SIGTERM);
            let deadline = Instant::now() + Duration::from_secs(2);
            while Instant::now() < deadline && matches!(l.child.try_wait(), Ok(None)) {
                std::thread::sleep(Duration::from_millis(2));
            }
            let _ = l.child.kill();
            let _ = l.child.wait();
            self.domain.remove_temp_of(l.pid);
        }
        for (dir, _) in std::mem::take(&mut self.remove_later) {
            let _ = std::fs::remove_dir_all(dir);
        }
        self.forward_logs();
    }
}

/// The longest the processes' own steps may take ([`handover::STEP_LIMIT_NS`]).
fn handover_limit() -> Duration {
    Duration::from_nanos(handover::STEP_LIMIT_NS)
}

/// `upgrade(module: text[, program: text[, force: bool]])` → ACK: a live upgrade of `module`
/// starts (to the program at `program`, else the module's own); `upgrade_status` follows it.
pub(super) fn upgrade_method(
    shared: &mut Shared,
    _: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let module = args.text(0)?;
    if !shared.rows.iter().any(|r| r.name == module) {
        let known: Vec<&str> = shared.rows.iter().map(|r| r.name.as_str()).collect();
        return Err(MethodError::Failed(format!(
            "no module named {module} (modules: {})",
            known.join(", ")
        )));
    }
    if shared
        .upgrade_status
        .get(module)
        .is_some_and(|s| s.state == "preparing")
    {
        return Err(MethodError::Busy(format!(
            "an upgrade of {module} is under way"
        )));
    }
    let program = match args.get(1) {
        Some(Value::Text(p)) if !p.is_empty() => Some((*p).to_owned()),
        _ => None,
    };
    let force = matches!(args.get(2), Some(Value::Bool(true)));
    shared.upgrade_requests.push(UpgradeRequest {
        module: module.to_owned(),
        program,
        force,
    });
    shared.upgrade_status.insert(
        module.to_owned(),
        UpgradeStatus {
            state: "preparing",
            detail: "asked".into(),
        },
    );
    Ok(())
}

/// `upgrade_status(module: text)` → `[state: text, detail: text]`: `preparing`, `done` (pids,
/// upgrade count, time) or `refused` (why).
pub(super) fn upgrade_status_method(
    shared: &mut Shared,
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let module = args.text(0)?;
    let Some(s) = shared.upgrade_status.get(module) else {
        return Err(MethodError::Failed(format!(
            "no upgrade of {module} was asked"
        )));
    };
    reply.push(Value::Text(s.state));
    reply.push(Value::Text(&s.detail));
    Ok(())
}
