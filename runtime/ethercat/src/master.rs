//! The master: ethercrab's `MainDevice` on a [`RawLink`], and the bring-up of a segment of
//! CiA 402 drives — scan, identities, the PDO mapping by SDO, SAFE-OP, OP, distributed clocks.
//!
//! ethercrab keeps its frames in a `static` storage that can be split once, so a process has
//! one master ([`EthercatError::SecondMaster`] for a second). Its futures borrow the
//! `MainDevice` for `'static`: it is leaked, once per process.
//!
//! Bring-up ([`Master::bring_up`]), every step refused with the slave named:
//! 1. listen on the interface: frames of another master mean the segment is not ours;
//! 2. `init`: count the slaves, give them station addresses, read their SII (identity, name),
//!    set up their mailboxes, PRE-OP;
//! 3. per declared drive: the slave exists and has the identity the description gives;
//! 4. the PDO mapping by CoE SDO downloads (see [`crate::pdo`]), several drives at once; the
//!    drive's own units (0x608F encoder resolution, 0x6076 rated torque) checked against the
//!    description where the drive has them;
//! 5. in lockstep, the slaves' process data watchdog off (the grid may pause the bus);
//!    with `dc`: SYNC0 on every drive at the base period, the clocks' offsets and delays set;
//! 6. SAFE-OP (ethercrab reads the mapping back and lays out the process image, checked
//!    against the backend's), then OP, with process data cycling until every slave is in OP.
//!
//! The CiA 402 state machine is not walked here: from OP on, the grid's `drive_enable` (or a
//! controller) writes the controlwords, every drive in the same cycle — all drives are enabled
//! together, not one after another.

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use ethercrab::error::{Error, MailboxError};
use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::{DcConfiguration, HasDc, NoDc, Op, PreOp};
use ethercrab::{
    DcSync, DefaultLock, MainDevice, MainDeviceConfig, PduStorage, RetryBehaviour, SubDeviceGroup,
    SubDeviceState, Timeouts,
};
use modbot_bus::link::{RawLink, ETHERTYPE_ETHERCAT};

use crate::config::{DriveConfig, EthercatConfig};
use crate::error::{EthercatError, SlaveRef};
use crate::pdo::{self, Scale, SdoWrite};
use crate::pump::Pump;

/// The most slaves on a segment.
pub const MAX_SLAVES: usize = 128;
/// The most bytes of process data of a segment.
pub const MAX_PDI: usize = 4096;
const MAX_FRAMES: usize = 16;
const FRAME_BYTES: usize = PduStorage::element_size(1400);
static STORAGE: PduStorage<MAX_FRAMES, FRAME_BYTES> = PduStorage::new();

/// Drives whose SDOs go out at the same time (each keeps frames in flight).
const MAPPING_AT_ONCE: usize = 6;
/// How long bring-up waits for every slave to reach OP.
const OP_WITHIN: Duration = Duration::from_secs(10);
/// The ESC's process data (sync manager) watchdog time register.
const WATCHDOG_PROCESS_DATA: u16 = 0x0420;
/// How long the master listens for another master's frames before it sends its own.
const LISTEN: Duration = Duration::from_millis(30);

pub type Group<S, DC = NoDc> = SubDeviceGroup<MAX_SLAVES, MAX_PDI, DefaultLock, S, DC>;

/// SAFE-OP (the process images checked against the backend's), then OP asked for: the same
/// steps for a group with distributed clocks and one without (ethercrab's group types differ by
/// their clock, so no generic function can take both).
macro_rules! into_op {
    ($master:ident, $group:expr, $md:ident, $config:ident, $slaves:ident, $error:ident) => {{
        let group = $master
            .pump
            .run($group.into_safe_op($md))
            .map_err(|e| $error("SAFE-OP", e))?;
        check_images(&group, $md, $config, &$slaves)?;
        $master
            .pump
            .run(group.request_into_op($md))
            .map_err(|e| $error("OP", e))?
    }};
}

/// A segment in OP, with or without distributed clocks.
pub enum Running {
    Free(Group<Op, NoDc>),
    Dc(Group<Op, HasDc>),
}

/// A slave as the scan and the bring-up found it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlaveInfo {
    pub position: u16,
    pub name: String,
    pub vendor: u32,
    pub product: u32,
    pub revision: u32,
    pub serial: u32,
    pub dc: bool,
    /// Its AL state when it was read ("PRE-OP", ...).
    pub state: String,
}

