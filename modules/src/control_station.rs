//! MOSER's control station: the operator's module.
//!
//! It sends the robot on patrol, receives the high-level module's progress summaries and the
//! intrusion module's alerts, and shows them as a clear line log. The operator's commands are
//! its methods: `patrol(wing)`, `stop()`, `activate_module(module)` and
//! `deactivate_module(module)` (the last two switch a module on or off, e.g. to let the near-infrared ring stand in for the sonar).
//! When the scenario ends it collects every module's traffic statistics and prints the summary.
//!
//! The station keeps the operator's mission: a high-level module that restarted (and so forgot
//! its patrol) reports itself idle, and the station sends it the patrol again.

use modbot_core::module::Report;
use modbot_core::stats::{Histogram, Stats};
use modbot_core::{Ctx, MethodError, Reply};
use modbot_ipc_schema::{Args, Value};

use crate::high_level::SUMMARY_TOPIC;
use crate::intrusion::ALERT_TOPIC;

/// An alert as received.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Alert {
    pub x: f64,
    pub y: f64,
    pub probability: f64,
    pub time_s: f64,
}

/// The latest progress summary.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Progress {
    pub x: f64,
    pub y: f64,
    pub odometer_m: f64,
    pub wing: i64,
    pub goal: i64,
    pub goals: i64,
    pub room: String,
    pub state: String,
}

/// The station's state.
#[derive(Debug, Default)]
pub struct Station {
    pub high_level: String,
    pub alert: Option<Alert>,
    pub progress: Progress,
    /// Simulated time of the last progress line printed.
    last_line_s: f64,
    /// Print a progress line at most this often (simulated seconds).
    pub line_every_s: f64,
    /// The wing the operator sent the robot to patrol, until a stop.
    pub mission: Option<i64>,
    /// When the patrol was last sent again (the module clock, seconds).
    resent_s: f64,
}

impl Station {
    pub fn new(high_level: &str, line_every_s: f64) -> Station {
        Station {
            high_level: high_level.to_owned(),
            line_every_s,
            last_line_s: f64::NEG_INFINITY,
            resent_s: f64::NEG_INFINITY,
            ..Default::default()
        }
    }
}

fn f(r: &Report<'_>, i: usize) -> f64 {
    r.values.f64(i).unwrap_or(f64::NAN)
}

/// How long after sending the patrol again the station waits before it may send it once more
/// (seconds of the module clock; the high-level module reports every simulated second).
const RESEND_AFTER_S: f64 = 3.0;

/// Reports from the robot: progress and alerts.
pub fn on_report(s: &mut Station, ctx: &mut Ctx, r: &Report<'_>) {
    match r.topic {
        SUMMARY_TOPIC => {
            s.progress = Progress {
                x: f(r, 0),
                y: f(r, 1),
                odometer_m: f(r, 3),
                wing: r.values.i64(4).unwrap_or(0),
                goal: r.values.i64(5).unwrap_or(0),
                goals: r.values.i64(6).unwrap_or(0),
                room: r.values.text(7).unwrap_or("?").to_owned(),
                state: r.values.text(8).unwrap_or("?").to_owned(),
            };
            keep_mission(s, ctx);
        }
        ALERT_TOPIC => {
            let alert = Alert {
                x: f(r, 0),
                y: f(r, 1),
                probability: f(r, 2),
                time_s: f(r, 3),
            };
            println!(
                "[{:7.1} s] *** ALERT: intruder at ({:.1}, {:.1}), probability {:.2} (heat {:.2}, motion {:.2}, light {:.2}) ***",
                alert.time_s,
                alert.x,
                alert.y,
                alert.probability,
                f(r, 4),
                f(r, 5),
                f(r, 6)
            );
            if s.alert.is_none() {
                s.alert = Some(alert);
            }
        }
        _ => {}
    }
}

