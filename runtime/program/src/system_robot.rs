//! The running system as a program drives it: a tool endpoint in its domain.
//!
//! - switches go through `modbot_grid::switch` (what `modbot assembly switch` does);
//! - the grid's tick and base period are the `tick` and `base_period_s` items of a host of
//!   the system's own components (the bus bridge: served every tick);
//! - `read("a.b")` is item `b` of module `a` when a module of that name runs, else output `b`
//!   of component `a`: item `a.b` of the host that steps it — a host of the running
//!   assembly's generation, or of the system's own components;
//! - a fault is the coordinator's ledger saying the grid faulted;
//! - on a grid in lockstep the program takes the coordinator's gate and **steps** the grid:
//!   it stands between commands, and runs only to the ticks the program says
//!   ([`Robot::run_to`]); a component's output is then read from its host's view (`latest`),
//!   which is current at the tick the grid holds before, and a switch runs the grid to its
//!   announced tick. So a program gives the same numbers in every run (`modbot up --lockstep
//!   --gate TICK` makes the first tick the same too). A real-time grid refuses the gate: the
//!   program follows it as it runs.

use std::time::Duration;

use modbot_core::calls::CallOptions;
use modbot_core::domain::Domain;
use modbot_core::error::CallError;
use modbot_core::tool::{Calls, Tool};
use modbot_grid::spec::{GridRole, COORDINATOR};
use modbot_grid::switch;
use modbot_ipc_schema::{NakCode, OwnedValue, Value};

use super::{Robot, RobotError};

/// How long one read or call may take: generous, since a method may do real work (the
/// recorder's `stop` closes its file) and a loaded machine stretches it to seconds; a module
/// that is not running fails a call at once, whatever this says.
const CALL_TIMEOUT: Duration = Duration::from_secs(30);
/// How long a switch may take (preparing a new assembly takes a fraction of a second here).
const SWITCH_TIMEOUT: Duration = Duration::from_secs(60);
/// How long a component is looked for among the hosts before it is said not to exist.
const LOOK_AGAIN: Duration = Duration::from_secs(2);
/// How long a stepped grid may take to reach a tick (a dead or stuck host is never done).
const STEP_TIMEOUT: Duration = Duration::from_secs(60);
/// After this long without a call of the gate, a program looks where the grid stands before it
/// trusts the tick it stepped to (the coordinator lifts a gate after 20 s without a call).
const GATE_LOOK_AGAIN: Duration = Duration::from_secs(15);
/// How far a stepped grid runs between two looks at a reset's answer, ticks.
const RESET_STRIDE: u64 = 10;

/// A running system in a domain.
pub struct SystemRobot {
    tool: Tool,
    domain: String,
    /// The running assembly's generation, once known.
    generation: Option<u16>,
    /// Where components were found: (generation, component, host module).
    hosts: Vec<(u16, String, String)>,
    /// The host module whose `tick` is the grid's.
    clock: Option<String>,
    /// Stepping a gated lockstep grid: the tick it holds before.
    stepping: Option<u64>,
    /// When the gate was last called: a program idle for the gate's lease (an idle REPL)
    /// has lost it, and looks again before it trusts `stepping`.
    gate_called: std::time::Instant,
}

impl SystemRobot {
    /// Joins `domain` as the tool `modbot-program`.
    pub fn open(domain: &str) -> Result<SystemRobot, RobotError> {
        let domain = Domain::new(domain).map_err(|e| RobotError::Grid(e.to_string()))?;
        let tool = Tool::open(&domain, "modbot-program")
            .map_err(|e| RobotError::Grid(format!("cannot join the domain: {e}")))?;
        let mut robot = SystemRobot {
            tool,
            domain: domain.name().to_owned(),
            generation: None,
            hosts: Vec::new(),
            clock: None,
            stepping: None,
            gate_called: std::time::Instant::now(),
        };
        let (held, lifted) = take_gate_noting(&mut robot.tool)?;
        if let (Some(held), Some(why)) = (held, lifted) {
            // `modbot up --gate` held the grid for a program that came too late: the grid ran
            // on, and this run starts where it got to.
            eprintln!(
                "modbot program: {why}; the program steps it from tick {held}: this run is not \
                 the same as another"
            );
        }
        robot.stepping = held;
        Ok(robot)
    }