impl SlaveInfo {
    pub fn slave(&self) -> SlaveRef {
        SlaveRef {
            position: self.position,
            name: self.name.clone(),
        }
    }
}

/// The master of one interface.
pub struct Master {
    pub pump: Pump,
    pub md: &'static MainDevice<'static>,
    interface: String,
}

/// The timeouts of a master whose frames come back within `pdu`.
fn timeouts(pdu: Duration) -> Timeouts {
    Timeouts {
        state_transition: Duration::from_secs(10),
        pdu,
        // A slave's EEPROM answers in milliseconds; a loaded controller may hold the master
        // up for more: failing a start for it would be wrong.
        eeprom: Duration::from_secs(1),
        wait_loop_delay: Duration::from_micros(200),
        mailbox_echo: Duration::from_millis(500),
        mailbox_response: Duration::from_secs(2),
    }
}

impl Master {
    /// Opens the master on `interface`; a frame not back within `pdu` is lost. Refused when
    /// another master's frames are on the interface.
    pub fn open(interface: &str, pdu: Duration, dc: bool) -> Result<Master, EthercatError> {
        let link = RawLink::open(interface, ETHERTYPE_ETHERCAT)?;
        // Another master talks here: its frames (or its slaves' replies) pass while we listen.
        let deadline = Instant::now() + LISTEN;
        let mut buf = [0u8; 1536];
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            match link.recv(&mut buf, left) {
                Ok(Some(_)) => return Err(EthercatError::InterfaceInUse(interface.to_owned())),
                Ok(None) => {}
                Err(source) => {
                    return Err(EthercatError::Link(modbot_bus::link::LinkError::Io {
                        interface: interface.to_owned(),
                        source,
                    }))
                }
            }
        }
        let (tx, rx, pdu_loop) = STORAGE
            .try_split()
            .map_err(|()| EthercatError::SecondMaster)?;
        let config = MainDeviceConfig {
            // Static drift compensation rounds at start (sequential round trips): only with DC.
            dc_static_sync_iterations: if dc { 1_000 } else { 0 },
            retry_behaviour: RetryBehaviour::None,
        };
        let md: &'static MainDevice<'static> =
            Box::leak(Box::new(MainDevice::new(pdu_loop, timeouts(pdu), config)));
        Ok(Master {
            pump: Pump::new(link, tx, rx),
            md,
            interface: interface.to_owned(),
        })
    }

    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// Steps 2–3 of the bring-up: the segment in PRE-OP and what is on it.
    pub fn init(&mut self) -> Result<(Group<PreOp>, Vec<SlaveInfo>), EthercatError> {
        let md = self.md;
        let group = self
            .pump
            .run(md.init_single_group::<MAX_SLAVES, MAX_PDI>(ethercat_now))
            .map_err(|source| EthercatError::NoSegment {
                interface: self.interface.clone(),
                source,
            })?;
        let mut slaves = Vec::with_capacity(group.len());
        for (position, sd) in group.iter(md).enumerate() {
            let id = sd.identity();
            let state = match self.pump.run(sd.status()) {
                Ok((state, _)) => state.to_string(),
                Err(e) => format!("unknown ({e})"),
            };
            slaves.push(SlaveInfo {
                position: position as u16,
                name: sd.name().to_owned(),
                vendor: id.vendor_id,
                product: id.product_id,
                revision: id.revision,
                serial: id.serial,
                dc: sd.dc_support().any(),
                state,
            });
        }
        Ok((group, slaves))
    }

    /// Brings the segment up for `config`'s drives: returns it in OP, what is on it, and the
    /// working counter of its process data when every slave is in OP (the reference each
    /// cycle's is compared with: it is summed over the frames the process data takes, so a
    /// slave whose data two frames share counts in both).
    pub fn bring_up(
        &mut self,
        config: &EthercatConfig,
    ) -> Result<(Running, Vec<SlaveInfo>, u16), EthercatError> {
        let md = self.md;
        let (mut group, slaves) = self.init()?;
        check_identities(config, &slaves, &self.interface)?;
        if !config.watchdog {
            // The process data watchdog's time (0x0420) at 0 turns it off.
            for (position, sd) in group.iter(md).enumerate() {
                self.pump
                    .run(sd.register_write(WATCHDOG_PROCESS_DATA, 0u16))
                    .map_err(|source| EthercatError::State {
                        interface: self.interface.clone(),
                        state: "PRE-OP without the process data watchdog",
                        source,
                    })
                    .map_err(|e| {
                        tracing::error!("slave {position}: {e}");
                        e
                    })?;
            }
        }
        // The mapping, MAPPING_AT_ONCE drives at a time.
        let axes: Vec<(usize, &DriveConfig)> = config.drives.iter().enumerate().collect();
        for chunk in axes.chunks(MAPPING_AT_ONCE) {
            let jobs = chunk.iter().map(|(axis, drive)| {
                let slave = slaves[usize::from(drive.position)].slave();
                map_drive(&group, md, *axis, drive, slave)
            });
            for result in self.pump.run(JoinAll::new(jobs.collect())) {
                result?;
            }
        }
        let state_error = |state, source| EthercatError::State {
            interface: self.interface.clone(),
            state,
            source,
        };
        let running = if config.dc {
            for (position, mut sd) in group.iter_mut(md).enumerate() {
                let driven = config
                    .drives
                    .iter()
                    .any(|d| usize::from(d.position) == position);
                if driven && sd.dc_support().any() {
                    sd.set_dc_sync(DcSync::Sync0);
                }
            }
            let period = Duration::from_nanos(config.period_ns);
            let group = self
                .pump
                .run(group.into_pre_op_pdi(md))
                .map_err(|e| state_error("PRE-OP with process data", e))?;
            let dc = DcConfiguration {
                start_delay: Duration::from_millis(100),
                sync0_period: period,
                sync0_shift: Duration::ZERO,
            };
            let group = self
                .pump
                .run(group.configure_dc_sync(md, dc))
                .map_err(|e| state_error("distributed clocks", e))?;
            Running::Dc(into_op!(self, group, md, config, slaves, state_error))
        } else {
            Running::Free(into_op!(self, group, md, config, slaves, state_error))
        };
        let working_counter = self.wait_for_op(&running, &slaves)?;
        Ok((running, slaves, working_counter))
    }

    /// Cycles process data (all outputs zero: no controlword enables anything) until every
    /// slave reports OP: the working counter of that cycle.
    fn wait_for_op(
        &mut self,
        running: &Running,
        slaves: &[SlaveInfo],
    ) -> Result<u16, EthercatError> {
        let md = self.md;
        let deadline = Instant::now() + OP_WITHIN;
        loop {
            let reply = match running {
                Running::Free(g) => self
                    .pump
                    .run(g.tx_rx(md))
                    .map(|r| (r.working_counter, r.subdevice_states)),
                Running::Dc(g) => self
                    .pump
                    .run(g.tx_rx_dc(md))
                    .map(|r| (r.working_counter, r.subdevice_states)),
            };
            let (working_counter, states) = reply.map_err(|source| EthercatError::State {
                interface: self.interface.clone(),
                state: "OP",
                source,
            })?;
            let behind = states.iter().position(|s| *s != SubDeviceState::Op);
            let Some(position) = behind else {
                return Ok(working_counter);
            };
            if Instant::now() >= deadline {
                return Err(EthercatError::NotOperational {
                    slave: slaves[position].slave(),
                    seconds: OP_WITHIN.as_secs(),
                    state: states[position].to_string(),
                });
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// Every declared drive is on the segment with the identity the description gives it.
fn check_identities(
    config: &EthercatConfig,
    slaves: &[SlaveInfo],
    interface: &str,
) -> Result<(), EthercatError> {
    for (axis, drive) in config.drives.iter().enumerate() {
        let Some(found) = slaves.get(usize::from(drive.position)) else {
            return Err(EthercatError::SlaveMissing {
                axis,
                position: drive.position,
                interface: interface.to_owned(),
                found: slaves.len(),
            });
        };
        let vendor = drive.vendor.unwrap_or(found.vendor);
        let product = drive.product.unwrap_or(found.product);
        if (vendor, product) != (found.vendor, found.product) {
            return Err(EthercatError::WrongIdentity {
                axis,
                slave: found.slave(),
                vendor,
                product,
                found_vendor: found.vendor,
                found_product: found.product,
            });
        }
    }
    Ok(())
}

/// Writes the PDO mapping of one drive, then checks its units where it has the objects.
async fn map_drive(
    group: &Group<PreOp>,
    md: &'static MainDevice<'static>,
    axis: usize,
    drive: &DriveConfig,
    slave: SlaveRef,
) -> Result<(), EthercatError> {
    let sd = group
        .subdevice(md, usize::from(drive.position))
        .map_err(|source| EthercatError::Mapping {
            axis,
            slave: slave.clone(),
            index: 0,
            sub: 0,
            source,
        })?;
    for SdoWrite {
        index,
        sub,
        value,
        bytes,
    } in pdo::sdo_writes(drive.link_encoder)
    {
        let written = match bytes {
            1 => sd.sdo_write(index, sub, value as u8).await,
            2 => sd.sdo_write(index, sub, value as u16).await,
            _ => sd.sdo_write(index, sub, value).await,
        };
        written.map_err(|source| EthercatError::Mapping {
            axis,
            slave: slave.clone(),
            index,
            sub,
            source,
        })?;
    }
    // The drive's own units, where it states them: an abort means it does not.
    let increments = sd.sdo_read::<u32>(0x608F, 1).await;
    let revolutions = sd.sdo_read::<u32>(0x608F, 2).await;
    if let (Ok(increments), Ok(revolutions)) = (increments, revolutions) {
        if revolutions > 0 {
            let found = Scale::of_drive(increments, revolutions, 1).counts_per_rad;
            check_scale(
                axis,
                &slave,
                "counts per rad (0x608F)",
                found,
                drive.scale.counts_per_rad,
            )?;
        }
    }
    match sd.sdo_read::<u32>(0x6076, 0).await {
        Ok(rated_mnm) if rated_mnm > 0 => {
            // 0x6071/0x6077 are in per mille of the rated torque (0x6076, mNm).
            let found = Scale::of_drive(1, 1, rated_mnm).torque_per_nm;
            check_scale(
                axis,
                &slave,
                "torque units per Nm (0x6076)",
                found,
                drive.scale.torque_per_nm,
            )?;
        }
        Ok(_) | Err(Error::Mailbox(MailboxError::Aborted { .. })) => {}
        Err(source) => {
            return Err(EthercatError::Mapping {
                axis,
                slave,
                index: 0x6076,
                sub: 0,
                source,
            })
        }
    }
    Ok(())
}

fn check_scale(
    axis: usize,
    slave: &SlaveRef,
    what: &'static str,
    found: f64,
    declared: f64,
) -> Result<(), EthercatError> {
    if (found - declared).abs() > 1e-9 * declared.abs() {
        return Err(EthercatError::WrongScale {
            axis,
            slave: slave.clone(),
            what,
            found,
            declared,
        });
    }
    Ok(())
}

/// The process image ethercrab laid out from the slaves' mapping has the backend's sizes.
fn check_images<S: ethercrab::subdevice_group::HasPdi, DC>(
    group: &SubDeviceGroup<MAX_SLAVES, MAX_PDI, DefaultLock, S, DC>,
    md: &'static MainDevice<'static>,
    config: &EthercatConfig,
    slaves: &[SlaveInfo],
) -> Result<(), EthercatError> {
    for (axis, drive) in config.drives.iter().enumerate() {
        let position = usize::from(drive.position);
        let sd = group
            .subdevice(md, position)
            .map_err(|source| EthercatError::Mapping {
                axis,
                slave: slaves[position].slave(),
                index: 0,
                sub: 0,
                source,
            })?;
        let io = sd.io_raw();
        let (found_in, found_out) = (io.inputs().len(), io.outputs().len());
        let (inp, out) = (pdo::in_bytes(drive.link_encoder), pdo::OUT_BYTES);
        if (found_in, found_out) != (inp, out) {
            return Err(EthercatError::WrongImage {
                axis,
                slave: slaves[position].slave(),
                out,
                inp,
                found_out,
                found_in,
            });
        }
    }
    Ok(())
}

/// Polls several futures of one kind until all are done: their outputs in order.
struct JoinAll<F: Future> {
    futures: Vec<Pin<Box<F>>>,
    outputs: Vec<Option<F::Output>>,
}

impl<F: Future> JoinAll<F> {
    fn new(futures: Vec<F>) -> JoinAll<F> {
        let outputs = futures.iter().map(|_| None).collect();
        JoinAll {
            futures: futures.into_iter().map(Box::pin).collect(),
            outputs,
        }
    }
}

impl<F: Future> Future for JoinAll<F>
where
    F::Output: Unpin,
{
    type Output = Vec<F::Output>;

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Self::Output> {
        let this = &mut *self;
        let mut pending = false;
        for (future, output) in this.futures.iter_mut().zip(this.outputs.iter_mut()) {
            if output.is_none() {
                match future.as_mut().poll(cx) {
                    Poll::Ready(out) => *output = Some(out),
                    Poll::Pending => pending = true,
                }
            }
        }
        if pending {
            return Poll::Pending;
        }
        Poll::Ready(this.outputs.iter_mut().filter_map(Option::take).collect())
    }
}
