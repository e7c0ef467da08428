//! What every host process of the grid does around its clocked work — `modbot-host` and the
//! bus bridge `modbot-bus` are this plus their loop: read the checked grid, open the node, make the
//! host's components, serve the process's module on a thread of normal priority, then make
//! this thread the real-time one.

use std::sync::Arc;
use std::thread::JoinHandle;

use clap::Args;
use modbot_core::transport::channels::Channels;
use modbot_core::{signals, IpcTransport, ModuleBuilder};
use modbot_grid::component::Registry;
use modbot_grid::host::{Host, LoadAssembly};
use modbot_grid::GridSpec;
use modbot_modules::common::ModuleArgs;

use crate::board::Board;
use crate::grid_args::{assembly_loader, GridArgs};
use crate::service_thread::serve_module;

/// The command line of a host process: the module's options, the grid's, and the host.
#[derive(Debug, Args)]
pub struct HostArgs {
    #[command(flatten)]
    pub module: ModuleArgs,
    #[command(flatten)]
    pub grid: GridArgs,
    /// The host name whose components this process steps.
    #[arg(long)]
    pub host: String,
}

/// A host process, set up: its grid loaded, its components made, listening on the grid.
pub struct HostProcess {
    pub grid: GridSpec,
    /// The grid's channels, through the host's node.
    pub node: Arc<dyn Channels>,
    pub host: Host,
    /// How an assembly the coordinator announces is loaded: its checked grid.
    loader: LoadAssembly,
    args: HostArgs,
    transport: Option<IpcTransport>,
}

impl HostProcess {
    /// Loads the grid, asks `registry` for the component types to make its components with
    /// (the bus bridge makes its drives there and registers the `bus` that drives them), opens
    /// the node and makes the components of `--host`; installs the termination handler.
    pub fn start(
        args: HostArgs,
        registry: impl FnOnce(&GridSpec) -> anyhow::Result<Registry>,
    ) -> anyhow::Result<HostProcess> {
        let grid = args.grid.load(&args.module.domain)?;
        let registry = registry(&grid)?;
        Self::start_loaded(args, grid, &registry)
    }

    /// Like [`HostProcess::start`], with the component types of `registry` from the start (a
    /// host program's own types are checked against what the description declares of them).
    pub fn start_with(args: HostArgs, registry: &Registry) -> anyhow::Result<HostProcess> {
        let grid = args.grid.load_with(&args.module.domain, registry)?;
        Self::start_loaded(args, grid, registry)
    }

    fn start_loaded(
        args: HostArgs,
        grid: GridSpec,
        registry: &Registry,
    ) -> anyhow::Result<HostProcess> {
        let transport = args.module.transport()?;
        let node: Arc<dyn Channels> =
            Arc::new(transport.channels(&format!("grid.host.{}", args.host))?);
        let mut host = Host::new(&*node, &grid, registry, &args.host)?;
        host.keep_node(node.clone());
        // Started by a live upgrade: it stands by to take the components over.
        if let Some(dir) = std::env::var_os(modbot_core::transport::launch::UPGRADE_DIR) {
            host.standby(node.clone(), Some(dir.into()))?;
        }
        signals::install_termination_handler()?;
        Ok(HostProcess {
            grid,
            node,
            host,
            loader: assembly_loader(&args.module.domain)?,
            args,
            transport: Some(transport),
        })
    }

    /// Between releases: a bounded piece of the preparation of an assembly the coordinator
    /// announced (see [`Host::prepare_step`]).
    pub fn prepare_step(&mut self) -> anyhow::Result<()> {
        Ok(self.host.prepare_step(&self.node, &self.loader)?)
    }

    /// The host name it steps.
    pub fn host_name(&self) -> &str {
        &self.args.host
    }

