//! Trajectory generators: `ptp`, synchronized point-to-point motion, and `hold_position`.
//!
//! # `ptp`
//! Inputs `goal` (the target joint positions) and `start` (the measured positions); outputs
//! the commanded `q`, `qd`, `qdd` and `done`. Params `v_max`, `a_max` (per axis, positive),
//! `bessel_hz` (f64, 0: no filter).
//!
//! At its first release it latches `start` and rests there. When a new goal arrives (`goal`
//! differs from the last goal it took) while it is at rest (`done`), it latches `start` again,
//! so that the motion starts from where the robot is (bumpless), and moves to `goal`,
//! beginning two ticks later (what it commands is decided two ticks ahead: see `handover`
//! below). A goal
//! that arrives during a motion is taken once that motion is done; a goal with a non-finite
//! value is ignored, and so is an axis of `start` that is not finite (the commanded position
//! stays).
//!
//! The goal it starts with is all zeros: what `goal` reads before its source's first output
//! is valid (LET). So it never moves towards those zeros, whatever `start` says then; but a
//! first goal of exactly all zeros is not new either: it takes effect after another goal.
//! A `ptp` that tracked (its assembly was prepared while another ran) has taken no goal yet:
//! the first it reads live is new, all zeros included (its sources are valid by then). One
//! that tracked because the robot was held under it (flag `HELD`: a safe stop, a drive fault,
//! an operator's reset) keeps the goal it had: when the robot follows again it holds where it
//! is found, and moves only for a new goal.
//!
//! Each axis follows a trapezoidal velocity profile (triangular when the distance is too short
//! to reach the velocity limit). The axes are time-synchronized: the axis that needs longest at
//! its limits sets the duration T, and every other axis keeps its acceleration limit and lowers
//! its cruise velocity to arrive at T too: v = 2D / (T + √(T² − 4D/a)), the smaller root of
//! D = v·(T − v/a). The profile is evaluated at the release's time since the motion began,
//! (tick − first tick) · base_period_s, so no error accumulates; from T on it is exactly `goal`.
//!
//! With `bessel_hz` > 0, `q`, `qd` and `qdd` are each passed through a [`Bessel2`] filter at
//! the component's period (a linear filter, so the filtered `qd` is still the derivative of the
//! filtered `q`). The filters are put at rest at `start` when a motion begins, and when they
//! have settled within 1e-9 of the goal they are put at rest there: `done` is then true and
//! the outputs are exactly `goal`. The filtered `q`, `qd` and `qdd` may pass the goal, `v_max`
//! and `a_max` by at most the filter's step overshoot (0.43 %, see [`super::bessel`]), in
//! practice far less (a 2 rad move at 5 Hz passes the goal by 3e-5 rad).
//!
//! While its assembly is being prepared (released to *track*), `ptp` follows `start` carried
//! ahead to where the running assembly will command the robot when it takes over, and takes
//! no goal; connect `start` to the bus's `demand_position` (the position the drives were last
//! commanded) for a swap without a jump. Taking over a robot in motion, it first brakes from the
//! velocity it predicted at `a_max` (per axis), so neither the commanded position nor its
//! velocity jumps, then takes the goal from where it came to rest.
//!
//! Output `handover` is the command it will give two ticks on (see [`super::handover`]). With
//! param `handover = true` it has an input `handover` too (connect the bus's): tracking, it
//! follows that instead of carrying `start` ahead, and taking over it brakes from exactly the
//! command it replaces, so the velocity changes at the switch by at most one tick of `a_max`
//! whatever the running motion did meanwhile.
//!
//! # `hold_position`
//! Input `start`; outputs `q` (= `start` as latched at the first release, 0 on an axis where it
//! was not finite), `qd` and `qdd` (zeros): the generator of an assembly that holds the robot.
//! Tracking, it follows `start` as `ptp` does; taking over a robot in motion it brakes at its
//! param `a_max` (default 4 rad/s², per axis) and holds where it comes to rest. Output and
//! param `handover` as for `ptp`.

use super::bessel::Bessel2;
use super::handover::{self, Handover};
use super::{
    array, array_mut, array_ports, at, axes, axes_decl, per_axis, per_axis_decl, per_axis_default,
    positive, rest,
};
use modbot_grid::carry::{Carry, CarryError};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamType, ParamValue, Params, PortDecl,
    PortType, PortValue, Released, BASE_PERIOD_S, PERIOD_S,
};

/// Within this of the goal (rad, rad/s, rad/s²) the filtered outputs have settled.
const SETTLED: f64 = 1e-9;

pub(super) fn ptp_info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        Ptp::new(p)?;
    }
    let mut outputs = array_ports(&["q", "qd", "qdd"], n);
    outputs.push(PortDecl::new("done", PortType::Bool));
    outputs.push(handover::port(n));
    let mut inputs = array_ports(&["goal", "start"], n);
    if handover::wanted(p)? {
        inputs.push(handover::port(n));
    }
    Ok(ComponentInfo {
        type_name: "ptp",
        doc: "synchronized trapezoidal point-to-point motion from start to goal",
        inputs,
        outputs,
        params: vec![
            axes_decl(),
            per_axis_decl("v_max"),
            per_axis_decl("a_max"),
            ParamDecl::optional("bessel_hz", ParamType::F64, ParamValue::F64(0.0)),
            handover::param(),
        ],
    })
}

pub(super) fn make_ptp(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(Ptp::new(p)?))
}

/// One axis of a motion.
#[derive(Debug, Clone, Copy, Default)]
struct Axis {
    from: f64,
    /// The distance, signed.
    distance: f64,
    /// The acceleration and cruise velocity used (magnitudes), and the acceleration time.
    a: f64,
    v: f64,
    t_a: f64,
}

impl Axis {
    /// Position, velocity and acceleration `t` seconds into a motion of `duration` (at rest
    /// where it starts before it begins, `t` < 0).
    fn at(&self, t: f64, duration: f64) -> [f64; 3] {
        if t < 0.0 {
            return [self.from, 0.0, 0.0];
        }
        let (d, a, v, t_a) = (self.distance.abs(), self.a, self.v, self.t_a);
        let [s, sd, sdd] = if t >= duration {
            [d, 0.0, 0.0]
        } else if t < t_a {
            [0.5 * a * t * t, a * t, a]
        } else if t < duration - t_a {
            [0.5 * a * t_a * t_a + v * (t - t_a), v, 0.0]
        } else {
            let rest = duration - t;
            [d - 0.5 * a * rest * rest, a * rest, -a]
        };
        let sign = self.distance.signum();
        let q = if t >= duration {
            self.from + self.distance
        } else {
            self.from + sign * s
        };
        [q, sign * sd, sign * sdd]
    }
}

