//! The emulator's cyclic frames allocate nothing: six CiA 402 drives brought to OP by
//! ethercrab in memory, with SYNC0 and the grid lock's write into the reference clock beside
//! every cycle's frame, enabled and moving in cyclic synchronous position; a counting
//! allocator counts every allocation made while the chain processes a frame.
//!
//! An allocation per slave and frame is what kept 64 drives from a 4 kHz cycle: 64 software
//! slaves pass a frame in series, so whatever one slave spends is spent 64 times per frame.

mod support;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ethercrab::{Command, MainDevice, MainDeviceConfig, PduStorage, RegisterAddress};
use futures_lite::future::block_on;
use modbot_bus::PlantParams;
use modbot_ecat_sim::drive::{drive_config, Cia402Drive, DriveUnits};
use modbot_ecat_sim::{Chain, Clock, Identity, ManualClock, Slave};
use support::{Wire, IN_CHAIN};

/// Counts the allocations made on a thread while its chain processes a frame.
struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: every call is passed to the system allocator unchanged; the count is a side effect
// (a thread-local read, which does not allocate, and an atomic add).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller's contract for `layout` is the system allocator's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (every allocation goes there).
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: as in `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: `ptr` and `layout` come from `System`; `new_size` is the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

fn count() {
    // `try_with`: the allocator may run while the thread's locals are torn down.
    if IN_CHAIN.try_with(|c| c.get()).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const DRIVES: usize = 6;
const PERIOD_NS: u64 = 250_000;
/// The reference clock's station address (ethercrab: 0x1000 + position; slave 0).
const REFERENCE: u16 = 0x1000;

fn drives(clock: ManualClock) -> Chain {
    let slaves = (0..DRIVES)
        .map(|position| {
            let identity = Identity {
                vendor_id: 0x0000_0B0B,
                product_code: 0x0000_0402,
                revision: 1,
                serial: position as u32 + 1,
            };
            let drive = Cia402Drive::new(PlantParams::default(), DriveUnits::default())
                .expect("the default joint is valid");
            Slave::new(drive_config(identity, "MB-DRIVE"), drive)
        })
        .collect();
    Chain::new(slaves, clock)
}

/// Cycle `n`'s outputs for every drive: shutdown, switch on, enable operation in cyclic
/// synchronous position (mode 8), then a slow position ramp.
fn command(group: &support::DcGroup, md: &MainDevice<'_>, n: u64) {
    let controlword: u16 = match n {
        0..=9 => 0x0006,
        10..=19 => 0x0007,
        _ => 0x000F,
    };
    let target = (n.saturating_sub(30) * 200) as i32;
    for sd in group.iter(md) {
        let mut outputs = sd.outputs_raw_mut();
        outputs[0..2].copy_from_slice(&controlword.to_le_bytes());
        outputs[2] = 8;
        outputs[3..7].copy_from_slice(&target.to_le_bytes());
    }
}

#[test]
fn a_cyclic_frame_through_six_moving_drives_allocates_nothing_in_the_emulator() {
    static STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();
    support::with_watchdog(Duration::from_secs(120), || {
        let clock = ManualClock::new(50_000_000_000);
        let chain = Arc::new(Mutex::new(drives(clock.clone())));
        let (tx, rx, pdu_loop) = STORAGE.try_split().expect("split the PDU storage once");
        let wire = Wire::start(tx, rx, chain.clone());
        let md = MainDevice::new(pdu_loop, support::timeouts(), MainDeviceConfig::default());
        let (frames, allocations, enabled) = block_on(async {
            let group = support::bring_up_dc(&md, &clock, PERIOD_NS).await;
            let mut counted = (0, 0);
            for n in 0..1100u64 {
                clock.advance(PERIOD_NS);
                command(&group, &md, n);
                // The grid lock's write of the tick's time, as the bus bridge sends it.
                Command::fpwr(REFERENCE, RegisterAddress::DcSystemTime.into())
                    .send(&md, clock.now_ns())
                    .await
                    .expect("write the tick's time into the reference clock");
                // Warm-up: the first cycles size the slaves' scratch buffers once.
                if n == 100 {
                    counted = (
                        wire.frames.load(Ordering::Relaxed),
                        ALLOCATIONS.load(Ordering::Relaxed),
                    );
                }
                let response = group.tx_rx_dc(&md).await.expect("cycle");
                assert_eq!(response.working_counter, 3 * DRIVES as u16);
            }
            let enabled = group
                .iter(&md)
                .filter(|sd| {
                    let status = u16::from_le_bytes([sd.inputs_raw()[0], sd.inputs_raw()[1]]);
                    status & 0x006F == 0x0027
                })
                .count();
            (
                wire.frames.load(Ordering::Relaxed) - counted.0,
                ALLOCATIONS.load(Ordering::Relaxed) - counted.1,
                enabled,
            )
        });
        drop(wire);
        eprintln!("{frames} frames through {DRIVES} drives, {allocations} allocations");
        assert_eq!(enabled, DRIVES, "every drive is in operation enabled");
        assert!(frames >= 1900, "only {frames} frames were processed");
        assert_eq!(
            allocations, 0,
            "the emulator allocated while processing frames"
        );
    });
}