    /// Announces the process: its module (`--name`, else `default_name`; `--addr`, else
    /// `default_addr`), as `declare` builds it, served with `state` on a thread of normal
    /// priority, so that a method call never delays the clocked work; its blackboard shows the
    /// components' latest outputs ([`Board`]). Then locks memory if
    /// the grid asks (`grid { mlock = true }`) and makes this thread the real-time one.
    pub fn serve<S: Send + 'static>(
        &mut self,
        default_name: String,
        default_addr: u8,
        declare: impl FnOnce(ModuleBuilder<S>) -> ModuleBuilder<S> + Send + 'static,
        state: S,
    ) -> anyhow::Result<JoinHandle<anyhow::Result<()>>> {
        let name = self.args.module.name.clone().unwrap_or(default_name);
        let (addr, mode) = (
            self.args.module.addr_or(default_addr),
            self.args.module.receive_mode(),
        );
        let transport = self
            .transport
            .take()
            .ok_or_else(|| anyhow::anyhow!("the module of this host is served already"))?;
        let mut board = Board::new(
            self.host.outputs_view(),
            self.grid.base_period.as_secs_f64(),
        );
        let bb = board.blackboard()?;
        crate::board::register_view(
            &name,
            self.host.outputs_view(),
            self.grid.base_period.as_secs_f64(),
        );
        let service = serve_module(
            move || {
                // In a live upgrade the grid hands the components' state over (at a tick,
                // before the module): the module itself has none to carry.
                let builder = ModuleBuilder::new(&name, addr)
                    .mode(mode)
                    .on_upgrade_out(1, state_in_the_grid::<S>)
                    .on_upgrade_in(carried_by_the_grid::<S>);
                let module = declare(builder).method("latest", crate::board::latest_method::<S>);
                Ok(module.blackboard(bb).open(transport, state)?)
            },
            move |module| board.refresh(&mut module.ctx().bb),
        )?;
        modbot_core::transport::launch::apply_mlockall();
        modbot_core::realtime::real_time_thread(self.grid.host_priority(), "serving thread");
        Ok(service)
    }

    /// Whether the clocked work goes on: no termination asked, the module still served (a
    /// process that handed its module over to a new one ends).
    pub fn running(service: &JoinHandle<anyhow::Result<()>>) -> bool {
        !signals::termination_requested() && !service.is_finished()
    }

    /// A new process of a live upgrade that could not take the components over ends here,
    /// with the reason (the running process serves on).
    pub fn check_upgrade(&self) -> anyhow::Result<()> {
        match self.host.refused() {
            Some(why) => anyhow::bail!("not upgraded: {why}"),
            None => Ok(()),
        }
    }

    /// Ends the process: reports releases not executed, and the service thread's result.
    pub fn finish(self, service: JoinHandle<anyhow::Result<()>>) -> anyhow::Result<()> {
        if self.host.stale > 0 {
            tracing::warn!(
                "{} release(s) not executed: an input's version was gone",
                self.host.stale
            );
        }
        match service.join() {
            Ok(result) => result,
            Err(_) => anyhow::bail!("the service thread panicked"),
        }
    }
}

/// A host module's own state in a live upgrade: none (its components' is the grid's to carry).
fn state_in_the_grid<S>(_: &S) -> Vec<u8> {
    Vec::new()
}

/// Takes the (empty) state of [`state_in_the_grid`].
fn carried_by_the_grid<S>(
    _: &mut S,
    _: &mut modbot_core::ctx::Ctx,
    _: u32,
    _: &[u8],
) -> Result<(), String> {
    Ok(())
}

/// The command line of a host program: what the supervisor passes.
#[derive(Debug, clap::Parser)]
struct HostCli {
    #[command(flatten)]
    host: HostArgs,
}

/// The `main` of a host program: `modbot-host` with the built-in component types, or a
/// program of your own that adds its types to `registry` (a system description names it in
/// `component_type "T" { program = ... }`). Steps the components the description puts on
/// `--host` whenever the coordinator releases them.
pub fn host_main(program: &str, registry: Registry) -> std::process::ExitCode {
    host_main_with(program, registry, |module| module)
}

/// [`host_main`] for a host program whose module has methods of its own: `declare` adds them
/// (the data recorder's `start` and `stop`).
pub fn host_main_with(
    program: &str,
    registry: Registry,
    declare: impl FnOnce(ModuleBuilder<()>) -> ModuleBuilder<()> + Send + 'static,
) -> std::process::ExitCode {
    modbot_modules::common::main(program, |cli: HostCli| {
        let mut p = HostProcess::start_with(cli.host, &registry)?;
        let name = p.grid.host_module(p.host_name());
        let service = p.serve(name, 200, declare, ())?;
        let now = || modbot_core::clock::Clock::now_ns(&modbot_core::clock::MonotonicClock);
        while HostProcess::running(&service) {
            // Wakes up for its releases; every 5 ms also to look at the termination flag.
            p.host
                .wait_and_serve(Some(std::time::Duration::from_millis(5)), &now)?;
            p.check_upgrade()?;
            p.prepare_step()?;
        }
        p.finish(service)
    })
}
