//! A two-mass elastic joint: the mechanics behind one simulated drive.
//!
//! The motor (inertia `Jm`, position `qm`) drives the link (inertia `Jl`, position `ql`)
//! through a gear of stiffness `k` and damping `d`, with ratio 1: every quantity is on the link
//! side, in rad, rad/s and Nm. Friction acts on the motor: viscous `b·ωm` and a Coulomb part
//! smoothed as `τc·tanh(ωm/ωc)`, so that it stays a continuous function the integrator can
//! follow through zero speed.
//!
//! ```text
//! Jm·ω̇m = τ − k·(qm − ql) − d·(ωm − ωl) − b·ωm − τc·tanh(ωm/ωc)
//! Jl·ω̇l =     k·(qm − ql) + d·(ωm − ωl)
//! ```
//!
//! [`Plant::step`] integrates one bus cycle `dt` with `n = ⌈dt / max_substep⌉` sub-steps of
//! semi-implicit (symplectic) Euler: the velocities are updated from the forces at the start
//! of the sub-step, then the positions from the new velocities. Without friction and damping
//! it does not gain or lose energy over time (the energy oscillates within `O(ω·h)` around its
//! start value instead of drifting, as explicit Euler's would), and it is stable while
//! `ω·h < 2` for the elastic mode's `ω`; [`PlantParams::check`] asks for ample margin. The
//! motor torque is held over the cycle, as a drive's output is.
//!
//! A *blocked* link is clamped: its velocity is 0 and its position frozen, whatever the gear
//! transmits (a collision, or a test of following-error monitoring).

/// The mechanical parameters of one joint, and the limits reported for monitoring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantParams {
    /// Motor inertia as seen at the link (kg·m²).
    pub motor_inertia: f64,
    /// Link inertia (kg·m²).
    pub link_inertia: f64,
    /// Gear stiffness (Nm/rad).
    pub stiffness: f64,
    /// Gear damping (Nm·s/rad).
    pub damping: f64,
    /// Viscous friction on the motor (Nm·s/rad).
    pub viscous_friction: f64,
    /// Coulomb friction on the motor (Nm).
    pub coulomb_friction: f64,
    /// The speed over which Coulomb friction builds up, `ωc` in `tanh(ωm/ωc)` (rad/s).
    pub coulomb_velocity: f64,
    /// The link's range of motion (rad); outside it the position limit is reported.
    pub position_min: f64,
    pub position_max: f64,
    /// The motor's speed limit (rad/s); beyond it the velocity limit is reported.
    pub velocity_limit: f64,
    /// The motor's peak torque (Nm); a drive saturates its output here.
    pub torque_limit: f64,
    /// The longest integration sub-step (s).
    pub max_substep: f64,
}

impl Default for PlantParams {
    /// A mid-size robot joint: elastic mode at √(k·(1/Jm + 1/Jl)) ≈ 224 rad/s (35.6 Hz), gear
    /// damping ratio ≈ 0.06, 8 sub-steps per 1 ms cycle.
    fn default() -> Self {
        PlantParams {
            motor_inertia: 0.5,
            link_inertia: 2.0,
            stiffness: 2.0e4,
            damping: 10.0,
            viscous_friction: 1.0,
            coulomb_friction: 3.0,
            coulomb_velocity: 0.05,
            position_min: -3.0,
            position_max: 3.0,
            velocity_limit: 3.0,
            torque_limit: 200.0,
            max_substep: 1.25e-4,
        }
    }
}

/// A parameter out of its range.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("parameter {name} = {value} is invalid: expected {expected}")]
pub struct InvalidParameter {
    pub name: &'static str,
    pub value: f64,
    pub expected: &'static str,
}

/// `Err` unless `ok` holds for `value`.
pub(crate) fn require(
    name: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), InvalidParameter> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(InvalidParameter {
            name,
            value,
            expected,
        })
    }
}

impl PlantParams {
    /// The elastic mode's angular frequency, `√(k·(1/Jm + 1/Jl))` (rad/s).
    pub fn resonance(&self) -> f64 {
        (self.stiffness * (1.0 / self.motor_inertia + 1.0 / self.link_inertia)).sqrt()
    }

    /// The fastest decay rate of the dissipative terms (1/s): gear damping on the relative
    /// motion, friction (the Coulomb part's slope at zero speed) on the motor.
    fn dissipation_rate(&self) -> f64 {
        self.damping * (1.0 / self.motor_inertia + 1.0 / self.link_inertia)
            + (self.viscous_friction + self.coulomb_friction / self.coulomb_velocity)
                / self.motor_inertia
    }

