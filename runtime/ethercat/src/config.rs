//! What the description says of an EtherCAT bus: the interface, and per drive (axis) the
//! slave it is, the identity that slave must have, and its units — the `bus` component's
//! params with `backend = "ethercat"` (declared in `modbot_bus::robot`).
//!
//! | param | type | default | meaning |
//! |---|---|---|---|
//! | `interface` | text | required | the network interface of the segment (`eth1`, `veth0`) |
//! | `slave` | per axis | 0, 1, 2, … | the drive's position on the segment (0: the first slave) |
//! | `vendor`, `product` | per axis | not checked | the identity the slave's SII must report |
//! | `counts_per_rad` | per axis | 2²⁰/2π | position counts per radian (checked against 0x608F) |
//! | `torque_per_nm` | per axis | 100 | torque units (‰ of the rated torque) per Nm (checked against 0x6076) |
//! | `link_encoder` | bool | false | the drive maps a load-side encoder (0x20A0): the link's position |
//! | `dc` | bool | false | distributed clocks: SYNC0 every base period |

use std::f64::consts::PI;

use modbot_grid::component::{ParamError, ParamValue, Params};

use crate::pdo::Scale;

/// Counts per radian when the description does not say: a 20-bit encoder on the motor.
pub const DEFAULT_COUNTS_PER_RAD: f64 = 1_048_576.0 / (2.0 * PI);
/// Torque units per Nm when the description does not say: ‰ of a 10 Nm rated torque.
pub const DEFAULT_TORQUE_PER_NM: f64 = 100.0;

/// One drive on the segment.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveConfig {
    /// Its position on the segment (0: the first slave after the master).
    pub position: u16,
    pub vendor: Option<u32>,
    pub product: Option<u32>,
    pub scale: Scale,
    pub link_encoder: bool,
}

/// The bus as the description declares it.
#[derive(Debug, Clone, PartialEq)]
pub struct EthercatConfig {
    pub interface: String,
    /// One per axis, in axis order.
    pub drives: Vec<DriveConfig>,
    /// The bus cycle (the grid's base period), ns.
    pub period_ns: u64,
    pub dc: bool,
    /// The slaves' process data watchdog (0x0420) stays on: a slave whose outputs stop
    /// coming leaves OP. Off for a grid in lockstep, which may pause the bus for as long as a
    /// step of the slowest process takes.
    pub watchdog: bool,
}

fn given<'p>(p: &'p Params, name: &str) -> Option<&'p [f64]> {
    match p.get(name) {
        Some(ParamValue::F64s(xs)) if !xs.is_empty() => Some(xs),
        _ => None,
    }
}

/// Param `name` per axis: one value for all or one per axis, each passing `ok`.
fn per_axis(
    p: &Params,
    name: &str,
    axes: usize,
    default: impl Fn(usize) -> f64,
    what: &str,
    ok: fn(f64) -> bool,
) -> Result<Vec<f64>, ParamError> {
    if given(p, name).is_none() {
        return Ok((0..axes).map(default).collect());
    }
    modbot_control::per_axis(p, name, axes, what, ok)
}

fn whole_u32(x: f64) -> bool {
    x.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&x)
}

fn flag(p: &Params, name: &str) -> Result<bool, ParamError> {
    Ok(p.get(name).is_some() && p.bool(name)?)
}

impl EthercatConfig {
    /// The bus of a `bus` component with `axes` drives, cycled every `period_ns`.
    pub fn from_params(
        p: &Params,
        axes: usize,
        period_ns: u64,
    ) -> Result<EthercatConfig, ParamError> {
        let interface = match p.get("interface") {
            Some(ParamValue::Text(name)) if !name.is_empty() => name.clone(),
            _ => {
                let why =
                    "is required with backend = \"ethercat\": the network interface of the segment"
                        .to_owned();
                return Err(ParamError::invalid("interface", why));
            }
        };
        let slaves = per_axis(
            p,
            "slave",
            axes,
            |i| i as f64,
            "a position from 0 to 65535",
            |x| x.fract() == 0.0 && (0.0..=65535.0).contains(&x),
        )?;
        let identity = |name| -> Result<Vec<Option<u32>>, ParamError> {
            if given(p, name).is_none() {
                return Ok(vec![None; axes]);
            }
            let xs = modbot_control::per_axis(
                p,
                name,
                axes,
                "a whole number from 0 to 2^32 - 1",
                whole_u32,
            )?;
            Ok(xs.into_iter().map(|x| Some(x as u32)).collect())
        };
        let (vendors, products) = (identity("vendor")?, identity("product")?);
        let positive = |x: f64| x.is_finite() && x > 0.0;
        let counts = per_axis(
            p,
            "counts_per_rad",
            axes,
            |_| DEFAULT_COUNTS_PER_RAD,
            "positive",
            positive,
        )?;
        let torque = per_axis(
            p,
            "torque_per_nm",
            axes,
            |_| DEFAULT_TORQUE_PER_NM,
            "positive",
            positive,
        )?;
        let link_encoder = flag(p, "link_encoder")?;
        let mut drives = Vec::with_capacity(axes);
        for axis in 0..axes {
            let position = slaves[axis] as u16;
            if let Some(other) = drives
                .iter()
                .position(|d: &DriveConfig| d.position == position)
            {
                let why = format!("gives axes {other} and {axis} the same slave {position}");
                return Err(ParamError::invalid("slave", why));
            }
            drives.push(DriveConfig {
                position,
                vendor: vendors[axis],
                product: products[axis],
                scale: Scale {
                    counts_per_rad: counts[axis],
                    torque_per_nm: torque[axis],
                },
                link_encoder,
            });
        }
        Ok(EthercatConfig {
            interface,
            drives,
            period_ns,
            dc: flag(p, "dc")?,
            watchdog: true,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> Params {
        Params::new().with("interface", ParamValue::Text("veth0".into()))
    }

    #[test]
    fn a_bus_without_an_interface_is_refused_naming_the_param() {
        let e = EthercatConfig::from_params(&Params::new(), 2, 1_000_000).unwrap_err();
        assert!(e.to_string().contains("interface"), "{e}");
    }

    #[test]
    fn drives_default_to_the_first_slaves_in_order_with_unchecked_identities() {
        let sut = EthercatConfig::from_params(&params(), 3, 1_000_000).unwrap();
        let positions: Vec<u16> = sut.drives.iter().map(|d| d.position).collect();
        assert_eq!(positions, [0, 1, 2]);
        assert_eq!(sut.drives[0].vendor, None);
        assert_eq!(sut.drives[2].scale.counts_per_rad, DEFAULT_COUNTS_PER_RAD);
    }

    #[test]
    fn two_axes_on_one_slave_are_refused() {
        let p = params().with("slave", ParamValue::F64s(vec![1.0, 1.0]));
        let e = EthercatConfig::from_params(&p, 2, 1_000_000).unwrap_err();
        assert!(e.to_string().contains("the same slave 1"), "{e}");
    }

    #[test]
    fn an_identity_is_taken_per_axis_or_for_all() {
        let p = params()
            .with("vendor", ParamValue::F64s(vec![0x4D42.into()]))
            .with("product", ParamValue::F64s(vec![1.0, 2.0]));
        let sut = EthercatConfig::from_params(&p, 2, 1_000_000).unwrap();
        assert_eq!(
            (sut.drives[1].vendor, sut.drives[1].product),
            (Some(0x4D42), Some(2))
        );
        let p = params().with("vendor", ParamValue::F64s(vec![-1.0]));
        assert!(EthercatConfig::from_params(&p, 2, 1_000_000).is_err());
    }
}
