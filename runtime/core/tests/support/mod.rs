//! Fixtures of the runtime suite that runs against both transport backends.
//!
//! - [`Backend`] names a backend ([`Local`]: crossbeam channels in one process; [`Ipc`]:
//!   iceoryx2 shared memory) and what differs between them: how a module is killed, whether
//!   files are left to check.
//! - [`TestDomain`] gives each test a domain of its own (`rt<pid>_<n>_<backend>_<test>`), runs
//!   modules on threads of their own, and on [`TestDomain::finish`] stops them and checks that
//!   the domain is empty: no module listed and, for shared memory, no file in `/dev/shm` or
//!   `/tmp/iceoryx2`. Its `Drop` removes the domain's files whatever happened.
//! - [`run_test`] wraps a test in a watchdog: a test that hangs fails after [`TEST_LIMIT`].
//!
//! A `Module` of the iceoryx2 backend holds an `Rc<Node>` and cannot move between threads, so
//! a module thread builds its module itself, then serves it with the default application
//! controller ([`Module::run`]) until its stop flag is set.

#![allow(dead_code)]

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use modbot_core::transport::Transport;
use modbot_core::{
    CallError, CallHandle, Ctx, Domain, IpcTransport, LocalTransport, Module, ModuleBuilder,
    ModuleError, Report,
};
use modbot_ipc_schema::{Addr, Args, OwnedValue, Value};

/// How long one test may take before the watchdog fails it: a hang detector, longer than any
/// wait of a test ([`PATIENCE`]), so a wait that times out fails with its own message.
pub const TEST_LIMIT: Duration = Duration::from_secs(120);
/// How long a test waits for what only needs the machine to run its threads (an answer, a
/// thread's end, a count to be reached): generous, since a wait ends as soon as its condition
/// holds, and a slow or loaded machine may take far longer than a quiet one.
pub const PATIENCE: Duration = Duration::from_secs(60);
/// How often a module thread looks at its stop flag.
const STOP_CHECK: Duration = Duration::from_millis(10);
/// How long a module thread may take to open its module.
const OPEN_LIMIT: Duration = PATIENCE;

/// A transport backend under test.
pub trait Backend: 'static {
    type Transport: Transport + Clone + Send + 'static;
    /// Short name, used in domain and thread names.
    const NAME: &'static str;
    /// Whether the backend keeps files in `/dev/shm` and `/tmp/iceoryx2`.
    const SHARED_MEMORY: bool;

    fn transport(domain: &Domain) -> Self::Transport;

    /// Kills module `addr` in place, as if its process died, if the backend can; `false` means
    /// it cannot, and the fixture stops the module's thread instead (which drops the module).
    fn kill(transport: &Self::Transport, addr: Addr) -> bool;
}

/// The in-process backend.
pub struct Local;

impl Backend for Local {
    type Transport = LocalTransport;
    const NAME: &'static str = "local";
    const SHARED_MEMORY: bool = false;

    fn transport(domain: &Domain) -> LocalTransport {
        LocalTransport::new(domain)
    }

    fn kill(transport: &LocalTransport, addr: Addr) -> bool {
        transport.kill(addr);
        true
    }
}

/// The iceoryx2 shared-memory backend.
pub struct Ipc;

impl Backend for Ipc {
    type Transport = IpcTransport;
    const NAME: &'static str = "ipc";
    const SHARED_MEMORY: bool = true;

    fn transport(domain: &Domain) -> IpcTransport {
        IpcTransport::new(domain).expect("the iceoryx2 backend opens")
    }

    fn kill(_: &IpcTransport, _: Addr) -> bool {
        false
    }
}

/// Runs `test` in a fresh [`TestDomain`] under a watchdog, then checks the domain is empty.
pub fn run_test<B: Backend>(name: &str, test: fn(&mut TestDomain<B>)) {
    let owned = name.to_owned();
    watchdog(&format!("{}::{name}", B::NAME), TEST_LIMIT, move || {
        let mut fx = TestDomain::<B>::new(&owned);
        test(&mut fx);
        fx.finish();
    });
}

