//! Shared by the integration tests: a small test device, a chain of them, and the "wire": a
//! thread that moves frames between ethercrab's PDU loop and the chain in memory.

#![allow(dead_code)]

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Wake, Waker};
use std::thread::{self, JoinHandle, Thread};
use std::time::Duration;

use ethercrab::subdevice_group::{DcConfiguration, HasDc, Op};
use ethercrab::{DcSync, DefaultLock, MainDevice, PduRx, PduTx, SubDeviceGroup, Timeouts};
use modbot_ecat_sim::{
    Application, Chain, Clock, Identity, ManualClock, ObjectDictionary, ObjectEntry, PdoDefinition,
    Reply, Slave, SlaveConfig,
};

/// Vendor id of the test devices.
pub const VENDOR: u32 = 0x0000_0EC5;

/// Outputs: command word (u16), setpoint (i32), and a mode byte (u8) not mapped by default.
/// Inputs: status word = command + 1, actual = 2·setpoint + mode, and a step counter (u32)
/// not mapped by default.
#[derive(Debug, Default)]
pub struct EchoIo {
    /// dt of the last step.
    pub last_dt_s: f64,
    /// Steps taken.
    pub steps: u64,
    /// When set, the status word reports a fault (bit 15) whatever the command.
    pub fault: bool,
}

impl Application for EchoIo {
    fn objects(&self) -> Vec<ObjectEntry> {
        vec![
            ObjectEntry::new(0x7000, 1, "Command word", 0u16).rx_pdo(),
            ObjectEntry::new(0x7000, 2, "Setpoint", 0i32).rx_pdo(),
            ObjectEntry::new(0x7000, 3, "Mode", 0u8).rx_pdo(),
            ObjectEntry::new(0x6000, 1, "Status word", 0u16).tx_pdo(),
            ObjectEntry::new(0x6000, 2, "Actual value", 0i32).tx_pdo(),
            ObjectEntry::new(0x6000, 3, "Steps", 0u32).tx_pdo(),
            ObjectEntry::new(0x8000, 1, "Gain", 1u32).read_write(),
        ]
    }

    fn step(&mut self, od: &mut ObjectDictionary, dt_s: f64) {
        self.last_dt_s = dt_s;
        self.steps += 1;
        let command: u16 = od.get(0x7000, 1).unwrap_or(0);
        let setpoint: i32 = od.get(0x7000, 2).unwrap_or(0);
        let mode: u8 = od.get(0x7000, 3).unwrap_or(0);
        let status = if self.fault {
            0x8000
        } else {
            command.wrapping_add(1)
        };
        od.set(0x6000, 1, status).unwrap();
        od.set(
            0x6000,
            2,
            setpoint.wrapping_mul(2).wrapping_add(i32::from(mode)),
        )
        .unwrap();
        od.set(0x6000, 3, self.steps as u32).unwrap();
    }
}

/// The name of the test device at `position`.
pub fn name(position: usize) -> String {
    format!("MB-IO-{position}")
}

/// The identity of the test device at `position`.
pub fn identity(position: usize) -> Identity {
    Identity {
        vendor_id: VENDOR,
        product_code: 0x0001_0000 + position as u32,
        revision: 0x0000_0002,
        serial: 1000 + position as u32,
    }
}

/// A chain of `count` EchoIo slaves.
pub fn chain(count: usize, clock: impl Clock + 'static) -> Chain {
    let slaves = (0..count)
        .map(|position| {
            let config = SlaveConfig::new(identity(position), &name(position))
                .with_rx_pdos(vec![PdoDefinition {
                    index: 0x1600,
                    entries: vec![(0x7000, 1), (0x7000, 2)],
                }])
                .with_tx_pdos(vec![PdoDefinition {
                    index: 0x1A00,
                    entries: vec![(0x6000, 1), (0x6000, 2)],
                }]);
            Slave::new(config, EchoIo::default())
        })
        .collect();
    Chain::new(slaves, clock)
}

thread_local! {
    /// True on the wire's thread while the chain processes a frame (a test's counting
    /// allocator looks at it).
    pub static IN_CHAIN: Cell<bool> = const { Cell::new(false) };
}

struct Unpark(Thread);

impl Wake for Unpark {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }
}

/// The in-memory wire between ethercrab and a chain.
pub struct Wire {
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
    /// Frames the chain answered.
    pub frames: Arc<AtomicU64>,
}

