//! The emulated slave's device: a CiA 402 servo drive on an elastic joint, the same drive and
//! plant as the bus bridge's simulator (`modbot_bus::SimBackend`, one axis), behind the objects
//! a real drive has.
//!
//! | object | name | type | PDO |
//! |---|---|---|---|
//! | 0x6040 | controlword | u16 | Rx |
//! | 0x6060 | modes of operation | i8 | Rx |
//! | 0x607A | target position | i32, counts | Rx |
//! | 0x60FF | target velocity | i32, counts/s | Rx |
//! | 0x6071 | target torque | i16, ‰ of the rated torque | Rx |
//! | 0x6041 | statusword | u16 | Tx |
//! | 0x6061 | modes of operation display | i8 | Tx |
//! | 0x6064 | position actual value | i32, counts | Tx |
//! | 0x606C | velocity actual value | i32, counts/s | Tx |
//! | 0x6077 | torque actual value | i16, ‰ | Tx |
//! | 0x603F | error code | u16 | Tx |
//! | 0x20A0 | load-side encoder position (the link's) | i32, counts | Tx |
//! | 0x608F:1, :2 | position encoder resolution: increments, motor revolutions | u32 | — |
//! | 0x6076 | motor rated torque | u32, mNm | — |
//!
//! When the slave leaves OP (the sync manager watchdog, the master's request), the drive
//! quick-stops, as a drive whose abort connection option code (0x6007) is 3 does.
//!
//! Its faults are the simulator's: it faults on a lasting following error and on a torque held
//! at its limit, and [`Cia402Drive::inject`] injects those and an encoder loss; the fault's
//! error code is in 0x603F.
//!
//! Each step converts the outputs to SI units, runs one cycle of the simulated drive with the
//! step's `dt`, and converts its actuals back (rounded to the nearest count). So the emulated
//! drive moves as the simulator's does, to within its encoder's resolution.

use modbot_bus::units::Scale;
use modbot_bus::{
    AxisActual, AxisCommand, Backend, DriveFault, DriveParams, PlantParams, SimBackend,
};

use crate::application::Application;
use crate::dictionary::{Object, ObjectDictionary, ObjectEntry};
use crate::pdo::PdoDefinition;
use crate::sii::Identity;
use crate::slave::SlaveConfig;

/// A drive's encoder and torque units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveUnits {
    /// Position encoder increments per motor revolution (0x608F:1, with :2 = 1).
    pub increments_per_rev: u32,
    /// Motor rated torque (0x6076), mNm: torques are in per mille of it.
    pub rated_torque_mnm: u32,
}

impl Default for DriveUnits {
    /// A 20-bit encoder and a 10 Nm rated torque: the EtherCAT backend's defaults.
    fn default() -> Self {
        DriveUnits {
            increments_per_rev: 1 << 20,
            rated_torque_mnm: 10_000,
        }
    }
}

impl DriveUnits {
    /// The conversions these units give (as a master computes them from 0x608F and 0x6076).
    pub fn scale(&self) -> Scale {
        Scale::of_drive(self.increments_per_rev, 1, self.rated_torque_mnm)
    }
}

/// A drive slave's configuration with a drive's usual default mapping (controlword, mode and
/// target position out; statusword, mode display and position actual in): the master maps
/// what it needs in PRE-OP.
pub fn drive_config(identity: Identity, name: &str) -> SlaveConfig {
    SlaveConfig::new(identity, name)
        .with_rx_pdos(vec![PdoDefinition {
            index: 0x1600,
            entries: vec![(0x6040, 0), (0x6060, 0), (0x607A, 0)],
        }])
        .with_tx_pdos(vec![PdoDefinition {
            index: 0x1A00,
            entries: vec![(0x6041, 0), (0x6061, 0), (0x6064, 0)],
        }])
}

/// A CiA 402 drive on an elastic joint.
pub struct Cia402Drive {
    sim: SimBackend,
    units: DriveUnits,
    /// The conversions of `units`.
    scale: Scale,
    actual: [AxisActual; 1],
    /// The process objects, each remembering where the dictionary keeps it.
    objects: ProcessObjects,
}

/// The objects a drive reads (RxPDO side) and writes (TxPDO side) every step.
#[derive(Debug, Clone, Copy)]
struct ProcessObjects {
    controlword: Object,
    mode: Object,
    target_position: Object,
    target_velocity: Object,
    target_torque: Object,
    statusword: Object,
    mode_display: Object,
    position: Object,
    velocity: Object,
    torque: Object,
    error_code: Object,
    link_position: Object,
}