    /// Checks signs, finiteness and that the sub-step resolves the fastest dynamics
    /// (`ω·h ≤ 0.5` for the elastic mode and the dissipation).
    pub fn check(&self) -> Result<(), InvalidParameter> {
        let p = self;
        require(
            "motor_inertia",
            p.motor_inertia,
            p.motor_inertia > 0.0,
            "> 0",
        )?;
        require("link_inertia", p.link_inertia, p.link_inertia > 0.0, "> 0")?;
        require("stiffness", p.stiffness, p.stiffness > 0.0, "> 0")?;
        require("damping", p.damping, p.damping >= 0.0, ">= 0")?;
        let viscous = p.viscous_friction;
        require("viscous_friction", viscous, viscous >= 0.0, ">= 0")?;
        let coulomb = p.coulomb_friction;
        require("coulomb_friction", coulomb, coulomb >= 0.0, ">= 0")?;
        let omega_c = p.coulomb_velocity;
        require("coulomb_velocity", omega_c, omega_c > 0.0, "> 0")?;
        require("position_min", p.position_min, true, "finite")?;
        let range_ok = p.position_max > p.position_min;
        require("position_max", p.position_max, range_ok, "> position_min")?;
        let speed = p.velocity_limit;
        require("velocity_limit", speed, speed > 0.0, "> 0")?;
        require("torque_limit", p.torque_limit, p.torque_limit > 0.0, "> 0")?;
        let h = p.max_substep;
        require("max_substep", h, h > 0.0, "> 0")?;
        let fastest = p.resonance().max(p.dissipation_rate());
        require(
            "max_substep",
            h,
            h * fastest <= 0.5,
            "<= 0.5 / (the elastic mode's ω or the dissipation rate, whichever is larger)",
        )
    }
}

/// Positions (rad) and velocities (rad/s) of motor and link.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantState {
    pub motor_position: f64,
    pub motor_velocity: f64,
    pub link_position: f64,
    pub link_velocity: f64,
}

/// Which monitoring limits the plant is beyond.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LimitStatus {
    /// The link is outside `position_min..=position_max`.
    pub position: bool,
    /// The motor is faster than `velocity_limit`.
    pub velocity: bool,
    /// The last torque reached `torque_limit`.
    pub torque: bool,
}

impl LimitStatus {
    pub fn any(&self) -> bool {
        self.position || self.velocity || self.torque
    }
}

/// The most sub-steps one cycle takes (a `dt` longer than this many `max_substep`s is
/// integrated with longer, possibly unstable, sub-steps rather than stall the caller).
pub const MAX_SUBSTEPS: u32 = 10_000;

/// One joint's mechanics.
#[derive(Debug, Clone)]
pub struct Plant {
    params: PlantParams,
    state: PlantState,
    /// The torque of the last step, for the torque limit.
    torque: f64,
    /// Whether the link is clamped.
    blocked: bool,
}

impl Plant {
    /// A joint at rest at position 0. The parameters are assumed checked
    /// ([`PlantParams::check`]).
    pub fn new(params: PlantParams) -> Plant {
        Plant {
            params,
            state: PlantState::default(),
            torque: 0.0,
            blocked: false,
        }
    }

    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    pub fn state(&self) -> PlantState {
        self.state
    }

    pub fn set_state(&mut self, state: PlantState) {
        self.state = state;
    }

    pub fn blocked(&self) -> bool {
        self.blocked
    }

    /// Clamps (or releases) the link where it is.
    pub fn set_blocked(&mut self, blocked: bool) {
        self.blocked = blocked;
        if blocked {
            self.state.link_velocity = 0.0;
        }
    }

    /// The number of sub-steps for a cycle of `dt` seconds (0 when `dt` is not positive).
    pub fn substeps(&self, dt: f64) -> u32 {
        if dt > 0.0 && dt.is_finite() {
            ((dt / self.params.max_substep).ceil() as u32).clamp(1, MAX_SUBSTEPS)
        } else {
            0
        }
    }

    /// Advances by `dt` seconds with the motor torque `torque` held (see the module
    /// documentation). A `dt` that is not positive and finite leaves the state unchanged.
    pub fn step(&mut self, torque: f64, dt: f64) {
        self.torque = torque;
        let n = self.substeps(dt);
        if n == 0 {
            return;
        }
        let h = dt / f64::from(n);
        let p = &self.params;
        let PlantState {
            motor_position: mut qm,
            motor_velocity: mut wm,
            link_position: mut ql,
            link_velocity: mut wl,
        } = self.state;
        for _ in 0..n {
            let gear = p.stiffness * (qm - ql) + p.damping * (wm - wl);
            let friction =
                p.viscous_friction * wm + p.coulomb_friction * (wm / p.coulomb_velocity).tanh();
            wm += h * (torque - gear - friction) / p.motor_inertia;
            if !self.blocked {
                wl += h * gear / p.link_inertia;
            }
            qm += h * wm;
            ql += h * wl;
        }
        self.state = PlantState {
            motor_position: qm,
            motor_velocity: wm,
            link_position: ql,
            link_velocity: wl,
        };
    }

    /// Kinetic energy of both masses plus the gear's spring energy (J).
    pub fn energy(&self) -> f64 {
        let s = &self.state;
        let p = &self.params;
        let twist = s.motor_position - s.link_position;
        0.5 * (p.motor_inertia * s.motor_velocity * s.motor_velocity
            + p.link_inertia * s.link_velocity * s.link_velocity
            + p.stiffness * twist * twist)
    }

    /// The monitoring limits the joint is beyond now.
    pub fn limits(&self) -> LimitStatus {
        let p = &self.params;
        let s = &self.state;
        LimitStatus {
            position: !(p.position_min..=p.position_max).contains(&s.link_position),
            velocity: s.motor_velocity.abs() > p.velocity_limit,
            torque: self.torque.abs() >= p.torque_limit,
        }
    }
}
