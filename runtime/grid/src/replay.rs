//! A recorded run computed again in one thread (`modbot replay`): the reference run's LET
//! semantics ([`crate::reference`]) with everything else that decided the real run's releases
//! applied as it happened — assembly switches (the incoming assembly tracking from the tick its
//! preparation announced, flag TRACK, until it takes over at the tick it did), the robot held
//! (TRACK | HELD for the running assembly), faults (SAFE_STOP; the assembly no longer released),
//! overruns and stale releases. What decided them is the coordinator's schedule of the run
//! ([`Schedule`], parsed from its replay log); which component is made of what ([`Make`]) is
//! the caller's: a replay makes the bus a player of its recorded outputs and the recorder a
//! comparer of what it recorded.
//!
//! Per tick n, in the coordinator's order: the versions valid at n become valid; `sink` sees
//! the grid's state hash; a switch at n makes the incoming assembly the running one; the
//! running grid's components due at n are released; then the incoming assembly's, once it
//! tracks.

use std::collections::BTreeSet;

use thiserror::Error;

use crate::component::{Component, ComponentError, Generation, PortValue, Released, Tick};
use crate::spec::GridSpec;
use crate::state_hash::{self, StateHasher};
use modbot_ipc_schema::grid::Release;

/// Makes the component `c` of `spec` for a replay.
pub trait Make {
    fn make(&mut self, spec: &GridSpec, c: usize) -> Result<Box<dyn Component>, ComponentError>;
}

/// What decided a recorded run's releases beyond LET, per tick.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Schedule {
    /// Switches, in order: the generation, the tick it was announced at, its tracking start,
    /// the switch tick as announced and as moved later ((tick, at) pairs), and the tick it
    /// took over (none: it never did).
    pub switches: Vec<SwitchAt>,
    /// (tick, held) where the running assembly's being held changed.
    pub held: Vec<(u64, bool)>,
    /// (tick, first component index) of faults.
    pub faults: Vec<(u64, usize)>,
    /// (generation, component name, release tick) of releases that finished late.
    pub late: BTreeSet<(u16, String, u64)>,
    /// (generation, component name, tick) of due ticks not released (still running) or
    /// releases not executed (stale).
    pub skipped: BTreeSet<(u16, String, u64)>,
    /// (tick, host) of host processes restarted: their components began anew.
    pub restarts: Vec<(u64, String)>,
    /// The ticks the run ended after, if it ended cleanly (its log is complete).
    pub ended: Option<u64>,
}

/// One switch of a recorded run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SwitchAt {
    pub generation: u16,
    pub announced: u64,
    pub from: u64,
    /// (tick from which it holds, switch tick): as announced, then each postponement.
    pub at: Vec<(u64, u64)>,
    pub took_over: Option<u64>,
}

impl SwitchAt {
    /// The switch tick as the coordinator knew it at tick `n`.
    fn at_as_of(&self, n: u64) -> u64 {
        self.at
            .iter()
            .rev()
            .find(|(t, _)| *t <= n)
            .or(self.at.first())
            .map_or(u64::MAX, |(_, at)| *at)
    }
}

/// Why a schedule cannot be read, or a replay cannot be made.
#[derive(Debug, Error)]
pub enum ReplayError {
    #[error("the schedule's line {line}: {why} ('{text}')")]
    Schedule {
        line: usize,
        text: String,
        why: String,
    },
    #[error("generation {0} ran, and the recording has no checked grid of it")]
    NoGrid(u16),
    #[error("component '{component}': {error}")]
    Make {
        component: String,
        #[source]
        error: ComponentError,
    },
    #[error("component '{component}': input {input} is not connected")]
    Unconnected { component: String, input: usize },
}