/// Runs `f` on a thread of its own; fails (panics) if it does not end within `limit` (see
/// [`modbot_testkit::watchdog`]). Module threads install the runtime's SIGINT/SIGTERM
/// handler (`Module::run` does); in a test process that must still end the process.
pub fn watchdog(name: &str, limit: Duration, f: impl FnOnce() + Send + 'static) {
    modbot_testkit::watchdog(name, limit, modbot_core::signals::termination_requested, f);
}

thread_local! {
    /// The stop flag of the module thread this runs on.
    static STOP: RefCell<Option<Arc<AtomicBool>>> = const { RefCell::new(None) };
}

/// Whether the module thread this runs on was asked to stop (a method that stalls checks it).
pub fn stopping() -> bool {
    STOP.with(|s| {
        s.borrow()
            .as_ref()
            .is_some_and(|f| f.load(Ordering::SeqCst))
    })
}

/// A task every module thread runs: ends the main loop once the thread is asked to stop.
///
/// Tasks do not run while a module is deactivated (`deactivate`): a test that deactivates a
/// module activates it again before it ends, or its thread cannot stop.
fn stop_when_asked<S>(_: &mut S, ctx: &mut Ctx) {
    if stopping() {
        ctx.stop();
    }
}

/// The payload of a module thread's deliberate crash.
pub struct Crash;

/// Crashes the module thread this runs on: it unwinds without answering, dropping the module
/// as a dying process drops its resources. No panic message is printed.
pub fn crash() -> ! {
    std::panic::resume_unwind(Box::new(Crash))
}

/// A module served on a thread of its own.
struct Server {
    name: String,
    addr: Addr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), ModuleError>>>,
    /// Killed in place: its thread still runs, but it is no longer the module of its name.
    killed: bool,
}

impl Server {
    /// Asks the thread to stop and waits for it; returns what went wrong, if anything.
    fn stop(&mut self) -> Option<String> {
        self.stop.store(true, Ordering::SeqCst);
        let thread = self.thread.take()?;
        match thread.join() {
            Ok(Ok(())) => None,
            Ok(Err(e)) => Some(format!("module {} failed: {e}", self.name)),
            Err(p) if p.is::<Crash>() => None,
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                    .unwrap_or_default();
                Some(format!("module {} panicked: {msg}", self.name))
            }
        }
    }
}

/// A domain of its own for one test, and the module threads started in it.
pub struct TestDomain<B: Backend> {
    /// Removes its files when dropped (after the module threads stopped).
    pub domain: modbot_testkit::TestDomain,
    pub transport: B::Transport,
    servers: Vec<Server>,
}

impl<B: Backend> TestDomain<B> {
    pub fn new(test: &str) -> TestDomain<B> {
        let domain = modbot_testkit::TestDomain::new("rt", &format!("{}_{test}", &B::NAME[..1]));
        let transport = B::transport(&domain);
        TestDomain {
            domain,
            transport,
            servers: Vec::new(),
        }
    }

