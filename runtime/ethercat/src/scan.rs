//! `modbot bus scan`: the slaves on a segment, like IgH's `ethercat slaves`.
//!
//! The scan is ethercrab's `init`: it resets every slave, gives it its station address, reads
//! its SII and leaves it in PRE-OP. So it is refused on a segment another master runs (its
//! frames are seen on the interface first): it never disturbs a running bus.

use std::fmt::Write as _;
use std::time::Duration;

use crate::error::EthercatError;
use crate::master::{Master, SlaveInfo};

/// The slaves on the segment of `interface`, in order.
pub fn scan(interface: &str) -> Result<Vec<SlaveInfo>, EthercatError> {
    let mut master = Master::open(interface, Duration::from_millis(200), false)?;
    let (_group, slaves) = master.init()?;
    Ok(slaves)
}

/// The scan as a table: position, station address, AL state, DC, identity, name.
pub fn render(slaves: &[SlaveInfo]) -> String {
    let mut out = String::from(
        "POS  ADDRESS  STATE    DC   VENDOR      PRODUCT     REVISION    SERIAL      NAME\n",
    );
    for s in slaves {
        let _ = writeln!(
            out,
            "{:>3}  {:#06x}   {:<7}  {:<3}  {:#010x}  {:#010x}  {:#010x}  {:<10}  {}",
            s.position,
            0x1000 + s.position,
            s.state,
            if s.dc { "yes" } else { "no" },
            s.vendor,
            s.product,
            s.revision,
            s.serial,
            s.name
        );
    }
    out
}