struct Ptp {
    v_max: Vec<f64>,
    a_max: Vec<f64>,
    /// The base tick in seconds: the motion's time is ticks since it began times this.
    dt: f64,
    /// For each axis the filters of q, qd and qdd; empty without `bessel_hz`.
    filters: Vec<[Bessel2; 3]>,
    /// The current (or last) motion, per axis, and where it ends.
    axes: Vec<Axis>,
    target: Vec<f64>,
    /// The last goal taken (zeros to begin with): a goal is new when it differs.
    taken: Vec<f64>,
    duration: f64,
    began: u64,
    moving: bool,
    /// Whether the first release has latched `start`.
    latched: bool,
    /// Whether the filters have settled at the target (always, without filters).
    settled: bool,
    /// While tracking: where the running assembly commands the robot to be when this one takes over.
    ahead: Lead,
    /// Taken over in motion: braking to rest before the next goal.
    brake: Brake,
    /// Scratch: where braking ends.
    stops: Vec<f64>,
    /// At rest where braking brought it: the next motion starts from there, not from the
    /// demand it reads (one tick old).
    braked: bool,
    /// Whether it has the `handover` input (param `handover`).
    takes_handover: bool,
}

/// Where the running assembly will have commanded the robot when a tracking component takes
/// over: the demand it reads is one tick old, and its own command applies one tick later, so
/// the newest demand is carried [`Lead::TICKS`] ticks ahead at its last rate. Taking over
/// there at that rate (see [`Brake`]), the command moves by one tick's motion at the switch,
/// not by three, and its velocity does not jump.
#[derive(Default)]
struct Lead {
    last: Vec<f64>,
    /// The demand's change over the tick before the last one.
    last_rate: Vec<f64>,
    ahead: Vec<f64>,
    /// The demand's velocity at the last release (its change over one base tick, per second).
    velocity: Vec<f64>,
    /// The base tick, s.
    dt: f64,
    /// Demands taken since tracking began (counted up to 2).
    samples: u8,
    /// Tracked since the last live release: the next live release takes over.
    tracking: bool,
}

impl Lead {
    const TICKS: f64 = 2.0;

    /// What it tracked (its base tick comes from the parameters).
    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        c.f64s("lead.last", &mut self.last)?;
        c.f64s("lead.last_rate", &mut self.last_rate)?;
        c.f64s("lead.ahead", &mut self.ahead)?;
        c.f64s("lead.velocity", &mut self.velocity)?;
        let mut samples = u64::from(self.samples);
        c.u64("lead.samples", &mut samples)?;
        self.samples = samples.min(2) as u8;
        c.bool("lead.tracking", &mut self.tracking)
    }

    fn new(n: usize, dt: f64) -> Lead {
        Lead {
            last: vec![0.0; n],
            last_rate: vec![0.0; n],
            ahead: vec![0.0; n],
            velocity: vec![0.0; n],
            dt,
            samples: 0,
            tracking: false,
        }
    }

    /// Takes the newest demand; returns where it will be [`Lead::TICKS`] ticks on, carried at
    /// its last rate and acceleration (a trajectory's acceleration is piecewise constant).
    fn track(&mut self, demand: &[f64]) -> &[f64] {
        let k = Self::TICKS;
        for i in 0..self.last.len() {
            let x = at(demand, i);
            let known = self.samples >= 1 && x.is_finite() && self.last[i].is_finite();
            let rate = if known { x - self.last[i] } else { 0.0 };
            let acc = if known && self.samples >= 2 {
                rate - self.last_rate[i]
            } else {
                0.0
            };
            self.ahead[i] = x + k * rate + 0.5 * k * (k + 1.0) * acc;
            // The change into the tick after the one ahead: the velocity taken over.
            let next = rate + (k + 1.0) * acc;
            self.velocity[i] = if self.dt > 0.0 { next / self.dt } else { 0.0 };
            self.last_rate[i] = rate;
            self.last[i] = x;
        }
        self.samples = self.samples.saturating_add(1).min(2);
        self.tracking = true;
        &self.ahead
    }

    /// At a live release: the velocity of the demand it takes over from, at its first one
    /// after tracking (`None` afterwards, and when it never tracked).
    fn take_over(&mut self) -> Option<&[f64]> {
        self.samples = 0;
        if std::mem::take(&mut self.tracking) {
            Some(&self.velocity)
        } else {
            None
        }
    }
}

/// Brings a command taken over in motion to rest: each axis decelerates from the velocity it
/// was taken over with at its acceleration limit, so the commanded velocity changes by at most
/// one tick's worth of that limit at the switch, and the position follows on.
#[derive(Default)]
struct Brake {
    from: Vec<f64>,
    v0: Vec<f64>,
    a: Vec<f64>,
    began: u64,
    /// The longest axis's braking time, s (0: at rest).
    duration: f64,
}

