//! The coordinator: the only process that reads the clock. Every base tick it releases the
//! components that are due, collects their done notices, detects overruns and keeps the ledger.
//!
//! Tick n, in this order:
//! 1. done notices that arrived are taken — for a component due now whose release still runs,
//!    after a short grace (the notice may be on its way): a release m of a component with
//!    period k that is done by now is *on time* if n ≤ m + k; its outputs become valid at
//!    m + k. A late one is only counted (its overrun was counted at its deadline);
//! 2. on-time outputs whose time has come (valid_from ≤ n) become the valid version;
//! 3. the recorder, if any, writes every output as valid at n;
//! 4. every component due at n (n mod k = 0) is released with, for each source of its inputs,
//!    the version valid at n. A component whose previous release is not done is not released:
//!    that is an overrun. With the `hold` policy downstream keeps reading its last valid
//!    outputs; with `fault` the grid stops releasing and reports the fault.
//!
//! The tick path does not allocate: notices are fixed-size and written in place.

use std::io::Write;

use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use modbot_ipc_schema::grid::{Done, Release, MAX_SOURCES};
use zerocopy::IntoBytes;

use super::ledger::{self, ComponentRow, GridRow};
use super::recorder::Recorder;
use super::spec::{GridSpec, OverrunPolicy};
use super::tick::TickSource;
use super::wire::{self, Pub, Sub};
use crate::stats::Histogram;
use crate::transport::TransportError;

/// One component, as the coordinator tracks it.
struct Comp {
    period: u64,
    host: usize,
    fault_policy: bool,
    sources: Vec<usize>,
    /// The release awaiting its done notice.
    pending: Option<u64>,
    /// An on-time completion whose outputs become valid at this tick.
    ready: Option<u64>,
    /// The version of its outputs valid now (0: the initial zeros).
    valid_from: u64,
    releases: u64,
    overruns: u64,
    late: u64,
    failed: u64,
    exec_min: u64,
    exec: Histogram,
    latency: Histogram,
}

struct HostLink {
    release: Pub,
    wake: Notifier<ipc::Service>,
    /// Released something this tick: wake it.
    woken: bool,
}

/// The grid's clock and bookkeeping.
pub struct Coordinator<W: Write> {
    spec: GridSpec,
    comps: Vec<Comp>,
    hosts: Vec<HostLink>,
    done: Sub,
    recorder: Option<Recorder<W>>,
    /// Scratch: the valid version of every component, for the recorder.
    versions: Vec<u64>,
    /// The next tick to run.
    tick: u64,
    missed: u64,
    tick_error: Histogram,
    fault: Option<String>,
    /// Timer expirations so far (ticks run plus ticks missed).
    expirations: u64,
    /// How long to wait at a tick for a due component's late done notice before calling it
    /// an overrun (absorbs the wake-up latency of the notice).
    grace_ns: u64,
    /// Every overrun: (tick, component, the release still running), for the trace.
    overrun_log: Vec<(u64, usize, u64)>,
    /// Ticks and time at the last rate measurement, and the rate then.
    rate: (u64, u64, f64),
}

impl<W: Write> Coordinator<W> {
    /// Opens the grid's services on `node`; with `trace`, records every output at every tick.
    pub fn new(
        node: &Node<ipc::Service>,
        spec: GridSpec,
        trace: Option<W>,
    ) -> Result<Coordinator<W>, TransportError> {
        let host_names = spec.hosts();
        let hosts = host_names
            .iter()
            .map(|h| {
                Ok(HostLink {
                    release: wire::release_publisher(node, h)?,
                    wake: wire::wake_notifier(node, h)?,
                    woken: false,
                })
            })
            .collect::<Result<Vec<_>, TransportError>>()?;
        let comps = spec
            .components
            .iter()
            .enumerate()
            .map(|(c, cs)| Comp {
                period: cs.period.max(1),
                host: host_names.iter().position(|h| *h == cs.host).unwrap_or(0),
                fault_policy: cs.policy == OverrunPolicy::Fault,
                sources: spec.sources(c),
                pending: None,
                ready: None,
                valid_from: 0,
                releases: 0,
                overruns: 0,
                late: 0,
                failed: 0,
                exec_min: u64::MAX,
                exec: Histogram::new(),
                latency: Histogram::new(),
            })
            .collect::<Vec<_>>();
        let recorder = match trace {
            Some(out) => Some(Recorder::new(node, &spec, out)?),
            None => None,
        };
        Ok(Coordinator {
            versions: vec![0; comps.len()],
            comps,
            hosts,
            done: wire::done_subscriber(node)?,
            recorder,
            spec,
            tick: 0,
            missed: 0,
            tick_error: Histogram::new(),
            fault: None,
            expirations: 0,
            grace_ns: 0,
            overrun_log: Vec::new(),
            rate: (0, 0, 0.0),
        })
    }

    /// Waits up to `grace_ns` at a tick for a due component's done notice before counting an
    /// overrun.
    pub fn with_grace(mut self, grace_ns: u64) -> Self {
        self.grace_ns = grace_ns;
        self
    }

