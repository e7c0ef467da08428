//! The grid's gate (lockstep only): whoever owns it steps the grid, so the ticks at which a
//! robot program reads, commands and switches are the same in every run.
//!
//! The gate holds the grid before tick `until`: every tick below it runs, then the tick thread
//! waits until every release is done and says the grid is *held* there. Its owner — the
//! module that took it with `gate()` — moves it on (`gate(until)`) and lifts it (`ungate()`).
//! `modbot up --lockstep --gate TICK` starts with an unowned gate at TICK, for a program to
//! take. The gate is lifted by itself, so a program that died or hangs never holds a robot's
//! grid: when its owner is gone (no live module at its address, or another process there),
//! or when neither owner nor anyone else has called it for [`LEASE`] — shorter than the bus
//! bridge's lockstep watchdog, which safe-stops a robot whose grid is silent for 30 s.
//!
//! This file decides; the service thread calls it and tells the tick thread (a
//! [`super::tick_thread::ToTick::Gate`] with a sequence number, whose
//! [`super::tick_thread::FromTick::Held`] answers only that setting).

use modbot_ipc_schema::Addr;

/// How long a gate stays without a call of its owner.
pub const LEASE_NS: u64 = 20_000_000_000;

// A gate held past the bus bridge's lockstep watchdog would safe-stop the robot.
const _: () = assert!(LEASE_NS < modbot_bus::bridge::LOCKSTEP_LOST_AFTER_NS);

/// The module that owns the gate: its address, and its process when known (from the directory,
/// or as a tool the directory does not list says it: without it, only the lease frees the
/// gate of a caller that died).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Owner {
    pub addr: Addr,
    pub pid: Option<u32>,
}

/// What `gate()` answers: the tick the grid holds before (or will hold before), and whether
/// it is held there now (every release before it done).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GateAnswer {
    pub next: u64,
    pub held: bool,
}

/// Why a call on the gate was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GateRefused {
    /// Another live module owns it (`name`: as the directory or the owner's process says).
    #[error("the grid is stepped by {name}; it owns the gate until it lifts it, ends, or does not call for 20 s")]
    Owned { name: String },
    /// The gate is not the caller's to move or lift.
    #[error("the gate is not yours: take it first with gate()")]
    NotOwner,
    /// A gate below where the grid already is.
    #[error("the grid is already at tick {at}: the gate cannot go back to tick {until}")]
    Behind { until: u64, at: u64 },
    /// The grid follows real time.
    #[error("a real-time grid keeps its own time: the gate is for a grid in lockstep")]
    RealTime,
    /// The caller owned the gate, lost it (`why`), and moves it as if it still stepped the
    /// grid: it is told once, so that it says its run is not the same as another.
    #[error("the gate was taken from this caller: {why}")]
    Lost { why: String },
}

/// A change the tick thread must be told of: hold before `until` (`None`: run free), answered
/// by a held report carrying `seq`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Setting {
    pub until: Option<u64>,
    pub seq: u32,
}

/// The gate as the service thread keeps it.
#[derive(Debug, Clone, Default)]
pub struct Gate {
    until: Option<u64>,
    seq: u32,
    owner: Option<Owner>,
    /// The last call on the gate (or its setting at the start), ns.
    touched_ns: u64,
    /// The tick the grid is held before, as the tick thread said for the current `seq`.
    held: Option<u64>,
    /// Why the gate was lifted by itself last, for its next caller.
    lifted: Option<String>,
    /// The owner it was lifted from, and why: told when it next moves the gate.
    lost: Option<(Addr, String)>,
}

impl Gate {
    /// A gate at `until` from the start (`--gate`), unowned; `now_ns` starts its lease.
    pub fn initial(until: Option<u64>, now_ns: u64) -> (Gate, Option<Setting>) {
        let mut gate = Gate {
            touched_ns: now_ns,
            ..Gate::default()
        };
        let setting = until.map(|t| gate.set(Some(t)));
        (gate, setting)
    }

    fn set(&mut self, until: Option<u64>) -> Setting {
        self.until = until;
        self.seq = self.seq.wrapping_add(1);
        self.held = None;
        Setting {
            until,
            seq: self.seq,
        }
    }

    /// The tick thread held the grid before `next` for setting `seq` (ignored if the gate has
    /// been set again since).
    pub fn held(&mut self, seq: u32, next: u64) {
        if seq == self.seq && self.until.is_some() {
            self.held = Some(next);
        }
    }

    /// The module that owns the gate, if one does.
    pub fn owner(&self) -> Option<Owner> {
        self.owner
    }

    /// What the gate answers now; `ticks`: the grid's tick as last reported.
    pub fn answer(&self, ticks: u64) -> GateAnswer {
        match (self.held, self.until) {
            (Some(next), _) => GateAnswer { next, held: true },
            (None, Some(until)) => GateAnswer {
                next: until,
                held: false,
            },
            (None, None) => GateAnswer {
                next: ticks,
                held: false,
            },
        }
    }

