//! MOSER's high-level processing module: the patrol planner.
//!
//! It keeps the building's map of rooms and wings. "Patrol wing 3" becomes the wing's rooms'
//! patrol points, each reached by a path planned on an occupancy grid; the path's legs become
//! `turn` and `forward` commands to the mobility module, one at a time. While the base drives,
//! the collision-avoidance module watches the way ahead; when it stops the base short of a
//! waypoint, something the map does not know is in the way: the planner reads the navigation
//! sonar's ranges from its blackboard snapshot, marks what is ahead on the grid, and plans
//! around it. Once a second it reports its progress to the control station.
//!
//! Methods: `patrol(wing)`, `stop()`. Blackboard: `state`, `wing`, `goal`, `replans`, `laps`.
//! A live upgrade carries the patrol under way to the new process (`carried`).

pub mod carried;

use modbot_core::sim::SimTime;
use modbot_core::{CallError, CallHandle, Ctx, MethodError, Reply};
use modbot_ipc_schema::{Args, Value};

use crate::moser::building::Building;
use crate::moser::geometry::P;
use crate::moser::planner::{self, Grid};
use crate::sonar::Ring;

/// REPORT topic of the progress summary to the control station:
/// `[x, y, heading_deg, odometer_m, wing: i64, goal: i64, goals: i64, room: text, state: text]`.
pub const SUMMARY_TOPIC: u8 = 0x20;
/// Grid cell size, metres.
pub const CELL_M: f64 = 0.2;
/// A waypoint counts as reached within this distance, metres.
const REACHED_M: f64 = 0.15;
/// A heading error below this is driven, not turned, degrees.
const ALIGNED_DEG: f64 = 2.0;

/// What the base is doing for the planner.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    /// Nothing in flight: choose the next command.
    Ready,
    /// A command was sent; its answer (the command number) is awaited.
    Sent {
        handle: CallHandle,
        drive_to: Option<P>,
    },
    /// The base executes command `seq`.
    Moving { seq: i64, drive_to: Option<P> },
    /// The command failed; try again after this simulated time.
    Backoff { until_s: f64 },
}

/// The pose and odometry read from the mobility module's snapshot.
#[derive(Debug, Clone, Copy, Default)]
struct Odometry {
    at: P,
    heading_deg: f64,
    done: i64,
    odometer: f64,
}

/// The planner's state.
pub struct HighLevel {
    pub building: Building,
    grid: Grid,
    pub mobility: String,
    pub nav_sonar: String,
    pub station: String,
    pub sim: SimTime,
    nav_ring: Ring,
    patrolling: bool,
    wing: u8,
    goals: Vec<P>,
    goal: usize,
    path: Vec<P>,
    leg: usize,
    step: Step,
    odo: Odometry,
    replans: i64,
    laps: i64,
    next_summary_s: f64,
    /// Whether a pose has arrived from the mobility module yet.
    located: bool,
    /// A patrol asked for before the first pose arrived: it begins with that pose.
    waiting: Option<(u8, Vec<P>)>,
    /// The goal for which a guessed obstacle was dropped (see [`HighLevel::blocked`]).
    guess_dropped_for: Option<(u8, usize)>,
}

impl HighLevel {
    pub fn new(building: Building, mobility: &str, nav_sonar: &str, station: &str) -> HighLevel {
        let grid = Grid::from_building(&building, CELL_M, crate::mobility::RADIUS_M);
        HighLevel {
            building,
            grid,
            mobility: mobility.to_owned(),
            nav_sonar: nav_sonar.to_owned(),
            station: station.to_owned(),
            sim: SimTime::from_env(),
            nav_ring: Ring {
                sensors: 24,
                arc_deg: 360.0,
                ..Ring::default()
            },
            patrolling: false,
            wing: 0,
            goals: Vec::new(),
            goal: 0,
            path: Vec::new(),
            leg: 0,
            step: Step::Ready,
            odo: Odometry::default(),
            replans: 0,
            laps: 0,
            next_summary_s: 0.0,
            located: false,
            waiting: None,
            guess_dropped_for: None,
        }
    }