    /// Before tick 0: sends every host `rounds` warm-up releases, one round at a time, and
    /// waits (up to `timeout`) for each round's answers. Returns the hosts that did not answer.
    pub fn warm_up(
        &mut self,
        rounds: u64,
        timeout: core::time::Duration,
    ) -> Result<usize, TransportError> {
        use modbot_ipc_schema::grid::PING;
        let until = std::time::Instant::now() + timeout;
        let mut silent = self.hosts.len();
        for round in 0..rounds {
            let ping = Release::new(round, 0, PING, &[]).map_err(|e| TransportError::Ipc {
                op: "warm-up",
                detail: e.to_string(),
            })?;
            for h in &mut self.hosts {
                wire::send(&h.release, ping.as_bytes().len(), |b| {
                    b.copy_from_slice(ping.as_bytes())
                })?;
                if let Err(e) = h.wake.notify() {
                    tracing::debug!("wake-up not sent: {e:?}");
                }
            }
            let mut answered = 0;
            while answered < self.hosts.len() && std::time::Instant::now() < until {
                match self.done.receive() {
                    Ok(Some(sample)) => {
                        if Done::parse(sample.payload())
                            .is_ok_and(|d| d.component.get() == PING && d.tick.get() == round)
                        {
                            answered += 1;
                        }
                    }
                    _ => std::thread::sleep(core::time::Duration::from_micros(100)),
                }
            }
            silent = self.hosts.len() - answered;
        }
        Ok(silent)
    }

    /// Host `host` was restarted: the releases its components had running died with the old
    /// process and will never report done. They are dropped, so each component is released
    /// again at its next due tick (its outputs held meanwhile). Returns how many were dropped.
    pub fn host_restarted(&mut self, host: &str) -> usize {
        let Some(h) = self.spec.hosts().iter().position(|x| x == host) else {
            return 0;
        };
        let mut dropped = 0;
        for comp in self.comps.iter_mut().filter(|c| c.host == h) {
            if comp.pending.take().is_some() {
                comp.failed += 1;
                dropped += 1;
            }
        }
        if dropped > 0 {
            tracing::warn!("host {host} restarted: {dropped} release(s) lost with it");
        }
        dropped
    }

    /// Ticks run so far.
    pub fn ticks(&self) -> u64 {
        self.tick
    }

    /// Why the grid faulted, if it did.
    pub fn fault(&self) -> Option<&str> {
        self.fault.as_deref()
    }

    /// Waits for the next tick of `source` and runs it.
    ///
    /// A late wake-up that finds several ticks elapsed runs one logical tick and counts the
    /// others as missed: the grid never runs ticks back to back to catch up, which would give
    /// the components no time. The tick error is the lateness of the wake-up.
    pub fn step(&mut self, source: &mut dyn TickSource) -> std::io::Result<()> {
        let elapsed = source.wait()?;
        let now = source.now_ns();
        self.expirations += elapsed;
        if self.tick == 0 {
            self.rate = (0, now, 0.0);
        }
        let due = source.due_ns(self.expirations.saturating_sub(1));
        self.tick_error.record(now.saturating_sub(due));
        self.missed += elapsed.saturating_sub(1);
        if now.saturating_sub(self.rate.1) >= 1_000_000_000 {
            let ticks = self.tick - self.rate.0;
            self.rate = (
                self.tick,
                now,
                ticks as f64 * 1e9 / (now - self.rate.1) as f64,
            );
        }
        self.run_tick(now)
    }

    /// Runs tick `self.tick` (the clock says `now_ns`).
    pub fn run_tick(&mut self, now_ns: u64) -> std::io::Result<()> {
        let n = self.tick;
        self.take_done(n);
        if self.fault.is_none() {
            self.await_due(n);
        }
        for (c, comp) in self.comps.iter_mut().enumerate() {
            if comp.ready.is_some_and(|from| from <= n) {
                comp.valid_from = comp.ready.take().unwrap_or(comp.valid_from);
            }
            self.versions[c] = comp.valid_from;
        }
        if let Some(rec) = self.recorder.as_mut() {
            rec.tick(n, &self.versions)?;
        }
        if self.fault.is_none() {
            self.release_due(n, now_ns);
        }
        for h in &mut self.hosts {
            if std::mem::take(&mut h.woken) {
                if let Err(e) = h.wake.notify() {
                    tracing::debug!("wake-up not sent: {e:?}");
                }
            }
        }
        self.tick += 1;
        Ok(())
    }

    fn take_done(&mut self, n: u64) {
        while let Ok(Some(sample)) = self.done.receive() {
            let Ok(done) = Done::parse(sample.payload()) else {
                continue;
            };
            let Some(comp) = self.comps.get_mut(usize::from(done.component.get())) else {
                continue;
            };
            let m = done.tick.get();
            if comp.pending != Some(m) {
                continue;
            }
            comp.pending = None;
            comp.exec.record(done.exec_ns.get());
            comp.exec_min = comp.exec_min.min(done.exec_ns.get());
            comp.latency.record(done.latency_ns.get());
            if done.status.get() != Done::OK {
                comp.failed += 1;
            } else if n <= m + comp.period {
                comp.ready = Some(m + comp.period);
            } else {
                comp.late += 1;
            }
        }
    }

