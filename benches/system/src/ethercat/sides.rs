//! The two child roles of the EtherCAT benchmark, both run inside the benchmark's namespace.
//!
//! - `ecat-echo IF PRIO`: the raw ping-pong's far end. Answers every 0x88A4 frame on `IF` with
//!   the same bytes, the source MAC's locally administered bit set (as the first slave of a
//!   segment does), waiting for frames as the emulator does (`RawLink::recv`, poll).
//! - `ecat-master MASTER SNIFF PING SLAVES QUICK DC PRIO`: brings the emulated segment up with
//!   [`EthercatBackend`] on `MASTER`, learns the sizes of one cycle's frames from a socket on
//!   the emulator's end `SNIFF`, then measures (a) one `cycle` against a raw ping-pong of frames
//!   of the same sizes on `PING`, interleaved in blocks, and (b) a loop on an absolute timerfd
//!   at 1 and 4 kHz running one cycle per period against the same loop without the cycle,
//!   in alternating blocks; with `DC` instead, where each frame lands in the SYNC0 cycle. One
//!   line `result {json}` ([`Measured`]) on stdout at the end.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use hdrhistogram::Histogram;
use modbot_bench_kit::interleave::{interleave, Side};
use modbot_bench_kit::procs;
use modbot_bench_kit::sample::{self, Plan};
use modbot_bus::link::{RawLink, ETHERTYPE_ETHERCAT};
use modbot_bus::{AxisActual, AxisCommand, Backend, BusFault};
use modbot_ethercat::config::{DEFAULT_COUNTS_PER_RAD, DEFAULT_TORQUE_PER_NM};
use modbot_ethercat::pdo::Scale;
use modbot_ethercat::{DriveConfig, EthercatBackend, EthercatConfig};
use modbot_grid::tick::{TickSource, TimerTicks};
use serde::{Deserialize, Serialize};

/// The locally administered bit of a MAC's first byte: set by the first slave in every reply.
const LOCALLY_ADMINISTERED: u8 = 0x02;
/// The longest Ethernet frame either side handles.
const FRAME_MAX: usize = 1536;
/// A frame not back within this is lost (as the bus bridge in real time: 10 periods, ≥ 10 ms).
const PDU_TIMEOUT: Duration = Duration::from_millis(10);

/// A distribution, as a row takes it.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct Stats {
    pub n: u64,
    pub p50: u64,
    pub p99: u64,
    pub p999: u64,
    pub max: u64,
}

impl Stats {
    pub fn of(h: &Histogram<u64>) -> Stats {
        Stats {
            n: h.len(),
            p50: h.value_at_quantile(0.5),
            p99: h.value_at_quantile(0.99),
            p999: h.value_at_quantile(0.999),
            max: h.max(),
        }
    }
}

/// One side of the timed loop at one rate.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct LoopSide {
    /// Wake-up lateness: the clock after the timerfd read minus the due time of the last
    /// expiration.
    pub lateness: Stats,
    /// From the due time to the end of the period's work (the cycle; nothing for the bare loop).
    pub done: Stats,
    /// Periods that passed (timerfd expirations).
    pub periods: u64,
    /// Periods skipped, or whose work ended after the next period's start.
    pub missed: u64,
    /// Cycles that ended in a bus fault (no reply, working counter short, ...).
    pub faults: u64,
}

/// The loop at one rate: bare and with a bus cycle, measured in alternating blocks.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Loop {
    pub hz: u64,
    pub bare: LoopSide,
    pub bus: LoopSide,
}

