//! What the page shows, as the watcher last saw it: serialised to JSON once per look and sent
//! to every browser alike.

use std::collections::BTreeMap;

use modbot_ipc_schema::ledger::{ComponentRow, GridRow};
use modbot_ipc_schema::status::Row;
use modbot_ipc_schema::Value;
use serde::Serialize;

/// Everything one update carries.
#[derive(Debug, Clone, Default, Serialize)]
pub struct State {
    #[serde(rename = "type")]
    pub kind: &'static str,
    pub domain: String,
    /// Milliseconds since the station started, when the look began.
    pub t_ms: u64,
    /// How long the look took (its calls into the domain), in milliseconds.
    pub look_ms: u64,
    /// How many pages are connected to the station.
    pub pages: usize,
    /// Whether this connection may command (set per connection when sent).
    pub can_command: bool,
    /// Whether a supervisor answers (else the modules come from iceoryx2's directory).
    pub supervised: bool,
    pub modules: Vec<Module>,
    pub grid: Option<Grid>,
    /// The robot's state as the bus bridge words it, if the system has a bus.
    pub robot: Option<String>,
    /// The bus bridge's module name, if the system has a bus (where a reset goes).
    pub bus: Option<String>,
    /// Watched modules' blackboards, item by item.
    pub blackboards: BTreeMap<String, BTreeMap<String, Json>>,
    /// The latest events, oldest first.
    pub events: Vec<Event>,
    /// What went wrong in the last look (a module that did not answer, say).
    pub problems: Vec<String>,
}

/// One module: the supervisor's row (name, address, state, pid, restarts, last exit, its
/// transport counters) and what the module says of itself.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Module {
    #[serde(flatten)]
    pub row: Row,
    /// Whether the module serves (`deactivate` switches it off); unknown until it answers.
    pub active: Option<bool>,
    pub methods: Vec<String>,
    /// Calls it made, and their round trip p50/p99 in µs.
    pub calls: u64,
    pub latency_p50_us: Option<f64>,
    pub latency_p99_us: Option<f64>,
}

impl Module {
    /// A module from the supervisor's row; what the module says of itself comes later.
    pub fn from_row(row: Row) -> Module {
        Module {
            row,
            active: None,
            methods: Vec::new(),
            calls: 0,
            latency_p50_us: None,
            latency_p99_us: None,
        }
    }

    pub fn name(&self) -> &str {
        &self.row.name
    }

    /// Whether a process runs for it.
    pub fn runs(&self) -> bool {
        self.row.pid != 0
    }
}

/// The grid as the coordinator's ledger tells it: the grid's line (state, fault, ticks,
/// missed, rate, tick error in ns) and a line per component (host, period, policy, releases,
/// overruns, late, failed, stale, exec and latency in ns).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Grid {
    #[serde(flatten)]
    pub grid: GridRow,
    pub components: Vec<ComponentRow>,
    /// The running assembly and its switches, for a grid with assemblies.
    pub assembly: Option<Assembly>,
}

/// The running assembly, the switch under way and the recent switches.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Assembly {
    pub name: String,
    pub generation: u16,
    /// The switch under way (`idle` when none).
    pub switch: String,
    /// The last switches, oldest first, as `modbot assembly` words them.
    pub history: Vec<String>,
}

impl Assembly {
    pub fn from_status(s: &modbot_ipc_schema::switch::Status) -> Assembly {
        Assembly {
            name: s.assembly.clone(),
            generation: s.generation,
            switch: s.state.to_string(),
            history: s.outcomes.iter().map(ToString::to_string).collect(),
        }
    }
}

/// A blackboard value as JSON: numbers, booleans, text, arrays of numbers; bytes by their
/// length (images and scans are not drawn); a number that is not finite as null.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Json {
    Number(Option<f64>),
    Integer(i64),
    Bool(bool),
    Text(String),
    Numbers(Vec<Option<f64>>),
    Bytes { bytes: usize },
}

impl Json {
    pub fn of(v: &Value<'_>) -> Json {
        let finite = |x: f64| x.is_finite().then_some(x);
        match v {
            Value::F64(x) => Json::Number(finite(*x)),
            Value::I64(i) => Json::Integer(*i),
            Value::Bool(b) => Json::Bool(*b),
            Value::Text(t) => Json::Text((*t).to_owned()),
            Value::Bytes(b) => Json::Bytes { bytes: b.len() },
            Value::F64s(a) => Json::Numbers(a.iter().map(finite).collect()),
        }
    }
}

/// One line of the station's event log ([`crate::events`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Event {
    /// Milliseconds since the station started.
    pub t_ms: u64,
    /// `module`, `restart`, `grid`, `robot`, `alert` or `command`.
    pub kind: &'static str,
    pub text: String,
    /// Where it happened on MOSER's map (an alert: where the robot was).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub at: Option<[f64; 2]>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_ipc_schema::F64s;

    #[test]
    fn blackboard_values_become_json_a_page_can_plot() {
        let arr = [1.5, f64::NAN];
        let cases = [
            (Value::F64(2.5), "2.5"),
            (Value::F64(f64::INFINITY), "null"),
            (Value::I64(-3), "-3"),
            (Value::Bool(true), "true"),
            (Value::Text("patrolling"), "\"patrolling\""),
            (Value::Bytes(&[1, 2, 3]), "{\"bytes\":3}"),
            (Value::F64s(F64s::from_slice(&arr)), "[1.5,null]"),
        ];
        for (v, json) in cases {
            assert_eq!(serde_json::to_string(&Json::of(&v)).unwrap(), json, "{v:?}");
        }
    }
}
