//! One slave: ESC + SII + dictionary + mailbox + application, and how it handles a datagram
//! on its pass (addressing, read/write, working counter). What its firmware does with the
//! ESC's events is in [`crate::firmware`].

use std::any::Any;

use crate::al::AlState;
use crate::application::{AnyApplication, Application};
use crate::datagram::{Addressing, Command, Datagram};
use crate::dictionary::ObjectDictionary;
use crate::esc::dc::PassTiming;
use crate::esc::{Esc, EscIdentity};
use crate::mailbox::MailboxServer;
use crate::pdo::{self, PdoDefinition, PdoLayout};
use crate::process_data::BoundLayout;
use crate::sii::{
    self, Identity, MailboxLayout, SiiDescription, SiiPdo, SiiPdoEntry, SiiSyncManager,
};

/// How a slave presents itself and lays out its memory.
#[derive(Debug, Clone, PartialEq)]
pub struct SlaveConfig {
    /// Identity (SII and 0x1018).
    pub identity: Identity,
    /// Short name: the master's `name()`, and 0x1008.
    pub name: String,
    /// Long name: the master's `description()`.
    pub description: String,
    /// Mailbox sync managers SM0/SM1 (the slave always speaks CoE).
    pub mailbox: MailboxLayout,
    /// Start of the outputs buffer (SM2).
    pub outputs_start: u16,
    /// Start of the inputs buffer (SM3).
    pub inputs_start: u16,
    /// Default RxPDOs (0x16xx), assigned in 0x1C12 at power-on.
    pub rx_pdos: Vec<PdoDefinition>,
    /// Default TxPDOs (0x1Axx), assigned in 0x1C13 at power-on.
    pub tx_pdos: Vec<PdoDefinition>,
    /// Shortest SYNC0 cycle accepted at the PRE-OP → SAFE-OP transition, in ns.
    pub min_sync0_cycle_ns: u32,
    /// ESC identity registers.
    pub esc: EscIdentity,
    /// Station alias in the SII.
    pub alias: u16,
}

impl SlaveConfig {
    /// A configuration with the usual layout: mailboxes of 128 bytes at 0x1000/0x1080,
    /// outputs at 0x1100, inputs at 0x1400.
    pub fn new(identity: Identity, name: &str) -> Self {
        Self {
            identity,
            name: name.to_owned(),
            description: format!("{name} (modbot emulated slave)"),
            mailbox: MailboxLayout::default(),
            outputs_start: 0x1100,
            inputs_start: 0x1400,
            rx_pdos: Vec::new(),
            tx_pdos: Vec::new(),
            min_sync0_cycle_ns: 50_000,
            esc: EscIdentity::default(),
            alias: 0,
        }
    }

    /// With default RxPDOs.
    pub fn with_rx_pdos(mut self, pdos: Vec<PdoDefinition>) -> Self {
        self.rx_pdos = pdos;
        self
    }

    /// With default TxPDOs.
    pub fn with_tx_pdos(mut self, pdos: Vec<PdoDefinition>) -> Self {
        self.tx_pdos = pdos;
        self
    }
}

/// One emulated slave.
pub struct Slave {
    /// Its configuration, kept to rebuild everything at power-on.
    pub(crate) config: SlaveConfig,
    /// The slave controller.
    pub(crate) esc: Esc,
    /// The object dictionary.
    pub(crate) od: ObjectDictionary,
    /// The mailbox side of the firmware.
    pub(crate) mailbox: MailboxServer,
    /// The device.
    pub(crate) app: Box<dyn AnyApplication>,
    /// The AL state the firmware is in.
    pub(crate) state: AlState,
    /// The AL error indication.
    pub(crate) error: bool,
    /// Outputs layout, fixed at PRE-OP → SAFE-OP.
    pub(crate) outputs: BoundLayout,
    /// Inputs layout, fixed at PRE-OP → SAFE-OP.
    pub(crate) inputs: BoundLayout,
    /// Step period when DC SYNC0 is not active.
    pub(crate) default_period_s: f64,
    /// True once the application stepped in the current frame.
    pub(crate) stepped_this_frame: bool,
    /// Steps since power-on, for tests.
    pub(crate) steps: u64,
    /// Chain time of the frame being processed.
    pub(crate) frame_ns: u64,
    /// Chain time of the last output write (for the sync manager watchdog).
    pub(crate) last_outputs_ns: u64,
    /// Where in its SYNC0 cycle the last frame that exchanged its process data found it, ns.
    pub(crate) sync0_offset_ns: Option<u64>,
    /// Bytes read before a write (read-write datagrams) and the process data on their way
    /// between sync manager and dictionary: kept, so a cyclic frame allocates nothing.
    pub(crate) scratch: Vec<u8>,
}

