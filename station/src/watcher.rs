//! The thread that owns the station's endpoint in the domain: it looks at the system ten
//! times a second, runs the page's commands between looks, and hands each look to the web
//! side as one JSON text.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam::channel::{Receiver, RecvTimeoutError};
use modbot_core::calls::CallOptions;
use modbot_core::error::CallError;
use modbot_core::stats::Stats;
use modbot_core::tool::{Calls, Tool};
use modbot_ipc_schema::ledger::{self, LedgerError};
use modbot_ipc_schema::status::{self, Row};
use modbot_ipc_schema::{sysmethod, ArgError, Args, SnapshotError, SnapshotView, Value};
use tokio::sync::{oneshot, watch};

use crate::commands::{Answer, Call};
use crate::events::Log;
use crate::state::{Assembly, Grid, Json, Module, State};

/// How often the station looks.
pub const LOOK_PERIOD: Duration = Duration::from_millis(100);
/// How often it asks every module what it says of itself.
pub const DESCRIBE_PERIOD: Duration = Duration::from_secs(1);
/// How long a page's wish to watch a blackboard lasts without being repeated.
pub const WATCH_FOR: Duration = Duration::from_secs(5);
/// The timeout of a look's calls: a module that does not answer this fast is reported.
const LOOK_TIMEOUT: Duration = Duration::from_millis(300);
/// The timeout of a page's command.
const COMMAND_TIMEOUT: Duration = Duration::from_secs(5);

/// The blackboards the station always shows when their modules exist: MOSER's pose, sonar,
/// intrusion and plan (and the bus bridge's: the arm's joints).
const ALWAYS_WATCHED: [&str; 4] = ["mobility", "nav_sonar", "intrusion", "high_level"];

/// What the web side hands the watcher.
pub enum Input {
    /// A command of a page allowed to command, and where its answer goes.
    Call(Call, oneshot::Sender<Answer>),
    /// Blackboards a page wants to see.
    Watch(Vec<String>),
}

/// What a module said of itself at its last describe.
#[derive(Debug, Clone, Default)]
struct SelfReport {
    active: Option<bool>,
    methods: Vec<String>,
    calls: u64,
    latency_p50_us: Option<f64>,
    latency_p99_us: Option<f64>,
}

pub struct Watcher {
    tool: Tool,
    domain: String,
    started: Instant,
    log: Log,
    watched: BTreeMap<String, Instant>,
    reports: BTreeMap<String, SelfReport>,
    described: Option<Instant>,
    bus_module: String,
    /// The pages connected, counted by the web side.
    pages: Arc<AtomicUsize>,
}

impl Watcher {
    pub fn new(tool: Tool, domain: &str) -> Watcher {
        Watcher {
            tool,
            domain: domain.to_owned(),
            started: Instant::now(),
            log: Log::new(),
            watched: BTreeMap::new(),
            reports: BTreeMap::new(),
            described: None,
            bus_module: modbot_bus::ask::bus_module(),
            pages: Arc::default(),
        }
    }

    /// Counts the pages in `pages` (the web side keeps it): each look says how many there are.
    pub fn with_pages(mut self, pages: Arc<AtomicUsize>) -> Watcher {
        self.pages = pages;
        self
    }