    /// The gate answered just now: the grid holds before `next` (`None`: not stepped).
    fn stepped_to(&mut self, next: Option<u64>) {
        self.stepping = next;
        self.gate_called = std::time::Instant::now();
    }

    /// The running assembly's generation.
    fn generation(&mut self) -> Result<u16, RobotError> {
        if let Some(g) = self.generation {
            return Ok(g);
        }
        let status = switch::status(&mut self.tool).map_err(|e| RobotError::Grid(e.to_string()))?;
        self.generation = Some(status.generation);
        Ok(status.generation)
    }

    /// The live host modules of generation `generation` and of the system's own components.
    fn host_modules(&self, generation: u16) -> Result<Vec<String>, RobotError> {
        let modules = self
            .tool
            .list_modules()
            .map_err(|e| RobotError::Grid(e.to_string()))?;
        Ok(modules
            .into_iter()
            .filter(|m| m.alive)
            .filter(|m| match GridRole::of(&m.name) {
                Some(GridRole::Host { generation: g, .. }) => g.0 == generation || g.0 == 0,
                _ => false,
            })
            .map(|m| m.name)
            .collect())
    }

    fn module_alive(&self, name: &str) -> Result<bool, RobotError> {
        let modules = self
            .tool
            .list_modules()
            .map_err(|e| RobotError::Grid(e.to_string()))?;
        Ok(modules.iter().any(|m| m.alive && m.name == name))
    }

    fn bb_get(&mut self, module: &str, item: &str) -> Result<OwnedValue, BbGetError> {
        self.item_call(module, "bb_get", item)
    }

    /// A host's `latest(item)`: the item as its serving thread left it.
    fn latest(&mut self, module: &str, item: &str) -> Result<OwnedValue, BbGetError> {
        self.item_call(module, "latest", item)
    }

    fn item_call(
        &mut self,
        module: &str,
        method: &str,
        item: &str,
    ) -> Result<OwnedValue, BbGetError> {
        self.tool.call_blocking(
            module,
            method,
            &[Value::Text(item)],
            CallOptions::timeout(CALL_TIMEOUT),
            |r| match r {
                Ok(args) => args
                    .get(0)
                    .map(|v| v.to_owned_value())
                    .ok_or(BbGetError::Empty),
                Err(e) => Err(BbGetError::Call(e.clone())),
            },
        )
    }

    /// The host module that has item `item` (`component.output`) in the running generation.
    fn host_of(&mut self, component: &str, item: &str) -> Result<String, RobotError> {
        let generation = self.generation()?;
        if let Some((_, _, module)) = self
            .hosts
            .iter()
            .find(|(g, c, _)| *g == generation && c == component)
        {
            return Ok(module.clone());
        }
        // A host that has just taken over may not be in this tool's view of the directory
        // yet: look again for a little while.
        let deadline = std::time::Instant::now() + LOOK_AGAIN;
        let mut seen = Vec::new();
        loop {
            for module in self.host_modules(generation)? {
                match self.bb_get(&module, item) {
                    Ok(_) => {
                        self.hosts
                            .push((generation, component.to_owned(), module.clone()));
                        return Ok(module);
                    }
                    Err(why) => seen.push(format!("{module}: {why}")),
                }
            }
            if std::time::Instant::now() > deadline {
                break;
            }
            seen.clear();
            std::thread::sleep(Duration::from_millis(20));
        }
        Err(RobotError::Read {
            what: item.to_owned(),
            why: format!(
                "no module named '{component}' runs, and no component '{component}' with that \
                 output in the running assembly (generation {generation}) or the system's own \
                 (hosts asked: {})",
                if seen.is_empty() {
                    "none".to_owned()
                } else {
                    seen.join("; ")
                }
            ),
        })
    }