    fn room_name(&self, p: P) -> &'static str {
        self.building.room_at(p).map_or("corridor", |r| r.name)
    }

    /// Plans the path to the current goal from where the base is.
    fn plan_to_goal(&mut self) -> Result<(), planner::PlanError> {
        let goal = self.goals[self.goal];
        self.path = planner::plan(&self.grid, self.odo.at, goal)?;
        self.leg = 0;
        Ok(())
    }

    /// The base stopped short: mark what the navigation sonar sees ahead, and replan.
    fn blocked(&mut self, ctx: &mut Ctx) {
        let ranges: Option<Vec<f64>> = ctx
            .snapshot_of(&self.nav_sonar.clone(), |v| match v.value("ranges") {
                Ok(Value::F64s(r)) => Some(r.iter().collect()),
                _ => None,
            })
            .ok()
            .flatten()
            .flatten();
        let ahead = |r: f64, bearing: f64| {
            // Ahead within 30°, or in the base's path (what the collision sonar watches: the
            // robot's width, straight on), up to 1.2 m.
            let b = bearing.to_radians();
            r < 1.2
                && (bearing.abs() <= 30.0
                    || (b.cos() > 0.0 && (r * b.sin()).abs() <= crate::sonar::PATH_HALF_WIDTH_M))
        };
        let (at, heading_deg) = (self.odo.at, self.odo.heading_deg);
        let mark = |grid: &mut Grid, r: f64, bearing: f64| {
            let a = (heading_deg + bearing).to_radians();
            let hit = P {
                x: at.x + (r + 0.1) * a.cos(),
                y: at.y + (r + 0.1) * a.sin(),
            };
            grid.mark_blocked(hit, 0.25);
        };
        let mut marked = 0;
        for (i, r) in ranges.unwrap_or_default().into_iter().enumerate() {
            let bearing = self.nav_ring.bearing_deg(i);
            if ahead(r, bearing) {
                mark(&mut self.grid, r, bearing);
                marked += 1;
            }
        }
        // The map before a guess, to drop it again (below).
        let mut before_guess = None;
        if marked == 0 {
            // The collision sonar stopped the base for something within two feet ahead that
            // the navigation sonar's beams missed: mark it there, so the new plan differs.
            before_guess = Some(self.grid.clone());
            mark(&mut self.grid, crate::mobility::TWO_FEET_M, 0.0);
        }
        self.replans += 1;
        let what = match marked {
            0 => "no sonar hit ahead, the spot two feet ahead marked on the map".to_owned(),
            n => format!("{n} sonar hit(s) marked on the map"),
        };
        tracing::info!(
            "blocked at ({:.2}, {:.2}) in {}: {what}, replanning",
            self.odo.at.x,
            self.odo.at.y,
            self.room_name(self.odo.at)
        );
        let mut planned = self.plan_to_goal();
        let this_goal = Some((self.wing, self.goal));
        let retry = planned.is_err() && self.guess_dropped_for != this_goal;
        if let Some(before) = before_guess.filter(|_| retry) {
            // Nothing the sonar sees, and the guess would close the way: what stopped the
            // base is more likely something passing (a person) or an echo off a corner than a
            // wall the map lacks. Drop the guess and try once more; a second stop on the way to
            // this goal marks it for good.
            tracing::info!(
                "the guessed obstacle would close the way to the goal: trying again without it"
            );
            self.grid = before;
            self.guess_dropped_for = this_goal;
            planned = self.plan_to_goal();
        }
        if let Err(e) = planned {
            tracing::warn!("no way to the goal after the obstacle ({e}); skipping it");
            self.next_goal();
        }
        let _ = ctx.bb.write("replans", Value::I64(self.replans));
    }

    /// On to the next room of the wing (and round again after the last).
    fn next_goal(&mut self) {
        self.goal += 1;
        if self.goal >= self.goals.len() {
            self.goal = 0;
            self.laps += 1;
            tracing::info!("wing {} patrolled ({} lap(s))", self.wing, self.laps);
        }
        if let Err(e) = self.plan_to_goal() {
            tracing::warn!("no path to goal {}: {e}", self.goal);
            self.path.clear();
        }
    }

    /// Chooses and sends the next command.
    fn next_command(&mut self, ctx: &mut Ctx) {
        if self.leg >= self.path.len() {
            let here = self.room_name(self.odo.at);
            tracing::info!(
                "reached patrol point {}/{} in {here}",
                self.goal + 1,
                self.goals.len()
            );
            self.next_goal();
            return;
        }
        let target = self.path[self.leg];
        let bearing = self.odo.at.angle_to(target).to_degrees();
        let turn = (bearing - self.odo.heading_deg + 540.0).rem_euclid(360.0) - 180.0;
        let (method, amount, drive_to) = if turn.abs() > ALIGNED_DEG {
            ("turn", turn, None)
        } else {
            ("forward", self.odo.at.dist(target), Some(target))
        };
        let mobility = self.mobility.clone();
        match ctx.call(&mobility, method, &[Value::F64(amount)]) {
            Ok(handle) => self.step = Step::Sent { handle, drive_to },
            Err(e) => {
                tracing::warn!("{method} not sent: {e}");
                self.step = Step::Backoff {
                    until_s: self.sim.seconds(ctx.now_ns()) + 1.0,
                };
            }
        }
    }

    fn read_odometry(&mut self, ctx: &mut Ctx) {
        let mobility = self.mobility.clone();
        if let Ok(Some(odo)) = ctx.snapshot_of(&mobility, |v| Odometry {
            at: P {
                x: v.f64("x").unwrap_or(0.0),
                y: v.f64("y").unwrap_or(0.0),
            },
            heading_deg: v.f64("heading").unwrap_or(0.0),
            done: match v.value("done") {
                Ok(Value::I64(n)) => n,
                _ => 0,
            },
            odometer: v.f64("odometer").unwrap_or(0.0),
        }) {
            self.odo = odo;
            self.located = true;
        }
    }

    fn summary(&mut self, ctx: &mut Ctx, now_s: f64) {
        if now_s < self.next_summary_s || !self.located {
            return;
        }
        self.next_summary_s = now_s + 1.0;
        let state = if self.patrolling {
            "patrolling"
        } else {
            "idle"
        };
        let room = self.room_name(self.odo.at);
        let station = self.station.clone();
        let values = [
            Value::F64(self.odo.at.x),
            Value::F64(self.odo.at.y),
            Value::F64(self.odo.heading_deg),
            Value::F64(self.odo.odometer),
            Value::I64(i64::from(self.wing)),
            Value::I64(self.goal as i64 + 1),
            Value::I64(self.goals.len() as i64),
            Value::Text(room),
            Value::Text(state),
        ];
        if let Err(e) = ctx.report_to(&station, SUMMARY_TOPIC, &values) {
            tracing::debug!("summary not delivered: {e}");
        }
    }
}

