//! The `ethercat` backend of the bus bridge: one bus cycle is one exchange of process data with
//! the segment (ethercrab's `tx_rx`, or `tx_rx_dc` with distributed clocks), on the bridge's
//! real-time thread, without allocation.
//!
//! Each cycle: every drive's command is written into its outputs (in its units); the frame goes
//! out and comes back; every slave's AL state comes back with it (ethercrab reads them in the
//! same frame); the drives' inputs are read into their actuals. A cycle is a [`BusFault`] when
//! no reply came, when a slave did not answer (it and those behind it: a cut cable, a slave
//! without power), when a slave left OP, or when the working counter of the process data is
//! short. The bridge turns a fault into a safe stop naming the slave.
//!
//! Safe stop ([`Backend::quick_stop_all`]): every drive is sent *quick stop* (controlword
//! 0x0002) and held there: until the master sends it *disable voltage* (bit 1 clear), no
//! command reaches the drive, as with the simulator's drives, so a master that lost control
//! cannot re-enable a drive by repeating a stale controlword.

use ethercrab::subdevice_group::Op;
use ethercrab::{
    Command, DefaultLock, MainDevice, RegisterAddress, SubDeviceGroup, SubDeviceState,
};
use modbot_bus::backend::MISSING_COMMAND;
use modbot_bus::cia402::DriveState;
use modbot_bus::{AxisActual, AxisCommand, Backend, BusFault, Sync0Phase};

use crate::config::EthercatConfig;
use crate::dc::GridLock;
use crate::error::EthercatError;
use crate::master::{Master, Running, SlaveInfo, MAX_PDI, MAX_SLAVES};
use crate::pdo;

/// CiA 402's quick stop command.
const QUICK_STOP: u16 = 0x0002;

/// CiA 402 drives on an EtherCAT segment.
pub struct EthercatBackend {
    /// The bus as the description declares it: a rejoin brings it up again from this.
    config: EthercatConfig,
    master: Master,
    running: Running,
    slaves: Vec<SlaveInfo>,
    /// Per axis: held in quick stop until disable voltage.
    held: Vec<bool>,
    /// The process data's working counter when every slave does its part.
    expected_wkc: u16,
    /// With distributed clocks: the phase lock of SYNC0 to the grid's tick, and where each
    /// frame lands in the SYNC0 cycle.
    lock: GridLock,
    /// With distributed clocks: the reference clock's station address (the first slave with
    /// a clock), into whose system time each cycle writes the tick's time.
    reference: Option<u16>,
    /// Writes of the tick's time into the reference clock not confirmed by the time the
    /// cycle's frame came back (lost, or the reference did not answer).
    pub unconfirmed_time_writes: u64,
}

fn al_state(state: SubDeviceState) -> u8 {
    match state {
        SubDeviceState::None => 0,
        SubDeviceState::Init => 1,
        SubDeviceState::PreOp => 2,
        SubDeviceState::Bootstrap => 3,
        SubDeviceState::SafeOp => 4,
        SubDeviceState::Op => 8,
        SubDeviceState::Other(x) => x,
    }
}

/// Writes the outputs of the slave at `position` with `fill`.
fn with_outputs<DC>(
    group: &SubDeviceGroup<MAX_SLAVES, MAX_PDI, DefaultLock, Op, DC>,
    md: &'static MainDevice<'static>,
    position: usize,
    fill: impl FnOnce(&mut [u8]),
) {
    if let Ok(sd) = group.subdevice(md, position) {
        let mut io = sd.io_raw_mut();
        fill(io.outputs());
    }
}

/// Reads the inputs of the slave at `position` with `read`.
fn with_inputs<DC>(
    group: &SubDeviceGroup<MAX_SLAVES, MAX_PDI, DefaultLock, Op, DC>,
    md: &'static MainDevice<'static>,
    position: usize,
    read: impl FnOnce(&[u8]),
) {
    if let Ok(sd) = group.subdevice(md, position) {
        let io = sd.io_raw();
        read(io.inputs());
    }
}

/// With distributed clocks: the station address of the first slave with a clock.
fn reference_clock(master: &Master, running: &Running) -> Option<u16> {
    match running {
        Running::Dc(g) => g
            .iter(master.md)
            .find(|sd| sd.dc_support().any())
            .map(|sd| sd.configured_address()),
        Running::Free(_) => None,
    }
}

