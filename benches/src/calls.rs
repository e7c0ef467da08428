//! Benchmark 1: the round trip of a method call (EXEC→REPLY) between two module processes,
//! against raw iceoryx2 and a Unix socket, for payloads from 8 B to 1 MiB.
//!
//! Rows (param `bytes`, the payload):
//! - `calls.modbot_busy`: both modules in busy-poll mode; baseline `calls.raw_iceoryx2_busy`,
//!   measured interleaved with it ([`crate::interleave`]: alternating blocks, the ratio the
//!   median of the blocks' ratios);
//! - `calls.modbot_blocking`: both in blocking mode (Event wake-ups); baseline
//!   `calls.uds_blocking`, interleaved the same way;
//! - `calls.raw_iceoryx2_busy`, `calls.raw_iceoryx2_event`, `calls.uds_blocking`: the
//!   baselines, each its own;
//! - `calls.modbot_work` against `calls.raw_iceoryx2_work`: the CPU work of a call, both sides
//!   in one thread ([`crate::work`]).
//!
//! Every path copies the payload in on the way out and out on the way back, on both sides:
//! the modbot client copies the answer out of shared memory, as the raw client does. The echo
//! module answers with its arguments. Frames beyond the default 64 KiB need a domain with a
//! larger maximum frame ([`modbot_core::Domain::with_max_frame`]): every size class runs in
//! a domain sized for it, so small calls are not measured in a 1 MiB system.
//!
//! Child role `calls-echo DOMAIN MAX_FRAME MODE CORE PRIO LOOK_US`: the echo module (LOOK_US:
//! how long it lingers after a frame in blocking mode).

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_core::{
    CallError, CallOptions, Ctx, Domain, IpcTransport, MethodError, Module, ModuleBuilder,
    ReceiveMode, Reply,
};
use modbot_ipc_schema::{Args, Value};

use crate::interleave::{interleave, Side, BLOCKS};
use crate::opts::Opts;
use crate::procs::{self, Proc, Scratch};
use crate::raw::{RawPorts, Wait};
use crate::report::{Report, Row};
use crate::sample::{self, size_label, Plan};
use crate::uds;
use modbot_core::transport::launch::inbox_senders_for;

/// The payloads, in bytes.
pub const SIZES: [usize; 5] = [8, 64, 4096, 64 * 1024, 1 << 20];

/// SCHED_FIFO priority of both sides of the blocking rows under `--fifo`.
const FIFO_PRIO: u8 = 50;

/// The largest frame a call with a payload of `bytes` needs (encoding and header included).
pub fn frame_for(bytes: usize) -> usize {
    bytes + 64
}

/// Payload sizes grouped by the domain's max frame they need: the default, or larger.
fn size_classes(sizes: &[usize]) -> Vec<(usize, Vec<usize>)> {
    let mut classes: Vec<(usize, Vec<usize>)> = Vec::new();
    for &s in sizes {
        let frame = frame_for(s).max(modbot_core::domain::DEFAULT_MAX_FRAME);
        match classes.iter_mut().find(|(f, _)| *f == frame) {
            Some((_, v)) => v.push(s),
            None => classes.push((frame, vec![s])),
        }
    }
    classes
}

