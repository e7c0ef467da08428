//! The bus and its drives as grid components (MoRC's EtherCAT module and Robot component).
//!
//! - `bus`: one bus cycle per release (give it period 1: the bus is served every tick).
//!   Inputs per axis (all `f64[axes]`): `controlword`, `mode` (8 CSP, 9 CSV, 10 CST),
//!   `target_position`, `target_velocity`, `target_torque`. Outputs per axis: `statusword`,
//!   `motor_position`, `motor_velocity`, `motor_torque`, `link_position`, and
//!   `demand_position`: the position the drive was last commanded (CiA 402's position demand
//!   value, 0x6062) while in operation enabled in CSP, else its actual position — where a
//!   generator taking over should start for the command not to jump; and `state`, the
//!   robot's state (0 disabled, 1 operational, 2 safe stop, 3 fault: see
//!   [`crate::robot_state`]). While the bridge holds the robot (a stop, a fault, a reset under
//!   way) the component says so ([`Component::holding`]) and the coordinator releases the
//!   running assembly's components to track. Params: `axes`
//!   (default 6), `backend` (`sim`), `watchdog` (base periods without a release after which
//!   the coordinator is lost and the drives stop, default 3), `handover` (bool, default false:
//!   with it, input and output `handover`, the running generator's handover forwarded one
//!   cycle later, see [`handover`]), and the simulated joints' mechanics per axis
//!   ([`joints`]: `motor_inertia`, `link_inertia`, `stiffness`, `damping`,
//!   `viscous_friction`, `coulomb_friction`, `torque_limit`; each one value for every axis or
//!   one per axis, [`PlantParams::default`]'s unless given). In the bus bridge process (`modbot-bus`) it drives that
//!   process's [`Bridge`], which has the watchdog, handed to it by [`register_bridge`];
//!   elsewhere (the reference run, tests) a private simulation.
//! - `drive_enable`: walks every drive through the CiA 402 state machine to operation enabled
//!   in a mode (param `mode`, default 8, CSP), resets faults once (a rising edge of bit 7) when
//!   param `reset_faults` is true, and never re-enables a drive held in quick stop unless
//!   `reset_faults` is true: then it sends *disable voltage* once (CiA 402 transition 12) and
//!   enables it again. While the bus bridge holds the robot (a safe stop, a drive fault) it
//!   obeys no assembly: only an operator's reset brings the drives back (see
//!   [`crate::reset`]). Input `statusword: f64[axes]`, outputs `controlword`, `mode`.

use std::sync::{Arc, Mutex};

use super::backend::AxisCommand;
use super::bridge::{self, Bridge, Served};
use super::cia402::DriveState;
use super::plant::PlantParams;
use super::sim::{DriveParams, SimBackend};
use modbot_control::handover;
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, ParamValue, Params,
    PortDecl, PortType, PortValue, Registry, Released, PERIOD_S,
};
use modbot_ipc_schema::grid::Release;

/// Registers `bus` and `drive_enable`.
pub fn register(registry: &mut Registry) {
    registry.register(bus_info, make_bus);
    registry.register(enable_info, make_enable);
}

fn axes(p: &Params) -> Result<usize, ParamError> {
    let n = if p.get("axes").is_some() {
        p.i64("axes")?
    } else {
        6
    };
    if !(1..=16).contains(&n) {
        return Err(ParamError::invalid(
            "axes",
            format!("must be 1 to 16, not {n}"),
        ));
    }
    Ok(n as usize)
}