/// `patrol(wing)`: patrols the wing's rooms, round and round, until `stop`.
pub fn patrol(
    h: &mut HighLevel,
    ctx: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let wing = args.i64(0)?;
    let wing = u8::try_from(wing)
        .map_err(|_| MethodError::Failed(format!("no wing {wing} in this building")))?;
    let goals =
        planner::patrol_route(&h.building, wing).map_err(|e| MethodError::Failed(e.to_string()))?;
    h.read_odometry(ctx);
    if !h.located {
        // Taken: it begins with the first pose (the mobility module's first snapshot).
        tracing::info!(
            "patrol of wing {wing} taken: it begins with the first pose from {}",
            h.mobility
        );
        h.waiting = Some((wing, goals));
        let _ = ctx.bb.write("state", Value::Text("waiting for a pose"));
        return Ok(());
    }
    begin_patrol(h, ctx, wing, goals).map_err(|e| MethodError::Failed(e.to_string()))
}

/// Begins patrolling `wing` along `goals` from where the base is.
fn begin_patrol(
    h: &mut HighLevel,
    ctx: &mut Ctx,
    wing: u8,
    goals: Vec<P>,
) -> Result<(), planner::PlanError> {
    h.waiting = None;
    h.wing = wing;
    h.goals = goals;
    h.goal = 0;
    h.plan_to_goal()?;
    h.patrolling = true;
    h.step = Step::Ready;
    tracing::info!(
        "patrolling wing {wing}: {} patrol points, first path {} legs",
        h.goals.len(),
        h.path.len()
    );
    let _ = ctx.bb.write("state", Value::Text("patrolling"));
    let _ = ctx.bb.write("wing", Value::I64(i64::from(wing)));
    Ok(())
}

/// `stop()`: stops patrolling and the base.
pub fn stop(
    h: &mut HighLevel,
    ctx: &mut Ctx,
    _: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    h.patrolling = false;
    h.waiting = None;
    h.step = Step::Ready;
    let mobility = h.mobility.clone();
    ctx.call(&mobility, "stop", &[])
        .map_err(|e| MethodError::Failed(format!("the base did not take the stop: {e}")))?;
    tracing::info!("patrol stopped");
    let _ = ctx.bb.write("state", Value::Text("idle"));
    Ok(())
}

/// The answer to a motion command: its number, to wait for.
pub fn on_done(
    h: &mut HighLevel,
    ctx: &mut Ctx,
    handle: CallHandle,
    result: Result<&Args<'_>, &CallError>,
) {
    let Step::Sent {
        handle: sent,
        drive_to,
    } = h.step
    else {
        return;
    };
    if sent != handle {
        return;
    }
    h.step = match result.map(|a| a.i64(0)) {
        Ok(Ok(seq)) => Step::Moving { seq, drive_to },
        Ok(Err(e)) => {
            tracing::warn!("odd answer from {}: {e}", h.mobility);
            Step::Backoff {
                until_s: h.sim.seconds(ctx.now_ns()) + 1.0,
            }
        }
        Err(e) => {
            tracing::warn!("motion refused: {e}");
            Step::Backoff {
                until_s: h.sim.seconds(ctx.now_ns()) + 1.0,
            }
        }
    };
}

/// Periodic: follow the plan.
pub fn tick(h: &mut HighLevel, ctx: &mut Ctx) {
    let now_s = h.sim.seconds(ctx.now_ns());
    h.read_odometry(ctx);
    h.summary(ctx, now_s);
    if h.located {
        if let Some((wing, goals)) = h.waiting.take() {
            if let Err(e) = begin_patrol(h, ctx, wing, goals) {
                tracing::error!("the patrol of wing {wing} cannot begin: {e}");
            }
        }
    }
    if !h.patrolling {
        return;
    }
    match h.step {
        Step::Ready => h.next_command(ctx),
        Step::Sent { .. } => {}
        Step::Backoff { until_s } => {
            if now_s >= until_s {
                h.step = Step::Ready;
            }
        }
        Step::Moving { seq, drive_to } => {
            if h.odo.done < seq {
                return;
            }
            h.step = Step::Ready;
            if let Some(target) = drive_to {
                if h.odo.at.dist(target) <= REACHED_M {
                    h.leg += 1;
                } else {
                    h.blocked(ctx);
                }
            }
            let _ = ctx.bb.write("goal", Value::I64(h.goal as i64 + 1));
        }
    }
}