fn log_slaves(slaves: &[SlaveInfo]) {
    for s in slaves {
        tracing::info!(
            "EtherCAT slave {} '{}': vendor {:#010x} product {:#010x} revision {:#010x} serial {}{}",
            s.position,
            s.name,
            s.vendor,
            s.product,
            s.revision,
            s.serial,
            if s.dc { ", distributed clocks" } else { "" }
        );
    }
}

impl EthercatBackend {
    /// Opens the master on the configured interface and brings the segment up to OP. A frame
    /// not back within `pdu_timeout` is lost.
    pub fn start(
        config: &EthercatConfig,
        pdu_timeout: std::time::Duration,
    ) -> Result<EthercatBackend, EthercatError> {
        let mut master = Master::open(&config.interface, pdu_timeout, config.dc)?;
        let (running, slaves, expected_wkc) = master.bring_up(config)?;
        let reference = reference_clock(&master, &running);
        log_slaves(&slaves);
        Ok(EthercatBackend {
            config: config.clone(),
            master,
            running,
            held: vec![false; config.drives.len()],
            slaves,
            expected_wkc,
            lock: GridLock::new(config.period_ns),
            reference,
            unconfirmed_time_writes: 0,
        })
    }

    /// The slaves on the segment, as bring-up found them.
    pub fn slaves(&self) -> &[SlaveInfo] {
        &self.slaves
    }

    fn write_commands(&mut self, commands: &[AxisCommand], actuals: &[AxisActual]) {
        let md = self.master.md;
        for (axis, drive) in self.config.drives.iter().enumerate() {
            let mut command = commands.get(axis).copied().unwrap_or(MISSING_COMMAND);
            if self.held[axis] {
                if command.controlword & 0x0002 == 0 {
                    self.held[axis] = false; // disable voltage: the master takes the drive back
                } else {
                    command.controlword = QUICK_STOP;
                }
            }
            let hold = actuals.get(axis).map_or(0.0, |a| a.motor_position);
            let fill = |out: &mut [u8]| pdo::write_outputs(out, &command, &drive.scale, hold);
            let position = usize::from(drive.position);
            match &self.running {
                Running::Free(g) => with_outputs(g, md, position, fill),
                Running::Dc(g) => with_outputs(g, md, position, fill),
            }
        }
    }

    /// Reads the actuals of the drives whose slaves are `in_op`. A drive whose slave is not in
    /// OP exchanges no process data: the master cannot command it and does not know its state
    /// (it reads as not ready to switch on; its positions stay as last read).
    fn read_actuals(&self, in_op: impl Fn(usize) -> bool, actuals: &mut [AxisActual]) {
        let md = self.master.md;
        for (drive, actual) in self.config.drives.iter().zip(actuals.iter_mut()) {
            let position = usize::from(drive.position);
            if !in_op(position) {
                actual.statusword = 0;
                actual.state = DriveState::NotReadyToSwitchOn;
                continue;
            }
            let read =
                |inputs: &[u8]| pdo::read_inputs(inputs, drive.link_encoder, &drive.scale, actual);
            match &self.running {
                Running::Free(g) => with_inputs(g, md, position, read),
                Running::Dc(g) => with_inputs(g, md, position, read),
            }
        }
    }
}

impl Backend for EthercatBackend {
    fn axes(&self) -> usize {
        self.config.drives.len()
    }

    fn cycle(
        &mut self,
        dt_s: f64,
        commands: &[AxisCommand],
        actuals: &mut [AxisActual],
    ) -> Result<(), BusFault> {
        self.cycle_at(None, dt_s, commands, actuals)
    }

