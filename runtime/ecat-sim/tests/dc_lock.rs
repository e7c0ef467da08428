//! The phase lock of SYNC0 to the grid's tick, against drifting clocks: ethercrab as the master
//! in memory, six slaves whose crystals run ±100 ppm and ±50 ppm off, the chain's clock as
//! the grid's time (CLOCK_MONOTONIC of a real run), moved by hand tick by tick; each cycle's
//! frames reach the slaves 30–50 µs after the tick, and every 500th cycle 400 µs late.
//!
//! Without the lock the reference clock's drift carries the frame through the SYNC0 cycle
//! (100 ns per 1 ms cycle); with it (the master writes each tick's time into the reference
//! clock's system time, `modbot_ethercat::dc::GridLock`), the frame's place in every slave's
//! SYNC0 cycle converges to half a period and stays there within the frames' own jitter.

mod support;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use ethercrab::{Command, MainDevice, MainDeviceConfig, PduStorage, RegisterAddress};
use futures_lite::future::block_on;
use modbot_ecat_sim::{Chain, Clock, ManualClock};
use modbot_ethercat::dc::GridLock;
use support::Wire;

const SLAVES: usize = 6;
const PERIOD_NS: u64 = 1_000_000;
const DRIFT_PPM: [f64; SLAVES] = [100.0, -100.0, 50.0, -50.0, 100.0, -100.0];
const CYCLES: u64 = 4_000;
/// The injected late frames: every this many cycles, 400 µs late.
const LATE_EVERY: u64 = 500;
/// The reference clock's station address (ethercrab: 0x1000 + position; slave 0).
const REFERENCE: u16 = 0x1000;

/// The latency of cycle `n`'s frames after the tick: 30–50 µs, and 400 µs more every
/// [`LATE_EVERY`] cycles (deterministic).
fn latency_ns(n: u64) -> u64 {
    let jitter = n.wrapping_mul(2_654_435_761) % 20_000;
    30_000
        + jitter
        + if n % LATE_EVERY == LATE_EVERY - 1 {
            400_000
        } else {
            0
        }
}

/// `x` − `target` in the cycle, into (−period/2, period/2].
fn distance(x: u64, target: u64) -> i64 {
    let d = (x as i64 - target as i64).rem_euclid(PERIOD_NS as i64);
    if d > PERIOD_NS as i64 / 2 {
        d - PERIOD_NS as i64
    } else {
        d
    }
}

/// What a run saw, per cycle: the frame's place in the reference's SYNC0 cycle, and in
/// every slave's.
struct Run {
    reference: Vec<u64>,
    slaves: Vec<[u64; SLAVES]>,
}

/// `CYCLES` cycles of the grid, the master writing each tick's time into the reference clock
/// when `lock`.
fn run(storage: &'static PduStorage<16, { PduStorage::element_size(1100) }>, lock: bool) -> Run {
    let clock = ManualClock::new(50_000_000_000);
    let mut chain: Chain = support::chain(SLAVES, clock.clone());
    for (position, ppm) in DRIFT_PPM.iter().enumerate() {
        chain.set_clock_drift_ppm(position, *ppm);
    }
    let chain = Arc::new(Mutex::new(chain));
    let (tx, rx, pdu_loop) = storage.try_split().expect("split the PDU storage once");
    let wire = Wire::start(tx, rx, chain.clone());
    let md = MainDevice::new(
        pdu_loop,
        support::timeouts(),
        MainDeviceConfig {
            dc_static_sync_iterations: 100,
            ..MainDeviceConfig::default()
        },
    );
    let out = block_on(async {
        let group = support::bring_up_dc(&md, &clock, PERIOD_NS).await;
        let mut sut = GridLock::new(PERIOD_NS);
        // The first SYNC0 pulse is 10 ms after configure_dc_sync: the grid starts after it.
        let first_tick = clock.now_ns() + 20 * PERIOD_NS;
        let mut out = Run {
            reference: Vec::new(),
            slaves: Vec::new(),
        };
        for n in 0..CYCLES {
            let tick = first_tick + n * PERIOD_NS;
            clock.set(tick + latency_ns(n));
            if let (true, Some(time)) = (lock, sut.app_time(tick)) {
                Command::fpwr(REFERENCE, RegisterAddress::DcSystemTime.into())
                    .send(&md, time)
                    .await
                    .expect("write the tick's time into the reference clock");
            }
            let response = group.tx_rx_dc(&md).await.expect("cycle");
            assert_eq!(response.working_counter, 3 * SLAVES as u16);
            sut.observe(Some(tick), response.extra.dc_system_time);
            out.reference
                .push(response.extra.cycle_start_offset.as_nanos() as u64);
            let chain = chain.lock().unwrap();
            let mut row = [0; SLAVES];
            for (position, slot) in row.iter_mut().enumerate() {
                *slot = chain
                    .slave(position)
                    .and_then(|s| s.sync0_offset_ns())
                    .expect("SYNC0 runs");
            }
            out.slaves.push(row);
        }
        if lock {
            let phase = sut.phase().expect("measured");
            assert!(phase.locked, "the lock says it is not locked: {phase:?}");
        }
        out
    });
    drop(wire);
    out
}