    /// Starts module `name` at `addr` on a thread of its own, built by `configure`, and waits
    /// until it is open.
    pub fn start<S: Send + 'static>(
        &mut self,
        name: &str,
        addr: u8,
        state: S,
        configure: impl FnOnce(ModuleBuilder<S>) -> ModuleBuilder<S> + Send + 'static,
    ) {
        let ready = self.spawn(name, addr, Duration::ZERO, state, configure);
        match ready.recv_timeout(OPEN_LIMIT) {
            Ok(Ok(())) => {}
            Ok(Err(e)) => panic!("module {name} did not open: {e}"),
            Err(_) => panic!("module {name} did not open within {OPEN_LIMIT:?}"),
        }
    }

    /// Starts module `name` after `delay`, without waiting for it.
    pub fn start_later<S: Send + 'static>(
        &mut self,
        delay: Duration,
        name: &str,
        addr: u8,
        state: S,
        configure: impl FnOnce(ModuleBuilder<S>) -> ModuleBuilder<S> + Send + 'static,
    ) {
        let _ = self.spawn(name, addr, delay, state, configure);
    }

    fn spawn<S: Send + 'static>(
        &mut self,
        name: &str,
        addr: u8,
        delay: Duration,
        state: S,
        configure: impl FnOnce(ModuleBuilder<S>) -> ModuleBuilder<S> + Send + 'static,
    ) -> mpsc::Receiver<Result<(), ModuleError>> {
        let (ready_tx, ready) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let transport = self.transport.clone();
        let (owned, flag) = (name.to_owned(), stop.clone());
        let thread = std::thread::Builder::new()
            .name(format!("{}:{name}", B::NAME))
            .spawn(move || {
                STOP.with(|s| *s.borrow_mut() = Some(flag));
                std::thread::sleep(delay);
                let builder =
                    configure(ModuleBuilder::new(&owned, addr)).every(STOP_CHECK, stop_when_asked);
                let module = match builder.open(transport, state) {
                    Ok(m) => m,
                    // Told to whoever waits for the module to open; else (no one waits) it
                    // is what the thread ends with.
                    Err(e) => {
                        return match ready_tx.send(Err(e)) {
                            Ok(()) => Ok(()),
                            Err(mpsc::SendError(unheard)) => unheard,
                        }
                    }
                };
                let _ = ready_tx.send(Ok(()));
                let result = module.run();
                if modbot_core::signals::termination_requested() {
                    eprintln!("interrupted");
                    std::process::exit(130);
                }
                result
            })
            .expect("spawn a module thread");
        self.servers.push(Server {
            name: name.to_owned(),
            addr: Addr(addr),
            stop,
            thread: Some(thread),
            killed: false,
        });
        ready
    }

    /// Opens module `name` at `addr` on the calling thread (no methods, no hooks).
    pub fn open<S: 'static>(
        &self,
        name: &str,
        addr: u8,
        state: S,
    ) -> Result<Module<S>, ModuleError> {
        ModuleBuilder::new(name, addr).open(self.transport.clone(), state)
    }

    /// Opens a tool endpoint on the calling thread that records answers to [`Ctx::call`] and
    /// every REPORT it hears.
    pub fn caller(&self) -> Module<Caller> {
        ModuleBuilder::new("tester", 0)
            .on_done(Caller::done)
            .on_report(Caller::heard)
            .open_tool(self.transport.clone(), Caller::default())
            .expect("the test's caller opens")
    }

    fn server(&mut self, name: &str) -> &mut Server {
        self.servers
            .iter_mut()
            .rev()
            .find(|s| s.name == name && s.thread.is_some() && !s.killed)
            .unwrap_or_else(|| panic!("no running module named {name}"))
    }

    /// Stops module `name` cleanly: its thread ends its main loop and drops the module.
    pub fn stop(&mut self, name: &str) {
        if let Some(e) = self.server(name).stop() {
            panic!("{e}");
        }
    }

    /// Kills module `name` as the backend can: in place ([`LocalTransport::kill`]), or by
    /// dropping it on its thread (iceoryx2: killing real processes is for the multi-process
    /// tests).
    pub fn kill(&mut self, name: &str) {
        let addr = self.server(name).addr;
        if B::kill(&self.transport, addr) {
            self.server(name).killed = true;
        } else {
            self.stop(name);
        }
    }

    /// Ends the threads of the modules killed in place (as reaping a dead process would).
    pub fn end_killed(&mut self) {
        for s in self.servers.iter_mut().filter(|s| s.killed) {
            if let Some(e) = s.stop() {
                panic!("{e}");
            }
        }
    }

    /// Waits for the thread of module `name`, which is expected to end by itself (a crash).
    pub fn wait_for_end(&mut self, name: &str) {
        let server = self.server(name);
        let thread = server.thread.take().expect("running");
        let deadline = Instant::now() + PATIENCE;
        while !thread.is_finished() {
            assert!(Instant::now() < deadline, "module {name} did not end");
            std::thread::sleep(Duration::from_millis(2));
        }
        match thread.join() {
            Err(p) if p.is::<Crash>() => {}
            Ok(r) => panic!("module {name} ended without crashing: {r:?}"),
            Err(_) => panic!("module {name} panicked"),
        }
    }

    /// The modules the domain's directory lists now.
    pub fn listed(&self) -> Vec<String> {
        let mut out = Vec::new();
        self.transport
            .directory()
            .expect("directory")
            .list(&mut |p| out.push(format!("{} at {} (alive: {})", p.name, p.addr, p.alive)))
            .expect("list");
        out
    }

    /// Stops every module thread and checks the domain is empty: the directory lists no
    /// module and no file of the domain is left. Every module the test opened on its own
    /// thread must be dropped before.
    pub fn finish(&mut self) {
        let problems: Vec<String> = self.servers.iter_mut().filter_map(Server::stop).collect();
        assert!(problems.is_empty(), "module threads failed: {problems:#?}");
        self.assert_empty();
    }

    /// Checks that no module is listed and, for shared memory, that no file is left.
    pub fn assert_empty(&self) {
        let listed = self.listed();
        assert!(
            listed.is_empty(),
            "modules still listed after every module left: {listed:?}"
        );
        if B::SHARED_MEMORY {
            let files = self.domain.files();
            assert!(
                files.is_empty(),
                "files of domain {} left behind after its last module left: {files:#?}",
                self.domain.name()
            );
        }
    }
}