    /// The host module that keeps the grid's tick: one of the system's own components'.
    fn clock(&mut self) -> Result<String, RobotError> {
        if let Some(c) = &self.clock {
            return Ok(c.clone());
        }
        let modules = self
            .tool
            .list_modules()
            .map_err(|e| RobotError::Grid(e.to_string()))?;
        let found = modules.into_iter().find(|m| {
            m.alive
                && matches!(GridRole::of(&m.name), Some(GridRole::Host { generation, .. }) if generation.0 == 0)
        });
        let clock = found.map(|m| m.name).ok_or_else(|| {
            RobotError::Grid("no host of the system's own components runs (no grid?)".into())
        })?;
        self.clock = Some(clock.clone());
        Ok(clock)
    }

    fn clock_item(&mut self, item: &str) -> Result<OwnedValue, RobotError> {
        let clock = self.clock()?;
        self.bb_get(&clock, item).map_err(|why| {
            self.clock = None;
            RobotError::Grid(format!("{clock}.{item}: {why}"))
        })
    }
}

/// Why a blackboard item could not be read.
#[derive(Debug, thiserror::Error)]
enum BbGetError {
    #[error(transparent)]
    Call(CallError),
    #[error("an empty answer")]
    Empty,
}

impl Robot for SystemRobot {
    fn switch(&mut self, name: &str) -> Result<u64, RobotError> {
        let stepped = self.stepping.is_some();
        let mut reached = None;
        let mut run_there = |tool: &mut Tool, at: u64| {
            if stepped {
                reached = Some(
                    run_to(tool, at).map_err(|why| switch::SwitchError::Stepping {
                        tick: at,
                        why: why.to_string(),
                    })?,
                );
            }
            Ok(())
        };
        let switched = switch::switch_with(&mut self.tool, name, SWITCH_TIMEOUT, &mut run_there);
        if reached.is_some() {
            self.stepped_to(reached);
        }
        let switched = switched.map_err(|e| RobotError::Switch {
            assembly: name.to_owned(),
            why: match e {
                switch::SwitchError::Failed { reason, .. } => reason,
                other => other.to_string(),
            },
        })?;
        self.generation = Some(switched.generation);
        self.hosts.retain(|(g, _, _)| *g == switched.generation);
        Ok(switched.tick)
    }

    fn tick(&mut self) -> Result<u64, RobotError> {
        if self.stepping.is_some() && self.gate_called.elapsed() >= GATE_LOOK_AGAIN {
            // The gate may have been lifted meanwhile: where does the grid stand?
            let held = take_gate(&mut self.tool)?;
            if held != self.stepping {
                eprintln!(
                    "modbot program: the grid ran on by itself while the program was idle; it \
                     is held again before tick {}: from here this run is not the same as another",
                    held.unwrap_or(0)
                );
            }
            self.stepped_to(held);
        }
        if let Some(next) = self.stepping {
            return Ok(next.saturating_sub(1));
        }
        match self.clock_item("tick")? {
            OwnedValue::I64(t) => Ok(u64::try_from(t).unwrap_or(0)),
            other => Err(RobotError::Grid(format!("the tick is {other}"))),
        }
    }

    fn base_period_s(&mut self) -> Result<f64, RobotError> {
        match self.clock_item("base_period_s")? {
            OwnedValue::F64(s) if s > 0.0 => Ok(s),
            other => Err(RobotError::Grid(format!("the base period is {other}"))),
        }
    }

    fn read(&mut self, what: &str) -> Result<OwnedValue, RobotError> {
        let (module, item) = what.split_once('.').ok_or_else(|| RobotError::Read {
            what: what.to_owned(),
            why: "write module.item or component.output".into(),
        })?;
        let read_error = |why: BbGetError| RobotError::Read {
            what: what.to_owned(),
            why: why.to_string(),
        };
        if self.module_alive(module)? {
            return self.bb_get(module, item).map_err(read_error);
        }
        let host = self.host_of(module, what)?;
        if self.stepping.is_some() {
            return self.latest(&host, what).map_err(|why| {
                self.hosts.retain(|(_, c, _)| c != module);
                self.generation = None;
                read_error(why)
            });
        }
        self.bb_get(&host, what).map_err(|why| {
            // Its host may have gone (a switch by someone else): look again next time.
            self.hosts.retain(|(_, c, _)| c != module);
            self.generation = None;
            read_error(why)
        })
    }

