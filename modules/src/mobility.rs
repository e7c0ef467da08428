//! The mobility module: a simulated base that starts at (0, 0) heading along +x.
//!
//! `forward(m)` drives ahead at a constant speed and asks the sonar module to monitor at two
//! feet (0.61 m); the base stops when the sonar reports, or when the distance is covered.
//! `turn(deg)` turns in place (positive is to the left); `stop()` stops. Odometry goes to the
//! blackboard items `x`, `y`, `heading` (degrees) and `moving`.

use modbot_ipc_schema::{Args, Value};
use modbot_runtime::blackboard::ItemId;
use modbot_runtime::{CallError, CallHandle, Ctx, MethodError, Reply, Report};

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
}

/// Blackboard handles, looked up once.
#[derive(Debug, Clone, Copy)]
pub struct Ids {
    pub x: ItemId,
    pub y: ItemId,
    pub heading: ItemId,
    pub moving: ItemId,
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
}

/// `forward(m)`.
pub fn forward(
    b: &mut Base,
    ctx: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
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
    b.remaining_m = m;
    b.remaining_deg = 0.0;
    b.last_ns = ctx.now_ns();
    ctx.bb.set_bool(b.ids.moving, true);
    tracing::info!("forward {m} m");
    Ok(())
}

/// `turn(deg)`.
pub fn turn(
    b: &mut Base,
    ctx: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
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
    b.remaining_m = 0.0;
    b.remaining_deg = deg;
    b.last_ns = ctx.now_ns();
    ctx.bb.set_bool(b.ids.moving, deg != 0.0);
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
    let dt = now.saturating_sub(b.last_ns) as f64 * 1e-9;
    b.last_ns = now;
    if b.remaining_m > 0.0 {
        let step = (b.speed * dt).min(b.remaining_m);
        b.remaining_m -= step;
        let h = ctx.bb.f64("heading").to_radians();
        let (x, y) = (
            ctx.bb.f64("x") + step * h.cos(),
            ctx.bb.f64("y") + step * h.sin(),
        );
        ctx.bb.set_f64(b.ids.x, x);
        ctx.bb.set_f64(b.ids.y, y);
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
        }
    }
}