/// Sends the patrol again when the high-level module says it is idle while the operator's
/// mission stands (it restarted and forgot it), at most every [`RESEND_AFTER_S`].
fn keep_mission(s: &mut Station, ctx: &mut Ctx) {
    let Some(wing) = s.mission else { return };
    let now_s = ctx.now_ns() as f64 / 1e9;
    if s.progress.state != "idle" || now_s - s.resent_s < RESEND_AFTER_S {
        return;
    }
    s.resent_s = now_s;
    let hl = s.high_level.clone();
    match ctx.call(&hl, "patrol", &[Value::I64(wing)]) {
        Ok(_) => println!(
            "control station: {hl} is idle (it restarted?): patrol of wing {wing} sent again"
        ),
        Err(e) => println!("control station: {hl} is idle and did not take the patrol again: {e}"),
    }
}

/// Prints a progress line when one is due.
pub fn progress_line(s: &mut Station, now_s: f64) {
    if now_s - s.last_line_s < s.line_every_s || s.progress.state.is_empty() {
        return;
    }
    s.last_line_s = now_s;
    let p = &s.progress;
    println!(
        "[{now_s:7.1} s] {:<10} wing {}  point {}/{}  in {:<14} at ({:5.1}, {:5.1})  {:6.1} m driven",
        p.state, p.wing, p.goal, p.goals, p.room, p.x, p.y, p.odometer_m
    );
}

/// `patrol(wing)`: sends the robot to patrol a wing.
pub fn patrol(
    s: &mut Station,
    ctx: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let wing = args.i64(0)?;
    let hl = s.high_level.clone();
    ctx.call(&hl, "patrol", &[Value::I64(wing)])
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    s.mission = Some(wing);
    println!("operator: patrol wing {wing}");
    Ok(())
}

/// `stop()`: stops the patrol.
pub fn stop(
    s: &mut Station,
    ctx: &mut Ctx,
    _: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let hl = s.high_level.clone();
    s.mission = None;
    ctx.call(&hl, "stop", &[])
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    println!("operator: stop");
    Ok(())
}

fn switch(ctx: &mut Ctx, args: &Args<'_>, on: bool) -> Result<(), MethodError> {
    let module = args.text(0)?;
    let method = if on { "activate" } else { "deactivate" };
    ctx.call(module, method, &[])
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    println!("operator: {method} {module}");
    Ok(())
}

/// `activate_module(module)`.
pub fn activate(
    _: &mut Station,
    ctx: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    switch(ctx, args, true)
}

/// `deactivate_module(module)`.
pub fn deactivate(
    _: &mut Station,
    ctx: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    switch(ctx, args, false)
}

/// The scenario's figures, gathered at its end.
#[derive(Debug, Default)]
pub struct Summary {
    pub sim_s: f64,
    pub real_s: f64,
    pub speed: f64,
    pub odometer_m: f64,
    pub collisions: i64,
    pub replans: i64,
    pub alert: Option<Alert>,
    pub modules: usize,
    pub frames_sent: u64,
    pub frames_received: u64,
    pub calls: u64,
    pub failed: u64,
    pub latency: Histogram,
}

impl Summary {
    /// Adds one module's statistics.
    pub fn add(&mut self, stats: &Stats) {
        self.modules += 1;
        self.frames_sent += stats.frames_sent;
        self.frames_received += stats.frames_received;
        self.calls += stats.calls;
        self.failed += stats.failed;
        self.latency.merge(&stats.latency);
    }

    /// The summary as printed at the end of the run.
    pub fn render(&self) -> String {
        let us = |ns: u64| ns as f64 / 1000.0;
        let alert = match self.alert {
            Some(a) => format!(
                "at {:.1} s: intruder at ({:.1}, {:.1}), probability {:.2}",
                a.time_s, a.x, a.y, a.probability
            ),
            None => "none: no intruder detected".to_owned(),
        };
        format!(
            "==== MOSER summary ====\n\
             duration            {:.1} s simulated, {:.1} s real ({}x)\n\
             distance patrolled  {:.1} m ({} replan(s) around unknown obstacles)\n\
             collisions          {}\n\
             alert               {alert}\n\
             messages            {} frames sent, {} received, by {} modules\n\
             calls               {} ({} failed), latency p50 {:.1} us, p99 {:.1} us\n",
            self.sim_s,
            self.real_s,
            self.speed,
            self.odometer_m,
            self.replans,
            self.collisions,
            self.frames_sent,
            self.frames_received,
            self.modules,
            self.calls,
            self.failed,
            us(self.latency.percentile(50.0)),
            us(self.latency.percentile(99.0)),
        )
    }
}
