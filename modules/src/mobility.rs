//! The mobility module: a simulated base that starts at (0, 0) heading along +x (or at a
//! building's start).
//!
//! `forward(m)` drives ahead at a constant speed and asks the collision-avoidance module to
//! monitor at two feet (0.61 m); the base stops when it reports, or when the distance is covered.
//! `turn(deg)` turns in place (positive is to the left); `stop()` stops; `use_collision(module)`
//! names another collision-avoidance module (the near-infrared ring can stand in for the sonar).
//! Odometry goes to the blackboard items `x`, `y`, `heading` (degrees), `moving` and `odometer`
//! (metres driven). Each motion command answers with its number; `done` holds the number of
//! the last one finished, so a planner knows when a motion is over.
//!
//! In a simulated building the base also checks its body (a disc) against the walls and
//! furniture: a move that would touch one is stopped and counted in `collisions`. Time may run
//! faster than real time: every step is scaled by the system's simulation speed.

use modbot_core::blackboard::ItemId;
use modbot_core::{CallError, CallHandle, Ctx, MethodError, Reply, Report};
use modbot_ipc_schema::{Args, Value};

use crate::moser::building::Building;
use crate::moser::geometry::P;

/// The base's radius, in metres.
pub const RADIUS_M: f64 = 0.3;

/// Two feet, in metres: the sonar's monitoring threshold while the base moves.
pub const TWO_FEET_M: f64 = 0.61;

/// The base's state.
#[derive(Debug)]
pub struct Base {
    /// Forward speed, m/s.
    pub speed: f64,
    /// Turn rate, degrees/s.
    pub turn_rate: f64,
    /// Distance still to drive, m.
    pub remaining_m: f64,
    /// Angle still to turn, degrees.
    pub remaining_deg: f64,
    /// The sonar module watching the way ahead.
    pub sonar: String,
    /// When the pose was last integrated (ns).
    pub last_ns: u64,
    pub ids: Ids,
    /// The monitor call in flight.
    pub monitor_call: Option<CallHandle>,
    /// Walls and furniture to collide with, in a simulated building.
    pub building: Option<Box<Building>>,
    /// Simulated seconds per real second.
    pub sim_speed: f64,
    /// Number of the last motion command accepted.
    pub cmd_seq: i64,
    /// Times the body touched a wall or obstacle.
    pub collisions: i64,
}

/// Blackboard handles, looked up once.
#[derive(Debug, Clone, Copy)]
pub struct Ids {
    pub x: ItemId,
    pub y: ItemId,
    pub heading: ItemId,
    pub moving: ItemId,
    pub odometer: ItemId,
    pub collisions: ItemId,
    pub done: ItemId,
}

fn halt(b: &mut Base, ctx: &mut Ctx, why: &str) {
    if b.remaining_m > 0.0 || b.remaining_deg != 0.0 {
        tracing::info!(
            "stopping at x={:.3} y={:.3}: {why}",
            ctx.bb.f64("x"),
            ctx.bb.f64("y")
        );
    }
    b.remaining_m = 0.0;
    b.remaining_deg = 0.0;
    ctx.bb.set_bool(b.ids.moving, false);
    let _ = ctx.bb.write_id(b.ids.done, Value::I64(b.cmd_seq));
}

/// Accepts a motion command: answers its number.
fn accept(b: &mut Base, ctx: &mut Ctx, reply: &mut Reply) {
    b.cmd_seq += 1;
    b.last_ns = ctx.now_ns();
    reply.push(Value::I64(b.cmd_seq));
}

/// `forward(m)` → the command's number.
pub fn forward(
    b: &mut Base,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let m = args.f64(0)?;
    if !(m.is_finite() && m >= 0.0) {
        return Err(MethodError::BadArguments(
            modbot_ipc_schema::ArgError::Invalid {
                index: 0,
                reason: "distance must be >= 0 m",
            },
        ));
    }
    let sonar = b.sonar.clone();
    let handle = ctx
        .call(&sonar, "monitor", &[Value::F64(TWO_FEET_M)])
        .map_err(|e| {
            MethodError::NotReady(format!("collision avoidance unavailable, not moving: {e}"))
        })?;
    b.monitor_call = Some(handle);
    accept(b, ctx, reply);
    b.remaining_m = m;
    b.remaining_deg = 0.0;
    ctx.bb.set_bool(b.ids.moving, true);
    tracing::info!("forward {m} m");
    Ok(())
}