impl std::fmt::Debug for Slave {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slave")
            .field("name", &self.config.name)
            .field("station_address", &self.esc.station_address())
            .field("state", &self.state)
            .field("error", &self.error)
            .finish()
    }
}

impl Slave {
    /// A slave running `application`, powered on at time 0 (a [`crate::Chain`] powers its
    /// slaves on again at its own clock's time).
    pub fn new(config: SlaveConfig, application: impl Application + 'static) -> Self {
        let app: Box<dyn AnyApplication> = Box::new(application);
        let od = build_dictionary(&config, app.objects());
        let image = sii::build_image(&sii_description(&config, &od));
        let esc = Esc::new(config.esc, image, 0);
        let mut slave = Self {
            config,
            esc,
            od,
            mailbox: MailboxServer::default(),
            app,
            state: AlState::Init,
            error: false,
            outputs: BoundLayout::default(),
            inputs: BoundLayout::default(),
            default_period_s: 0.001,
            stepped_this_frame: false,
            steps: 0,
            frame_ns: 0,
            last_outputs_ns: 0,
            sync0_offset_ns: None,
            // A datagram's data fits in a standard frame.
            scratch: Vec::with_capacity(1500),
        };
        slave.power_on(0);
        slave
    }

    /// Power-on: the ESC resets, the dictionary returns to its defaults, AL state INIT.
    pub fn power_on(&mut self, now_ns: u64) {
        self.esc.power_on(now_ns);
        self.od = build_dictionary(&self.config, self.app.objects());
        self.mailbox.reset();
        self.state = AlState::Init;
        self.error = false;
        self.outputs = BoundLayout::default();
        self.inputs = BoundLayout::default();
        self.steps = 0;
        self.sync0_offset_ns = None;
        for sm in 0..4 {
            self.esc.set_sm_deactivated(sm, true);
        }
        self.publish_al_status(crate::al::status_code::NO_ERROR);
    }

    /// Its configuration.
    pub fn config(&self) -> &SlaveConfig {
        &self.config
    }

    /// The AL state.
    pub fn al_state(&self) -> AlState {
        self.state
    }

    /// True while the AL error indication is set.
    pub fn al_error(&self) -> bool {
        self.error
    }

    /// The AL status code (0x0134).
    pub fn al_status_code(&self) -> u16 {
        self.esc.al_status_code()
    }

    /// The configured station address.
    pub fn station_address(&self) -> u16 {
        self.esc.station_address()
    }

    /// The slave controller.
    pub fn esc(&self) -> &Esc {
        &self.esc
    }

    /// The object dictionary.
    pub fn dictionary(&self) -> &ObjectDictionary {
        &self.od
    }

    /// The object dictionary, writable (as the firmware writes it).
    pub fn dictionary_mut(&mut self) -> &mut ObjectDictionary {
        &mut self.od
    }

    /// The application.
    pub fn application_mut(&mut self) -> &mut dyn Application {
        self.app.as_application_mut()
    }

    /// The application as its concrete type.
    pub fn application_as<T: Application + Any>(&mut self) -> Option<&mut T> {
        self.app.as_any_mut().downcast_mut::<T>()
    }

