//! A CiA 402 drive's units: position counts per radian and torque in per mille of the motor's
//! rated torque, and the conversions to and from SI, as the EtherCAT master (`modbot-ethercat`)
//! and the emulated drives (`modbot-ecat-sim`) both use them. Values are rounded to the
//! nearest unit and saturate at the wire type's range.

use std::f64::consts::TAU;

/// A drive's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    /// Position counts per radian of the motor (and of a load-side encoder).
    pub counts_per_rad: f64,
    /// Torque units (per mille of the rated torque) per Nm.
    pub torque_per_nm: f64,
}

impl Scale {
    /// The units a drive states: its position encoder resolution (0x608F: `increments` per
    /// `revolutions` of the motor) and its rated torque (0x6076, mNm).
    pub fn of_drive(increments: u32, revolutions: u32, rated_torque_mnm: u32) -> Scale {
        Scale {
            counts_per_rad: f64::from(increments) / f64::from(revolutions) / TAU,
            torque_per_nm: 1.0e6 / f64::from(rated_torque_mnm),
        }
    }

    /// `rad` (or rad/s) in counts (counts/s).
    pub fn counts(&self, rad: f64) -> i32 {
        (rad * self.counts_per_rad)
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    }

    /// `counts` (counts/s) in rad (rad/s).
    pub fn rad(&self, counts: i32) -> f64 {
        f64::from(counts) / self.counts_per_rad
    }

    /// `nm` in torque units.
    pub fn torque(&self, nm: f64) -> i16 {
        (nm * self.torque_per_nm)
            .round()
            .clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    }

    /// Torque `units` in Nm.
    pub fn nm(&self, units: i16) -> f64 {
        f64::from(units) / self.torque_per_nm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drive_s_stated_units_give_its_scale_and_values_round_and_saturate() {
        let sut = Scale::of_drive(1 << 20, 1, 10_000);
        assert_eq!(sut.torque_per_nm, 100.0);
        assert_eq!(sut.counts(TAU), 1 << 20);
        assert_eq!(sut.rad(1 << 20), TAU);
        assert_eq!((sut.torque(1.234), sut.nm(123)), (123, 1.23));
        assert_eq!((sut.counts(1e9), sut.torque(-1e9)), (i32::MAX, i16::MIN));
    }
}