/// What the master child measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Measured {
    pub slaves: usize,
    pub dc: bool,
    /// Whether the measuring thread ran under SCHED_FIFO.
    pub fifo: bool,
    /// From opening the interface to every slave in OP.
    pub bring_up_ms: f64,
    /// The lengths of the frames of one cycle, in order (Ethernet header included).
    pub frames: Vec<usize>,
    /// One `cycle`, back to back, and the raw ping-pong of the same frames.
    pub cycle: Option<Stats>,
    pub ping: Option<Stats>,
    /// Per block: the cycle's median over the ping-pong's.
    pub ratios: Vec<f64>,
    pub loops: Vec<Loop>,
    /// With DC: ethercrab's `cycle_start_offset` of every cycle of the 1 kHz loop, whose
    /// cycles pass the timer's due time as the tick's time (the grid lock runs).
    pub sync0: Option<Stats>,
    /// With DC: how far from the lock's target each frame landed, once locked.
    pub sync0_from_target: Option<Stats>,
    /// With DC: the cycle the lock was first won at (from the loop's start), and whether it
    /// held at the end.
    pub locked_at: Option<u64>,
    pub locked_at_end: bool,
    /// Cycles of the whole run that ended in a bus fault (the frames came back), and the
    /// first fault as the backend describes it.
    pub faults: u64,
    pub first_fault: Option<String>,
    /// Of those, cycles whose frame did not come back within the PDU timeout (10 ms).
    pub no_replies: u64,
}

/// The child roles of the benchmark.
pub fn child(role: &str, args: &[String]) -> Option<anyhow::Result<()>> {
    match role {
        "ecat-echo" => Some(echo(args)),
        "ecat-master" => Some(master(args)),
        _ => None,
    }
}

fn parse_prio(text: &str) -> anyhow::Result<Option<u8>> {
    if text == "-" {
        return Ok(None);
    }
    text.parse()
        .map(Some)
        .with_context(|| format!("priority '{text}': a number or -"))
}

/// `ecat-echo IF PRIO`.
fn echo(args: &[String]) -> anyhow::Result<()> {
    let [interface, prio] = args else {
        bail!("ecat-echo IF PRIO");
    };
    let link = RawLink::open(interface, ETHERTYPE_ETHERCAT)?;
    let fifo = procs::set_fifo(parse_prio(prio)?).is_ok();
    println!("ready fifo={fifo}");
    let mut buf = [0u8; FRAME_MAX];
    while !procs::interrupted() {
        let Some(n) = link.recv(&mut buf, Duration::from_millis(50))? else {
            continue;
        };
        if n < 14 || buf[6] & LOCALLY_ADMINISTERED != 0 {
            continue;
        }
        buf[6] |= LOCALLY_ADMINISTERED;
        link.send(&buf[..n])?;
    }
    Ok(())
}

/// The raw ping-pong's near end: sends frames of the given lengths one after another, each
/// after the echo of the one before (as ethercrab sends the frames of a cycle).
struct Ping {
    link: RawLink,
    frames: Vec<Vec<u8>>,
    buf: [u8; FRAME_MAX],
}

impl Ping {
    fn new(interface: &str, lengths: &[usize]) -> anyhow::Result<Ping> {
        let link = RawLink::open(interface, ETHERTYPE_ETHERCAT)?;
        let frames = lengths
            .iter()
            .map(|&len| {
                let mut f = vec![0u8; len.max(16)];
                f[..6].fill(0xff);
                f[6..12].fill(0x10);
                f[12..14].copy_from_slice(&ETHERTYPE_ETHERCAT.to_be_bytes());
                // EtherCAT header: the length of what follows, type 1 (PDUs).
                let header = ((len.saturating_sub(16) as u16) & 0x07ff) | 0x1000;
                f[14..16].copy_from_slice(&header.to_le_bytes());
                f
            })
            .collect();
        Ok(Ping {
            link,
            frames,
            buf: [0; FRAME_MAX],
        })
    }

    /// One exchange of every frame: ns.
    fn one(&mut self) -> anyhow::Result<u64> {
        let t = Instant::now();
        for frame in &self.frames {
            self.link.send(frame)?;
            let deadline = Instant::now() + PDU_TIMEOUT;
            loop {
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    bail!(
                        "no echo of a {}-byte frame within {PDU_TIMEOUT:?}",
                        frame.len()
                    );
                }
                match self.link.recv(&mut self.buf, left)? {
                    Some(n) if n == frame.len() && self.buf[6] & LOCALLY_ADMINISTERED != 0 => break,
                    _ => {}
                }
            }
        }
        Ok(sample::since(t))
    }
}