    fn call(&mut self, target: &str, args: &[OwnedValue]) -> Result<Vec<OwnedValue>, RobotError> {
        let (module, method) = target.split_once('.').ok_or_else(|| RobotError::Call {
            target: target.to_owned(),
            why: "write module.method".into(),
        })?;
        let values: Vec<Value<'_>> = args.iter().map(OwnedValue::as_value).collect();
        self.tool
            .call_owned(module, method, &values, CallOptions::timeout(CALL_TIMEOUT))
            .map_err(|e| RobotError::Call {
                target: target.to_owned(),
                why: e.to_string(),
            })
    }

    fn fault(&mut self) -> Result<Option<String>, RobotError> {
        let row = self.tool.call_blocking(
            COORDINATOR,
            "ledger",
            &[],
            CallOptions::timeout(CALL_TIMEOUT),
            |r| -> Result<_, RobotError> {
                let failed = |e: &dyn std::fmt::Display| {
                    RobotError::Grid(format!("the coordinator's ledger: {e}"))
                };
                let args = r.map_err(|e| failed(e))?;
                let bytes = args.bytes(0).map_err(|e| failed(&e))?;
                let (row, _) = modbot_ipc_schema::ledger::decode(bytes).map_err(|e| failed(&e))?;
                Ok(row)
            },
        );
        let row = row?;
        Ok(row.state.starts_with("faulted").then_some(row.fault))
    }

    fn robot_state(&mut self) -> Result<Option<modbot_bus::RobotState>, RobotError> {
        modbot_bus::ask::robot_state(&mut self.tool, CALL_TIMEOUT)
            .map_err(|e| RobotError::Robot(e.to_string()))
    }

    fn reset(&mut self) -> Result<String, RobotError> {
        let Some(mut next) = self.stepping else {
            return modbot_bus::ask::reset(&mut self.tool, modbot_bus::ask::RESET_TIMEOUT)
                .map_err(|e| RobotError::Robot(e.to_string()));
        };
        // The bridge takes a reset at a release: the held grid runs on, RESET_STRIDE ticks at a
        // time, until it answers.
        let answer = modbot_bus::ask::reset_with(
            &mut self.tool,
            modbot_bus::ask::RESET_TIMEOUT,
            &mut |tool| {
                next = run_to(tool, next - 1 + RESET_STRIDE).map_err(|e| {
                    modbot_bus::ask::AskError::Call(format!("stepping the grid: {e}"))
                })?;
                Ok(())
            },
        );
        self.stepped_to(Some(next));
        answer.map_err(|e| RobotError::Robot(e.to_string()))
    }

    fn domain(&self) -> &str {
        &self.domain
    }

    fn stepped(&self) -> bool {
        self.stepping.is_some()
    }

    fn run_to(&mut self, tick: u64) -> Result<u64, RobotError> {
        let next = run_to(&mut self.tool, tick)?;
        self.stepped_to(Some(next));
        Ok(tick)
    }
}

impl Drop for SystemRobot {
    /// A program that ends lets the grid run free again.
    fn drop(&mut self) {
        if self.stepping.is_some() {
            let _ = self.tool.call_owned(
                COORDINATOR,
                "ungate",
                &[],
                CallOptions::timeout(Duration::from_secs(1)),
            );
        }
    }
}

/// What the coordinator's gate says to a call.
enum GateSays {
    /// The tick the grid holds before, whether it is held there, and — to the caller that
    /// takes a gate which was lifted by itself — why it was lifted.
    At(u64, bool, Option<String>),
    /// Refused, with the coordinator's words: a real-time grid, or a tick the grid has passed
    /// (the gate was lifted meanwhile).
    Refused(String),
    /// No gate here: no coordinator, or one without a gate.
    Absent,
}