    /// With distributed clocks and the tick's time, the tick's time in the DC time base goes
    /// into the reference clock's system time (an FPWR in a frame of its own, sent beside the
    /// cycle's: no round trip of its own), before the cycle's FRMW hands the reference's time
    /// to the others (see [`crate::dc`]).
    fn cycle_at(
        &mut self,
        tick_ns: Option<u64>,
        _dt_s: f64,
        commands: &[AxisCommand],
        actuals: &mut [AxisActual],
    ) -> Result<(), BusFault> {
        self.write_commands(commands, actuals);
        let md = self.master.md;
        let reply = match &self.running {
            Running::Free(g) => self
                .master
                .pump
                .run(g.tx_rx(md))
                .map(|r| (r.working_counter, r.subdevice_states)),
            Running::Dc(g) => {
                let app = tick_ns.and_then(|t| self.lock.app_time(t));
                let reply = match (app, self.reference) {
                    (Some(time), Some(reference)) => {
                        let write = Command::fpwr(reference, RegisterAddress::DcSystemTime.into())
                            .send(md, time);
                        let (written, reply) = self.master.pump.run_beside(write, g.tx_rx_dc(md));
                        if !matches!(written, Some(Ok(()))) {
                            self.unconfirmed_time_writes += 1;
                        }
                        reply
                    }
                    _ => self.master.pump.run(g.tx_rx_dc(md)),
                };
                reply.map(|r| {
                    self.lock.observe(tick_ns, r.extra.dc_system_time);
                    (r.working_counter, r.subdevice_states)
                })
            }
        };
        let Ok((wkc, states)) = reply else {
            return Err(BusFault::NoReply);
        };
        let mut fault = None;
        for (position, state) in states.iter().enumerate() {
            let position = position as u16;
            match *state {
                SubDeviceState::Op => {}
                SubDeviceState::None => {
                    fault = Some(BusFault::SlaveLost { position });
                    break;
                }
                other => {
                    fault.get_or_insert(BusFault::SlaveState {
                        position,
                        state: al_state(other),
                    });
                }
            }
        }
        if fault.is_none() && wkc != self.expected_wkc {
            fault = Some(BusFault::WorkingCounter {
                expected: self.expected_wkc,
                received: wkc,
            });
        }
        let in_op = |p: usize| states.get(p).is_some_and(|s| *s == SubDeviceState::Op);
        self.read_actuals(in_op, actuals);
        fault.map_or(Ok(()), Err)
    }

    fn quick_stop_all(&mut self) {
        self.held.iter_mut().for_each(|h| *h = true);
    }

    fn describe(&self, fault: &BusFault) -> String {
        let name = |position: u16| {
            let axis = self
                .config
                .drives
                .iter()
                .position(|d| d.position == position);
            let slave = self.slaves.get(usize::from(position));
            format!(
                "EtherCAT slave {position}{}{}",
                slave.map_or(String::new(), |s| format!(" ('{}')", s.name)),
                axis.map_or(String::new(), |a| format!(", axis {a}"))
            )
        };
        match *fault {
            BusFault::NoReply => format!("no reply from the EtherCAT segment on '{}'", self.master.interface()),
            BusFault::SlaveLost { position } => format!(
                "{} stopped answering (lost its power or its link; the slaves behind it with it)",
                name(position)
            ),
            BusFault::SlaveState { position, state } => {
                format!("{} left OP (AL state {state:#x})", name(position))
            }
            BusFault::WorkingCounter { expected, received } => format!(
                "the EtherCAT process data's working counter is {received}, expected {expected}: a slave did not exchange its process data"
            ),
        }
    }

    fn sync0_phase(&self) -> Option<Sync0Phase> {
        self.lock.phase()
    }

    fn name(&self) -> &'static str {
        "ethercat"
    }

    /// The segment brought up again from INIT, as at start (identities checked, PDOs mapped,
    /// distributed clocks configured, every slave to OP): what an operator's reset needs after
    /// a slave lost power or its link. ethercrab initialises a segment as a whole, so every
    /// slave goes through INIT; the drives come back switch-on-disabled, and the reset enables
    /// them. The phase lock starts afresh.
    fn rejoin(&mut self) -> Result<Option<String>, Box<dyn std::error::Error + Send + Sync>> {
        let started = std::time::Instant::now();
        let (running, slaves, expected_wkc) = self.master.bring_up(&self.config)?;
        self.reference = reference_clock(&self.master, &running);
        self.running = running;
        self.slaves = slaves;
        self.expected_wkc = expected_wkc;
        self.lock = GridLock::new(self.config.period_ns);
        log_slaves(&self.slaves);
        Ok(Some(format!(
            "the EtherCAT segment on '{}' brought up again: {} slaves in OP in {} ms",
            self.master.interface(),
            self.slaves.len(),
            started.elapsed().as_millis()
        )))
    }
}