impl Brake {
    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        c.f64s("brake.from", &mut self.from)?;
        c.f64s("brake.v0", &mut self.v0)?;
        c.f64s("brake.a", &mut self.a)?;
        c.u64("brake.began", &mut self.began)?;
        c.f64("brake.duration", &mut self.duration)
    }

    fn new(n: usize) -> Brake {
        Brake {
            from: vec![0.0; n],
            v0: vec![0.0; n],
            a: vec![0.0; n],
            began: 0,
            duration: 0.0,
        }
    }

    /// Begins braking at `tick` with decelerations `a`, from `from` carried on at velocities
    /// `v0` for `lead` seconds (where the running assembly's command will be when the first
    /// braking command applies); an axis whose values are not finite or whose limit is not
    /// positive rests where it is.
    fn begin(&mut self, tick: u64, from: &[f64], v0: &[f64], a: &[f64], lead: f64) {
        self.began = tick;
        self.duration = 0.0;
        for i in 0..self.from.len() {
            let (x, v, acc) = (at(from, i), at(v0, i), at(a, i));
            let ok = x.is_finite() && v.is_finite() && acc.is_finite() && acc > 0.0;
            self.from[i] = if ok { x + v * lead } else { x };
            self.v0[i] = if ok { v } else { 0.0 };
            self.a[i] = if ok { acc } else { 1.0 };
            self.duration = self.duration.max(self.v0[i].abs() / self.a[i]);
        }
    }

    /// Begins braking at `tick`, the first live release after tracking: from the command the
    /// running generator handed over (exactly the one replaced), else from `rest` carried one
    /// tick on at the velocities `v0` its [`Lead`] predicted (its outputs apply a tick later).
    fn take_over(
        &mut self,
        tick: u64,
        handed: Option<Handover<'_>>,
        rest: &[f64],
        v0: &[f64],
        a: &[f64],
        dt: f64,
    ) {
        match handed {
            Some(h) => self.begin(tick, h.q(), h.qd(), a, 0.0),
            None => self.begin(tick, rest, v0, a, dt),
        }
    }

    /// Whether it is braking `t` seconds after it began.
    fn active(&self, t: f64) -> bool {
        t < self.duration
    }

    /// Position, velocity and acceleration of `axis` `t` seconds into the braking.
    fn at(&self, axis: usize, t: f64) -> [f64; 3] {
        let (v0, a) = (self.v0[axis], self.a[axis]);
        let sign = v0.signum();
        let stop = v0.abs() / a;
        let t = t.min(stop);
        let qdd = if t < stop { -sign * a } else { 0.0 };
        [
            self.from[axis] + v0 * t - 0.5 * sign * a * t * t,
            v0 - sign * a * t,
            qdd,
        ]
    }

    /// Where every axis comes to rest.
    fn stops(&self, out: &mut [f64]) {
        for (i, x) in out.iter_mut().enumerate() {
            *x = self.at(i, f64::INFINITY)[0];
        }
    }

    /// Writes every axis's position, velocity and acceleration `t` seconds in to `outputs`
    /// (ports q, qd, qdd).
    fn write(&self, t: f64, outputs: &mut [PortValue]) {
        for i in 0..self.from.len() {
            for (port, y) in outputs.iter_mut().zip(self.at(i, t)) {
                if let Some(slot) = array_mut(port).get_mut(i) {
                    *slot = y;
                }
            }
        }
    }
}

impl Ptp {
    fn new(p: &Params) -> Result<Ptp, ComponentError> {
        let n = axes(p)?;
        let bessel_hz = p.f64("bessel_hz")?;
        let filters = if bessel_hz == 0.0 {
            Vec::new()
        } else {
            let filter = Bessel2::new(bessel_hz, p.f64(PERIOD_S)?)
                .map_err(|e| ComponentError::param_refused("bessel_hz", e))?;
            vec![[filter; 3]; n]
        };
        Ok(Ptp {
            v_max: per_axis(p, "v_max", n, "positive", positive)?,
            a_max: per_axis(p, "a_max", n, "positive", positive)?,
            dt: p.f64(BASE_PERIOD_S)?,
            filters,
            axes: vec![Axis::default(); n],
            target: vec![0.0; n],
            taken: vec![0.0; n],
            duration: 0.0,
            began: 0,
            moving: false,
            latched: false,
            ahead: Lead::new(n, p.f64(BASE_PERIOD_S)?),
            settled: true,
            brake: Brake::new(n),
            stops: vec![0.0; n],
            braked: false,
            takes_handover: handover::wanted(p)?,
        })
    }

    /// Rests at `start` (each finite axis of it; the others stay where they are).
    fn latch(&mut self, start: &[f64]) {
        for (i, (axis, target)) in self.axes.iter_mut().zip(&mut self.target).enumerate() {
            let x = at(start, i);
            if x.is_finite() {
                *target = x;
            }
            *axis = Axis {
                from: *target,
                ..Axis::default()
            };
        }
        for (filters, &x) in self.filters.iter_mut().zip(&self.target) {
            filters[0].reset(x);
            filters[1].reset(0.0);
            filters[2].reset(0.0);
        }
        self.moving = false;
        self.settled = true;
    }

    /// Begins a motion from `start` to `goal` at `tick`, if `goal` is a new, finite goal.
    fn plan(&mut self, tick: u64, goal: &[f64], start: &[f64]) {
        let n = self.target.len();
        let new = (0..n).any(|i| at(goal, i) != self.taken[i]);
        let finite = (0..n).all(|i| at(goal, i).is_finite());
        if !new || !finite {
            return;
        }
        self.taken.copy_from_slice(&goal[..n]);
        if !std::mem::take(&mut self.braked) {
            self.latch(start);
        }
        let too_far = (0..n).any(|i| !(at(goal, i) - self.target[i]).is_finite());
        if too_far {
            return;
        }
        // The time each axis needs at its limits; the longest is the motion's.
        let goal = &goal[..n];
        let mut duration = 0.0f64;
        for (i, &to) in goal.iter().enumerate() {
            let (d, v, a) = ((to - self.target[i]).abs(), self.v_max[i], self.a_max[i]);
            let t = if d * a <= v * v {
                2.0 * (d / a).sqrt()
            } else {
                d / v + v / a
            };
            duration = duration.max(t);
        }
        for (i, &to) in goal.iter().enumerate() {
            let (from, a) = (self.target[i], self.a_max[i]);
            let distance = to - from;
            let d = distance.abs();
            let root = (duration * duration - 4.0 * d / a).max(0.0).sqrt();
            let v = if d == 0.0 {
                0.0
            } else {
                (2.0 * d / (duration + root)).min(self.v_max[i])
            };
            self.axes[i] = Axis {
                from,
                distance,
                a,
                v,
                t_a: v / a,
            };
            self.target[i] = to;
        }
        self.duration = duration;
        // Begun [`handover::TICKS`] ticks on: what it commands is decided that far ahead, so
        // the handover it writes is what it will command, a new goal included.
        self.began = tick + handover::TICKS;
        self.moving = duration > 0.0;
        self.settled = self.filters.is_empty();
    }

    /// At rest where braking brings it: the next goal is taken from there.
    fn rest_where_braking_ends(&mut self) {
        let mut stops = std::mem::take(&mut self.stops);
        self.brake.stops(&mut stops);
        self.latch(&stops);
        self.stops = stops;
        self.brake.duration = 0.0;
        self.braked = true;
    }