fn ports(names: &[&'static str], n: usize) -> Vec<PortDecl> {
    names
        .iter()
        .map(|name| PortDecl::new(name, PortType::F64s(n)))
        .collect()
}

const BUS_IN: [&str; 5] = [
    "controlword",
    "mode",
    "target_position",
    "target_velocity",
    "target_torque",
];
/// The output with the robot's state: 0 disabled, 1 operational, 2 safe stop, 3 fault
/// ([`crate::robot_state::RobotState::code`]).
const STATE: &str = "state";

const BUS_OUT: [&str; 6] = [
    "statusword",
    "motor_position",
    "motor_velocity",
    "motor_torque",
    "link_position",
    "demand_position",
];

fn bus_info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    watchdog_periods(p)?;
    if backend(p)? == "ethercat"
        && !matches!(p.get("interface"), Some(ParamValue::Text(i)) if !i.is_empty())
    {
        let why = "is required with backend = \"ethercat\": the network interface of the segment";
        return Err(ParamError::invalid("interface", why.to_owned()).into());
    }
    let (mut inputs, mut outputs) = (ports(&BUS_IN, n), ports(&BUS_OUT, n));
    if handover::wanted(p)? {
        inputs.push(handover::port(n));
        outputs.push(handover::port(n));
    }
    outputs.push(PortDecl::new(STATE, PortType::F64));
    Ok(ComponentInfo {
        type_name: "bus",
        doc: "the drives on the bus: one cycle per release (serve it every tick)",
        inputs,
        outputs,
        params: vec![
            ParamDecl::optional("axes", ParamType::I64, ParamValue::I64(6)),
            ParamDecl::optional("backend", ParamType::Text, ParamValue::Text("sim".into())),
            ParamDecl::optional(
                "watchdog",
                ParamType::I64,
                ParamValue::I64(bridge::LOST_AFTER as i64),
            ),
            handover::param(),
        ]
        .into_iter()
        .chain(JOINT_PARAMS.iter().map(|(name, default)| {
            ParamDecl::optional(name, ParamType::F64s, ParamValue::F64s(vec![*default]))
        }))
        .chain(ethercat_params())
        .collect(),
    })
}

/// The backends a `bus` may name.
pub const BACKENDS: [&str; 2] = ["sim", "ethercat"];

/// The params of the `ethercat` backend (`modbot_ethercat::config` reads them): the
/// interface, and per axis the slave, its identity and its units; empty lists mean "not
/// given" (the defaults are the backend's).
fn ethercat_params() -> impl Iterator<Item = ParamDecl> {
    let list = |name| ParamDecl::optional(name, ParamType::F64s, ParamValue::F64s(Vec::new()));
    [
        ParamDecl::optional(
            "interface",
            ParamType::Text,
            ParamValue::Text(String::new()),
        ),
        list("slave"),
        list("vendor"),
        list("product"),
        list("counts_per_rad"),
        list("torque_per_nm"),
        ParamDecl::optional("link_encoder", ParamType::Bool, ParamValue::Bool(false)),
        ParamDecl::optional("dc", ParamType::Bool, ParamValue::Bool(false)),
    ]
    .into_iter()
}

/// Param `backend`: one of [`BACKENDS`].
pub fn backend(p: &Params) -> Result<&str, ParamError> {
    let name = if p.get("backend").is_some() {
        p.text("backend")?
    } else {
        "sim"
    };
    if !BACKENDS.contains(&name) {
        let why = format!("names an unknown bus backend '{name}' (known: sim, ethercat)");
        return Err(ParamError::invalid("backend", why));
    }
    Ok(name)
}

/// The joint parameters of `bus` and their defaults ([`PlantParams::default`]'s).
const JOINT_PARAMS: [(&str, f64); 7] = [
    ("motor_inertia", 0.5),
    ("link_inertia", 2.0),
    ("stiffness", 2.0e4),
    ("damping", 10.0),
    ("viscous_friction", 1.0),
    ("coulomb_friction", 3.0),
    ("torque_limit", 200.0),
];

/// The mechanics of the `axes` simulated joints, from `bus`'s params: each joint parameter is
/// one value for every axis or one per axis; the rest is [`PlantParams::default`]'s. A joint
/// its checks refuse (a non-positive inertia, a sub-step too long for its elastic mode) is
/// refused here, naming the axis.
pub fn joints(p: &Params, axes: usize) -> Result<Vec<PlantParams>, ParamError> {
    let mut joints = vec![PlantParams::default(); axes];
    for (name, _) in JOINT_PARAMS {
        let Some(ParamValue::F64s(_)) = p.get(name) else {
            continue;
        };
        let values = modbot_control::per_axis(p, name, axes, "finite", f64::is_finite)?;
        for (joint, x) in joints.iter_mut().zip(values) {
            let slot = match name {
                "motor_inertia" => &mut joint.motor_inertia,
                "link_inertia" => &mut joint.link_inertia,
                "stiffness" => &mut joint.stiffness,
                "damping" => &mut joint.damping,
                "viscous_friction" => &mut joint.viscous_friction,
                "coulomb_friction" => &mut joint.coulomb_friction,
                _ => &mut joint.torque_limit,
            };
            *slot = x;
        }
    }
    for (axis, joint) in joints.iter().enumerate() {
        if let Err(e) = joint.check() {
            let why = format!("makes joint {axis} invalid: {e}");
            return Err(ParamError::invalid(e.name, why));
        }
    }
    Ok(joints)
}