    /// Looks and serves commands until `stop` is set or `inputs` closes (the web side
    /// ended); then its endpoint leaves the domain.
    pub fn run(mut self, inputs: Receiver<Input>, out: watch::Sender<Arc<str>>, stop: &AtomicBool) {
        let mut next = Instant::now();
        while !stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            if now >= next {
                let state = self.look();
                let json = serde_json::to_string(&state).unwrap_or_else(|e| {
                    format!("{{\"type\":\"error\",\"text\":\"the state did not serialise: {e}\"}}")
                });
                out.send_replace(json.into());
                next = now + LOOK_PERIOD;
            }
            match inputs.recv_timeout(next.saturating_duration_since(Instant::now())) {
                Ok(Input::Call(call, reply)) => {
                    let answer = self.command(&call);
                    let _ = reply.send(answer);
                }
                Ok(Input::Watch(modules)) => {
                    let until = Instant::now() + WATCH_FOR;
                    for m in modules {
                        self.watched.insert(m, until);
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return,
            }
        }
    }

    fn t_ms(&self) -> u64 {
        self.started.elapsed().as_millis() as u64
    }

    /// Runs one command of a page, and logs it with its outcome. The bus bridge's `reset` is
    /// the operator's reset: answered when the bridge has done or refused it (up to
    /// [`modbot_bus::ask::RESET_TIMEOUT`]; the looks wait meanwhile), not when it took it.
    pub fn command(&mut self, call: &Call) -> Answer {
        let args: Vec<Value<'_>> = call.args.iter().map(|a| a.as_value()).collect();
        let reset = call.module == self.bus_module && call.method == "reset" && args.is_empty();
        let result = if reset {
            modbot_bus::ask::reset(&mut self.tool, modbot_bus::ask::RESET_TIMEOUT)
                .map_err(|e| e.to_string())
        } else {
            self.tool.call_blocking(
                &call.module,
                &call.method,
                &args,
                CallOptions::timeout(COMMAND_TIMEOUT),
                |r| match r {
                    Ok(a) => Ok(answer_text(a)),
                    Err(e) => Err(e.to_string()),
                },
            )
        };
        let shown: Vec<String> = call.args.iter().map(ToString::to_string).collect();
        let what = format!("{}.{}({})", call.module, call.method, shown.join(", "));
        let t = self.t_ms();
        match result {
            Ok(text) => {
                self.log.push(t, "command", format!("{what} → {text}"));
                Answer::ok(call.id, text)
            }
            Err(e) => {
                self.log.push(t, "command", format!("{what} failed: {e}"));
                Answer::err(call.id, e)
            }
        }
    }

    /// One look at the system.
    pub fn look(&mut self) -> State {
        let began = Instant::now();
        let mut state = State {
            kind: "state",
            domain: self.domain.clone(),
            t_ms: self.t_ms(),
            pages: self.pages.load(Ordering::Relaxed),
            ..State::default()
        };
        self.modules(&mut state);
        self.describe_due(&state);
        for m in &mut state.modules {
            if let Some(r) = self.reports.get(&m.row.name) {
                m.active = r.active;
                m.methods = r.methods.clone();
                m.calls = r.calls;
                m.latency_p50_us = r.latency_p50_us;
                m.latency_p99_us = r.latency_p99_us;
            }
        }
        let exists = |name: &str| state.modules.iter().any(|m| m.name() == name && m.runs());
        if exists("coordinator") {
            state.grid = self.grid(&mut state.problems);
        }
        if exists(&self.bus_module) {
            state.robot = self.robot(&mut state.problems);
            state.bus = Some(self.bus_module.clone());
        }
        let now = Instant::now();
        self.watched.retain(|_, until| *until > now);
        let mut watched: Vec<String> = ALWAYS_WATCHED
            .iter()
            .map(|s| (*s).to_owned())
            .chain([self.bus_module.clone()])
            .chain(self.watched.keys().cloned())
            .filter(|m| exists(m))
            .collect();
        watched.sort();
        watched.dedup();
        for m in watched {
            if let Some(bb) = self.blackboard(&m, &mut state.problems) {
                state.blackboards.insert(m, bb);
            }
        }
        self.log.observe(&mut state);
        state.look_ms = began.elapsed().as_millis() as u64;
        state
    }

    /// The modules: the supervisor's rows, or iceoryx2's directory without a supervisor.
    fn modules(&mut self, state: &mut State) {
        let rows = self.tool.call_blocking(
            "supervisor",
            "status",
            &[],
            CallOptions::timeout(LOOK_TIMEOUT),
            |r| match r {
                Ok(a) => a
                    .bytes(0)
                    .map_err(|e| e.to_string())
                    .and_then(|b| status::decode(b).map_err(|e| e.to_string()))
                    .map(Some),
                Err(CallError::UnknownModule(_)) => Ok(None),
                Err(e) => Err(e.to_string()),
            },
        );
        match rows {
            Ok(Some(rows)) => {
                state.supervised = true;
                state.modules = rows.into_iter().map(Module::from_row).collect();
                self.imports(state);
            }
            Ok(None) => match self.tool.list_modules() {
                Ok(peers) => {
                    let me = self.tool.addr();
                    state.modules = peers
                        .iter()
                        .filter(|p| Some(p.addr) != me)
                        .map(|p| {
                            Module::from_row(Row {
                                name: p.name.clone(),
                                addr: p.addr.0,
                                state: if p.alive { "running" } else { "down" }.into(),
                                pid: if p.alive { p.pid } else { 0 },
                                restarts: 0,
                                last_exit: String::new(),
                                counters: Default::default(),
                                heartbeat_age_ms: None,
                                upgrades: 0,
                            })
                        })
                        .collect();
                }
                Err(e) => state.problems.push(format!("the domain's directory: {e}")),
            },
            Err(e) => state.problems.push(format!("supervisor status: {e}")),
        }
    }

    /// The modules a bridge imports from other hosts (`bridge { imports = ... }`): the
    /// directory lists them alive under the pid of a module the supervisor runs (the bridge's
    /// process holds their addresses), and the supervisor does not. Shown with the state
    /// `imported`; their blackboards are read through the bridge as any module's.
    fn imports(&mut self, state: &mut State) {
        let Ok(peers) = self.tool.list_modules() else {
            return;
        };
        let supervised: Vec<u32> = state
            .modules
            .iter()
            .filter(|m| m.runs())
            .map(|m| m.row.pid)
            .collect();
        for p in peers {
            let listed = state.modules.iter().any(|m| m.name() == p.name);
            if p.alive && !listed && supervised.contains(&p.pid) {
                state.modules.push(Module::from_row(Row {
                    name: p.name,
                    addr: p.addr.0,
                    state: "imported".into(),
                    pid: p.pid,
                    restarts: 0,
                    last_exit: String::new(),
                    counters: Default::default(),
                    heartbeat_age_ms: None,
                    upgrades: 0,
                }));
            }
        }
    }

    /// Once a second: what every running module says of itself (describe, stats).
    fn describe_due(&mut self, state: &State) {
        if self
            .described
            .is_some_and(|t| t.elapsed() < DESCRIBE_PERIOD)
        {
            return;
        }
        self.described = Some(Instant::now());
        let names: Vec<&str> = state
            .modules
            .iter()
            .filter(|m| m.row.state == "running")
            .map(Module::name)
            .collect();
        let mut reports: Vec<SelfReport> = vec![SelfReport::default(); names.len()];
        let describe = sysmethod::name(sysmethod::DESCRIBE).unwrap_or("describe");
        self.tool.call_each(
            &names,
            describe,
            CallOptions::timeout(LOOK_TIMEOUT),
            |i, r| {
                if let Ok(a) = r {
                    reports[i].methods = a
                        .text(3)
                        .map(|m| {
                            m.split(',')
                                .filter(|s| !s.is_empty())
                                .map(str::to_owned)
                                .collect()
                        })
                        .unwrap_or_default();
                    // Modules older than `active` do not send it: active.
                    reports[i].active = Some(!matches!(a.get(8), Some(Value::Bool(false))));
                }
            },
        );
        let stats = sysmethod::name(sysmethod::STATS).unwrap_or("stats");
        self.tool
            .call_each(&names, stats, CallOptions::timeout(LOOK_TIMEOUT), |i, r| {
                if let Some(s) = r.ok().and_then(|a| Stats::from_answer(a).ok()) {
                    reports[i].calls = s.calls;
                    if !s.latency.is_empty() {
                        reports[i].latency_p50_us = Some(s.latency.percentile(50.0) as f64 / 1e3);
                        reports[i].latency_p99_us = Some(s.latency.percentile(99.0) as f64 / 1e3);
                    }
                }
            });
        self.reports = names.iter().map(|n| (*n).to_owned()).zip(reports).collect();
    }

    fn grid(&mut self, problems: &mut Vec<String>) -> Option<Grid> {
        let ledger = self.tool.call_blocking(
            "coordinator",
            "ledger",
            &[],
            CallOptions::timeout(LOOK_TIMEOUT),
            |r| -> Result<Grid, LookError> {
                let bytes = r.map_err(CallError::clone)?.bytes(0)?;
                let (grid, components) = ledger::decode(bytes)?;
                Ok(Grid {
                    grid,
                    components,
                    assembly: None,
                })
            },
        );
        let mut grid = ledger
            .map_err(|e| problems.push(format!("coordinator ledger: {e}")))
            .ok()?;
        // A grid without assemblies answers with a status of none.
        match modbot_grid::switch::status(&mut self.tool) {
            Ok(s) if s.assembly != "none" || !s.outcomes.is_empty() => {
                grid.assembly = Some(Assembly::from_status(&s));
            }
            Ok(_) => {}
            Err(e) => problems.push(format!("coordinator assembly: {e}")),
        }
        Some(grid)
    }

    fn robot(&mut self, problems: &mut Vec<String>) -> Option<String> {
        match modbot_bus::ask::robot_state(&mut self.tool, LOOK_TIMEOUT) {
            Ok(state) => state.map(|s| s.to_string()),
            Err(e) => {
                problems.push(format!("robot state: {e}"));
                None
            }
        }
    }

    fn blackboard(
        &mut self,
        module: &str,
        problems: &mut Vec<String>,
    ) -> Option<BTreeMap<String, Json>> {
        let snapshot = sysmethod::name(sysmethod::BB_SNAPSHOT).unwrap_or("bb_snapshot");
        let bb = self.tool.call_blocking(
            module,
            snapshot,
            &[],
            CallOptions::timeout(LOOK_TIMEOUT),
            |r| -> Result<BTreeMap<String, Json>, LookError> {
                let bytes = r.map_err(CallError::clone)?.bytes(0)?;
                let view = SnapshotView::parse(bytes)?;
                Ok(view
                    .iter()
                    .map(|it| (it.name.to_owned(), Json::of(&it.value)))
                    .collect())
            },
        );
        bb.map_err(|e| problems.push(format!("{module}'s blackboard: {e}")))
            .ok()
    }
}

/// Why a look at the coordinator's ledger or at a module's blackboard found nothing to show.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum LookError {
    /// The call failed.
    #[error(transparent)]
    Call(#[from] CallError),
    /// The answer is not one bytes value.
    #[error(transparent)]
    Answer(#[from] ArgError),
    /// The coordinator's bytes are not a ledger.
    #[error(transparent)]
    Ledger(#[from] LedgerError),
    /// The module's bytes are not a blackboard snapshot.
    #[error(transparent)]
    Snapshot(#[from] SnapshotError),
}

/// An answer's values as one line: `ok` for none.
fn answer_text(a: &Args<'_>) -> String {
    let values: Vec<String> = a.as_slice().iter().map(ToString::to_string).collect();
    if values.is_empty() {
        "ok".to_owned()
    } else {
        values.join(", ")
    }
}