    /// The handover it reads, if it has the input and what it reads there is valid.
    fn handover<'a>(&self, inputs: &'a [PortValue]) -> Option<Handover<'a>> {
        let port = inputs.get(2).filter(|_| self.takes_handover)?;
        Handover::read(port, self.target.len())
    }

    /// Writes the command it will give [`handover::TICKS`] ticks after `tick`, as things stand
    /// (a goal it has not taken yet aside).
    fn write_handover(&self, tick: u64, out: &mut PortValue) {
        let then = tick + handover::TICKS;
        // Signed: a motion may begin after `tick`.
        let elapsed = |began: u64, at: u64| (at as f64 - began as f64) * self.dt;
        if self.brake.duration > 0.0 {
            let t = elapsed(self.brake.began, then);
            handover::write(out, |i| self.brake.at(i, t));
        } else if self.moving || !self.settled {
            handover::write(out, |i| {
                let profile = |m: u64| self.axes[i].at(elapsed(self.began, m), self.duration);
                let Some(filters) = self.filters.get(i) else {
                    return profile(then);
                };
                // The filters as they will have stepped through the ticks to come.
                let mut filters = *filters;
                let mut y = [0.0; 3];
                for m in tick + 1..=then {
                    for ((y, filter), x) in y.iter_mut().zip(&mut filters).zip(profile(m)) {
                        *y = filter.step(x);
                    }
                }
                y
            });
        } else {
            handover::write(out, |i| [self.target[i], 0.0, 0.0]);
        }
    }

    /// The command of a live release (see [`Component::step`]).
    fn command(&mut self, tick: u64, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let (goal, start) = (array(&inputs[0]), array(&inputs[1]));
        let taken = self.handover(inputs);
        if let Some(v0) = self.ahead.take_over() {
            // Taken over from the running assembly's motion: brake from its velocity first.
            self.brake
                .take_over(tick, taken, &self.target, v0, &self.a_max, self.dt);
            if self.brake.duration == 0.0 {
                // At rest already: the next motion starts where it took over, not from the
                // demand it reads (older).
                self.rest_where_braking_ends();
            }
        }
        if !self.latched {
            self.latch(start);
            self.latched = true;
        }
        let dt = self.dt;
        // Signed: a motion planned begins [`handover::TICKS`] ticks later.
        let elapsed = |began: u64| (tick as f64 - began as f64) * dt;
        if self.brake.duration > 0.0 {
            let t = elapsed(self.brake.began);
            if self.brake.active(t) {
                self.brake.write(t, outputs);
                outputs[3] = PortValue::Bool(false);
                return;
            }
            self.rest_where_braking_ends();
        }
        if self.moving && elapsed(self.began) >= self.duration {
            self.moving = false;
        }
        if !self.moving && self.settled {
            self.plan(tick, goal, start);
        }
        if !self.moving && self.settled {
            // At rest: exactly where it is, whatever the filters' rounding.
            rest(outputs, &self.target);
            outputs[3] = PortValue::Bool(true);
            return;
        }
        let t = elapsed(self.began);
        let mut residual = 0.0f64;
        for i in 0..self.axes.len() {
            let mut y = self.axes[i].at(t, self.duration);
            if let Some(filters) = self.filters.get_mut(i) {
                for (y, filter) in y.iter_mut().zip(filters.iter_mut()) {
                    *y = filter.step(*y);
                }
                let off = [y[0] - self.target[i], y[1], y[2]];
                residual = off.iter().fold(residual, |r, x| r.max(x.abs()));
            }
            for (port, y) in outputs.iter_mut().zip(y) {
                if let Some(slot) = array_mut(port).get_mut(i) {
                    *slot = y;
                }
            }
        }
        if t >= self.duration && residual <= SETTLED {
            // Settled (at once without filters): rest exactly at the goal from the next release.
            self.moving = false;
            self.settled = true;
            self.latch(&[]);
        }
        outputs[3] = PortValue::Bool(false);
    }
}

impl Component for Ptp {
    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let tick = rel.tick.0;
        self.command(tick, inputs, outputs);
        self.write_handover(tick, &mut outputs[4]);
    }

    /// The motion (per axis and its goal), the filters, what tracking and braking keep.
    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        for f in self.filters.iter_mut().flatten() {
            f.carry(c)?;
        }
        for a in &mut self.axes {
            c.f64("an axis's start", &mut a.from)?;
            c.f64("an axis's distance", &mut a.distance)?;
            c.f64("an axis's acceleration", &mut a.a)?;
            c.f64("an axis's velocity", &mut a.v)?;
            c.f64("an axis's acceleration time", &mut a.t_a)?;
        }
        c.f64s("target", &mut self.target)?;
        c.f64s("taken", &mut self.taken)?;
        c.f64("duration", &mut self.duration)?;
        c.u64("began", &mut self.began)?;
        c.bool("moving", &mut self.moving)?;
        c.bool("latched", &mut self.latched)?;
        c.bool("settled", &mut self.settled)?;
        c.bool("braked", &mut self.braked)?;
        self.ahead.carry(c)?;
        self.brake.carry(c)
    }

    /// Rests where the robot will be commanded to be when it takes over (the handover it
    /// reads, else `start` carried ahead: see [`Lead`]); the first goal it sees after that is
    /// new, so it then moves from there.
    fn track(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let tick = rel.tick.0;
        let mut ahead = std::mem::take(&mut self.ahead);
        let taken = self.handover(inputs);
        let extrapolated = ahead.track(array(&inputs[1]));
        match taken {
            Some(h) => self.latch(h.q()),
            None => self.latch(extrapolated),
        }
        self.ahead = ahead;
        self.latched = true;
        // Prepared: no goal taken, the first one read live is new, whatever it is. Held (the
        // robot stopped under the running assembly): the goal it had stays taken, so when the
        // robot follows again it holds where it is found instead of setting out once more.
        if !rel.held() {
            self.taken.fill(f64::NAN);
        }
        rest(outputs, &self.target);
        outputs[3] = PortValue::Bool(true);
        self.write_handover(tick, &mut outputs[4]);
    }
}

/// The deceleration `hold_position` brakes with when it takes over a moving robot, rad/s².
const HOLD_A_MAX: f64 = 4.0;

pub(super) fn hold_info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    let mut inputs = array_ports(&["start"], n);
    if handover::wanted(p)? {
        inputs.push(handover::port(n));
    }
    let mut outputs = array_ports(&["q", "qd", "qdd"], n);
    outputs.push(handover::port(n));
    Ok(ComponentInfo {
        type_name: "hold_position",
        doc: "holds start as latched at the first release: q = start, qd = qdd = 0; taking \
              over a moving robot, brakes at a_max first and holds where it comes to rest",
        inputs,
        outputs,
        params: vec![
            axes_decl(),
            per_axis_default("a_max", HOLD_A_MAX),
            handover::param(),
        ],
    })
}

