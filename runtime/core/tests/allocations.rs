//! After start-up, calls and snapshots allocate nothing: busy and blocking calls, serving
//! them, publishing a blackboard and reading a peer's snapshot in place. A global allocator
//! counts the allocations of the threads that asked to be counted (the caller's and the
//! server's), between a warm-up and the end of the measured calls.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use modbot_core::transport::ipc::DirectoryWriter;
use modbot_core::transport::ReceiveMode;
use modbot_core::{Blackboard, CallOptions, Ctx, IpcTransport, MethodError, ModuleBuilder, Reply};
use modbot_ipc_schema::directory::Listing;
use modbot_ipc_schema::heartbeat::ModuleState;
use modbot_ipc_schema::{Addr, Args, OwnedValue, Value};
use modbot_testkit::TestDomain;

/// Counts the allocations (and reallocations) of counted threads.
struct Counting;

/// Allocations of counted threads made by modbot (or the standard library on its behalf).
static COUNTED: AtomicU64 = AtomicU64::new(0);
/// Allocations of counted threads made inside iceoryx2 (0.10 allocates an `Rc` per loaned
/// sample, and a list when a blackboard's writers are listed): not modbot's to avoid.
static ICEORYX2: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static COUNT_HERE: Cell<bool> = const { Cell::new(false) };
    /// Inside [`attribute`]: its own allocations are not counted.
    static LOOKING: Cell<bool> = const { Cell::new(false) };
}

/// Whose allocation this is: iceoryx2's if an iceoryx2 frame calls the allocator before any
/// of modbot's does. With `MODBOT_ALLOC_TRACE=N` the first N of modbot's print their frames.
fn attribute() {
    let trace = std::backtrace::Backtrace::force_capture().to_string();
    let frames: Vec<&str> = trace
        .lines()
        .filter(|l| !l.trim_start().starts_with("at "))
        .filter(|l| {
            !l.contains("alloc::") && !l.contains("allocations::") && !l.contains("backtrace")
        })
        .collect();
    let first = frames
        .iter()
        .find(|l| l.contains("iceoryx2") || l.contains("modbot"))
        .copied()
        .unwrap_or("");
    if first.contains("iceoryx2") {
        ICEORYX2.fetch_add(1, Ordering::Relaxed);
        return;
    }
    let n = COUNTED.fetch_add(1, Ordering::Relaxed);
    let limit = std::env::var("MODBOT_ALLOC_TRACE")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        .unwrap_or(0);
    if n < limit {
        let ours: Vec<&str> = frames.iter().take(8).copied().collect();
        eprintln!("allocation {n}:\n{}", ours.join("\n"));
    }
}

fn count_here(on: bool) {
    COUNT_HERE.with(|c| c.set(on));
}

fn note() {
    // `try_with`: a thread being torn down has no thread-locals left.
    if COUNT_HERE.try_with(Cell::get).unwrap_or(false)
        && !LOOKING.try_with(Cell::get).unwrap_or(true)
    {
        LOOKING.with(|t| t.set(true));
        attribute();
        LOOKING.with(|t| t.set(false));
    }
}

// SAFETY: every call is passed on to the system allocator unchanged; counting touches only an
// atomic and a const-initialised thread-local, neither of which allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: the caller's promises about `layout` are passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: as above.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        // SAFETY: as above: `ptr` came from this allocator, which is the system's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The server's state: its allocation count is read by `stop_counting`.
#[derive(Default)]
struct Server {
    round: i64,
}

/// `echo(..)`: answers its arguments.
fn echo(
    _: &mut Server,
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    for v in args.as_slice() {
        reply.push(*v);
    }
    Ok(())
}

/// `count(on)`: counts this thread's allocations from now on (or stops); answers the count.
fn count(
    _: &mut Server,
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    count_here(args.bool(0)?);
    reply.push(Value::I64(COUNTED.load(Ordering::Relaxed) as i64));
    Ok(())
}

/// `quit()`: the server ends its run once this is answered (its files go before the domain's).
fn quit(_: &mut Server, ctx: &mut Ctx, _: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    ctx.stop();
    Ok(())
}

/// Every millisecond: a new value on the blackboard (published with the next snapshot).
fn tick(s: &mut Server, ctx: &mut Ctx) {
    s.round += 1;
    let _ = ctx.bb.write("round", Value::I64(s.round));
}