#[test]
fn without_the_lock_the_drifting_reference_carries_the_frame_through_the_sync0_cycle() {
    static STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();
    let sut = support::with_watchdog(Duration::from_secs(120), || run(&STORAGE, false));
    // Compare cycles that are not late: the wander is the clock's, not the frames'.
    let on_time = |n: &u64| n % LATE_EVERY != LATE_EVERY - 1;
    let first = sut.reference[0];
    let last = sut.reference[CYCLES as usize - 2];
    let wander = distance(last, first);
    eprintln!("unlocked: the frame moved {wander} ns through the SYNC0 cycle in {CYCLES} cycles");
    // The reference runs 100 ppm fast: 100 ns per cycle, 400 us in 4000 cycles (± jitter).
    assert!(
        (370_000..=430_000).contains(&wander),
        "the frame moved {wander} ns"
    );
    let spread = (0..CYCLES)
        .filter(on_time)
        .map(|n| sut.reference[n as usize])
        .fold((u64::MAX, 0), |(lo, hi), x| (lo.min(x), hi.max(x)));
    eprintln!("unlocked: least {} ns, most {} ns", spread.0, spread.1);
}

#[test]
fn with_the_lock_every_slave_s_sync0_keeps_a_fixed_phase_to_the_tick_despite_drift() {
    static STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();
    let sut = support::with_watchdog(Duration::from_secs(120), || run(&STORAGE, true));
    let target = PERIOD_NS / 2;
    const BOUND_NS: i64 = 25_000;
    let on_time = |n: u64| n % LATE_EVERY != LATE_EVERY - 1;
    // Converged: from this cycle on every on-time frame is within the bound, in every slave.
    let worst = |n: u64| {
        let row = &sut.slaves[n as usize];
        row.iter()
            .chain(std::iter::once(&sut.reference[n as usize]))
            .map(|x| distance(*x, target).abs())
            .max()
            .unwrap()
    };
    let converged = (0..CYCLES)
        .rev()
        .find(|&n| on_time(n) && worst(n) > BOUND_NS)
        .map_or(0, |n| n + 1);
    let tail: Vec<i64> = (converged..CYCLES)
        .filter(|&n| on_time(n))
        .map(|n| distance(sut.reference[n as usize], target))
        .collect();
    let (lo, hi) = (tail.iter().min().unwrap(), tail.iter().max().unwrap());
    let late = (converged..CYCLES)
        .filter(|&n| !on_time(n))
        .map(worst)
        .max()
        .unwrap_or(0);
    eprintln!(
        "locked: converged within {BOUND_NS} ns of half a period after {converged} cycles; then \
         the reference's frame {lo}..{hi} ns from it, every slave within {} ns; late frames {late} ns",
        (converged..CYCLES).filter(|&n| on_time(n)).map(worst).max().unwrap()
    );
    assert!(
        converged <= 1_500,
        "converged only after {converged} cycles"
    );
    assert!(CYCLES - converged >= 2_000, "too short a tail to judge");
    // The second half: every on-time frame within 15 us of its place in every slave (the
    // frames' own jitter is 20 us wide), and the slaves within 2.5 us of the reference (their
    // clocks follow the reference through the FRMW, once a cycle, while the reference's own
    // loop moves it by up to ~1 us a cycle after the frames' jitter; the frame reaches slave k
    // 700 ns·k later).
    let half = CYCLES / 2..CYCLES;
    let steady = half
        .clone()
        .filter(|&n| on_time(n))
        .map(worst)
        .max()
        .unwrap();
    let apart = half
        .filter(|&n| on_time(n))
        .flat_map(|n| {
            let r = sut.reference[n as usize];
            sut.slaves[n as usize]
                .iter()
                .enumerate()
                .map(move |(k, x)| (distance(*x, r) - 700 * k as i64).abs())
        })
        .max()
        .unwrap();
    eprintln!("locked, second half: every slave within {steady} ns of its place, {apart} ns of the reference");
    assert!(
        steady <= 15_000,
        "{steady} ns from the place in the second half"
    );
    assert!(apart <= 2_500, "a slave {apart} ns from the reference");
}
