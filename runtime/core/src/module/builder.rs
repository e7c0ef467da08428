//! Declaring a module: [`ModuleBuilder`] collects its name, address, methods, hooks, tasks
//! and blackboard, then claims the address in the domain.

use core::time::Duration;
use std::sync::Arc;

use modbot_ipc_schema::{sysmethod, Addr};

use super::look::{realtime_thread, Look};
use super::{
    ActivationFn, Definition, DoneFn, MethodFn, Module, Reply, ReportFn, TaskFn, UpgradeInFn,
    UpgradeOutFn, DEFAULT_LINGER,
};
use crate::beat::Heartbeats;
use crate::blackboard::Blackboard;
use crate::clock::{Clock, MonotonicClock};
use crate::ctx::{Ctx, Link, Liveness};
use crate::error::ModuleError;
use crate::phonebook::PhoneBook;
use crate::stats::Stats;
use crate::transport::{Joins, ReceiveMode, Transport};

/// Declares a module.
pub struct ModuleBuilder<S> {
    name: String,
    addr: Addr,
    mode: ReceiveMode,
    methods: Vec<(String, MethodFn<S>)>,
    on_report: Option<ReportFn<S>>,
    on_done: Option<DoneFn<S>>,
    on_activation: Option<ActivationFn<S>>,
    tasks: Vec<(Duration, TaskFn<S>)>,
    groups: Vec<String>,
    peers: Vec<String>,
    blackboard: Option<Blackboard>,
    snapshot_period: Duration,
    clock: Arc<dyn Clock>,
    linger: Duration,
    upgrade_out: Option<(u32, UpgradeOutFn<S>)>,
    upgrade_in: Option<UpgradeInFn<S>>,
}

impl<S> ModuleBuilder<S> {
    /// A module named `name` at `addr`.
    pub fn new(name: &str, addr: u8) -> Self {
        ModuleBuilder {
            name: name.to_owned(),
            addr: Addr(addr),
            mode: ReceiveMode::Blocking,
            methods: Vec::new(),
            on_report: None,
            on_done: None,
            on_activation: None,
            tasks: Vec::new(),
            groups: Vec::new(),
            peers: Vec::new(),
            blackboard: None,
            snapshot_period: Duration::from_millis(100),
            clock: Arc::new(MonotonicClock),
            linger: DEFAULT_LINGER,
            upgrade_out: None,
            upgrade_in: None,
        }
    }

    /// How long a module in blocking mode that served a frame looks for the next one before
    /// it sleeps again (default [`DEFAULT_LINGER`]): a call that follows within it is taken
    /// without a wake-up, which costs tens of µs where idle cores halt. Adaptive: after a linger
    /// that found nothing, the next 16 sleep at once. Zero sleeps at once; a thread under
    /// SCHED_FIFO or SCHED_RR never lingers.
    pub fn linger(mut self, linger: Duration) -> Self {
        self.linger = linger;
        self
    }

    /// Adds a local method; ids are given in declaration order.
    pub fn method(mut self, name: &str, f: MethodFn<S>) -> Self {
        self.methods.push((name.to_owned(), f));
        self
    }

    pub fn on_report(mut self, f: ReportFn<S>) -> Self {
        self.on_report = Some(f);
        self
    }

    pub fn on_done(mut self, f: DoneFn<S>) -> Self {
        self.on_done = Some(f);
        self
    }

    /// Calls `f` when the operator activates or deactivates the module (the `activate` and
    /// `deactivate` system methods), after the change and only when the state changes. While
    /// deactivated, the module answers its own methods with NAK not-ready and its tasks do not
    /// run ([`Ctx::is_active`]).
    pub fn on_activation(mut self, f: ActivationFn<S>) -> Self {
        self.on_activation = Some(f);
        self
    }

    /// What of the module's own state a live upgrade carries to the new process (`modbot
    /// upgrade`): `f` writes it as bytes when this process hands over, tagged with `version`
    /// (the new program's [`ModuleBuilder::on_upgrade_in`] checks it). Without it the new process
    /// gets the blackboard's values only, and starts its own state from its defaults.
    pub fn on_upgrade_out(mut self, version: u32, f: UpgradeOutFn<S>) -> Self {
        self.upgrade_out = Some((version, f));
        self
    }

    /// Takes the state the process this one upgrades handed over (its
    /// [`ModuleBuilder::on_upgrade_out`] bytes and their version), before the module serves
    /// its first frame; an `Err` (a version it cannot read, say) is logged and the module starts
    /// from its defaults.
    pub fn on_upgrade_in(mut self, f: UpgradeInFn<S>) -> Self {
        self.upgrade_in = Some(f);
        self
    }

    /// Runs `f` every `period` (not while the operator has deactivated the module).
    pub fn every(mut self, period: Duration, f: TaskFn<S>) -> Self {
        self.tasks.push((period, f));
        self
    }

    pub fn mode(mut self, mode: ReceiveMode) -> Self {
        self.mode = mode;
        self
    }

    /// Joins a multicast group.
    pub fn group(mut self, group: &str) -> Self {
        self.groups.push(group.to_owned());
        self
    }

    /// Names a module this one calls: it is looked up at start-up and whenever it (re)appears.
    pub fn peer(mut self, name: &str) -> Self {
        self.peers.push(name.to_owned());
        self
    }

    pub fn blackboard(mut self, bb: Blackboard) -> Self {
        self.blackboard = Some(bb);
        self
    }