fn serve(domain: &TestDomain, mode: ReceiveMode) -> std::thread::JoinHandle<()> {
    let transport = IpcTransport::new(domain).unwrap();
    std::thread::spawn(move || {
        let bb = Blackboard::builder()
            .item("round", OwnedValue::I64(0))
            .item("bulk", OwnedValue::Bytes(vec![0; 4096]))
            .build()
            .unwrap();
        let module = ModuleBuilder::new("server", 2)
            .mode(mode)
            .method("echo", echo)
            .method("count", count)
            .method("quit", quit)
            .every(Duration::from_millis(1), tick)
            .blackboard(bb)
            .snapshot_period(Duration::from_millis(1))
            .open(transport, Server::default())
            .unwrap();
        let _ = module.run();
    })
}

/// Publishes the directory a supervisor would: both modules running in this process. Modules
/// of a domain with a published directory read it when it changes, and never scan iceoryx2's
/// node files (which allocates); an unsupervised domain is not what runs a robot. The writer
/// and its node are returned: the directory lives as long as the test holds them.
fn publish_directory(transport: &IpcTransport, mode: ReceiveMode) -> (DirectoryWriter, impl Sized) {
    let node = transport.node("directory").unwrap();
    let mut writer = DirectoryWriter::create(&node).unwrap();
    let listing = |addr: u8, name: &str| Listing {
        addr: Addr(addr),
        mode: mode.code() as u8,
        state: ModuleState::Running,
        pid: std::process::id(),
        methods_digest: 0,
        upgrades: 0,
        name: name.into(),
    };
    writer
        .publish(&[listing(1, "caller"), listing(2, "server")])
        .unwrap();
    (writer, node)
}

fn calls_and_snapshots_allocate_nothing(test: &str, mode: ReceiveMode) {
    let domain = TestDomain::new("alloc", test);
    let _directory = publish_directory(&IpcTransport::new(&domain).unwrap(), mode);
    let server = serve(&domain, mode);
    let mut caller = ModuleBuilder::new("caller", 1)
        .mode(mode)
        .open(IpcTransport::new(&domain).unwrap(), ())
        .unwrap();
    let opts = CallOptions::timeout(Duration::from_secs(10));
    let payload = [7u8; 64];
    let args = [Value::I64(42), Value::Bytes(&payload)];
    let round = |caller: &mut modbot_core::Module<()>| {
        let ok = caller.call_blocking("server", "echo", &args, opts, |r| {
            r.is_ok_and(|a| a.len() == 2)
        });
        assert!(ok, "echo answered its arguments");
        let seen = caller
            .ctx()
            .snapshot_of("server", |view| view.len())
            .unwrap();
        assert!(seen.is_none_or(|n| n == 2));
    };
    // Warm-up: links opened, method tables learned, buffers grown to their size.
    for _ in 0..2000 {
        round(&mut caller);
    }
    let at = |caller: &mut modbot_core::Module<()>, on: bool| -> i64 {
        caller.call_blocking("server", "count", &[Value::Bool(on)], opts, |r| {
            r.unwrap().i64(0).unwrap()
        })
    };
    let before = at(&mut caller, true);
    count_here(true);
    for _ in 0..2000 {
        round(&mut caller);
    }
    count_here(false);
    let after = at(&mut caller, false);
    eprintln!(
        "{mode:?}: iceoryx2 allocated {} times in 2000 rounds",
        ICEORYX2.load(Ordering::Relaxed)
    );
    assert_eq!(
        after - before,
        0,
        "allocations in 2000 calls and snapshot reads ({mode:?}), caller and server together"
    );
    // The server ends before the domain is cleaned up: a thread still running at the end of
    // the test process would leave what it had opened (a run beside CPU hogs once left 22
    // files in /dev/shm).
    caller.call_blocking("server", "quit", &[], opts, |r| {
        r.expect("the server answers quit");
    });
    caller.ctx().stop();
    drop(caller);
    server.join().expect("the server thread ends");
}

#[test]
fn busy_calls_and_snapshots_allocate_nothing_after_start_up() {
    calls_and_snapshots_allocate_nothing("busy", ReceiveMode::BusyPoll);
}

#[test]
fn blocking_calls_and_snapshots_allocate_nothing_after_start_up() {
    calls_and_snapshots_allocate_nothing("blocking", ReceiveMode::Blocking);
}