    /// Application steps since power-on.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Where in its SYNC0 cycle (on its own system time) the last frame that exchanged its
    /// process data reached this slave, ns: the offset a phase lock keeps constant. `None`
    /// without SYNC0 or before its first pulse.
    pub fn sync0_offset_ns(&self) -> Option<u64> {
        self.sync0_offset_ns
    }

    /// The outputs layout in force (empty before SAFE-OP).
    pub fn outputs_layout(&self) -> &PdoLayout {
        self.outputs.layout()
    }

    /// The inputs layout in force (empty before SAFE-OP).
    pub fn inputs_layout(&self) -> &PdoLayout {
        self.inputs.layout()
    }

    pub(crate) fn set_default_period(&mut self, period_s: f64) {
        self.default_period_s = period_s;
    }

    pub(crate) fn begin_frame(&mut self, now_ns: u64) {
        self.stepped_this_frame = false;
        self.frame_ns = now_ns;
        self.check_watchdog();
    }

    /// Handles one datagram on this slave's pass: addressing (incrementing ADP for
    /// auto-increment and broadcast), the access, the working counter, then the firmware's
    /// reaction to what the access changed.
    pub fn process(&mut self, datagram: &mut Datagram<'_>, timing: &PassTiming) {
        let Some(command) = datagram.command() else {
            return;
        };
        let adp = datagram.adp();
        let ado = datagram.ado();
        let addressed = match command.addressing() {
            Addressing::None => return,
            Addressing::Position => {
                datagram.set_adp(adp.wrapping_add(1));
                adp == 0
            }
            Addressing::Broadcast => {
                datagram.set_adp(adp.wrapping_add(1));
                true
            }
            Addressing::Station => adp == self.esc.station_address(),
            Addressing::Logical => true,
        };
        let increment: u16 = match command {
            Command::Nop => 0,
            Command::Aprd | Command::Fprd if addressed => {
                u16::from(self.esc.read(ado, datagram.data_mut(), timing))
            }
            Command::Apwr | Command::Fpwr | Command::Bwr if addressed => {
                u16::from(self.esc.write(ado, datagram.data(), timing))
            }
            Command::Aprw | Command::Fprw if addressed => {
                let old = scratch_of(&mut self.scratch, datagram.len());
                let read = self.esc.read(ado, old, timing);
                let written = self.esc.write(ado, datagram.data(), timing);
                datagram.data_mut().copy_from_slice(old);
                u16::from(read) + 2 * u16::from(written)
            }
            Command::Brd => {
                let mine = scratch_of(&mut self.scratch, datagram.len());
                let read = self.esc.read(ado, mine, timing);
                if read {
                    for (d, m) in datagram.data_mut().iter_mut().zip(mine.iter()) {
                        *d |= m;
                    }
                }
                u16::from(read)
            }
            Command::Brw => {
                let mine = scratch_of(&mut self.scratch, datagram.len());
                let read = self.esc.read(ado, mine, timing);
                let written = self.esc.write(ado, datagram.data(), timing);
                for (d, m) in datagram.data_mut().iter_mut().zip(mine.iter()) {
                    *d |= m;
                }
                u16::from(read) + 2 * u16::from(written)
            }
            Command::Armw | Command::Frmw => {
                if addressed {
                    u16::from(self.esc.read(ado, datagram.data_mut(), timing))
                } else {
                    u16::from(self.esc.write(ado, datagram.data(), timing))
                }
            }
            Command::Lrd | Command::Lwr | Command::Lrw => {
                self.process_logical(command, datagram, timing)
            }
            _ => 0,
        };
        datagram.add_working_counter(increment);
        self.handle_events();
    }