impl Schedule {
    /// Reads the coordinator's replay log (see `modbot_grid_processes`' `replay_log`).
    pub fn parse(log: &str) -> Result<Schedule, ReplayError> {
        let mut s = Schedule::default();
        for (i, text) in log.lines().enumerate() {
            let bad = |why: &str| ReplayError::Schedule {
                line: i + 1,
                text: text.to_owned(),
                why: why.to_owned(),
            };
            let mut words = text.split_whitespace();
            let Some(kind) = words.next() else {
                continue;
            };
            let fields: Vec<(&str, &str)> = text
                .split_whitespace()
                .filter_map(|w| w.split_once('='))
                .collect();
            let field = |k: &str| fields.iter().find(|(key, _)| *key == k).map(|(_, v)| *v);
            let number = |k: &str| -> Result<u64, ReplayError> {
                field(k)
                    .and_then(|v| v.parse().ok())
                    .ok_or_else(|| bad(&format!("no number {k}=")))
            };
            let generation = || -> Result<u16, ReplayError> {
                let g = number("generation")?;
                u16::try_from(g).map_err(|_| bad("generation out of range"))
            };
            let name = || {
                field("component")
                    .map(str::to_owned)
                    .ok_or_else(|| bad("no component="))
            };
            let tick = number("tick")?;
            match kind {
                "announce" => s.switches.push(SwitchAt {
                    generation: generation()?,
                    announced: tick,
                    from: number("from")?,
                    at: vec![(0, number("at")?)],
                    took_over: None,
                }),
                "postpone" | "switch" => {
                    let g = generation()?;
                    let Some(sw) = s.switches.iter_mut().rev().find(|x| x.generation == g) else {
                        return Err(bad("no announce of this generation before"));
                    };
                    if kind == "switch" {
                        sw.took_over = Some(tick);
                        // A fault taken at this tick before the switch ended with it.
                        s.faults.retain(|(t, _)| *t != tick);
                    } else {
                        sw.at.push((tick, number("at")?));
                    }
                }
                "held" => s.held.push((tick, text.ends_with(" on"))),
                "fault" => s.faults.push((tick, number("from")? as usize)),
                "overrun" => {
                    let (g, c) = (generation()?, name()?);
                    s.late.insert((g, c.clone(), number("release")?));
                    s.skipped.insert((g, c, tick));
                }
                "late" => {
                    s.late.insert((generation()?, name()?, tick));
                }
                "stale" => {
                    s.skipped.insert((generation()?, name()?, tick));
                }
                "restart" => {
                    let host = field("host").ok_or_else(|| bad("no host="))?;
                    s.restarts.push((tick, host.to_owned()));
                }
                "end" => s.ended = Some(tick),
                // A live upgrade of a host: a new process stepped its components on from this
                // tick, their state carried — nothing for a replay to do differently.
                "upgrade" => {}
                _ => return Err(bad("unknown line")),
            }
        }
        Ok(s)
    }

    /// Whether the running assembly is held at tick `n`.
    fn held_at(&self, n: u64) -> bool {
        self.held
            .iter()
            .rev()
            .find(|(t, _)| *t <= n)
            .is_some_and(|(_, h)| *h)
    }
}

/// One component's state in the replay.
struct Slot {
    component: Box<dyn Component>,
    period: u64,
    /// What its steps write into, as a host's buffer: the outputs of its last step.
    outputs: Vec<PortValue>,
    valid: Vec<PortValue>,
    pending: Vec<PortValue>,
    pending_from: Option<u64>,
    valid_hash: Option<u64>,
    pending_hash: Option<u64>,
    inputs: Vec<PortValue>,
    /// For each input: (component, port) of its source, in the grid it runs in.
    bindings: Vec<(usize, usize)>,
    /// Its name (events name components by generation and name).
    name: String,
}

impl Slot {
    fn new(spec: &GridSpec, c: usize, make: &mut dyn Make) -> Result<Slot, ReplayError> {
        let cs = &spec.components[c];
        let mut component = make.make(spec, c).map_err(|error| ReplayError::Make {
            component: cs.name.clone(),
            error,
        })?;
        let mut initial = cs.info.zero_outputs();
        component.initial_outputs(&mut initial);
        Ok(Slot {
            component,
            period: cs.period.max(1),
            outputs: initial.clone(),
            valid: initial.clone(),
            pending: initial,
            pending_from: None,
            valid_hash: None,
            pending_hash: None,
            inputs: cs.info.zero_inputs(),
            bindings: bindings(spec, c)?,
            name: cs.name.clone(),
        })
    }

    fn take_ready(&mut self, n: u64) {
        if self.pending_from == Some(n) {
            std::mem::swap(&mut self.valid, &mut self.pending);
            self.pending_from = None;
            self.valid_hash = self.pending_hash.take();
        }
    }

    /// Steps (or tracks, with TRACK) with the inputs gathered; the outputs become valid at
    /// n + period unless the release finished late.
    fn release(&mut self, rel: &Released, late: bool) {
        if rel.flags & Release::TRACK != 0 {
            self.component.track(rel, &self.inputs, &mut self.outputs);
        } else {
            self.component.step(rel, &self.inputs, &mut self.outputs);
        }
        for (p, o) in self.pending.iter_mut().zip(&self.outputs) {
            p.assign(o);
        }
        let mut hasher = StateHasher::new();
        self.component.state_hash(&self.outputs, &mut hasher);
        (self.pending_from, self.pending_hash) = match late {
            true => (None, None),
            false => (Some(rel.tick.0 + self.period), hasher.finish()),
        };
    }
}

/// The (component, port) feeding each input of `c` in `spec`.
fn bindings(spec: &GridSpec, c: usize) -> Result<Vec<(usize, usize)>, ReplayError> {
    (0..spec.components[c].info.inputs.len())
        .map(|i| {
            spec.source_of(c, i)
                .map(|p| (p.component, p.port))
                .ok_or_else(|| ReplayError::Unconnected {
                    component: spec.components[c].name.clone(),
                    input: i,
                })
        })
        .collect()
}