impl<B: Backend> Drop for TestDomain<B> {
    fn drop(&mut self) {
        for s in &mut self.servers {
            let _ = s.stop();
        }
    }
}

/// A REPORT as a test records it.
#[derive(Debug, Clone, PartialEq)]
pub struct Heard {
    /// The module that heard it.
    pub by: String,
    pub from: Addr,
    pub topic: u8,
    pub values: Vec<OwnedValue>,
}

impl Heard {
    pub fn new(by: &str, r: &Report<'_>) -> Heard {
        Heard {
            by: by.to_owned(),
            from: r.from,
            topic: r.topic,
            values: owned(&r.values),
        }
    }
}

/// The state of the test's caller: what came back.
#[derive(Debug, Default)]
pub struct Caller {
    /// Answers to [`Ctx::call`], in arrival order.
    pub answers: Vec<(CallHandle, Result<Vec<OwnedValue>, CallError>)>,
    pub heard: Vec<Heard>,
}

impl Caller {
    fn done(s: &mut Caller, _: &mut Ctx, h: CallHandle, r: Result<&Args<'_>, &CallError>) {
        s.answers.push((h, r.map(owned).map_err(Clone::clone)));
    }

    fn heard(s: &mut Caller, ctx: &mut Ctx, r: &Report<'_>) {
        let by = ctx.name().to_owned();
        s.heard.push(Heard::new(&by, r));
    }
}

/// Owned copies of arguments or results.
pub fn owned(args: &Args<'_>) -> Vec<OwnedValue> {
    args.as_slice().iter().map(Value::to_owned_value).collect()
}

/// Serves `module` on the calling thread until `done` holds or `limit` passes; returns whether
/// `done` held.
pub fn pump<S>(
    module: &mut Module<S>,
    limit: Duration,
    mut done: impl FnMut(&mut Module<S>) -> bool,
) -> bool {
    let deadline = Instant::now() + limit;
    loop {
        while module.poll_once().expect("receive") {}
        module.housekeeping();
        if done(module) {
            return true;
        }
        if Instant::now() >= deadline {
            return false;
        }
        std::thread::sleep(Duration::from_micros(500));
    }
}

#[allow(unused_imports)]
pub use modbot_testkit::eventually;