/// Runs benchmark 1.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    if procs::cores() < 2 {
        bail!(
            "busy-poll round trips need two cores; this machine has {}",
            procs::cores()
        );
    }
    let _pinned = procs::pin(procs::core_for(opts, 0))?;
    let fifo = opts.fifo.then_some(FIFO_PRIO);
    for (max_frame, sizes) in size_classes(&SIZES) {
        let class = size_label(*sizes.last().unwrap_or(&0));
        let pairs: [(&str, PairFn<'_>); 3] = [
            (
                "modbot busy against raw iceoryx2 busy",
                Box::new(|r| busy_pair(opts, r, max_frame, &sizes)),
            ),
            (
                "modbot blocking against the Unix socket",
                Box::new(|r| blocking_pair(opts, r, max_frame, &sizes, fifo)),
            ),
            (
                "raw iceoryx2 event",
                Box::new(|r| raw_event(opts, r, max_frame, &sizes, fifo)),
            ),
        ];
        for (what, pair) in pairs {
            procs::check_interrupted()?;
            if let Err(e) = pair(report) {
                procs::check_interrupted()?;
                report.note(format!(
                    "calls: {what} (payloads up to {class}) failed: {e:#}"
                ));
            }
        }
    }
    if let Err(e) = crate::work::run(opts, report) {
        procs::check_interrupted()?;
        report.note(format!("calls: the _work rows failed: {e:#}"));
    }
    report.note(format!(
        "calls: each modbot row and its baseline were measured interleaved, in {BLOCKS} \
         alternating blocks with both sides' processes kept up (the idle side's server stopped \
         with SIGSTOP), so the machine's changes hit both alike; a row's ratio is the median of \
         the blocks' ratios of medians, with their range. The modbot rows use \
         CallOptions::default() (2 s timeout, 2 retransmissions, so the request payload is also \
         kept for retransmission; in blocking mode the caller looks for its answer and the echo \
         module for the next call {} µs before sleeping, adaptively (ModuleBuilder::linger), \
         where the Unix-socket sides sleep at once, as both modbot sides of the _no_spin rows \
         do; the _paced rows pause 200 µs before each call, so that both sides sleep when it \
         starts) and \
         inboxes with the {} sender slots a supervisor gives a system of two modules \
         (MODBOT_INBOX_SENDERS); every path copies the payload in and out on both sides; {}",
        LOOK.as_micros(),
        inbox_senders_for(2),
        if opts.pin {
            "client pinned to core 0, servers to core 1"
        } else {
            "processes not pinned (--pin pins them to cores 0 and 1)"
        }
    ));
    if opts.fifo {
        report.note(format!(
            "calls: the blocking rows (modbot_blocking, raw_iceoryx2_event, uds_blocking) ran \
             both sides under SCHED_FIFO {FIFO_PRIO}; busy rows never run under SCHED_FIFO"
        ));
    }
    Ok(())
}

/// Measures one pair of paths (or one path) into the report.
type PairFn<'a> = Box<dyn Fn(&mut Report) -> anyhow::Result<()> + 'a>;

fn mode_arg(mode: ReceiveMode) -> &'static str {
    match mode {
        ReceiveMode::BusyPoll => "busy",
        ReceiveMode::Blocking => "blocking",
    }
}

/// `calls.modbot_busy` interleaved with `calls.raw_iceoryx2_busy`.
fn busy_pair(
    opts: &Opts,
    report: &mut Report,
    max_frame: usize,
    sizes: &[usize],
) -> anyhow::Result<()> {
    let mut modbot = ModbotPath::open(opts, ReceiveMode::BusyPoll, max_frame, None, LOOK)?;
    let mut raw = RawPath::open(opts, Wait::Busy, max_frame, sizes, None)?;
    let rows = ("calls.modbot_busy", "calls.raw_iceoryx2_busy");
    let result = pair_sizes(opts, report, sizes, rows, &mut modbot, &mut raw, None);
    modbot.close(report, sizes)?;
    raw.close()?;
    result
}

/// `calls.modbot_blocking` interleaved with `calls.uds_blocking`.
fn blocking_pair(
    opts: &Opts,
    report: &mut Report,
    max_frame: usize,
    sizes: &[usize],
    fifo: Option<u8>,
) -> anyhow::Result<()> {
    let mut modbot = ModbotPath::open(opts, ReceiveMode::Blocking, max_frame, fifo, LOOK)?;
    let mut uds = UdsPath::open(opts, sizes, fifo)?;
    let _fifo = procs::set_fifo(fifo)?;
    let rows = ("calls.modbot_blocking", "calls.uds_blocking");
    let mut result = pair_sizes(opts, report, sizes, rows, &mut modbot, &mut uds, None);
    // The sizes of the targets again: each call after a pause, so that both sides sleep when
    // it starts (calls back to back find a server that has not gone to sleep yet); then back
    // to back with both sides sleeping at once (no look, no linger), the wake-ups alone.
    let target_sizes: Vec<usize> = sizes
        .iter()
        .copied()
        .filter(|s| [8, 4096].contains(s))
        .collect();
    if result.is_ok() && !target_sizes.is_empty() {
        let rows = ("calls.modbot_blocking_paced", "calls.uds_blocking_paced");
        let pace = Some(PACE);
        result = pair_sizes(
            opts,
            report,
            &target_sizes,
            rows,
            &mut modbot,
            &mut uds,
            pace,
        );
    }
    if result.is_ok() && !target_sizes.is_empty() {
        // An echo module of its own, which sleeps at once too.
        let mut sleeper =
            ModbotPath::open(opts, ReceiveMode::Blocking, max_frame, fifo, Duration::ZERO)?;
        let rows = (
            "calls.modbot_blocking_no_spin",
            "calls.uds_blocking_beside_no_spin",
        );
        result = pair_sizes(
            opts,
            report,
            &target_sizes,
            rows,
            &mut sleeper,
            &mut uds,
            None,
        );
        sleeper.close(report, sizes)?;
    }
    modbot.close(report, sizes)?;
    uds.close()?;
    result
}