impl ProcessObjects {
    const fn new() -> Self {
        Self {
            controlword: Object::new(0x6040, 0),
            mode: Object::new(0x6060, 0),
            target_position: Object::new(0x607A, 0),
            target_velocity: Object::new(0x60FF, 0),
            target_torque: Object::new(0x6071, 0),
            statusword: Object::new(0x6041, 0),
            mode_display: Object::new(0x6061, 0),
            position: Object::new(0x6064, 0),
            velocity: Object::new(0x606C, 0),
            torque: Object::new(0x6077, 0),
            error_code: Object::new(0x603F, 0),
            link_position: Object::new(0x20A0, 0),
        }
    }
}

impl Cia402Drive {
    /// A drive just powered on, its joint (`plant`) at rest at 0.
    pub fn new(
        plant: PlantParams,
        units: DriveUnits,
    ) -> Result<Cia402Drive, modbot_bus::InvalidParameter> {
        Ok(Cia402Drive {
            sim: SimBackend::with_joints(&[plant], DriveParams::default())?,
            units,
            scale: units.scale(),
            actual: [AxisActual::default()],
            objects: ProcessObjects::new(),
        })
    }

    /// What the drive reported at its last step.
    pub fn actual(&self) -> &AxisActual {
        &self.actual[0]
    }

    /// Injects `fault` into the drive, or, with `on` false, takes its lasting cause away (the
    /// encoder back): the simulator's [`Backend::inject`]. The drive reports it (statusword,
    /// 0x603F) from its next step.
    pub fn inject(&mut self, fault: DriveFault, on: bool) {
        // The drive is axis 0 of a one-axis simulator: the axis exists.
        let _ = self.sim.inject(0, fault, on);
    }

    /// Why the drive cannot leave its fault yet (its encoder still lost); `None` when a
    /// fault reset can clear it.
    pub fn fault_cause(&self) -> Option<&'static str> {
        self.sim.fault_cause(0)
    }
}

impl Application for Cia402Drive {
    fn objects(&self) -> Vec<ObjectEntry> {
        vec![
            ObjectEntry::new(0x6040, 0, "Controlword", 0u16).rx_pdo(),
            ObjectEntry::new(0x6060, 0, "Modes of operation", 0i8).rx_pdo(),
            ObjectEntry::new(0x607A, 0, "Target position", 0i32).rx_pdo(),
            ObjectEntry::new(0x60FF, 0, "Target velocity", 0i32).rx_pdo(),
            ObjectEntry::new(0x6071, 0, "Target torque", 0i16).rx_pdo(),
            ObjectEntry::new(0x6041, 0, "Statusword", 0u16).tx_pdo(),
            ObjectEntry::new(0x6061, 0, "Modes of operation display", 0i8).tx_pdo(),
            ObjectEntry::new(0x6064, 0, "Position actual value", 0i32).tx_pdo(),
            ObjectEntry::new(0x606C, 0, "Velocity actual value", 0i32).tx_pdo(),
            ObjectEntry::new(0x6077, 0, "Torque actual value", 0i16).tx_pdo(),
            ObjectEntry::new(0x603F, 0, "Error code", 0u16).tx_pdo(),
            ObjectEntry::new(0x20A0, 0, "Load-side encoder position", 0i32).tx_pdo(),
            ObjectEntry::new(0x608F, 0, "Position encoder resolution", 2u8),
            ObjectEntry::new(
                0x608F,
                1,
                "Encoder increments",
                self.units.increments_per_rev,
            ),
            ObjectEntry::new(0x608F, 2, "Motor revolutions", 1u32),
            ObjectEntry::new(0x6076, 0, "Motor rated torque", self.units.rated_torque_mnm),
        ]
    }

    fn step(&mut self, od: &mut ObjectDictionary, dt_s: f64) {
        let (scale, o) = (self.scale, &mut self.objects);
        let command = AxisCommand {
            controlword: od.read::<u16>(&mut o.controlword).unwrap_or(0),
            mode: od.read::<i8>(&mut o.mode).unwrap_or(0),
            target_position: scale.rad(od.read::<i32>(&mut o.target_position).unwrap_or(0)),
            target_velocity: scale.rad(od.read::<i32>(&mut o.target_velocity).unwrap_or(0)),
            target_torque: scale.nm(od.read::<i16>(&mut o.target_torque).unwrap_or(0)),
        };
        // The simulated drive never fails a cycle.
        let _ = self.sim.cycle(dt_s, &[command], &mut self.actual);
        let a = self.actual[0];
        // The objects exist (objects() declared them) with these types: write cannot fail.
        let _ = od.write(&mut o.statusword, a.statusword);
        let _ = od.write(&mut o.mode_display, a.mode);
        let _ = od.write(&mut o.position, scale.counts(a.motor_position));
        let _ = od.write(&mut o.velocity, scale.counts(a.motor_velocity));
        let _ = od.write(&mut o.torque, scale.torque(a.motor_torque));
        let _ = od.write(&mut o.error_code, a.error_code);
        let _ = od.write(&mut o.link_position, scale.counts(a.link_position));
    }