/// `turn(deg)` → the command's number.
pub fn turn(
    b: &mut Base,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let deg = args.f64(0)?;
    if !deg.is_finite() {
        return Err(MethodError::BadArguments(
            modbot_ipc_schema::ArgError::Invalid {
                index: 0,
                reason: "angle must be finite",
            },
        ));
    }
    accept(b, ctx, reply);
    b.remaining_m = 0.0;
    b.remaining_deg = deg;
    ctx.bb.set_bool(b.ids.moving, deg != 0.0);
    if deg == 0.0 {
        let _ = ctx.bb.write_id(b.ids.done, Value::I64(b.cmd_seq));
    }
    Ok(())
}

/// `use_collision(module)`: another module watches the way ahead from the next `forward` on.
pub fn use_collision(
    b: &mut Base,
    _: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let module = args.text(0)?;
    tracing::info!("collision avoidance now by {module}");
    b.sonar = module.to_owned();
    Ok(())
}

/// `stop()`.
pub fn stop(b: &mut Base, ctx: &mut Ctx, _: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    halt(b, ctx, "stop requested");
    Ok(())
}

/// The sonar's report: something is within two feet.
pub fn on_report(b: &mut Base, ctx: &mut Ctx, r: &Report<'_>) {
    if r.topic == crate::sonar::MONITOR_TOPIC {
        let range = r.values.f64(0).unwrap_or(f64::NAN);
        halt(b, ctx, &format!("sonar reports an object at {range:.3} m"));
    }
}

/// The answer to the monitor call: if the sonar refused or vanished, the base must not drive blind.
pub fn on_done(
    b: &mut Base,
    ctx: &mut Ctx,
    handle: CallHandle,
    result: Result<&Args<'_>, &CallError>,
) {
    if b.monitor_call == Some(handle) {
        b.monitor_call = None;
        if let Err(e) = result {
            halt(b, ctx, &format!("collision avoidance failed: {e}"));
        }
    }
}

/// Periodic: integrate the motion.
pub fn tick(b: &mut Base, ctx: &mut Ctx) {
    let now = ctx.now_ns();
    let dt = now.saturating_sub(b.last_ns) as f64 * 1e-9 * b.sim_speed;
    b.last_ns = now;
    if b.remaining_m > 0.0 {
        let step = (b.speed * dt).min(b.remaining_m);
        let h = ctx.bb.f64("heading").to_radians();
        let (x, y) = (
            ctx.bb.f64("x") + step * h.cos(),
            ctx.bb.f64("y") + step * h.sin(),
        );
        if let Some(building) = &b.building {
            if building.collides(P { x, y }, RADIUS_M) {
                // The bumper: the body would touch a wall or obstacle. Collision avoidance
                // failed; the base stops and counts it.
                b.collisions += 1;
                let _ = ctx.bb.write_id(b.ids.collisions, Value::I64(b.collisions));
                tracing::warn!(
                    "COLLISION: the base touched a wall or obstacle at ({x:.2}, {y:.2})"
                );
                halt(b, ctx, "bumper hit");
                return;
            }
        }
        b.remaining_m -= step;
        ctx.bb.set_f64(b.ids.x, x);
        ctx.bb.set_f64(b.ids.y, y);
        let odo = ctx.bb.f64("odometer") + step;
        ctx.bb.set_f64(b.ids.odometer, odo);
        if b.remaining_m <= 0.0 {
            halt(b, ctx, "distance covered");
        }
    } else if b.remaining_deg != 0.0 {
        let step = (b.turn_rate * dt).min(b.remaining_deg.abs()) * b.remaining_deg.signum();
        b.remaining_deg -= step;
        let h = (ctx.bb.f64("heading") + step + 540.0).rem_euclid(360.0) - 180.0;
        ctx.bb.set_f64(b.ids.heading, h);
        if b.remaining_deg.abs() < 1e-9 {
            b.remaining_deg = 0.0;
            ctx.bb.set_bool(b.ids.moving, false);
            let _ = ctx.bb.write_id(b.ids.done, Value::I64(b.cmd_seq));
        }
    }
}
