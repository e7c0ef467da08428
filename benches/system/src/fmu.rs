//! Benchmark 9, fmu: what an FMU costs a release. Under `modbot up`, at 1 kHz, a sine feeds
//! two components that do the same arithmetic — the FMU `modbot_filter3` (FMI 3.0, from Rust
//! with fmi-export; `fmus/filter3`) on a `modbot-fmu-host`, and the built-in `lowpass` (the
//! same low-pass filter, step for step: `tests/fmu.rs` checks their outputs are identical) on a
//! `modbot-host` — each on a host process of its own, in the same run.
//!
//! A tap in this process reads the grid's done notices: each carries the host's release
//! latency (its clock at the start of the step minus the coordinator's wake-up stamp) and the
//! step's execution time. Rows: `fmu.release_to_done` (latency + execution, the coordinator's
//! wake-up to the end of the FMU's step) against `fmu.native_release_to_done`, and `fmu.step`
//! (the execution alone: set the input, `fmi3DoStep`, get the output) against
//! `fmu.native_step`. Under SCHED_FIFO with `--fifo`.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use hdrhistogram::Histogram;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::supervised::Supervised;
use modbot_core::IpcTransport;
use modbot_grid::wire;
use modbot_ipc_schema::grid::{Done, PING, READY};

/// The FMU of the benchmark, next to the workspace's programs.
const FMU: &str = "modbot_filter3.fmu";
/// Component indices in the description: the sine, the native filter, the FMU.
const NATIVE: u16 = 1;
const FMU_COMPONENT: u16 = 2;

/// Runs the FMU benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    let (warm, span) = if opts.quick {
        (Duration::from_millis(500), Duration::from_secs(3))
    } else {
        (Duration::from_secs(2), Duration::from_secs(30))
    };
    let mut scratch = Scratch::new("fmu", None)?;
    let file = scratch.path("fmu.lua");
    let fmu = procs::binary(opts, FMU)?;
    let priority = if opts.fifo { ", priority = 60" } else { "" };
    std::fs::write(
        &file,
        format!(
            r#"-- modbot-benches fmu: the same filter as an FMU and as a built-in, at 1 kHz.
domain "{domain}"
supervision {{ heartbeat_timeout = 2.0 }}
grid {{ base_period = 0.001{priority} }}
component "wave"   {{ type = "sine", host = "src", params = {{ amplitude = 1, freq = 5 }} }}
component "native" {{ type = "lowpass", host = "h_native", params = {{ k = 2, T = 0.02 }} }}
component "fmu"    {{ type = "fmu", fmu = "{fmu}", host = "h_fmu", params = {{ k = 2, T = 0.02 }} }}
connect "wave.y -> native.u"
connect "wave.y -> fmu.u"
"#,
            domain = scratch.domain.name(),
            fmu = fmu.display()
        ),
    )?;
    let mut sys = Supervised::start(opts, &scratch.domain, &file, &[], Duration::from_secs(10))?;
    sys.wait_up(Duration::from_secs(30))?;
    let channels = IpcTransport::new(&scratch.domain)?.channels("bench.fmu_tap")?;
    let done = wire::done_subscriber(&channels)?;
    let mut seen = Seen::default();
    let start = Instant::now();
    while start.elapsed() < warm + span {
        let recording = start.elapsed() >= warm;
        while done.receive(&mut |s| {
            for d in Done::batch(s).into_iter().flatten() {
                let c = d.component.get();
                if recording && c != PING && c != READY && d.status.get() == Done::OK {
                    seen.add(c, d.latency_ns.get(), d.exec_ns.get());
                }
            }
        })? {}
        sys.check_running()?;
        procs::check_interrupted()?;
        std::thread::sleep(Duration::from_millis(2));
    }
    let remarks = sys.tail(4);
    sys.stop()?;
    seen.push_rows(report, opts.fifo)
        .with_context(|| remarks.clone())
}

/// The done notices of the two filters, in ns.
#[derive(Default)]
struct Seen {
    native: (Vec<u64>, Vec<u64>),
    fmu: (Vec<u64>, Vec<u64>),
}

impl Seen {
    fn add(&mut self, component: u16, latency_ns: u64, exec_ns: u64) {
        let to = match component {
            NATIVE => &mut self.native,
            FMU_COMPONENT => &mut self.fmu,
            _ => return,
        };
        to.0.push(latency_ns + exec_ns);
        to.1.push(exec_ns);
    }

    fn push_rows(&self, report: &mut Report, fifo: bool) -> anyhow::Result<()> {
        if self.native.0.is_empty() || self.fmu.0.is_empty() {
            bail!(
                "no done notices: {} of the native filter, {} of the FMU",
                self.native.0.len(),
                self.fmu.0.len()
            );
        }
        let p = [("fifo", serde_json::Value::Bool(fifo))];
        let row = |name: &str, samples: &[u64]| -> anyhow::Result<Row> {
            Ok(Row::from_histogram(name, &histogram(samples)?).param("fifo", fifo))
        };
        report.push(row("fmu.native_release_to_done", &self.native.0)?.is_baseline());
        report.push(
            row("fmu.release_to_done", &self.fmu.0)?.against("fmu.native_release_to_done", &p),
        );
        report.push(row("fmu.native_step", &self.native.1)?.is_baseline());
        report.push(row("fmu.step", &self.fmu.1)?.against("fmu.native_step", &p));
        let p50 = |s: &[u64]| histogram(s).map(|h| h.value_at_quantile(0.5) as f64 / 1e3);
        report.note(format!(
            "fmu (fifo={fifo}): {} releases of each filter at 1 kHz, each on a host of its own; \
             step p50 {:.2} µs as an FMU (FMI 3.0 from Rust: set the input, fmi3DoStep, get the \
             output through the fmi crate) against {:.2} µs built in; release to done p50 {:.1} \
             against {:.1} µs",
            self.fmu.0.len(),
            p50(&self.fmu.1)?,
            p50(&self.native.1)?,
            p50(&self.fmu.0)?,
            p50(&self.native.0)?,
        ));
        Ok(())
    }
}

fn histogram(samples: &[u64]) -> anyhow::Result<Histogram<u64>> {
    let mut h = Histogram::new(3)?;
    for &s in samples {
        h.record(s.max(1))?;
    }
    Ok(h)
}