/// Param `watchdog`: the base periods without a release after which the bus bridge judges
/// the coordinator lost and stops the drives (default [`bridge::LOST_AFTER`], 1 to 1000).
pub fn watchdog_periods(p: &Params) -> Result<u64, ParamError> {
    if p.get("watchdog").is_none() {
        return Ok(bridge::LOST_AFTER);
    }
    let periods = p.i64("watchdog")?;
    if !(1..=1000).contains(&periods) {
        let why = format!("must be 1 to 1000 base periods, not {periods}");
        return Err(ParamError::invalid("watchdog", why));
    }
    Ok(periods as u64)
}

/// A `bus` with drives of its own: a private simulation (the reference run, tests).
fn make_bus(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    let n = axes(p)?;
    if backend(p)? != "sim" {
        let why = "is 'ethercat': real drives are driven by the bus bridge process (the host named \"bus\") only".to_owned();
        return Err(ParamError::invalid("backend", why).into());
    }
    let period_ns = (p.f64(PERIOD_S)? * 1e9).round() as u64;
    let sim = SimBackend::with_joints(&joints(p, n)?, DriveParams::default())
        .map_err(|e| ParamError::invalid(e.name, e.to_string()))?;
    let bridge = Bridge::new(Box::new(sim), period_ns).watchdog_periods(watchdog_periods(p)?);
    Ok(Box::new(Bus {
        bridge: Arc::new(Mutex::new(bridge)),
    }))
}

/// Registers `bus` as the component that drives `bridge` (the bus bridge process's, which also
/// runs its watchdog); the axes must agree.
pub fn register_bridge(registry: &mut Registry, bridge: Arc<Mutex<Bridge>>) {
    registry.register_with(bus_info, move |p| {
        let n = axes(p)?;
        let axes = bridge::lock(&bridge).axes();
        if axes != n {
            let why = format!("must be {axes}, the axes of the bus bridge, not {n}");
            return Err(ParamError::invalid("axes", why).into());
        }
        Ok(Box::new(Bus {
            bridge: bridge.clone(),
        }))
    });
}

struct Bus {
    bridge: Arc<Mutex<Bridge>>,
}

fn slice(v: &PortValue) -> &[f64] {
    match v {
        PortValue::F64s(x) => x,
        _ => &[],
    }
}

impl Component for Bus {
    fn holding(&self) -> bool {
        bridge::lock(&self.bridge).holding()
    }