/// One way to make a round trip with a payload, and the server process that answers.
pub(crate) trait Path {
    /// One round trip of `payload`, in ns.
    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64>;
    fn server(&mut self) -> &mut Proc;
}

/// How long modbot's blocking side looks before sleeping: the default of [`CallOptions::spin`]
/// and of [`ModuleBuilder::linger`], which is defined as the same.
pub(crate) const LOOK: Duration = modbot_core::module::DEFAULT_LINGER;

/// The pause before each call of the paced rows: long enough for both sides to sleep.
const PACE: Duration = Duration::from_micros(200);

/// Every size of `sizes` with `subject` interleaved with `baseline`: rows `names.0` (ratio over
/// the blocks) and `names.1` (the baseline, its own). With `pace`, each round trip follows a
/// pause of that long (not measured), with a tenth of the samples.
fn pair_sizes(
    opts: &Opts,
    report: &mut Report,
    sizes: &[usize],
    names: (&str, &str),
    subject: &mut dyn Path,
    baseline: &mut dyn Path,
    pace: Option<Duration>,
) -> anyhow::Result<()> {
    for &size in sizes {
        let payload = vec![0x5a_u8; size];
        let plan = match pace {
            None => Plan::for_bytes(opts, size),
            Some(_) => Plan::new(opts, Plan::for_bytes(opts, size).n / 10),
        };
        let servers = (subject.server().pid(), baseline.server().pid());
        let pause = || {
            if let Some(p) = pace {
                std::thread::sleep(p);
            }
        };
        let mut a = || {
            pause();
            subject.one(&payload)
        };
        let mut b = || {
            pause();
            baseline.one(&payload)
        };
        let measured = interleave(
            &plan,
            Side {
                one: &mut a,
                server: Some(servers.0),
            },
            Side {
                one: &mut b,
                server: Some(servers.1),
            },
        );
        match measured {
            Ok(pair) => {
                report.push(
                    Row::from_histogram(names.0, &pair.subject)
                        .param("bytes", size)
                        .against(names.1, &[])
                        .blocks(pair.blocks),
                );
                report.push(
                    Row::from_histogram(names.1, &pair.baseline)
                        .param("bytes", size)
                        .is_baseline(),
                );
            }
            Err(e) => {
                procs::check_interrupted()?;
                report.note(format!(
                    "calls: {} against {} with {} failed: {e:#}",
                    names.0,
                    names.1,
                    size_label(size)
                ));
                subject.server().check_running()?;
                baseline.server().check_running()?;
            }
        }
    }
    Ok(())
}

/// A modbot call to the echo module, in a domain of its own.
pub(crate) struct ModbotPath {
    tool: Module<()>,
    child: Proc,
    mode: ReceiveMode,
    /// How long a blocking call looks for its answer before sleeping ([`CallOptions::spin`]).
    spin: Duration,
    /// The answer, copied out of shared memory.
    sink: Vec<u8>,
    // Declared last, dropped last: after the processes, nothing of the run stays behind.
    scratch: Scratch,
}

impl ModbotPath {
    /// `look`: how long the caller looks for an answer and the echo module for the next call
    /// before sleeping (blocking mode: [`CallOptions::spin`], [`ModuleBuilder::linger`]).
    pub(crate) fn open(
        opts: &Opts,
        mode: ReceiveMode,
        max_frame: usize,
        fifo: Option<u8>,
        look: Duration,
    ) -> anyhow::Result<ModbotPath> {
        let what = format!(
            "calls_{}_{}_{}",
            mode_arg(mode),
            max_frame >> 10,
            look.as_micros()
        );
        let scratch = Scratch::new(&what, Some(max_frame))?;
        let domain = scratch.domain.clone();
        let mut child = procs::spawn_role(
            opts,
            "calls-echo",
            &[
                domain.name().to_owned(),
                max_frame.to_string(),
                mode_arg(mode).to_owned(),
                procs::core_arg(procs::core_for(opts, 1)),
                uds::prio_arg(fifo),
                look.as_micros().to_string(),
            ],
        )?;
        let mut tool = ModuleBuilder::new("bench", 0)
            .mode(mode)
            .open_tool(two_module_system(&domain)?, ())
            .context("opening the benchmark's module")?;
        wait_for_echo(&mut tool, &mut child)?;
        Ok(ModbotPath {
            tool,
            child,
            mode,
            spin: look,
            sink: Vec::new(),
            scratch,
        })
    }