/// The coordinator's `gate(until, pid)` (`until` < 0: do not move it).
fn gate(tool: &mut Tool, until: i64) -> Result<GateSays, RobotError> {
    let pid = i64::from(std::process::id());
    tool.call_blocking(
        COORDINATOR,
        "gate",
        &[Value::I64(until), Value::I64(pid)],
        CallOptions::timeout(CALL_TIMEOUT),
        |r| match r {
            Ok(args) => match (args.i64(0), args.bool(1)) {
                (Ok(next), Ok(held)) => Ok(GateSays::At(
                    u64::try_from(next).unwrap_or(0),
                    held,
                    args.text(2).ok().map(str::to_owned),
                )),
                _ => Err(RobotError::Grid(
                    "the coordinator's gate answered oddly".into(),
                )),
            },
            // Busy: another program steps this grid; two cannot.
            Err(CallError::Nak { code, detail, .. }) if *code == NakCode::BUSY => {
                Err(RobotError::Grid(detail.clone()))
            }
            Err(CallError::Nak { detail, .. }) => Ok(GateSays::Refused(detail.clone())),
            Err(CallError::UnknownModule(_)) | Err(CallError::UnknownMethod { .. }) => {
                Ok(GateSays::Absent)
            }
            Err(e) => Err(RobotError::Grid(format!("the coordinator's gate: {e}"))),
        },
    )
}

/// Takes the gate of a lockstep grid and waits until the grid is held: the tick it holds
/// before. `None`: a grid that keeps its own time (real time), or none.
fn take_gate(tool: &mut Tool) -> Result<Option<u64>, RobotError> {
    take_gate_noting(tool).map(|(held, _)| held)
}

/// [`take_gate`], and why the gate had been lifted by itself when it was (the grid ran on
/// before this program took it).
fn take_gate_noting(tool: &mut Tool) -> Result<(Option<u64>, Option<String>), RobotError> {
    match gate(tool, -1)? {
        GateSays::At(next, true, lifted) => Ok((Some(next), lifted)),
        GateSays::At(_, false, lifted) => Ok((Some(wait_held(tool, None)?), lifted)),
        GateSays::Refused(_) | GateSays::Absent => Ok((None, None)),
    }
}

/// Polls the gate until the grid is held (before `next`, if given): the tick it holds before.
fn wait_held(tool: &mut Tool, next: Option<u64>) -> Result<u64, RobotError> {
    let deadline = std::time::Instant::now() + STEP_TIMEOUT;
    loop {
        match gate(tool, -1)? {
            GateSays::At(at, true, _) if next.is_none_or(|n| n == at) => return Ok(at),
            GateSays::At(..) => {}
            GateSays::Refused(why) => return Err(RobotError::Grid(why)),
            GateSays::Absent => {
                return Err(RobotError::Grid(
                    "the coordinator went away while the program stepped the grid".into(),
                ))
            }
        }
        if std::time::Instant::now() > deadline {
            return Err(RobotError::Grid(format!(
                "the grid did not get {} within {} s (a host stopped?)",
                next.map_or("held".to_owned(), |n| format!("to tick {n}")),
                STEP_TIMEOUT.as_secs()
            )));
        }
        std::thread::sleep(Duration::from_micros(200));
    }
}

/// Runs the gated grid until tick `tick` is done: moves the gate to `tick + 1` and waits until
/// the grid is held there. Returns the tick it holds before. A gate lifted meanwhile (the
/// program did not call for 20 s: an idle REPL) is taken again where the grid has got to, with
/// a warning: from there the run is not the same as another.
fn run_to(tool: &mut Tool, tick: u64) -> Result<u64, RobotError> {
    let next = tick + 1;
    match gate(tool, i64::try_from(next).unwrap_or(i64::MAX))? {
        GateSays::At(at, true, _) if at == next => Ok(next),
        GateSays::At(..) => wait_held(tool, Some(next)),
        GateSays::Refused(why) => match take_gate(tool)? {
            Some(held) => {
                eprintln!(
                    "modbot program: {why}; it is held again before tick {held}: from here \
                     this run is not the same as another"
                );
                Ok(held)
            }
            None => Err(RobotError::Grid(why)),
        },
        GateSays::Absent => Err(RobotError::Grid(
            "the coordinator went away while the program stepped the grid".into(),
        )),
    }
}