pub(super) fn make_hold(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    let n = axes(p)?;
    let a_max = if p.get("a_max").is_some() {
        per_axis(p, "a_max", n, "positive", positive)?
    } else {
        vec![HOLD_A_MAX; n]
    };
    let dt = if p.get(BASE_PERIOD_S).is_some() {
        p.f64(BASE_PERIOD_S)?
    } else {
        0.0
    };
    Ok(Box::new(Hold {
        q: vec![0.0; n],
        latched: false,
        ahead: Lead::new(n, dt),
        a_max,
        dt,
        brake: Brake::new(n),
        takes_handover: handover::wanted(p)?,
    }))
}

struct Hold {
    /// The position held.
    q: Vec<f64>,
    latched: bool,
    /// While tracking: where the running assembly commands the robot to be when this one takes over.
    ahead: Lead,
    a_max: Vec<f64>,
    /// The base tick, s.
    dt: f64,
    /// Taken over in motion: braking to rest, then holding there.
    brake: Brake,
    /// Whether it has the `handover` input (param `handover`).
    takes_handover: bool,
}

impl Hold {
    /// The handover it reads, if it has the input and what it reads there is valid.
    fn handover<'a>(&self, inputs: &'a [PortValue]) -> Option<Handover<'a>> {
        let port = inputs.get(1).filter(|_| self.takes_handover)?;
        Handover::read(port, self.q.len())
    }

    /// Writes the command it will give [`handover::TICKS`] ticks after `tick`.
    fn write_handover(&self, tick: u64, out: &mut PortValue) {
        let t = (tick + handover::TICKS).saturating_sub(self.brake.began) as f64 * self.dt;
        if self.brake.active(t) {
            handover::write(out, |i| self.brake.at(i, t));
        } else {
            handover::write(out, |i| [self.q[i], 0.0, 0.0]);
        }
    }

    /// The command of a live release (see [`Component::step`]).
    fn command(&mut self, tick: u64, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let taken = self.handover(inputs);
        if let Some(v0) = self.ahead.take_over() {
            // As ptp: brake from what it takes over.
            self.brake
                .take_over(tick, taken, &self.q, v0, &self.a_max, self.dt);
            self.brake.stops(&mut self.q);
        }
        let t = tick.saturating_sub(self.brake.began) as f64 * self.dt;
        if self.brake.active(t) {
            self.brake.write(t, outputs);
            return;
        }
        if !self.latched {
            let start = array(&inputs[0]);
            for (i, q) in self.q.iter_mut().enumerate() {
                let x = at(start, i);
                *q = if x.is_finite() { x } else { 0.0 };
            }
            self.latched = true;
        }
        rest(outputs, &self.q);
    }
}

impl Component for Hold {
    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let tick = rel.tick.0;
        self.command(tick, inputs, outputs);
        self.write_handover(tick, &mut outputs[3]);
    }

    /// Where it holds, what it tracked, its braking.
    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        c.f64s("q", &mut self.q)?;
        c.bool("latched", &mut self.latched)?;
        self.ahead.carry(c)?;
        self.brake.carry(c)
    }

    /// Follows the handover it reads, else `start` carried ahead (see [`Lead`]), until it
    /// takes over, then holds there.
    fn track(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let tick = rel.tick.0;
        let taken = self.handover(inputs);
        let extrapolated = self.ahead.track(array(&inputs[0]));
        let ahead = match taken {
            Some(h) => h.q(),
            None => extrapolated,
        };
        for (i, q) in self.q.iter_mut().enumerate() {
            let x = at(ahead, i);
            *q = if x.is_finite() { x } else { 0.0 };
        }
        self.latched = true;
        rest(outputs, &self.q);
        self.write_handover(tick, &mut outputs[3]);
    }
}

#[cfg(test)]
mod tests {
    use super::super::harness::{list, refusal, Harness};
    use super::*;

    fn ptp(v_max: &[f64], a_max: &[f64], bessel_hz: f64) -> Harness {
        let params = Params::new()
            .with("axes", ParamValue::I64(v_max.len() as i64))
            .with("v_max", list(v_max))
            .with("a_max", list(a_max))
            .with("bessel_hz", ParamValue::F64(bessel_hz));
        Harness::new("ptp", params, 1)
    }

    #[test]
    fn a_motion_carried_into_another_instance_goes_on_to_the_bit() {
        let (mut old, mut new) = (
            ptp(&[1.0, 2.0], &[4.0, 3.0], 20.0),
            ptp(&[1.0, 2.0], &[4.0, 3.0], 20.0),
        );
        // Tracking a demand that moves (the lead), then live towards a goal, carried mid-motion.
        for tick in 0..5 {
            // Moving at 0.1 and -0.2 rad/s when taken over.
            let demand = [0.0001 * tick as f64, -0.0002 * tick as f64];
            old.track(tick, &[&[0.0, 0.0], &demand]);
        }
        let goal = [0.8, -0.5];
        for tick in 5..300 {
            let start = old.out(0).to_vec();
            old.step(tick, &[&goal, &start]);
        }
        super::super::harness::carry_into(old.sut.as_mut(), new.sut.as_mut());
        for tick in 300..2500 {
            let start = old.out(0).to_vec();
            old.step(tick, &[&goal, &start]);
            new.step(tick, &[&goal, &start]);
            assert_eq!(
                format!("{:?}", old.outputs),
                format!("{:?}", new.outputs),
                "tick {tick}"
            );
        }
        let end = old.out(0).to_vec();
        assert!(
            (end[0] - goal[0]).abs() < 1e-6 && (end[1] - goal[1]).abs() < 1e-6,
            "the motion went on to the goal after the carry: {end:?}"
        );
    }

    /// Runs `sut` from tick `from` until done (at most `ticks`): q, qd, qdd at every release.
    fn run(sut: &mut Harness, from: u64, ticks: u64, goal: &[f64]) -> Vec<[Vec<f64>; 3]> {
        let mut seen = Vec::new();
        for tick in from..from + ticks {
            let start = sut.out(0).to_vec();
            sut.step(tick, &[goal, &start]);
            seen.push([0, 1, 2].map(|p| sut.out(p).to_vec()));
            if sut.outputs[3] == PortValue::Bool(true) {
                break;
            }
        }
        seen
    }