impl Wire {
    /// Starts moving frames: each frame ethercrab sends is processed by the chain and, unless
    /// lost, handed back to ethercrab's receiver.
    pub fn start(mut tx: PduTx<'static>, mut rx: PduRx<'static>, chain: Arc<Mutex<Chain>>) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let frames = Arc::new(AtomicU64::new(0));
        let (stop2, frames2) = (stop.clone(), frames.clone());
        let handle = thread::Builder::new()
            .name("ecat-wire".into())
            .spawn(move || {
                let waker = Waker::from(Arc::new(Unpark(thread::current())));
                let mut buf = Vec::with_capacity(1536);
                while !stop2.load(Ordering::Relaxed) {
                    tx.replace_waker(&waker);
                    let mut moved = false;
                    while let Some(frame) = tx.next_sendable_frame() {
                        buf.clear();
                        frame
                            .send_blocking(|bytes| {
                                buf.extend_from_slice(bytes);
                                Ok(bytes.len())
                            })
                            .expect("hand the frame to the wire");
                        let mut chain = chain.lock().unwrap();
                        IN_CHAIN.with(|c| c.set(true));
                        let reply = chain.process(&mut buf);
                        IN_CHAIN.with(|c| c.set(false));
                        drop(chain);
                        match reply {
                            Ok(Reply::Frame) => {
                                frames2.fetch_add(1, Ordering::Relaxed);
                                if let Err(error) = rx.receive_frame(&buf) {
                                    eprintln!("ethercrab refused a reply: {error}");
                                }
                            }
                            Ok(Reply::Lost) => {}
                            Err(error) => panic!("the chain refused ethercrab's frame: {error}"),
                        }
                        moved = true;
                    }
                    if !moved {
                        thread::park_timeout(Duration::from_millis(1));
                    }
                }
            })
            .expect("spawn the wire thread");
        Self {
            stop,
            handle: Some(handle),
            frames,
        }
    }
}

impl Drop for Wire {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(handle) = self.handle.take() {
            handle.thread().unpark();
            let _ = handle.join();
        }
    }
}

/// Fails the test if `f` takes longer than `limit` (a watchdog against hangs).
pub fn with_watchdog<T: Send + 'static>(
    limit: Duration,
    f: impl FnOnce() -> T + Send + 'static,
) -> T {
    let (done_tx, done_rx) = std::sync::mpsc::channel();
    let handle = thread::spawn(move || {
        let out = f();
        let _ = done_tx.send(());
        out
    });
    match done_rx.recv_timeout(limit) {
        Ok(()) => handle.join().expect("test body panicked"),
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => match handle.join() {
            Ok(out) => out,
            Err(panic) => std::panic::resume_unwind(panic),
        },
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            panic!("test did not finish within {limit:?}")
        }
    }
}

/// The master's timeouts in the tests. Generous: the emulated chain answers on a thread of the
/// test or a process of its own, which a loaded machine (two CPU hogs on two cores) holds up
/// for tens of milliseconds; ethercrab's defaults (an EEPROM read in 10 ms) then time out
/// where nothing is wrong. A lost frame still times out, after `pdu`.
pub fn timeouts() -> Timeouts {
    Timeouts {
        wait_loop_delay: Duration::from_millis(1),
        state_transition: Duration::from_secs(30),
        pdu: Duration::from_secs(1),
        eeprom: Duration::from_secs(10),
        mailbox_echo: Duration::from_secs(10),
        mailbox_response: Duration::from_secs(10),
    }
}

/// A group of up to 8 slaves in OP with distributed clocks.
pub type DcGroup = SubDeviceGroup<8, 128, DefaultLock, Op, HasDc>;

/// INIT → OP with SYNC0 every `period_ns` on every slave, the chain's clock moved one period
/// per cycle until all are in OP.
pub async fn bring_up_dc(md: &MainDevice<'_>, clock: &ManualClock, period_ns: u64) -> DcGroup {
    let now = || clock.now_ns();
    let mut group = md
        .init_single_group::<8, 128>(now)
        .await
        .expect("init to PRE-OP");
    for mut sd in group.iter_mut(md) {
        sd.set_dc_sync(DcSync::Sync0);
    }
    let group = group.into_pre_op_pdi(md).await.expect("PRE-OP with PDI");
    let dc = DcConfiguration {
        start_delay: Duration::from_millis(10),
        sync0_period: Duration::from_nanos(period_ns),
        sync0_shift: Duration::ZERO,
    };
    let group = group.configure_dc_sync(md, dc).await.expect("DC sync");
    let group = group.into_safe_op(md).await.expect("SAFE-OP");
    let group = group.request_into_op(md).await.expect("request OP");
    for _ in 0..4000 {
        clock.advance(period_ns);
        if group.tx_rx_dc(md).await.expect("cycle").all_op() {
            return group;
        }
    }
    panic!("the slaves did not reach OP");
}
