//! The planner's state a live upgrade carries to the new process (`modbot upgrade
//! high_level`): the patrol under way — wing, patrol point, path and leg, laps and replans,
//! what the base is doing — and the obstacles marked on the grid. Version [`VERSION`], little
//! endian: patrolling (u8), wing (u8), goal (u32), leg (u32), laps (i64), replans (i64), next
//! summary (f64 s), step (u8: 0 ready, 1 moving + seq i64 + drive-to, 2 backoff + until f64 s),
//! a patrol waiting for a pose (u8 flag + wing u8), the guess dropped for (u8 flag + wing u8 +
//! goal u32), the path (u32 count + points), the grid's cells (u32 count + bytes). A point is
//! x, y (f64); a drive-to is a u8 flag and a point.

use modbot_core::Ctx;
use modbot_ipc_schema::Value;

use super::{HighLevel, Step};
use crate::moser::geometry::P;
use crate::moser::planner;

/// The version of the carried state.
pub const VERSION: u32 = 1;

/// The state as bytes (see the file's doc).
pub fn upgrade_out(h: &HighLevel) -> Vec<u8> {
    let mut w = Vec::with_capacity(64 + h.path.len() * 16 + h.grid.cells().len());
    w.push(u8::from(h.patrolling));
    w.push(h.wing);
    w.extend_from_slice(&(h.goal as u32).to_le_bytes());
    w.extend_from_slice(&(h.leg as u32).to_le_bytes());
    w.extend_from_slice(&h.laps.to_le_bytes());
    w.extend_from_slice(&h.replans.to_le_bytes());
    w.extend_from_slice(&h.next_summary_s.to_le_bytes());
    let point = |w: &mut Vec<u8>, p: P| {
        w.extend_from_slice(&p.x.to_le_bytes());
        w.extend_from_slice(&p.y.to_le_bytes());
    };
    match h.step {
        Step::Moving { seq, drive_to } => {
            w.push(1);
            w.extend_from_slice(&seq.to_le_bytes());
            w.push(u8::from(drive_to.is_some()));
            point(&mut w, drive_to.unwrap_or_default());
        }
        Step::Backoff { until_s } => {
            w.push(2);
            w.extend_from_slice(&until_s.to_le_bytes());
        }
        // A command whose answer did not come before the handover: the new process chooses
        // the next one from where the base is.
        Step::Ready | Step::Sent { .. } => w.push(0),
    }
    w.push(u8::from(h.waiting.is_some()));
    w.push(h.waiting.as_ref().map_or(0, |(wing, _)| *wing));
    w.push(u8::from(h.guess_dropped_for.is_some()));
    let (gw, gg) = h.guess_dropped_for.unwrap_or((0, 0));
    w.push(gw);
    w.extend_from_slice(&(gg as u32).to_le_bytes());
    w.extend_from_slice(&(h.path.len() as u32).to_le_bytes());
    for p in &h.path {
        point(&mut w, *p);
    }
    let cells = h.grid.cells();
    w.extend_from_slice(&(cells.len() as u32).to_le_bytes());
    w.extend_from_slice(cells);
    w
}

/// Reads bytes in order, refusing to read past their end.
struct Reader<'a> {
    rest: &'a [u8],
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        let Some((head, rest)) = self.rest.split_first_chunk::<N>() else {
            return Err(format!("the state ends before {what}"));
        };
        self.rest = rest;
        Ok(*head)
    }
    fn u8(&mut self, what: &str) -> Result<u8, String> {
        Ok(self.take::<1>(what)?[0])
    }
    fn u32(&mut self, what: &str) -> Result<usize, String> {
        Ok(u32::from_le_bytes(self.take(what)?) as usize)
    }
    fn i64(&mut self, what: &str) -> Result<i64, String> {
        Ok(i64::from_le_bytes(self.take(what)?))
    }
    fn f64(&mut self, what: &str) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.take(what)?))
    }
    fn point(&mut self, what: &str) -> Result<P, String> {
        Ok(P {
            x: self.f64(what)?,
            y: self.f64(what)?,
        })
    }
}

/// Takes [`upgrade_out`]'s state over; refuses another version, or state that does not fit
/// this program's building (another grid, an unknown wing).
pub fn upgrade_in(
    h: &mut HighLevel,
    ctx: &mut Ctx,
    version: u32,
    bytes: &[u8],
) -> Result<(), String> {
    if version != VERSION {
        return Err(format!(
            "state version {version}; this program reads version {VERSION}"
        ));
    }
    take(h, bytes)?;
    let _ = ctx.bb.write("replans", Value::I64(h.replans));
    Ok(())
}