    /// Why the gate was last lifted by itself, once (the next `gate()` of a program that lost
    /// it says so).
    pub fn take_lifted(&mut self) -> Option<String> {
        self.lifted.take()
    }

    /// `gate()` or `gate(until)` by `caller`: takes the gate if it is free (unowned, or its
    /// owner is gone: `alive` says), and moves it to `until` if given, else — a free gate
    /// taken while the grid runs — holds the grid at the tick it has reached (`ticks`).
    /// Refused while another live module owns it.
    pub fn call(
        &mut self,
        caller: Owner,
        until: Option<u64>,
        ticks: u64,
        now_ns: u64,
        owner_name: impl Fn(Owner) -> Option<String>,
    ) -> Result<(GateAnswer, Option<Setting>), GateRefused> {
        if let Some(owner) = self.owner.filter(|o| *o != caller) {
            if let Some(name) = owner_name(owner) {
                return Err(GateRefused::Owned { name });
            }
        }
        // Whoever calls next, the one that lost the gate is told only until then.
        if let Some((lost_by, why)) = self.lost.take() {
            if until.is_some() && lost_by == caller.addr && self.owner.is_none() {
                // Told now: not again when it takes the gate back.
                self.lifted = None;
                return Err(GateRefused::Lost { why });
            }
        }
        self.owner = Some(caller);
        self.touched_ns = now_ns;
        let at = self.held.unwrap_or(ticks);
        let setting = match (until, self.until) {
            (Some(t), _) if t < at => return Err(GateRefused::Behind { until: t, at }),
            (Some(t), Some(now)) if t == now => None,
            (Some(t), _) => Some(self.set(Some(t))),
            (None, None) => Some(self.set(Some(ticks))),
            (None, Some(_)) => None,
        };
        Ok((self.answer(ticks), setting))
    }

    /// `ungate()` by the caller at `addr`: the grid runs free again. The owner's address is
    /// enough (a tool that owns the gate names its process only when it takes it).
    pub fn lift(&mut self, addr: Addr) -> Result<Setting, GateRefused> {
        if self.owner.map(|o| o.addr) != Some(addr) {
            return Err(GateRefused::NotOwner);
        }
        self.owner = None;
        Ok(self.set(None))
    }