    /// Notes the shared memory a big domain took, and stops the echo module.
    pub(crate) fn close(self, report: &mut Report, sizes: &[usize]) -> anyhow::Result<()> {
        let max_frame = self.scratch.domain.max_frame();
        if max_frame > modbot_core::domain::DEFAULT_MAX_FRAME {
            let (reserved, used) = procs::shm_usage(&self.scratch.domain);
            report.note(format!(
                "calls: the {} domain with a max frame of {} (two modules, {} mode) reserved {} \
                 of /dev/shm, {} of it touched",
                size_label(*sizes.last().unwrap_or(&0)),
                crate::report::format_value(max_frame as u64, Some("bytes")),
                self.mode.name(),
                crate::report::format_value(reserved, Some("bytes")),
                crate::report::format_value(used, Some("bytes")),
            ));
        }
        let ModbotPath {
            tool,
            child,
            scratch,
            ..
        } = self;
        drop(tool);
        child.stop()?;
        drop(scratch);
        Ok(())
    }
}

impl Path for ModbotPath {
    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64> {
        let sink = &mut self.sink;
        let t = Instant::now();
        let got = self.tool.call_blocking(
            "echo",
            "echo",
            &[Value::Bytes(payload)],
            CallOptions::default().with_spin(self.spin),
            |r| copy_answer(r, sink),
        );
        let ns = sample::since(t);
        match got {
            Ok(len) if len == payload.len() => Ok(ns),
            Ok(len) => bail!("echo answered {len} bytes for {}", payload.len()),
            Err(e) => bail!("echo call: {e}"),
        }
    }

    fn server(&mut self) -> &mut Proc {
        &mut self.child
    }
}

/// Copies the echo module's answer (its first value, bytes) out of shared memory into `sink`;
/// its length, or why there is none.
pub(crate) fn copy_answer(
    answer: Result<&Args<'_>, &CallError>,
    sink: &mut Vec<u8>,
) -> Result<usize, String> {
    match answer {
        Ok(args) => match args.as_slice().first() {
            Some(Value::Bytes(b)) => {
                sink.clear();
                sink.extend_from_slice(b);
                Ok(b.len())
            }
            other => Err(format!("unexpected answer {other:?}")),
        },
        Err(e) => Err(e.to_string()),
    }
}

/// The transport of either side: inboxes with the sender slots a supervisor gives a system of
/// two modules, as `modbot up` would run them.
pub(crate) fn two_module_system(domain: &Domain) -> anyhow::Result<IpcTransport> {
    Ok(IpcTransport::new(domain)?.with_inbox_senders(inbox_senders_for(2)))
}

