//! The station's log of what changed: a module's state, a restart, the grid's state or
//! generation, the robot's state, an intruder alert, and the answers to the page's commands.
//! Found by comparing each look with the one before.

use std::collections::{BTreeMap, VecDeque};

use crate::state::{Event, Json, State};

/// How many events the page gets (the latest).
pub const KEPT: usize = 200;

/// What the last look saw, to compare the next one with.
#[derive(Debug, Default)]
pub struct Log {
    events: VecDeque<Event>,
    modules: BTreeMap<String, (String, u32, Option<bool>)>,
    grid: Option<String>,
    robot: Option<String>,
    alerts: Option<i64>,
    first: bool,
}

impl Log {
    pub fn new() -> Log {
        Log {
            first: true,
            ..Log::default()
        }
    }

    /// Adds an event.
    pub fn push(&mut self, t_ms: u64, kind: &'static str, text: String) {
        self.push_at(t_ms, kind, text, None);
    }

    fn push_at(&mut self, t_ms: u64, kind: &'static str, text: String, at: Option<[f64; 2]>) {
        if self.events.len() == KEPT {
            self.events.pop_front();
        }
        self.events.push_back(Event {
            t_ms,
            kind,
            text,
            at,
        });
    }

    /// Compares `now` with the look before, logs what changed (nothing for the first look
    /// but what it found), and gives the log to `now`.
    pub fn observe(&mut self, now: &mut State) {
        let t = now.t_ms;
        let first = std::mem::replace(&mut self.first, false);
        for m in &now.modules {
            let (row, active_now) = (&m.row, m.active);
            let seen = (row.state.clone(), row.restarts, active_now);
            match self.modules.get(&row.name).cloned() {
                None if first => {}
                None => self.push(t, "module", format!("{} appeared: {}", row.name, row.state)),
                Some((state, restarts, active)) => {
                    if restarts < row.restarts {
                        let why = if row.last_exit.is_empty() {
                            String::new()
                        } else {
                            format!(" after it {}", row.last_exit)
                        };
                        self.push(
                            t,
                            "restart",
                            format!("{} restarted ({} in all){why}", row.name, row.restarts),
                        );
                    }
                    if state != row.state {
                        self.push(
                            t,
                            "module",
                            format!("{}: {} → {}", row.name, state, row.state),
                        );
                    }
                    if let (Some(before), Some(after)) = (active, active_now) {
                        if before != after {
                            let word = if after { "activated" } else { "deactivated" };
                            self.push(t, "module", format!("{} {word}", row.name));
                        }
                    }
                }
            }
            self.modules.insert(row.name.clone(), seen);
        }
        let grid = now.grid.as_ref().map(|g| match g.grid.fault.as_str() {
            "" => g.grid.state.clone(),
            fault => format!("{}: {fault}", g.grid.state),
        });
        if grid != self.grid && !(first && grid.is_none()) {
            if let Some(g) = &grid {
                self.push(t, "grid", format!("grid {g}"));
            }
            self.grid = grid;
        }
        if now.robot != self.robot {
            if let Some(r) = &now.robot {
                self.push(t, "robot", format!("robot {r}"));
            }
            self.robot = now.robot.clone();
        }
        self.observe_alerts(now);
        now.events = self.events.iter().cloned().collect();
    }

    /// MOSER's intrusion module counts its alerts on its blackboard (`alerts`, with the
    /// fused `probability`).
    fn observe_alerts(&mut self, now: &State) {
        let Some(bb) = now.blackboards.get("intrusion") else {
            return;
        };
        let Some(Json::Integer(alerts)) = bb.get("alerts") else {
            return;
        };
        if self.alerts.is_some_and(|a| a < *alerts) || (self.alerts.is_none() && *alerts > 0) {
            let p = match bb.get("probability") {
                Some(Json::Number(Some(p))) => format!(", probability {p:.2}"),
                _ => String::new(),
            };
            let at = match (
                now.blackboards.get("mobility").and_then(|m| m.get("x")),
                now.blackboards.get("mobility").and_then(|m| m.get("y")),
            ) {
                (Some(Json::Number(Some(x))), Some(Json::Number(Some(y)))) => Some([*x, *y]),
                _ => None,
            };
            let shown = at.map_or(String::new(), |[x, y]| {
                format!(" (robot at {x:.1}, {y:.1})")
            });
            self.push_at(
                now.t_ms,
                "alert",
                format!("INTRUDER ALERT {alerts}{p}{shown}"),
                at,
            );
        }
        self.alerts = Some(*alerts);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::Module;
    use modbot_ipc_schema::status::Row;

    fn module(name: &str, state: &str, restarts: u32, active: Option<bool>) -> Module {
        let mut m = Module::from_row(Row {
            name: name.into(),
            addr: 3,
            state: state.into(),
            pid: 42,
            restarts,
            last_exit: if restarts > 0 {
                "was killed by SIGKILL".into()
            } else {
                String::new()
            },
            counters: Default::default(),
            heartbeat_age_ms: None,
            upgrades: 0,
        });
        m.active = active;
        m
    }

    fn look(t_ms: u64, modules: Vec<Module>, robot: Option<&str>, alerts: Option<i64>) -> State {
        let mut s = State {
            t_ms,
            modules,
            robot: robot.map(str::to_owned),
            ..State::default()
        };
        if let Some(a) = alerts {
            s.blackboards.insert(
                "intrusion".into(),
                [("alerts".to_owned(), Json::Integer(a))]
                    .into_iter()
                    .collect(),
            );
        }
        s
    }

    #[test]
    fn changes_between_looks_are_logged_once_each() {
        let mut log = Log::new();
        let mut s = look(
            0,
            vec![module("sonar", "running", 0, Some(true))],
            Some("operational"),
            Some(0),
        );
        log.observe(&mut s);
        assert_eq!(s.events.len(), 1, "{:?}", s.events); // the robot's state as found
        let mut s = look(
            100,
            vec![module("sonar", "running", 1, Some(false))],
            Some("operational"),
            Some(1),
        );
        log.observe(&mut s);
        let texts: Vec<&str> = s.events.iter().map(|e| e.text.as_str()).collect();
        assert_eq!(
            texts[1..],
            [
                "sonar restarted (1 in all) after it was killed by SIGKILL",
                "sonar deactivated",
                "INTRUDER ALERT 1",
            ]
        );
        let mut s = look(
            200,
            vec![module("sonar", "running", 1, Some(false))],
            Some("safe stop"),
            Some(1),
        );
        log.observe(&mut s);
        assert_eq!(s.events.last().unwrap().text, "robot safe stop");
        assert_eq!(s.events.len(), 5);
    }

    #[test]
    fn the_log_keeps_the_latest_events() {
        let mut log = Log::new();
        for i in 0..(KEPT as u64 + 10) {
            log.push(i, "command", format!("{i}"));
        }
        let mut s = State::default();
        log.observe(&mut s);
        assert_eq!(s.events.len(), KEPT);
        assert_eq!(s.events[0].text, "10");
    }
}