    #[test]
    fn one_axis_follows_a_trapezoid_and_stops_exactly_at_the_goal() {
        let mut sut = ptp(&[1.0], &[2.0], 0.0);
        sut.step(0, &[&[0.0], &[0.0]]);
        assert_eq!(sut.outputs[3], PortValue::Bool(true));
        // 2 rad at 1 rad/s and 2 rad/s²: 0.5 s up, 1.5 s cruising, 0.5 s down, begun two
        // ticks after the goal came.
        let seen = run(&mut sut, 10, 5000, &[2.0]);
        assert_eq!(seen.len(), 2 + 2501);
        assert_eq!(
            seen[..2],
            [
                [vec![0.0], vec![0.0], vec![0.0]],
                [vec![0.0], vec![0.0], vec![0.0]]
            ]
        );
        let at = |ms: usize| [0, 1, 2].map(|p| seen[2 + ms][p][0]);
        assert_eq!(at(0), [0.0, 0.0, 2.0]);
        assert!((at(250)[0] - 0.0625).abs() < 1e-12);
        assert!((at(250)[1] - 0.5).abs() < 1e-12);
        assert_eq!(at(1000)[1..], [1.0, 0.0]);
        assert!((at(1000)[0] - 0.75).abs() < 1e-12);
        assert!((at(2250)[0] - 1.9375).abs() < 1e-12);
        assert_eq!(at(2250)[2], -2.0);
        assert_eq!(at(2500), [2.0, 0.0, 0.0]);
    }

    #[test]
    fn a_short_move_is_triangular_below_the_velocity_limit() {
        let mut sut = ptp(&[1.0], &[2.0], 0.0);
        let seen = run(&mut sut, 0, 5000, &[-0.25]);
        // 2·√(0.25 / 2) = 0.7071 s, peak 2 · 0.3536 = 0.7071 rad/s.
        assert_eq!(seen.len(), 2 + 709);
        let peak = seen.iter().map(|s| s[1][0].abs()).fold(0.0, f64::max);
        assert!((peak - 0.5f64.sqrt()).abs() < 2e-3, "{peak}");
        assert_eq!(seen[2 + 708][0], [-0.25]);
    }

    #[test]
    fn axes_arrive_together_each_within_its_own_limits() {
        let (v_max, a_max) = ([1.0, 3.0, 0.5], [2.0, 1.0, 5.0]);
        let goal = [2.0, -1.0, 0.1];
        let mut sut = ptp(&v_max, &a_max, 0.0);
        let seen = run(&mut sut, 0, 10_000, &goal);
        for i in 0..3 {
            let moved_until = seen.iter().rposition(|s| s[0][i] != goal[i]).unwrap();
            assert_eq!(moved_until, seen.len() - 2, "axis {i}");
            for s in &seen {
                assert!(
                    s[1][i].abs() <= v_max[i] && s[2][i].abs() <= a_max[i],
                    "axis {i}"
                );
            }
        }
        // Axis 0 sets the duration (2.5 s); axis 1 (2 s alone) keeps its acceleration.
        assert_eq!(seen.len(), 2 + 2501);
        assert_eq!(seen[2 + 10][2][1], -1.0);
    }

    #[test]
    fn a_motion_starts_bumpless_from_the_measured_start() {
        let mut sut = ptp(&[1.0, 1.0], &[1.0, 1.0], 0.0);
        sut.step(0, &[&[0.0, 0.0], &[0.3, -0.2]]);
        assert_eq!(sut.out(0), [0.3, -0.2]);
        sut.step(1, &[&[0.0, 0.0], &[0.4, -0.2]]);
        assert_eq!(sut.out(0), [0.3, -0.2], "the initial zeros are no goal");
        sut.step(2, &[&[1.0, 1.0], &[0.35, -0.25]]);
        assert_eq!(sut.out(0), [0.35, -0.25]);
        assert_eq!(sut.outputs[3], PortValue::Bool(false));
    }

    #[test]
    fn after_tracking_a_goal_of_all_zeros_is_new() {
        let mut sut = ptp(&[1.0, 1.0], &[1.0, 1.0], 0.0);
        sut.track(0, &[&[0.0, 0.0], &[0.3, -0.2]]);
        let seen = run(&mut sut, 1, 10_000, &[0.0, 0.0]);
        assert_eq!(seen.last().unwrap()[0], [0.0, 0.0], "moved home");
    }

    #[test]
    fn a_goal_that_arrives_during_a_motion_is_taken_when_it_is_done() {
        let mut sut = ptp(&[1.0], &[1.0], 0.0);
        let first = run(&mut sut, 0, 100, &[1.0]);
        assert_eq!(first.len(), 100);
        let rest = run(&mut sut, 100, 10_000, &[-1.0]);
        let turn = rest.iter().position(|s| s[1][0] < 0.0).unwrap();
        assert!(rest[..turn]
            .iter()
            .all(|s| s[1][0] >= 0.0 && s[0][0] <= 1.0));
        assert!(rest[turn - 1][0][0] > 1.0 - 1e-6);
        assert_eq!(rest.last().unwrap()[0], [-1.0]);
    }

    #[test]
    fn non_finite_goals_and_starts_are_ignored_and_never_emitted() {
        let mut sut = ptp(&[1.0, 1.0], &[1.0, 1.0], 4.0);
        sut.step(0, &[&[0.0, 0.0], &[f64::NAN, 0.5]]);
        assert_eq!(sut.out(0), [0.0, 0.5]);
        sut.step(1, &[&[f64::NAN, 1.0], &[0.0, 0.5]]);
        assert_eq!(sut.outputs[3], PortValue::Bool(true));
        sut.step(2, &[&[1.0, f64::INFINITY], &[0.0, 0.5]]);
        sut.step(3, &[&[1.0, 1.0], &[0.0, f64::NAN]]);
        let seen = run(&mut sut, 4, 10_000, &[1.0, 1.0]);
        assert!(seen.iter().flatten().flatten().all(|x| x.is_finite()));
        assert_eq!(seen.last().unwrap()[0], [1.0, 1.0]);
    }

    #[test]
    fn a_bessel_filtered_motion_settles_exactly_at_the_goal_without_noticeable_overshoot() {
        let mut sut = ptp(&[1.0], &[2.0], 5.0);
        let seen = run(&mut sut, 0, 10_000, &[2.0]);
        // The filter's 0.43 % step overshoot, on the steps of the acceleration: 3.3e-5 rad.
        let peak = seen.iter().map(|s| s[0][0]).fold(0.0, f64::max);
        assert!(peak - 2.0 < 1e-4, "overshoot {}", peak - 2.0);
        assert!(seen.len() > 2600 && seen.len() < 3500, "{}", seen.len());
        assert_eq!(seen.last().unwrap(), &[vec![2.0], vec![0.0], vec![0.0]]);
        // The filtered q starts where the robot is and lags the profile (1.0 at 1.25 s).
        assert_eq!(seen[0][0], [0.0]);
        assert!(seen[1250][0][0] > 0.9 && seen[1250][0][0] < 1.0);
    }