/// Reads the state into `h`, which is left as it was if the state is refused.
fn take(h: &mut HighLevel, bytes: &[u8]) -> Result<(), String> {
    let mut r = Reader { rest: bytes };
    let patrolling = r.u8("patrolling")? != 0;
    let wing = r.u8("the wing")?;
    let goal = r.u32("the goal")?;
    let leg = r.u32("the leg")?;
    let laps = r.i64("the laps")?;
    let replans = r.i64("the replans")?;
    let next_summary_s = r.f64("the next summary")?;
    let step = match r.u8("the step")? {
        0 => Step::Ready,
        1 => {
            let seq = r.i64("the command")?;
            let has = r.u8("the drive-to")? != 0;
            let to = r.point("the drive-to")?;
            Step::Moving {
                seq,
                drive_to: has.then_some(to),
            }
        }
        2 => Step::Backoff {
            until_s: r.f64("the backoff")?,
        },
        s => return Err(format!("unknown step {s}")),
    };
    let waiting = (r.u8("the waiting patrol")? != 0, r.u8("its wing")?);
    let guess = (
        r.u8("the dropped guess")? != 0,
        r.u8("its wing")?,
        r.u32("its goal")?,
    );
    let n = r.u32("the path")?;
    let path = (0..n)
        .map(|_| r.point("the path"))
        .collect::<Result<Vec<_>, _>>()?;
    let n = r.u32("the grid")?;
    let cells = (0..n)
        .map(|_| r.u8("the grid"))
        .collect::<Result<Vec<_>, _>>()?;
    let grid = h.grid.with_cells(cells)?;
    let goals = if patrolling {
        planner::patrol_route(&h.building, wing).map_err(|e| e.to_string())?
    } else {
        Vec::new()
    };
    if patrolling && goal >= goals.len() {
        return Err(format!(
            "patrol point {goal} of {} in wing {wing}",
            goals.len()
        ));
    }
    h.patrolling = patrolling;
    h.wing = wing;
    h.goals = goals;
    h.goal = goal;
    h.path = path;
    h.leg = leg;
    h.laps = laps;
    h.replans = replans;
    h.next_summary_s = next_summary_s;
    h.step = step;
    h.grid = grid;
    h.guess_dropped_for = guess.0.then_some((guess.1, guess.2));
    if waiting.0 {
        let goals = planner::patrol_route(&h.building, waiting.1).map_err(|e| e.to_string())?;
        h.waiting = Some((waiting.1, goals));
    }
    tracing::info!(
        "took the patrol over: {}, point {}/{}, leg {}/{}, {} replan(s)",
        if patrolling { "patrolling" } else { "idle" },
        goal + 1,
        h.goals.len(),
        leg,
        h.path.len(),
        replans
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::moser::building::moser_building;

    fn planner() -> HighLevel {
        HighLevel::new(moser_building(), "mobility", "nav_sonar", "station")
    }

    #[test]
    fn a_patrol_under_way_is_carried_whole_to_the_new_process() {
        let mut old = planner();
        old.patrolling = true;
        old.wing = 3;
        old.goals = planner::patrol_route(&old.building, 3).unwrap();
        old.goal = 2;
        old.path = vec![P::new(1.0, 2.0), P::new(3.5, 2.0)];
        old.leg = 1;
        old.laps = 1;
        old.replans = 4;
        old.step = Step::Moving {
            seq: 17,
            drive_to: Some(P::new(3.5, 2.0)),
        };
        old.guess_dropped_for = Some((3, 2));
        old.grid.mark_blocked(P::new(25.0, 6.0), 0.25);
        let mut new = planner();
        take(&mut new, &upgrade_out(&old)).unwrap();
        assert_eq!(
            (
                new.patrolling,
                new.wing,
                new.goal,
                new.leg,
                new.laps,
                new.replans
            ),
            (true, 3, 2, 1, 1, 4)
        );
        assert_eq!(
            (new.goals, new.path, new.step),
            (old.goals, old.path, old.step)
        );
        assert_eq!(new.guess_dropped_for, Some((3, 2)));
        assert!(new.grid == old.grid && new.grid != planner().grid);
    }

    #[test]
    fn a_truncated_state_is_refused_and_changes_nothing() {
        let mut old = planner();
        old.patrolling = true;
        old.wing = 3;
        old.goals = planner::patrol_route(&old.building, 3).unwrap();
        let bytes = upgrade_out(&old);
        let mut new = planner();
        let refused = take(&mut new, &bytes[..bytes.len() - 1]).unwrap_err();
        assert!(refused.contains("the grid"), "{refused}");
        assert!(!new.patrolling);
    }
}