    /// Publishes a snapshot at least this often (and at once on every change).
    pub fn snapshot_period(mut self, period: Duration) -> Self {
        self.snapshot_period = period;
        self
    }

    pub fn clock(mut self, clock: Arc<dyn Clock>) -> Self {
        self.clock = clock;
        self
    }

    /// Claims the address and name in the domain and announces the module.
    ///
    /// Under a supervisor, the environment adds to the declaration: `MODBOT_GROUPS` (groups to
    /// join, comma-separated) and `MODBOT_HEARTBEAT_MS` (the heartbeat period).
    pub fn open<T: Transport + 'static>(
        mut self,
        transport: T,
        state: S,
    ) -> Result<Module<S>, ModuleError> {
        if let Ok(groups) = std::env::var(crate::transport::launch::GROUPS) {
            for g in groups.split(',').filter(|g| !g.is_empty()) {
                if !self.groups.iter().any(|have| have == g) {
                    self.groups.push(g.to_owned());
                }
            }
        }
        self.check_methods()?;
        let endpoint = transport
            .open(
                self.addr,
                &self.name,
                self.mode,
                &Joins {
                    broadcast: self.on_report.is_some(),
                    groups: &self.groups,
                },
            )
            .map_err(|source| ModuleError::Open {
                name: self.name.clone(),
                addr: self.addr,
                source,
            })?;
        Self::assemble(self, Box::new(transport), endpoint, state)
    }

    /// Opens a tool's endpoint at a free address (the CLI, benchmark drivers).
    pub fn open_tool<T: Transport + 'static>(
        self,
        transport: T,
        state: S,
    ) -> Result<Module<S>, ModuleError> {
        self.check_methods()?;
        let joins = Joins {
            broadcast: self.on_report.is_some(),
            groups: &[],
        };
        let endpoint = transport.open_tool(&self.name, self.mode, &joins)?;
        Self::assemble(self, Box::new(transport), endpoint, state)
    }

    /// At most 240 methods, none named like a system method (a caller could not reach it:
    /// names resolve to the system method first).
    fn check_methods(&self) -> Result<(), ModuleError> {
        if self.methods.len() > usize::from(sysmethod::FIRST_RESERVED) {
            return Err(ModuleError::Definition(format!(
                "{} methods; at most 240",
                self.methods.len()
            )));
        }
        if let Some((name, _)) = self
            .methods
            .iter()
            .find(|(name, _)| sysmethod::id(name).is_some())
        {
            return Err(ModuleError::Definition(format!(
                "method '{name}' of module '{}' has the name of a system method every module \
                 answers; choose another name",
                self.name
            )));
        }
        Ok(())
    }

    fn assemble(
        b: Self,
        transport: Box<dyn Transport>,
        endpoint: crate::transport::Endpoint,
        state: S,
    ) -> Result<Module<S>, ModuleError> {
        let now = b.clock.now_ns();
        let beat_period_ns = crate::transport::launch::heartbeat_period().as_nanos() as u64;
        let methods_digest =
            modbot_ipc_schema::directory::methods_digest(b.methods.iter().map(|(n, _)| n.as_str()));
        let ctx = Ctx {
            addr: endpoint.addr,
            name: b.name.clone(),
            mode: b.mode,
            link: Link {
                tx: endpoint.tx,
                snapshots: endpoint.snapshots,
                directory: endpoint.directory,
            },
            bb: b.blackboard.unwrap_or_else(Blackboard::empty),
            out: Default::default(),
            book: PhoneBook::new(),
            clock: b.clock,
            serving: Default::default(),
            stats: Stats::default(),
            liveness: Liveness {
                stop: false,
                active: true,
                heartbeats: Heartbeats::new(beat_period_ns, now, methods_digest),
            },
        };
        let tasks = b
            .tasks
            .iter()
            .map(|(p, _)| now + p.as_nanos() as u64)
            .collect();
        let mut module = Module {
            answer_look: Look::default(),
            linger: Look::default(),
            linger_span: b.linger,
            realtime: realtime_thread(),
            book_generation: 0,
            def: Definition {
                methods: b.methods,
                on_report: b.on_report,
                on_done: b.on_done,
                on_activation: b.on_activation,
                tasks: b.tasks,
                peers: b.peers,
                snapshot_period_ns: b.snapshot_period.as_nanos() as u64,
                upgrade_out: b.upgrade_out,
                upgrade_in: b.upgrade_in,
            },
            state,
            ctx,
            rx: endpoint.rx,
            transport,
            next_task_ns: tasks,
            next_refresh_ns: 0,
            last_snapshot_ns: 0,
            reply: Reply {
                buf: Vec::with_capacity(4096),
                count: 0,
            },
        };
        // Others learn of this module from the directory (its supervisor publishes it at the
        // first heartbeat; without a supervisor, their next scan finds its node).
        module.ctx.refresh_book();
        if module.rx.standby() {
            // A live upgrade's new process: it takes the running module over first (its
            // blackboard's values included), and only then looks up its peers and publishes.
            let dir = std::env::var_os(crate::transport::launch::UPGRADE_DIR).unwrap_or_default();
            module.take_over(std::path::Path::new(&dir))?;
        }
        module.look_up_peers();
        module.publish_snapshot(module.ctx.now_ns());
        tracing::info!(addr = %module.ctx.addr, mode = module.ctx.mode.name(), "module {} is up", module.ctx.name);
        Ok(module)
    }
}