    #[test]
    fn a_scalar_limit_is_the_limit_of_every_axis() {
        let params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("v_max", ParamValue::F64(1.0))
            .with("a_max", ParamValue::I64(2));
        let mut sut = Harness::new("ptp", params, 1);
        let seen = run(&mut sut, 0, 10_000, &[2.0, 2.0]);
        assert_eq!(seen.len(), 2 + 2501);
    }

    #[test]
    fn ptp_refuses_bad_limits() {
        let params = |v_max: &[f64], bessel_hz: f64| {
            Params::new()
                .with("axes", ParamValue::I64(3))
                .with("v_max", list(v_max))
                .with("a_max", list(&[1.0]))
                .with("bessel_hz", ParamValue::F64(bessel_hz))
        };
        let sut = refusal("ptp", params(&[1.0, 2.0], 0.0));
        assert_eq!(
            sut,
            "param 'v_max' must have 1 value or 3 (one per axis), not 2"
        );
        let sut = refusal("ptp", params(&[1.0, 0.0, 1.0], 0.0));
        assert_eq!(sut, "param 'v_max' must be positive, not 0 (axis 1)");
        let sut = refusal("ptp", params(&[1.0], 600.0));
        assert!(
            sut.starts_with("param 'bessel_hz': the cutoff must be"),
            "{sut}"
        );
    }

    /// The commands the bus gets around a take-over, as LET runs it: the running assembly
    /// commands `old(n)` up to tick `at - 1`; `sut` tracks from tick 10 (reading the demand
    /// one tick old), is released live from `at - 1` on (its output valid one tick later), and
    /// reads its own last command as the demand from then on. Returns the commands from tick
    /// `at - 3` on, `after` of them past the switch.
    fn take_over(
        sut: &mut Harness,
        old: impl Fn(u64) -> f64,
        at: u64,
        after: u64,
        live: impl Fn(&mut Harness, u64, &[f64]),
    ) -> Vec<f64> {
        for m in 10..at - 1 {
            sut.track(m, &[&[old(m - 1)], &[old(m - 1)]]);
        }
        let mut commands: Vec<f64> = (at - 3..at).map(&old).collect();
        for m in at - 1..at - 1 + after {
            let demand = [*commands.last().unwrap()];
            live(sut, m, &demand);
            commands.push(sut.out(0)[0]);
        }
        commands
    }