    /// The periodic look (every 200 ms): lifts the gate when its owner is gone (`owner_name`
    /// finds no live module of its address and pid) or its lease ran out; returns the setting
    /// to send and why.
    pub fn look(
        &mut self,
        now_ns: u64,
        ticks: u64,
        owner_name: impl Fn(Owner) -> Option<String>,
    ) -> Option<(Setting, String)> {
        self.until?;
        let why = match self.owner {
            Some(owner) if owner_name(owner).is_none() => format!(
                "its owner (address {}{}) is gone",
                owner.addr.0,
                owner.pid.map_or(String::new(), |p| format!(", pid {p}"))
            ),
            _ if now_ns.saturating_sub(self.touched_ns) >= LEASE_NS => {
                format!("no call for {} s", LEASE_NS / 1_000_000_000)
            }
            _ => return None,
        };
        let why = format!(
            "the gate was lifted at tick {} ({why}): the grid ran on by itself",
            self.held.unwrap_or(ticks)
        );
        self.lost = self.owner.take().map(|o| (o.addr, why.clone()));
        self.lifted = Some(why.clone());
        Some((self.set(None), why))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: Owner = Owner {
        addr: Addr(7),
        pid: Some(100),
    };
    const B: Owner = Owner {
        addr: Addr(8),
        pid: Some(200),
    };

    fn alive(o: Owner) -> Option<String> {
        Some(format!("m{}", o.addr.0))
    }

    fn gone(_: Owner) -> Option<String> {
        None
    }

    #[test]
    fn an_initial_gate_holds_unowned_and_says_held_once_the_tick_thread_does() {
        let (mut sut, setting) = Gate::initial(Some(500), 0);
        let setting = setting.expect("a setting for the tick thread");
        assert_eq!(setting.until, Some(500));
        assert_eq!(
            sut.answer(480),
            GateAnswer {
                next: 500,
                held: false
            }
        );
        sut.held(setting.seq, 500);
        assert_eq!(
            sut.answer(500),
            GateAnswer {
                next: 500,
                held: true
            }
        );
        // A program takes it: the gate stays where it is, held.
        let (answer, change) = sut.call(A, None, 500, 1, alive).unwrap();
        assert_eq!(
            (answer, change),
            (
                GateAnswer {
                    next: 500,
                    held: true
                },
                None
            )
        );
    }

    #[test]
    fn a_free_gate_taken_while_the_grid_runs_holds_it_where_it_is() {
        let (mut sut, none) = Gate::initial(None, 0);
        assert_eq!(none, None);
        let (answer, change) = sut.call(A, None, 1234, 5, alive).unwrap();
        assert_eq!(change.map(|s| s.until), Some(Some(1234)));
        assert!(!answer.held);
    }

    #[test]
    fn the_owner_moves_the_gate_and_a_held_report_of_an_older_setting_is_ignored() {
        let (mut sut, first) = Gate::initial(Some(100), 0);
        let first = first.unwrap();
        sut.held(first.seq, 100);
        sut.call(A, None, 100, 1, alive).unwrap();
        let (answer, change) = sut.call(A, Some(110), 100, 2, alive).unwrap();
        let change = change.unwrap();
        assert_eq!(
            answer,
            GateAnswer {
                next: 110,
                held: false
            }
        );
        sut.held(first.seq, 100);
        assert!(!sut.answer(100).held, "a report of the old setting");
        sut.held(change.seq, 110);
        assert_eq!(
            sut.answer(110),
            GateAnswer {
                next: 110,
                held: true
            }
        );
        assert_eq!(
            sut.call(A, Some(105), 110, 3, alive).unwrap_err(),
            GateRefused::Behind {
                until: 105,
                at: 110
            }
        );
    }

    #[test]
    fn another_live_module_is_refused_but_takes_the_gate_of_one_that_is_gone() {
        let (mut sut, _) = Gate::initial(Some(100), 0);
        sut.call(A, None, 100, 1, alive).unwrap();
        let refused = sut.call(B, Some(200), 100, 2, alive).unwrap_err();
        assert_eq!(
            refused.to_string(),
            "the grid is stepped by m7; it owns the gate until it lifts it, ends, or does not call for 20 s"
        );
        assert_eq!(sut.lift(B.addr).unwrap_err(), GateRefused::NotOwner);
        let (answer, _) = sut.call(B, Some(200), 100, 3, gone).unwrap();
        assert_eq!(answer.next, 200);
    }

    #[test]
    fn a_gate_whose_owner_is_gone_or_silent_for_the_lease_is_lifted_with_the_reason() {
        let (mut sut, _) = Gate::initial(Some(100), 0);
        sut.call(A, None, 100, 0, alive).unwrap();
        assert_eq!(sut.look(1_000, 100, alive), None);
        let (setting, why) = sut.look(2_000, 100, gone).expect("lifted");
        assert_eq!(setting.until, None);
        assert!(
            why.contains("its owner (address 7, pid 100) is gone"),
            "{why}"
        );
        assert_eq!(sut.take_lifted(), Some(why.clone()));
        // Its owner, stepping on as if it still held it, is told once; then takes it again.
        assert_eq!(
            sut.call(A, Some(110), 150, 3_000, alive).unwrap_err(),
            GateRefused::Lost { why }
        );
        assert!(sut.call(A, None, 150, 3_001, alive).is_ok());
        // Unowned, from the start: the lease.
        let (mut sut, _) = Gate::initial(Some(100), 0);
        assert_eq!(sut.look(LEASE_NS - 1, 100, alive), None);
        let (_, why) = sut.look(LEASE_NS, 100, alive).expect("lifted");
        assert!(
            why.ends_with("(no call for 20 s): the grid ran on by itself"),
            "{why}"
        );
        // A lifted gate has nothing to look at.
        assert_eq!(sut.look(2 * LEASE_NS, 100, gone), None);
    }

    #[test]
    fn who_takes_a_gate_lifted_by_itself_learns_why_once_and_its_lost_owner_is_told_only_once() {
        // `--gate 100`, and no program came for the lease: the first taker learns why.
        let (mut sut, _) = Gate::initial(Some(100), 0);
        let (_, why) = sut.look(LEASE_NS, 100, alive).expect("lifted");
        sut.call(A, None, 180, LEASE_NS + 1, alive).unwrap();
        assert_eq!(sut.take_lifted(), Some(why));
        assert_eq!(sut.take_lifted(), None);
        // An owner that lost it is told by the refusal of its next move, not again after.
        let (_, why) = sut.look(2 * LEASE_NS + 2, 180, gone).expect("lifted");
        assert_eq!(
            sut.call(A, Some(200), 250, 2 * LEASE_NS + 3, alive)
                .unwrap_err(),
            GateRefused::Lost { why }
        );
        sut.call(A, None, 250, 2 * LEASE_NS + 4, alive).unwrap();
        assert_eq!(sut.take_lifted(), None);
    }

    #[test]
    fn the_owner_lifts_the_gate() {
        let (mut sut, _) = Gate::initial(Some(100), 0);
        sut.call(A, None, 100, 0, alive).unwrap();
        assert_eq!(sut.lift(A.addr).unwrap().until, None);
        assert_eq!(
            sut.answer(140),
            GateAnswer {
                next: 140,
                held: false
            }
        );
    }
}
