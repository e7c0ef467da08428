//! The numbers of CoE: SDO abort codes and the services of the CoE header, shared by the SDO
//! server ([`crate::coe`]) and SDO information ([`crate::coe_info`]).

/// SDO abort codes (ETG.1000.6 Table 41) used by the server.
pub mod abort {
    /// Toggle bit not alternated.
    pub const TOGGLE_BIT: u32 = 0x0503_0000;
    /// Client/server command specifier not valid or unknown.
    pub const INVALID_COMMAND: u32 = 0x0504_0001;
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// Attempt to read a write-only object.
    pub const WRITE_ONLY: u32 = 0x0601_0001;
    /// Attempt to write a read-only object.
    pub const READ_ONLY: u32 = 0x0601_0002;
    /// Subindex cannot be written, subindex 0 must be 0 for write access.
    pub const SUBINDEX_0_NOT_ZERO: u32 = 0x0601_0003;
    /// Complete access not supported.
    pub const NO_COMPLETE_ACCESS: u32 = 0x0601_0004;
    /// The object does not exist in the dictionary.
    pub const NOT_FOUND: u32 = 0x0602_0000;
    /// The object cannot be mapped into the PDO.
    pub const CANNOT_MAP: u32 = 0x0604_0041;
    /// The number and length of the objects to be mapped would exceed the PDO length.
    pub const PDO_TOO_LONG: u32 = 0x0604_0042;
    /// Data type does not match, length of service parameter does not match.
    pub const LENGTH_MISMATCH: u32 = 0x0607_0010;
    /// Length of service parameter too high.
    pub const DATA_TOO_LONG: u32 = 0x0607_0012;
    /// Length of service parameter too low.
    pub const DATA_TOO_SHORT: u32 = 0x0607_0013;
    /// Subindex does not exist.
    pub const SUBINDEX_NOT_FOUND: u32 = 0x0609_0011;
    /// Value range of parameter exceeded.
    pub const VALUE_OUT_OF_RANGE: u32 = 0x0609_0030;
    /// Value of parameter written too high.
    pub const VALUE_TOO_HIGH: u32 = 0x0609_0031;
    /// Data cannot be transferred or stored because of the present device state.
    pub const WRONG_STATE: u32 = 0x0800_0022;
}

/// CoE services (bits 12–15 of the CoE header).
pub mod service {
    /// SDO request (master → slave).
    pub const SDO_REQUEST: u8 = 2;
    /// SDO response (slave → master).
    pub const SDO_RESPONSE: u8 = 3;
    /// SDO information.
    pub const SDO_INFORMATION: u8 = 8;
}