    fn process_logical(
        &mut self,
        command: Command,
        datagram: &mut Datagram<'_>,
        timing: &PassTiming,
    ) -> u16 {
        let logical = datagram.logical_address();
        let mut increment = 0;
        if matches!(command, Command::Lwr | Command::Lrw)
            && self.esc.logical_write(logical, datagram.data(), timing)
        {
            increment += if command == Command::Lrw { 2 } else { 1 };
        }
        // The outputs just written reach the application before the inputs are read.
        self.handle_events();
        if matches!(command, Command::Lrd | Command::Lrw) {
            if self.outputs.bytes() == 0 && self.esc.logical_maps(logical, datagram.len(), false) {
                self.step_if_running();
            }
            if self.esc.logical_read(logical, datagram.data_mut(), timing) {
                increment += 1;
            }
        }
        if increment > 0 {
            self.sync0_offset_ns = self.esc.sync0_phase_ns(timing.port0_ns);
        }
        increment
    }
}

fn build_dictionary(config: &SlaveConfig, objects: Vec<crate::ObjectEntry>) -> ObjectDictionary {
    let mut od = ObjectDictionary::new();
    for entry in objects {
        od.insert(entry);
    }
    pdo::add_standard_objects(
        &mut od,
        config.identity,
        &config.name,
        &config.rx_pdos,
        &config.tx_pdos,
    );
    od
}

fn sii_pdos(pdos: &[PdoDefinition], sync_manager: u8, od: &ObjectDictionary) -> Vec<SiiPdo> {
    pdos.iter()
        .map(|pdo| SiiPdo {
            index: pdo.index,
            sync_manager,
            entries: pdo
                .entries
                .iter()
                .map(|&(index, sub_index)| SiiPdoEntry {
                    index,
                    sub_index,
                    data_type: pdo::sii_data_type(od, index, sub_index),
                    bit_len: od
                        .entry(index, sub_index)
                        .map(|e| e.bit_len().min(255) as u8)
                        .unwrap_or(0),
                })
                .collect(),
        })
        .collect()
}

fn sii_description(config: &SlaveConfig, od: &ObjectDictionary) -> SiiDescription {
    let rx_bytes = pdo::layout(od, pdo::Direction::Rx)
        .map(|l| l.bytes())
        .unwrap_or(0) as u16;
    let tx_bytes = pdo::layout(od, pdo::Direction::Tx)
        .map(|l| l.bytes())
        .unwrap_or(0) as u16;
    let mb = config.mailbox;
    SiiDescription {
        identity: config.identity,
        alias: config.alias,
        name: config.name.clone(),
        description: config.description.clone(),
        group: "modbot".into(),
        mailbox: Some(mb),
        coe_details: sii::coe_details::SDO
            | sii::coe_details::SDO_INFO
            | sii::coe_details::PDO_ASSIGN
            | sii::coe_details::PDO_CONFIG,
        sync_managers: vec![
            // Mailbox, master writes, PDI event.
            SiiSyncManager {
                start: mb.receive_offset,
                length: mb.receive_size,
                control: 0x26,
                enable: 1,
                usage: 1,
            },
            // Mailbox, master reads, PDI event.
            SiiSyncManager {
                start: mb.send_offset,
                length: mb.send_size,
                control: 0x22,
                enable: 1,
                usage: 2,
            },
            // Buffered, master writes, PDI event, watchdog.
            SiiSyncManager {
                start: config.outputs_start,
                length: rx_bytes,
                control: 0x64,
                enable: 1,
                usage: 3,
            },
            // Buffered, master reads.
            SiiSyncManager {
                start: config.inputs_start,
                length: tx_bytes,
                control: 0x20,
                enable: 1,
                usage: 4,
            },
        ],
        fmmus: vec![1, 2, 3],
        rx_pdos: sii_pdos(&config.rx_pdos, 2, od),
        tx_pdos: sii_pdos(&config.tx_pdos, 3, od),
    }
}

/// `scratch` as `len` zeroed bytes (it grows once, to the largest datagram seen).
pub(crate) fn scratch_of(scratch: &mut Vec<u8>, len: usize) -> &mut [u8] {
    scratch.clear();
    scratch.resize(len, 0);
    scratch
}