    /// Gives components due at `n` whose release still runs the grace period to report done.
    fn await_due(&mut self, n: u64) {
        let late = |comps: &[Comp]| {
            comps
                .iter()
                .any(|c| n.is_multiple_of(c.period) && c.pending.is_some())
        };
        if self.grace_ns == 0 || !late(&self.comps) {
            return;
        }
        let until = std::time::Instant::now() + core::time::Duration::from_nanos(self.grace_ns);
        while late(&self.comps) && std::time::Instant::now() < until {
            core::hint::spin_loop();
            self.take_done(n);
        }
    }

    fn release_due(&mut self, n: u64, now_ns: u64) {
        let mut versions = [0u64; MAX_SOURCES];
        for c in 0..self.comps.len() {
            let comp = &self.comps[c];
            if !n.is_multiple_of(comp.period) {
                continue;
            }
            if let Some(m) = comp.pending {
                let comp = &mut self.comps[c];
                comp.overruns += 1;
                self.overrun_log.push((n, c, m));
                if comp.fault_policy {
                    let name = &self.spec.components[c].name;
                    let why = format!(
                        "component {name} overran its deadline at tick {n} (released at {m}); the grid stops releasing"
                    );
                    tracing::error!("{why}");
                    self.fault = Some(why);
                    return;
                }
                continue;
            }
            for (slot, &s) in versions.iter_mut().zip(&comp.sources) {
                *slot = self.comps[s].valid_from;
            }
            let k = comp.sources.len().min(MAX_SOURCES);
            let host = comp.host;
            let Ok(notice) = Release::new(n, now_ns, c as u16, &versions[..k]) else {
                continue;
            };
            let link = &mut self.hosts[host];
            let sent = wire::send(&link.release, notice.as_bytes().len(), |buf| {
                buf.copy_from_slice(notice.as_bytes())
            });
            match sent {
                Ok(()) => {
                    link.woken = true;
                    let comp = &mut self.comps[c];
                    comp.pending = Some(n);
                    comp.releases += 1;
                }
                Err(e) => tracing::warn!("release of component {c} not sent: {e}"),
            }
        }
    }

    /// Waits up to `timeout_ns` (by `now`) for the releases still running, then takes their
    /// done notices; returns how many are still pending.
    pub fn drain(&mut self, now: &dyn Fn() -> u64, timeout_ns: u64) -> usize {
        let until = now() + timeout_ns;
        loop {
            self.take_done(self.tick);
            let pending = self.comps.iter().filter(|c| c.pending.is_some()).count();
            if pending == 0 || now() >= until {
                return pending;
            }
            std::thread::sleep(core::time::Duration::from_micros(200));
        }
    }

    /// The ledger as it stands.
    pub fn ledger(&self, done: bool) -> (GridRow, Vec<ComponentRow>) {
        let (p50, p99, max) = ledger::p50_p99_max(&self.tick_error);
        let grid = GridRow {
            state: match (&self.fault, done) {
                (Some(_), _) => "faulted",
                (None, true) => "done",
                (None, false) => "running",
            }
            .into(),
            fault: self.fault.clone().unwrap_or_default(),
            ticks: self.tick,
            missed: self.missed,
            rate_hz: self.rate.2,
            tick_err_p50: p50,
            tick_err_p99: p99,
            tick_err_max: max,
        };
        let rows = self
            .comps
            .iter()
            .zip(&self.spec.components)
            .map(|(c, s)| {
                let (e50, e99, emax) = ledger::p50_p99_max(&c.exec);
                let (l50, l99, _) = ledger::p50_p99_max(&c.latency);
                ComponentRow {
                    name: s.name.clone(),
                    host: s.host.clone(),
                    period: c.period,
                    policy: if c.fault_policy { "fault" } else { "hold" }.into(),
                    releases: c.releases,
                    overruns: c.overruns,
                    late: c.late,
                    failed: c.failed,
                    exec_min: if c.exec.count() == 0 { 0 } else { c.exec_min },
                    exec_p50: e50,
                    exec_p99: e99,
                    exec_max: emax,
                    latency_p50: l50,
                    latency_p99: l99,
                }
            })
            .collect();
        (grid, rows)
    }

    /// Ends the run: the recorder's trace is flushed, with a line per overrun at its end
    /// (`# overrun tick=T component=C release=M`); returns the versions it could not find.
    pub fn finish(self) -> std::io::Result<u64> {
        match self.recorder {
            Some(rec) => {
                let missing = rec.missing;
                let mut out = rec.finish()?;
                for &(t, c, m) in &self.overrun_log {
                    let name = &self.spec.components[c].name;
                    writeln!(out, "# overrun tick={t} component={name} release={m}")?;
                }
                out.flush()?;
                Ok(missing)
            }
            None => Ok(0),
        }
    }
}