/// The drives of a segment of `slaves` emulated CiA 402 drives, in the description's defaults.
fn config(interface: &str, slaves: usize, dc: bool) -> EthercatConfig {
    EthercatConfig {
        interface: interface.to_owned(),
        drives: (0..slaves)
            .map(|i| DriveConfig {
                position: i as u16,
                vendor: None,
                product: None,
                scale: Scale {
                    counts_per_rad: DEFAULT_COUNTS_PER_RAD,
                    torque_per_nm: DEFAULT_TORQUE_PER_NM,
                },
                link_encoder: false,
            })
            .collect(),
        period_ns: 1_000_000,
        dc,
        // The bare loop's blocks leave the bus without a cycle for up to a second: with the
        // process data watchdog on, the slaves would leave OP meanwhile.
        watchdog: false,
    }
}

/// The bus: its backend, the commands it sends (every drive disabled: controlword 0) and the
/// actuals it reads, and the bus faults of its cycles.
struct Bus {
    backend: EthercatBackend,
    commands: Vec<AxisCommand>,
    actuals: Vec<AxisActual>,
    /// Cycles that ended in a bus fault, and the first one's description.
    faults: u64,
    first_fault: Option<String>,
    /// Cycles whose frame did not come back within [`PDU_TIMEOUT`]: in all, and in a row.
    no_replies: u64,
    no_reply_in_a_row: u32,
}

/// This many cycles in a row without a reply: the segment is gone, the measurement ends.
const NO_REPLY_IN_A_ROW: u32 = 100;

impl Bus {
    /// One cycle: whether it went without a bus fault. A fault is counted, not an error: a
    /// cycle whose frame did not come back took the PDU timeout (its time stays in the rows),
    /// one with a working counter short or long or a slave out of OP exchanged its frames.
    /// Only [`NO_REPLY_IN_A_ROW`] cycles in a row without a reply end the measurement.
    /// One bus cycle; `tick_ns`: the time of the tick it belongs to, for the grid lock.
    fn cycle(&mut self, tick_ns: Option<u64>) -> anyhow::Result<bool> {
        match self
            .backend
            .cycle_at(tick_ns, 0.001, &self.commands, &mut self.actuals)
        {
            Ok(()) => {
                self.no_reply_in_a_row = 0;
                Ok(true)
            }
            Err(fault) => {
                self.faults += 1;
                if fault == BusFault::NoReply {
                    self.no_replies += 1;
                    self.no_reply_in_a_row += 1;
                    if self.no_reply_in_a_row >= NO_REPLY_IN_A_ROW {
                        bail!(
                            "{} ({NO_REPLY_IN_A_ROW} cycles in a row)",
                            self.backend.describe(&fault)
                        );
                    }
                } else {
                    self.no_reply_in_a_row = 0;
                }
                if self.first_fault.is_none() {
                    self.first_fault = Some(self.backend.describe(&fault));
                }
                Ok(false)
            }
        }
    }
}

/// The lengths of one cycle's frames, as a socket on the emulator's end sees them arrive; the
/// same in three cycles in a row, or an error.
fn frame_lengths(bus: &mut Bus, sniff: &str) -> anyhow::Result<Vec<usize>> {
    let link = RawLink::open(sniff, ETHERTYPE_ETHERCAT)?;
    let mut buf = [0u8; FRAME_MAX];
    let mut seen: Vec<Vec<usize>> = Vec::new();
    for _ in 0..3 {
        while link.try_recv(&mut buf)?.is_some() {}
        bus.cycle(None)
            .context("a bus cycle failed while the frame sizes were measured")?;
        let mut lengths = Vec::new();
        // The replies are back: the requests were seen before them.
        while let Some(n) = link.recv(&mut buf, Duration::from_millis(2))? {
            if buf[6] & LOCALLY_ADMINISTERED == 0 {
                lengths.push(n);
            }
        }
        seen.push(lengths);
    }
    if seen.iter().any(|s| *s != seen[0]) || seen[0].is_empty() {
        bail!("the cycles' frames differ from cycle to cycle: {seen:?}");
    }
    Ok(seen.swap_remove(0))
}