    /// Abort connection option code 3 (0x6007): the drive quick-stops when the master's
    /// outputs stop coming.
    fn outputs_invalid(&mut self, od: &mut ObjectDictionary) {
        let _ = od.set(0x6040, 0, 0x0002u16);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dictionary_of(drive: &Cia402Drive) -> ObjectDictionary {
        let mut od = ObjectDictionary::new();
        for entry in drive.objects() {
            od.insert(entry);
        }
        od
    }

    #[test]
    fn the_emulated_drive_moves_as_the_simulator_does_to_within_a_count() {
        let mut sut = Cia402Drive::new(PlantParams::default(), DriveUnits::default()).unwrap();
        let mut od = dictionary_of(&sut);
        let mut reference = SimBackend::new(1, PlantParams::default());
        let mut want = [AxisActual::default()];
        let scale = DriveUnits::default().scale();
        let per_rad = scale.counts_per_rad;
        for tick in 0..600u32 {
            let controlword = match tick {
                0 => 0x06,
                1 => 0x07,
                _ => 0x0F,
            };
            let target = if tick < 100 { 0.0 } else { 0.2 };
            let command = AxisCommand {
                controlword,
                mode: 8,
                target_position: scale.rad(scale.counts(target)),
                ..Default::default()
            };
            od.set(0x6040, 0, controlword).unwrap();
            od.set(0x6060, 0, 8i8).unwrap();
            od.set(0x607A, 0, scale.counts(target)).unwrap();
            sut.step(&mut od, 0.001);
            reference.cycle(0.001, &[command], &mut want).unwrap();
            let link = scale.rad(od.get::<i32>(0x20A0, 0).unwrap());
            assert!(
                (link - want[0].link_position).abs() <= 0.5 / per_rad + 1e-12,
                "tick {tick}: {link} against {}",
                want[0].link_position
            );
            assert_eq!(
                od.get::<u16>(0x6041, 0).unwrap(),
                want[0].statusword,
                "tick {tick}"
            );
        }
        assert!((sut.actual().link_position - 0.2).abs() < 1e-3);
    }

    #[test]
    fn a_lost_encoder_shows_in_the_error_code_and_freezes_the_position_actual_value() {
        let mut sut = Cia402Drive::new(PlantParams::default(), DriveUnits::default()).unwrap();
        let mut od = dictionary_of(&sut);
        od.set(0x6060, 0, 9i8).unwrap();
        od.set(0x60FF, 0, DriveUnits::default().scale().counts(1.0))
            .unwrap();
        for controlword in [0x06u16, 0x07, 0x0F, 0x0F, 0x0F] {
            od.set(0x6040, 0, controlword).unwrap();
            for _ in 0..100 {
                sut.step(&mut od, 0.001);
            }
        }
        let before = od.get::<i32>(0x6064, 0).unwrap();
        let link = od.get::<i32>(0x20A0, 0).unwrap();
        sut.inject(DriveFault::Encoder, true);
        for _ in 0..10 {
            sut.step(&mut od, 0.001);
        }
        assert_eq!(od.get::<u16>(0x603F, 0), Some(0x7305));
        assert_eq!(od.get::<u16>(0x6041, 0).unwrap() & 0x004F, 0x0008, "fault");
        assert_eq!(od.get::<i32>(0x6064, 0), Some(before), "frozen");
        assert!(
            od.get::<i32>(0x20A0, 0).unwrap() > link,
            "the link moves on"
        );
        assert!(sut.fault_cause().is_some());
        sut.inject(DriveFault::Encoder, false);
        for controlword in [0x00u16, 0x80] {
            od.set(0x6040, 0, controlword).unwrap();
            sut.step(&mut od, 0.001);
        }
        assert_eq!(od.get::<u16>(0x603F, 0), Some(0));
        assert_eq!(
            od.get::<u16>(0x6041, 0).unwrap() & 0x004F,
            0x0040,
            "switch on disabled"
        );
    }
}