/// Calls until the echo module answers (it is starting, and the tool must learn its methods).
fn wait_for_echo(tool: &mut Module<()>, child: &mut Proc) -> anyhow::Result<()> {
    let end = Instant::now() + Duration::from_secs(15);
    loop {
        let answer = tool.call_owned(
            "echo",
            "echo",
            &[],
            CallOptions::timeout(Duration::from_millis(200)),
        );
        match answer {
            Ok(_) => return Ok(()),
            Err(e) => {
                child
                    .check_running()
                    .context("waiting for the echo module")?;
                procs::check_interrupted()?;
                if Instant::now() > end {
                    bail!("the echo module did not answer within 15 s: {e}");
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    }
}

/// A raw iceoryx2 round trip (publish-subscribe both ways, the payload written into the loaned
/// sample), in a scratch domain of its own.
pub(crate) struct RawPath {
    ports: RawPorts,
    child: Proc,
    sink: Vec<u8>,
    _scratch: Scratch,
}

impl RawPath {
    pub(crate) fn open(
        opts: &Opts,
        wait: Wait,
        max_frame: usize,
        sizes: &[usize],
        fifo: Option<u8>,
    ) -> anyhow::Result<RawPath> {
        let max = sizes.iter().copied().max().unwrap_or(8);
        let scratch = Scratch::new(&format!("raw_{}_{}", wait.arg(), max_frame >> 10), None)?;
        let domain = scratch.domain.clone();
        let mut child = procs::spawn_role(
            opts,
            "raw-echo",
            &[
                domain.name().to_owned(),
                max.to_string(),
                wait.arg().to_owned(),
                procs::core_arg(procs::core_for(opts, 1)),
                uds::prio_arg(fifo),
            ],
        )?;
        let ports = RawPorts::open(&domain, "ping", "pong", max, wait)?;
        ports.handshake(&mut child)?;
        Ok(RawPath {
            ports,
            child,
            sink: vec![0u8; max],
            _scratch: scratch,
        })
    }

    pub(crate) fn close(self) -> anyhow::Result<()> {
        let RawPath {
            ports,
            child,
            _scratch,
            ..
        } = self;
        drop(ports);
        child.stop()?;
        Ok(())
    }
}

impl Path for RawPath {
    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64> {
        let t = Instant::now();
        let len = self.ports.round_trip(payload, &mut self.sink)?;
        let ns = sample::since(t);
        if len != payload.len() {
            bail!("raw echo answered {len} bytes for {}", payload.len());
        }
        Ok(ns)
    }

    fn server(&mut self) -> &mut Proc {
        &mut self.child
    }
}

/// The raw iceoryx2 rows with Event wake-ups (a baseline of its own, not interleaved).
fn raw_event(
    opts: &Opts,
    report: &mut Report,
    max_frame: usize,
    sizes: &[usize],
    fifo: Option<u8>,
) -> anyhow::Result<()> {
    let mut raw = RawPath::open(opts, Wait::Event, max_frame, sizes, fifo)?;
    let _fifo = procs::set_fifo(fifo)?;
    for &size in sizes {
        let payload = vec![0x5a_u8; size];
        let h = sample::record(&Plan::for_bytes(opts, size), || raw.one(&payload))?;
        report.push(
            Row::from_histogram("calls.raw_iceoryx2_event", &h)
                .param("bytes", size)
                .is_baseline(),
        );
    }
    raw.close()
}

/// A Unix stream socket round trip to an echo process that sleeps in a blocking read.
struct UdsPath {
    client: uds::Client,
    child: Proc,
    _scratch: Scratch,
}

impl UdsPath {
    fn open(opts: &Opts, sizes: &[usize], fifo: Option<u8>) -> anyhow::Result<UdsPath> {
        let max = sizes.iter().copied().max().unwrap_or(8);
        let mut scratch = Scratch::new(&format!("uds_{}", max >> 10), None)?;
        let path = scratch.path("echo.sock");
        let mut child = procs::spawn_role(
            opts,
            "uds-echo",
            &[
                path.display().to_string(),
                procs::core_arg(procs::core_for(opts, 1)),
                uds::prio_arg(fifo),
            ],
        )?;
        let client = uds::Client::connect(&path, &mut child)?;
        Ok(UdsPath {
            client,
            child,
            _scratch: scratch,
        })
    }

    fn close(self) -> anyhow::Result<()> {
        let UdsPath {
            client,
            child,
            _scratch,
        } = self;
        drop(client);
        child.stop()?;
        Ok(())
    }
}

impl Path for UdsPath {
    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64> {
        let t = Instant::now();
        let len = self.client.echo(payload)?;
        let ns = sample::since(t);
        if len != payload.len() {
            bail!("uds echo answered {len} bytes for {}", payload.len());
        }
        Ok(ns)
    }

    fn server(&mut self) -> &mut Proc {
        &mut self.child
    }
}

/// The child roles of this benchmark.
pub fn child(role: &str, args: &[String]) -> Option<anyhow::Result<()>> {
    (role == "calls-echo").then(|| echo_module(args))
}

pub(crate) fn echo(
    _: &mut (),
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    for v in args.as_slice() {
        reply.push(*v);
    }
    Ok(())
}

fn echo_module(args: &[String]) -> anyhow::Result<()> {
    let [domain, max_frame, mode, core, prio, look_us] = args else {
        bail!("usage: child calls-echo DOMAIN MAX_FRAME busy|blocking CORE PRIO LOOK_US");
    };
    let look = Duration::from_micros(
        look_us
            .parse()
            .with_context(|| format!("look '{look_us}' (µs)"))?,
    );
    let _pinned = procs::pin(procs::parse_core(core)?)?;
    let mode = match mode.as_str() {
        "busy" => ReceiveMode::BusyPoll,
        "blocking" => ReceiveMode::Blocking,
        other => bail!("mode '{other}': expected busy or blocking"),
    };
    let _fifo = procs::set_fifo(uds::parse_prio(prio)?)?;
    let max_frame: usize = max_frame
        .parse()
        .with_context(|| format!("max frame '{max_frame}'"))?;
    let domain = Domain::new(domain)?.with_max_frame(max_frame);
    let module = ModuleBuilder::new("echo", 1)
        .mode(mode)
        .method("echo", echo)
        .linger(look)
        .open(two_module_system(&domain)?, ())?;
    module.run()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payloads_up_to_64_kib_share_the_default_domain() {
        let classes = size_classes(&SIZES);
        assert_eq!(classes.len(), 2);
        assert_eq!(
            classes[0],
            (
                modbot_core::domain::DEFAULT_MAX_FRAME,
                vec![8, 64, 4096, 65536]
            )
        );
        assert_eq!(classes[1].1, vec![1 << 20]);
    }
}