/// `ecat-master MASTER SNIFF PING SLAVES QUICK DC PRIO`.
fn master(args: &[String]) -> anyhow::Result<()> {
    let [master_if, sniff, ping_if, slaves, quick, dc, prio] = args else {
        bail!("ecat-master MASTER SNIFF PING SLAVES QUICK DC PRIO");
    };
    let slaves: usize = slaves.parse().context("SLAVES")?;
    let (quick, dc) = (quick == "true", dc == "true");
    let started = Instant::now();
    let backend = EthercatBackend::start(&config(master_if, slaves, dc), PDU_TIMEOUT)
        .with_context(|| format!("bringing up {slaves} emulated drives on {master_if}"))?;
    let bring_up_ms = started.elapsed().as_secs_f64() * 1e3;
    let mut bus = Bus {
        backend,
        commands: vec![
            AxisCommand {
                controlword: 0,
                mode: 8,
                ..AxisCommand::default()
            };
            slaves
        ],
        actuals: vec![AxisActual::default(); slaves],
        faults: 0,
        first_fault: None,
        no_replies: 0,
        no_reply_in_a_row: 0,
    };
    let fifo = procs::set_fifo(parse_prio(prio)?);
    let mut out = Measured {
        slaves,
        dc,
        fifo: fifo.is_ok() && prio != "-",
        bring_up_ms,
        frames: Vec::new(),
        cycle: None,
        ping: None,
        ratios: Vec::new(),
        loops: Vec::new(),
        sync0: None,
        sync0_from_target: None,
        locked_at: None,
        locked_at_end: false,
        faults: 0,
        first_fault: None,
        no_replies: 0,
    };
    let side_span = Duration::from_millis(if quick { 1000 } else { 10_000 });
    if dc {
        let mut offsets = sample::histogram();
        let mut from_target = sample::histogram();
        let mut side = LoopSide::default();
        let (mut cycles, mut locked_at, mut locked_now) = (0u64, None, false);
        // The timer's due time is the tick's nominal time, as the coordinator's is in a grid:
        // the master locks SYNC0 to it (`modbot_ethercat::dc::GridLock`).
        let mut work = |due_ns: u64| {
            let ok = bus.cycle(Some(due_ns));
            cycles += 1;
            if let Some(phase) = bus.backend.sync0_phase() {
                offsets.saturating_record(phase.last_ns.max(1));
                locked_now = phase.locked;
                if phase.locked && locked_at.is_none() {
                    locked_at = Some(cycles);
                }
                if let (Some(target), Some(_)) = (phase.target_ns, locked_at) {
                    from_target.saturating_record(phase.last_ns.abs_diff(target).max(1));
                }
            }
            ok
        };
        timed_loop(
            1_000_000,
            side_span,
            Some(&mut work),
            &mut Acc::new(&mut side),
        )?;
        out.sync0 = Some(Stats::of(&offsets));
        out.sync0_from_target = (!from_target.is_empty()).then(|| Stats::of(&from_target));
        (out.locked_at, out.locked_at_end) = (locked_at, locked_now);
        out.loops.push(Loop {
            hz: 1000,
            bare: LoopSide::default(),
            bus: side,
        });
    } else {
        out.frames = frame_lengths(&mut bus, sniff)?;
        let mut ping = Ping::new(ping_if, &out.frames)?;
        let n = if quick { 2_000 } else { 20_000 };
        let plan = Plan {
            warm: (n / 10).max(50),
            n,
            cap: Duration::from_secs(if quick { 5 } else { 120 }),
        };
        let mut cycle = || {
            let t = Instant::now();
            bus.cycle(None)?;
            Ok(sample::since(t))
        };
        let mut pong = || ping.one();
        let pair = interleave(&plan, Side::alone(&mut cycle), Side::alone(&mut pong))?;
        out.cycle = Some(Stats::of(&pair.subject));
        out.ping = Some(Stats::of(&pair.baseline));
        out.ratios = block_ratios(pair.blocks);
        for hz in [1000, 4000] {
            out.loops
                .push(bare_and_bus(&mut bus, hz, side_span, quick)?);
        }
    }
    drop(fifo);
    out.faults = bus.faults;
    out.first_fault = bus.first_fault.take();
    out.no_replies = bus.no_replies;
    println!("result {}", serde_json::to_string(&out)?);
    Ok(())
}