    fn stopping(&mut self) {
        bridge::lock(&self.bridge).grid_stopping();
    }

    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let input = |port: usize, i: usize| slice(&inputs[port]).get(i).copied().unwrap_or(0.0);
        let served = Served {
            tick: rel.tick.0,
            generation: rel.generation.0,
            safe_stop: rel.flags & Release::SAFE_STOP != 0,
        };
        let mut b = bridge::lock(&self.bridge);
        b.serve_release(rel.now_ns, &served, |i| AxisCommand {
            controlword: input(0, i).clamp(0.0, 65535.0) as u16,
            mode: input(1, i).clamp(-128.0, 127.0) as i8,
            target_position: input(2, i),
            target_velocity: input(3, i),
            target_torque: input(4, i),
        });
        let holding = b.holding();
        if let Some(PortValue::F64(state)) = outputs.last_mut() {
            *state = b.state_code() as f64;
        }
        let actuals = b.actuals();
        let (outputs, forwarded) = outputs.split_at_mut(BUS_OUT.len().min(outputs.len()));
        if let (Some(from), Some(to)) = (inputs.get(BUS_IN.len()), forwarded.first_mut()) {
            // The running generator's handover, for a generator taking over; none while the
            // drives do not follow the assembly.
            if let PortValue::F64s(to) = &mut *to {
                if to.len() == slice(from).len() {
                    to.copy_from_slice(slice(from));
                }
            }
            if holding {
                handover::invalidate(to);
            }
        }
        for (port, out) in outputs.iter_mut().enumerate() {
            if let PortValue::F64s(values) = out {
                for (i, (v, a)) in values.iter_mut().zip(actuals.iter()).enumerate() {
                    *v = match port {
                        0 => f64::from(a.statusword),
                        1 => a.motor_position,
                        2 => a.motor_velocity,
                        3 => a.motor_torque,
                        4 => a.link_position,
                        _ => b.demand_position(i),
                    };
                }
            }
        }
    }
}

fn enable_info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    Ok(ComponentInfo {
        type_name: "drive_enable",
        doc: "walks every drive to operation enabled in a mode; never re-enables a quick stop",
        inputs: ports(&["statusword"], n),
        outputs: ports(&["controlword", "mode"], n),
        params: vec![
            ParamDecl::optional("axes", ParamType::I64, ParamValue::I64(6)),
            ParamDecl::optional("mode", ParamType::I64, ParamValue::I64(8)),
            ParamDecl::optional("reset_faults", ParamType::Bool, ParamValue::Bool(false)),
        ],
    })
}

fn make_enable(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    let n = axes(p)?;
    let mode = if p.get("mode").is_some() {
        p.i64("mode")?
    } else {
        8
    };
    if !(8..=10).contains(&mode) {
        let why = format!("must be 8 (CSP), 9 (CSV) or 10 (CST), not {mode}");
        return Err(ParamError::invalid("mode", why).into());
    }
    let reset = p.get("reset_faults").is_some() && p.bool("reset_faults")?;
    Ok(Box::new(Enable {
        mode: mode as f64,
        reset,
        reset_sent: vec![false; n],
    }))
}

struct Enable {
    mode: f64,
    reset: bool,
    /// Per axis: the fault reset's rising edge was sent (bit 7 goes low again next).
    reset_sent: Vec<bool>,
}

impl Component for Enable {
    /// Which axes' fault reset edge was sent (its mode and whether it resets are parameters).
    fn carry(
        &mut self,
        c: &mut modbot_grid::carry::Carry<'_>,
    ) -> Result<(), modbot_grid::carry::CarryError> {
        c.bools("reset_sent", &mut self.reset_sent)
    }

    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let status = slice(&inputs[0]);
        let (cw, rest) = outputs.split_at_mut(1);
        let (PortValue::F64s(cw), PortValue::F64s(mode)) = (&mut cw[0], &mut rest[0]) else {
            return;
        };
        for i in 0..cw.len() {
            let sw = status.get(i).copied().unwrap_or(0.0).clamp(0.0, 65535.0) as u16;
            let state = DriveState::from_statusword(sw).unwrap_or(DriveState::NotReadyToSwitchOn);
            let word = match state {
                DriveState::SwitchOnDisabled => 0x06,
                DriveState::ReadyToSwitchOn => 0x07,
                DriveState::SwitchedOn | DriveState::OperationEnabled => 0x0f,
                // The recovery after a safe stop: disable voltage (transition 12), then enable.
                DriveState::QuickStopActive if self.reset => 0x00,
                // Held: a lost master must not re-enable it.
                DriveState::QuickStopActive => 0x02,
                DriveState::Fault if self.reset && !self.reset_sent[i] => {
                    self.reset_sent[i] = true;
                    0x80
                }
                DriveState::Fault
                | DriveState::FaultReactionActive
                | DriveState::NotReadyToSwitchOn => 0x00,
            };
            if word != 0x80 && state != DriveState::Fault {
                self.reset_sent[i] = false;
            }
            cw[i] = f64::from(word);
            mode[i] = self.mode;
        }
    }
}