/// Gathers the inputs of `c` (in `slots`) from the outputs valid now: of `base` for the
/// system's components (index < `base_len`) when given, else of `slots`.
fn gather(slots: &mut [Option<Slot>], c: usize, base: Option<(&[Slot], usize)>) {
    let Some(mut inputs) = slots[c].as_mut().map(|s| std::mem::take(&mut s.inputs)) else {
        return;
    };
    if let Some(slot) = slots[c].as_ref() {
        for (value, &(s, p)) in inputs.iter_mut().zip(&slot.bindings) {
            let from = match base {
                Some((base, len)) if s < len => base.get(s),
                _ => slots.get(s).and_then(Option::as_ref),
            };
            if let Some(v) = from.and_then(|x| x.valid.get(p)) {
                value.assign(v);
            }
        }
    }
    if let Some(slot) = slots[c].as_mut() {
        slot.inputs = inputs;
    }
}

/// The assembly being prepared in the replay.
struct Incoming<'a> {
    spec: &'a GridSpec,
    switch: &'a SwitchAt,
    /// Its own components (index ≥ base); `None` for the system's.
    slots: Vec<Option<Slot>>,
}

/// Replays `first` (the grid of the first generation) and the generations `specs` the
/// schedule switches to, for `ticks` ticks, making components with `make`. Events name the
/// system's own components (index below the assembly's base) with generation 0. Played
/// components (a source's player) take their events as the rest: the rows they play hold
/// what was valid at each tick, which their skipped and late releases keep valid.
/// `on_tick(n, hash)` sees the grid's state hash at every tick, and ends the replay there by
/// answering false.
pub fn run(
    specs: &[GridSpec],
    schedule: &Schedule,
    make: &mut dyn Make,
    ticks: u64,
    on_tick: &mut dyn FnMut(u64, u64) -> bool,
) -> Result<(), ReplayError> {
    let Some(first) = specs.first() else {
        return Err(ReplayError::NoGrid(0));
    };
    let spec_of = |g: u16| {
        specs
            .iter()
            .find(|s| s.generation().0 == g)
            .ok_or(ReplayError::NoGrid(g))
    };
    let base_ns = u64::try_from(first.base_period.as_nanos()).unwrap_or(u64::MAX);
    let mut spec = first;
    let mut cur = (0..first.components.len())
        .map(|c| Slot::new(first, c, make))
        .collect::<Result<Vec<_>, _>>()?;
    let mut incoming: Option<Incoming<'_>> = None;
    let mut switches = schedule.switches.iter();
    let mut next_switch = switches.next();
    let mut fault: Option<(u64, usize)> = None;
    let mut faults = schedule.faults.iter().peekable();
    let event = |set: &BTreeSet<(u16, String, u64)>, g: Generation, slot: &Slot, t: u64| {
        set.contains(&(g.0, slot.name.clone(), t))
    };
    for n in 0..ticks {
        // The incoming assembly's components are made when it begins to track.
        // A switch that never took over (its assembly failed) changed nothing recorded.
        while next_switch.is_some_and(|sw| sw.took_over.is_none()) {
            next_switch = switches.next();
        }
        if let Some(sw) = next_switch.filter(|sw| sw.from <= n) {
            let inc_spec = spec_of(sw.generation)?;
            let base = inc_spec.assembly.as_ref().map_or(0, |a| a.base);
            let slots = (0..inc_spec.components.len())
                .map(|c| match c < base {
                    true => Ok(None),
                    false => Slot::new(inc_spec, c, make).map(Some),
                })
                .collect::<Result<Vec<_>, _>>()?;
            incoming = Some(Incoming {
                spec: inc_spec,
                switch: sw,
                slots,
            });
            next_switch = switches.next();
        }
        for slot in &mut cur {
            slot.take_ready(n);
        }
        if let Some(inc) = incoming.as_mut() {
            inc.slots.iter_mut().flatten().for_each(|s| s.take_ready(n));
        }
        let tick_hash = state_hash::combine(
            cur.iter()
                .enumerate()
                .filter_map(|(c, s)| Some((c, s.valid_hash?))),
        );
        if !on_tick(n, tick_hash) {
            break;
        }
        if incoming
            .as_ref()
            .is_some_and(|i| i.switch.took_over == Some(n))
        {
            if let Some(inc) = incoming.take() {
                let base = inc.spec.assembly.as_ref().map_or(0, |a| a.base);
                for old in cur.drain(base..) {
                    let mut old = old;
                    old.component.terminate();
                }
                for (c, slot) in cur.iter_mut().enumerate() {
                    slot.bindings = bindings(inc.spec, c)?;
                }
                cur.extend(inc.slots.into_iter().skip(base).flatten());
                spec = inc.spec;
                fault = None;
            }
        }
        while let Some(&&f) = faults.peek().filter(|f| f.0 <= n) {
            fault = Some(f);
            faults.next();
        }
        // The running grid's releases.
        let base = spec.assembly.as_ref().map_or(0, |a| a.base);
        let generation = spec.generation();
        let held = schedule.held_at(n);
        for c in 0..cur.len() {
            let faulted = fault.is_some_and(|(t, from)| t < n || c >= from);
            let logged = if c < base {
                Generation::SYSTEM
            } else {
                generation
            };
            if !n.is_multiple_of(cur[c].period)
                || (faulted && c >= base)
                || event(&schedule.skipped, logged, &cur[c], n)
            {
                continue;
            }
            let mut inputs = std::mem::take(&mut cur[c].inputs);
            for (value, &(s, p)) in inputs.iter_mut().zip(&cur[c].bindings) {
                value.assign(&cur[s].valid[p]);
            }
            let slot = &mut cur[c];
            slot.inputs = inputs;
            let flags = if faulted {
                Release::SAFE_STOP
            } else if held && c >= base {
                Release::TRACK | Release::HELD
            } else {
                0
            };
            let rel = Released {
                tick: Tick(n),
                generation,
                flags,
                now_ns: n.saturating_mul(base_ns),
                state_hash: tick_hash,
            };
            let late = event(&schedule.late, logged, slot, n);
            slot.release(&rel, late);
        }
        // The incoming assembly's, tracking until the switch.
        let Some(inc) = incoming.as_mut() else {
            continue;
        };
        if n < inc.switch.from {
            continue;
        }
        let at = inc.switch.at_as_of(n);
        let inc_generation = inc.spec.generation();
        let inc_base = inc.spec.assembly.as_ref().map_or(0, |a| a.base);
        for c in inc_base..inc.slots.len() {
            let due = inc.slots[c].as_ref().is_some_and(|slot| {
                n.is_multiple_of(slot.period) && !event(&schedule.skipped, inc_generation, slot, n)
            });
            if !due {
                continue;
            }
            gather(&mut inc.slots, c, Some((&cur, inc_base)));
            if let Some(slot) = inc.slots[c].as_mut() {
                let flags = if n + slot.period < at {
                    Release::TRACK
                } else {
                    0
                };
                let rel = Released {
                    tick: Tick(n),
                    generation: inc_generation,
                    flags,
                    now_ns: n.saturating_mul(base_ns),
                    state_hash: tick_hash,
                };
                let late = event(&schedule.late, inc_generation, slot, n);
                slot.release(&rel, late);
            }
        }
    }
    for slot in &mut cur {
        slot.component.terminate();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_coordinators_log_reads_as_switches_holds_faults_and_events_by_name() {
        let log = "announce tick=300 generation=2 from=301 at=356\n\
                   postpone tick=350 generation=2 at=360\n\
                   fault tick=360 from=0\n\
                   switch tick=360 generation=2\n\
                   late tick=359 generation=1 component=hold\n\
                   restart tick=700 host=ctrl\n\
                   end tick=800\n\
                   held tick=400 on\n\
                   held tick=420 off\n\
                   fault tick=500 from=3\n\
                   overrun tick=451 generation=2 component=ptp release=450\n\
                   stale tick=460 generation=2 component=ff\n";
        let sut = Schedule::parse(log).unwrap();
        let sw = &sut.switches[0];
        assert_eq!((sw.generation, sw.from, sw.took_over), (2, 301, Some(360)));
        assert_eq!((sw.at_as_of(349), sw.at_as_of(350)), (356, 360));
        assert!(!sut.held_at(399) && sut.held_at(400) && sut.held_at(419) && !sut.held_at(420));
        assert_eq!(
            sut.faults,
            [(500, 3)],
            "the fault at 360 ended with the switch"
        );
        assert!(sut.late.contains(&(1, "hold".into(), 359)));
        assert_eq!(sut.restarts, [(700, "ctrl".to_owned())]);
        assert_eq!(sut.ended, Some(800));
        assert!(sut.late.contains(&(2, "ptp".into(), 450)));
        assert!(sut.skipped.contains(&(2, "ptp".into(), 451)));
        assert!(sut.skipped.contains(&(2, "ff".into(), 460)));
        let bad = Schedule::parse("switch tick=3 generation=9\n").unwrap_err();
        assert!(bad.to_string().contains("line 1: no announce"), "{bad}");
        let bad = Schedule::parse("held on\n").unwrap_err();
        assert!(bad.to_string().contains("no number tick="), "{bad}");
    }
}