/// The blocks' summary as the parent rebuilds it: median, min and max (and the count).
fn block_ratios(blocks: Option<modbot_bench_kit::interleave::Blocks>) -> Vec<f64> {
    blocks.map_or_else(Vec::new, |b| vec![b.median, b.min, b.max, b.count as f64])
}

/// The loop at `hz`, bare and with a cycle, each for `span` in alternating blocks.
fn bare_and_bus(bus: &mut Bus, hz: u64, span: Duration, quick: bool) -> anyhow::Result<Loop> {
    let blocks: u32 = if quick { 2 } else { 10 };
    let block = span / blocks;
    let period = 1_000_000_000 / hz;
    let (mut bare, mut with_bus) = (LoopSide::default(), LoopSide::default());
    let (mut bare_acc, mut bus_acc) = (Acc::new(&mut bare), Acc::new(&mut with_bus));
    for b in 0..blocks {
        // Without distributed clocks (these segments): no lock, no tick time.
        let mut work = |_: u64| bus.cycle(None);
        if b % 2 == 0 {
            timed_loop(period, block, None, &mut bare_acc)?;
            timed_loop(period, block, Some(&mut work), &mut bus_acc)?;
        } else {
            timed_loop(period, block, Some(&mut work), &mut bus_acc)?;
            timed_loop(period, block, None, &mut bare_acc)?;
        }
    }
    // Dropping an accumulator writes its distributions into its side.
    drop(bare_acc);
    drop(bus_acc);
    Ok(Loop {
        hz,
        bare,
        bus: with_bus,
    })
}

/// A loop side's histograms while it is measured.
struct Acc<'a> {
    side: &'a mut LoopSide,
    lateness: Histogram<u64>,
    done: Histogram<u64>,
}

impl<'a> Acc<'a> {
    fn new(side: &'a mut LoopSide) -> Acc<'a> {
        Acc {
            side,
            lateness: sample::histogram(),
            done: sample::histogram(),
        }
    }
}

impl Drop for Acc<'_> {
    fn drop(&mut self) {
        self.side.lateness = Stats::of(&self.lateness);
        self.side.done = Stats::of(&self.done);
    }
}

/// Periods thrown away at the start of every block (the first wake-ups of a fresh timer).
const WARM_PERIODS: u64 = 20;

/// Wakes on an absolute timerfd of `period_ns` for `span`, runs `work` (if any) each period,
/// and records the lateness of every wake-up, the time from due to done, and the periods
/// missed: skipped (more than one expiration) or whose work ended after the next one's start.
fn timed_loop(
    period_ns: u64,
    span: Duration,
    mut work: Option<&mut dyn FnMut(u64) -> anyhow::Result<bool>>,
    acc: &mut Acc<'_>,
) -> anyhow::Result<()> {
    let shutdown = modbot_core::signals::Shutdown::on_signals()?;
    let mut timer = TimerTicks::new(period_ns, shutdown)?;
    let periods = WARM_PERIODS + span.as_nanos() as u64 / period_ns;
    let mut expirations = 0u64;
    while expirations < periods {
        let k = match timer.wait() {
            Ok(k) => k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => bail!("interrupted"),
            Err(e) => return Err(e.into()),
        };
        expirations += k;
        let due = timer.due_ns(expirations - 1);
        let woke = timer.now_ns();
        let ok = match work.as_mut() {
            Some(w) => w(due)?,
            None => true,
        };
        let end = timer.now_ns();
        if expirations <= WARM_PERIODS {
            continue;
        }
        let side = &mut *acc.side;
        side.periods += k;
        side.missed += k - 1 + u64::from(end > due + period_ns);
        side.faults += u64::from(!ok);
        acc.lateness
            .saturating_record(woke.saturating_sub(due).max(1));
        acc.done.saturating_record(end.saturating_sub(due).max(1));
    }
    Ok(())
}