    /// The largest change of velocity between two ticks of `commands`, rad/s.
    fn largest_velocity_step(commands: &[f64]) -> f64 {
        commands
            .windows(3)
            .map(|w| ((w[2] - 2.0 * w[1] + w[0]) / 0.001).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_ptp_taking_over_a_moving_robot_brakes_from_its_velocity_without_a_velocity_step() {
        let a_max = 4.0;
        let one_tick = a_max * 0.001 * 1.000_001;
        // At cruise velocity, and while accelerating (3 rad/s² from 0.2 rad/s).
        let cruise = |n: u64| 0.3 + 0.8 * n as f64 * 0.001;
        let accelerating = |n: u64| {
            let t = n as f64 * 0.001;
            0.2 * t + 1.5 * t * t
        };
        for (name, old) in [
            ("cruise", &cruise as &dyn Fn(u64) -> f64),
            ("accelerating", &accelerating),
        ] {
            let mut sut = ptp(&[1.0], &[a_max], 0.0);
            let goal = [2.0];
            let commands = take_over(&mut sut, old, 100, 3000, |sut, m, demand| {
                sut.step(m, &[&goal, demand]);
            });
            let step = largest_velocity_step(&commands);
            assert!(
                step <= one_tick,
                "{name}: the velocity jumped {step} rad/s (one tick of a_max: {one_tick})"
            );
            assert_eq!(
                *commands.last().unwrap(),
                2.0,
                "{name}: then it went to the goal"
            );
        }
    }

    #[test]
    fn hold_position_carried_while_braking_brakes_and_holds_the_same_to_the_bit() {
        let hold = || {
            Harness::new(
                "hold_position",
                Params::new().with("axes", ParamValue::I64(2)),
                1,
            )
        };
        let (mut old, mut new) = (hold(), hold());
        // Tracking a robot moving at 0.8 and -0.4 rad/s, then live: it brakes; carried mid-brake.
        for tick in 0..5 {
            let demand = [0.0008 * tick as f64, -0.0004 * tick as f64];
            old.track(tick, &[&demand]);
        }
        for tick in 5..60 {
            let demand = old.out(0).to_vec();
            old.step(tick, &[&demand]);
        }
        super::super::harness::carry_into(old.sut.as_mut(), new.sut.as_mut());
        for tick in 60..600 {
            let demand = old.out(0).to_vec();
            old.step(tick, &[&demand]);
            new.step(tick, &[&demand]);
            assert_eq!(
                format!("{:?}", old.outputs),
                format!("{:?}", new.outputs),
                "tick {tick}"
            );
        }
        assert_eq!(old.out(1), [0.0, 0.0], "at rest");
    }

    #[test]
    fn hold_position_taking_over_a_moving_robot_brakes_and_holds_where_it_stops() {
        let params = Params::new().with("axes", ParamValue::I64(1));
        let mut sut = Harness::new("hold_position", params, 1);
        let cruise = |n: u64| 0.8 * n as f64 * 0.001;
        let commands = take_over(&mut sut, cruise, 100, 400, |sut, m, demand| {
            sut.step(m, &[demand]);
        });
        assert!(largest_velocity_step(&commands) <= 4.0 * 0.001 * 1.000_001);
        let end = *commands.last().unwrap();
        // From 0.8 rad/s at 4 rad/s², it stops 0.08 rad on.
        assert!((end - (cruise(99) + 0.08)).abs() < 2e-3, "held at {end}");
        assert_eq!(sut.out(1), [0.0], "at rest");
    }

    /// The bus's position commands, tick by tick, when `new` takes over from `old` at tick
    /// `switch` as LET and a bus with `handover` connect them: the bus at tick n commands the
    /// output of n − 1 of the generator live at n and forwards its handover of n − 1 (at the
    /// switch tick, the incoming one's last tracking release); the generators read the bus's
    /// outputs of n − 1 (`inputs(demand, handover)`), so the handover they read at n is the
    /// one written at n − 2. `new` tracks from tick 10.
    fn swap(
        old: &mut Harness,
        old_inputs: impl Fn(u64, &[f64], &[f64]) -> Vec<Vec<f64>>,
        new: &mut Harness,
        new_inputs: impl Fn(u64, &[f64], &[f64]) -> Vec<Vec<f64>>,
        switch: u64,
        end: u64,
    ) -> Vec<f64> {
        let ports = [old.outputs.len() - 1, new.outputs.len() - 1];
        let mut commands = Vec::new();
        // The bus's outputs of the tick before (demand and handover), and each generator's
        // (command and handover).
        let mut bus = (0.0, vec![0.0; 4]);
        let mut released = [(0.0, vec![0.0; 4]), (0.0, vec![0.0; 4])];
        for n in 0..end {
            // The bus at n reads the output of n − 1 of the generator live at n: at the switch
            // tick the incoming one's last tracking output.
            let served = released[usize::from(n >= switch)].clone();
            commands.push(served.0);
            let demand = [bus.0];
            let mut release = |sut: &mut Harness, which: usize, inputs: Vec<Vec<f64>>, live| {
                let inputs: Vec<&[f64]> = inputs.iter().map(Vec::as_slice).collect();
                if live {
                    sut.step(n, &inputs);
                } else {
                    sut.track(n, &inputs);
                }
                released[which] = (sut.out(0)[0], sut.out(ports[which]).to_vec());
            };
            if n < switch {
                release(old, 0, old_inputs(n, &demand, &bus.1), true);
            }
            if n >= 10 {
                release(new, 1, new_inputs(n, &demand, &bus.1), n >= switch);
            }
            bus = served;
        }
        commands
    }

    fn handover_params(sut: Params) -> Params {
        sut.with("handover", ParamValue::Bool(true))
    }

    /// The largest velocity step of a swap from a ptp moving 0.1 rad (from tick 40 on, at
    /// 4 rad/s²: triangular, turning from +a to −a at tick 198, at rest from 356) to `new`,
    /// at each switch tick from 20 to 400: before, during and after the motion.
    fn largest_step_of_swaps(
        new: impl Fn() -> Harness,
        new_inputs: impl Fn(&[f64], &[f64]) -> Vec<Vec<f64>> + Copy,
        check: impl Fn(u64, &Harness, &[f64]),
    ) -> f64 {
        let mut largest = 0.0f64;
        for switch in 20..=400 {
            let mut old = ptp(&[1.0], &[4.0], 0.0);
            let mut new = new();
            let commands = swap(
                &mut old,
                |n, d, _| vec![vec![if n < 40 { 0.0 } else { 0.1 }], d.to_vec()],
                &mut new,
                |_, d, h| new_inputs(d, h),
                switch,
                1000,
            );
            check(switch, &new, &commands);
            largest = largest.max(largest_velocity_step(&commands));
        }
        largest
    }

    #[test]
    fn a_generator_taking_over_at_any_tick_of_the_running_motion_changes_the_velocity_by_at_most_one_tick_of_its_limit(
    ) {
        let one_tick = 4.0 * 0.001 * 1.000_001;
        let hold = || {
            let params = Params::new().with("axes", ParamValue::I64(1));
            Harness::new("hold_position", handover_params(params), 1)
        };
        let step = largest_step_of_swaps(
            hold,
            |d, h| vec![d.to_vec(), h.to_vec()],
            |switch, hold, _| assert_eq!(hold.out(1), [0.0], "to hold at {switch}: at rest"),
        );
        assert!(step <= one_tick, "to hold: {step} rad/s");
        let ptp = || {
            let params = Params::new()
                .with("axes", ParamValue::I64(1))
                .with("v_max", list(&[1.0]))
                .with("a_max", list(&[4.0]));
            Harness::new("ptp", handover_params(params), 1)
        };
        let step = largest_step_of_swaps(
            ptp,
            |d, h| vec![vec![-0.05], d.to_vec(), h.to_vec()],
            |switch, _, commands| {
                assert_eq!(
                    commands.last(),
                    Some(&-0.05),
                    "to ptp at {switch}: then at its goal"
                )
            },
        );
        assert!(step <= one_tick, "to ptp: {step} rad/s");
    }

    #[test]
    fn without_the_handover_a_take_over_extrapolates_and_steps_further_at_the_corners() {
        // What the handover is for: the same swaps, the demand carried ahead instead.
        let hold = || {
            Harness::new(
                "hold_position",
                Params::new().with("axes", ParamValue::I64(1)),
                1,
            )
        };
        let step = largest_step_of_swaps(hold, |d, _| vec![d.to_vec()], |_, _, _| {});
        assert!(step > 4.0 * 0.001 * 1.5, "{step}");
    }

    #[test]
    fn a_handover_written_by_ptp_is_the_command_it_gives_two_ticks_later() {
        for bessel_hz in [0.0, 5.0] {
            let mut sut = ptp(&[1.0], &[4.0], bessel_hz);
            let mut written = Vec::new();
            let mut given = Vec::new();
            for tick in 0..1500 {
                sut.step(tick, &[&[0.3], &[0.0]]);
                given.push([0, 1, 2].map(|p| sut.out(p)[0]));
                written.push(sut.out(4).to_vec());
            }
            for tick in 2..1500 {
                let [q, qd, qdd] = given[tick];
                let h = &written[tick - 2];
                // Within what settling snaps to the goal.
                let close = (h[0] - q).abs() < 1e-9
                    && (h[1] - qd).abs() < 1e-9
                    && (h[2] - qdd).abs() < 1e-9;
                assert!(
                    close && h[3] == 1.0,
                    "bessel {bessel_hz}, tick {tick}: {h:?} vs {:?}",
                    given[tick]
                );
            }
        }
    }

    #[test]
    fn hold_position_holds_the_start_of_its_first_release() {
        let params = Params::new().with("axes", ParamValue::I64(3));
        let mut sut = Harness::new("hold_position", params, 1);
        sut.step(0, &[&[0.5, f64::NAN, -1.0]]);
        sut.step(1, &[&[0.7, 0.7, 0.7]]);
        assert_eq!(sut.out(0), [0.5, 0.0, -1.0]);
        assert_eq!(sut.out(1), [0.0; 3]);
        assert_eq!(sut.out(2), [0.0; 3]);
    }
}
