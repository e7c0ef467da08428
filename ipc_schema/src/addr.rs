//! Module addresses: 8 bits, as on the MRA's MODBOT network.

use core::fmt;

/// The address of a module in a domain.
///
/// `1..=254` address modules, [`Addr::BROADCAST`] (`0xFF`) addresses every module, and `0` is
/// reserved (never a module's address), so that a zeroed header is never mistaken for a real one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Addr(pub u8);

impl Addr {
    /// Every module of the domain.
    pub const BROADCAST: Addr = Addr(0xFF);
    /// Reserved; not a module address.
    pub const NONE: Addr = Addr(0);
    /// The lowest module address.
    pub const FIRST: u8 = 1;
    /// The highest module address.
    pub const LAST: u8 = 254;

    /// Whether this address can belong to one module (`1..=254`).
    pub fn is_module(self) -> bool {
        (Self::FIRST..=Self::LAST).contains(&self.0)
    }

    /// Whether this is the broadcast address.
    pub fn is_broadcast(self) -> bool {
        self == Self::BROADCAST
    }
}

impl fmt::Display for Addr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_broadcast() {
            f.write_str("broadcast")
        } else {
            write!(f, "{}", self.0)
        }
    }
}
