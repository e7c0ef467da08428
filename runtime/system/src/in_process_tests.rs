//! The real coordinator and hosts, on threads of one process over the in-process channels
//! (the transport layer's local backend), in lockstep: the trace they record is the reference
//! run's, tick for tick. No timing is involved: lockstep waits for every due release.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use modbot_grid::host::Host;
use modbot_grid::reference::reference_trace;
use modbot_grid::spec::{GridClock, GridSpec};
use modbot_grid_processes::coordinator::Coordinator;
use modbot_testkit::TestDomain;
use modbot_transport::channels::Channels;
use modbot_transport::local::LocalTransport;

/// A trace written into memory the test reads afterwards.
#[derive(Clone, Default)]
struct Shared(Arc<Mutex<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The grid of a description whose body is `body`, in lockstep.
fn grid(body: &str) -> GridSpec {
    let mut grid = crate::let_tests::grid(body);
    grid.timing.clock = GridClock::Lockstep;
    grid
}

/// Runs `spec` for `ticks` ticks: every host on a thread of its own, the coordinator on this
/// one; returns the coordinator's trace.
fn run_in_process(test: &str, spec: &GridSpec, ticks: u64) -> String {
    let domain = TestDomain::new("inproc", test);
    let channels = LocalTransport::new(&domain).channels();
    let registry = modbot_components::builtin();
    let period = spec.base_period.as_nanos() as u64;
    let stop = Arc::new(AtomicBool::new(false));
    // Every host listens before the coordinator's first release, as under a supervisor.
    let hosts: Vec<Host> = spec
        .hosts()
        .iter()
        .map(|h| Host::new(&channels, spec, &registry, h).unwrap())
        .collect();
    let threads: Vec<_> = hosts
        .into_iter()
        .map(|mut host| {
            let stop = stop.clone();
            std::thread::spawn(move || {
                let start = std::time::Instant::now();
                let now = move || start.elapsed().as_nanos() as u64;
                while !stop.load(Ordering::SeqCst) {
                    host.wait_and_serve(Some(Duration::from_millis(5)), &now)
                        .unwrap();
                }
                host.stale
            })
        })
        .collect();
    let trace = Shared::default();
    let mut coord = Coordinator::new(
        &channels as &dyn Channels,
        spec.clone(),
        Some(trace.clone()),
    )
    .unwrap();
    assert_eq!(coord.warm_up(20, Duration::from_secs(30)).unwrap(), 0);
    for n in 0..ticks {
        coord.run_tick(n * period).unwrap();
    }
    coord.drain(&|| ticks * period, 10_000_000_000);
    assert_eq!(coord.fault(), None);
    assert_eq!(coord.finish().unwrap(), 0, "no version was missing");
    stop.store(true, Ordering::SeqCst);
    for t in threads {
        assert_eq!(t.join().unwrap(), 0, "no release was stale");
    }
    let bytes = trace.0.lock().unwrap().clone();
    String::from_utf8(bytes).unwrap()
}

#[test]
fn a_chain_on_one_host_records_the_reference_run() {
    let spec = grid(
        r#"grid {}
component "A" { type = "ramp", host = "h", period = 1, params = { slope = 1000 } }
component "B" { type = "gain", host = "h", period = 2, params = { k = 2 } }
component "C" { type = "delay", host = "h", period = 5 }
connect "A.y -> B.u"
connect "B.y -> C.u"
"#,
    );
    let sut = run_in_process("chain", &spec, 200);
    assert_eq!(
        sut,
        reference_trace(&spec, &modbot_components::builtin(), 200)
    );
}

#[test]
fn periods_1_2_5_10_on_three_hosts_record_the_reference_run() {
    let spec = grid(
        r#"grid {}
component "src" { type = "ramp", host = "h1", period = 1, params = { slope = 1000 } }
component "half" { type = "gain", host = "h2", period = 2, params = { k = 0.5 } }
component "slow" { type = "integrator", host = "h3", period = 5 }
component "both" { type = "sum", host = "h1", period = 10 }
component "late" { type = "delay", host = "h2", period = 1 }
connect "src.y -> half.u"
connect "half.y -> slow.u"
connect "src.y -> both.a"
connect "slow.y -> both.b"
connect "both.y -> late.u"
"#,
    );
    let sut = run_in_process("hosts", &spec, 300);
    assert_eq!(
        sut,
        reference_trace(&spec, &modbot_components::builtin(), 300)
    );
}
