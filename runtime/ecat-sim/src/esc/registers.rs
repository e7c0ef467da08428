//! ESC register addresses (ETG.1000.4 / Beckhoff "EtherCAT Slave Controller" section II), the
//! ones this model gives a meaning to.

/// Type (0x11 = ET1100).
pub const TYPE: u16 = 0x0000;
/// Revision.
pub const REVISION: u16 = 0x0001;
/// Build (u16).
pub const BUILD: u16 = 0x0002;
/// Number of FMMUs supported.
pub const FMMU_COUNT: u16 = 0x0004;
/// Number of sync managers supported.
pub const SM_COUNT: u16 = 0x0005;
/// Process RAM size in KiB.
pub const RAM_SIZE: u16 = 0x0006;
/// Port descriptor (2 bits per port).
pub const PORT_DESCRIPTOR: u16 = 0x0007;
/// ESC features supported (u16).
pub const FEATURES: u16 = 0x0008;
/// Configured station address (u16).
pub const STATION_ADDRESS: u16 = 0x0010;
/// Configured station alias (u16), loaded from SII word 4.
pub const STATION_ALIAS: u16 = 0x0012;
/// DL control (u32).
pub const DL_CONTROL: u16 = 0x0100;
/// DL status (u16): link, loop and communication of each port.
pub const DL_STATUS: u16 = 0x0110;
/// AL control (u16): the state the master requests, bit 4 acknowledges an error.
pub const AL_CONTROL: u16 = 0x0120;
/// AL status (u16): the state, bit 4 the error indication.
pub const AL_STATUS: u16 = 0x0130;
/// AL status code (u16).
pub const AL_STATUS_CODE: u16 = 0x0134;
/// PDI control (u8), from SII word 0.
pub const PDI_CONTROL: u16 = 0x0140;
/// Watchdog divider (u16).
pub const WATCHDOG_DIVIDER: u16 = 0x0400;
/// PDI watchdog time (u16).
pub const WATCHDOG_PDI: u16 = 0x0410;
/// Sync manager watchdog time (u16).
pub const WATCHDOG_SM: u16 = 0x0420;
/// Sync manager watchdog status (u16, bit 0: 1 = not expired).
pub const WATCHDOG_SM_STATUS: u16 = 0x0440;
/// SII configuration / PDI access state.
pub const SII_CONFIG: u16 = 0x0500;
/// SII control/status (u16).
pub const SII_CONTROL: u16 = 0x0502;
/// SII address (u32, in words).
pub const SII_ADDRESS: u16 = 0x0504;
/// SII data (8 bytes).
pub const SII_DATA: u16 = 0x0508;
/// First FMMU; each is 16 bytes.
pub const FMMU_BASE: u16 = 0x0600;
/// Bytes of one FMMU's registers.
pub const FMMU_LEN: u16 = 16;
/// First sync manager; each is 8 bytes.
pub const SM_BASE: u16 = 0x0800;
/// Bytes of one sync manager's registers.
pub const SM_LEN: u16 = 8;
/// Receive time of port 0 (u32); a write here latches the receive times of all ports.
pub const DC_RECEIVE_TIME_PORT0: u16 = 0x0900;
/// Receive time of port 1 (u32).
pub const DC_RECEIVE_TIME_PORT1: u16 = 0x0904;
/// System time (u64): read gives local time + offset; write feeds the drift control loop.
pub const DC_SYSTEM_TIME: u16 = 0x0910;
/// Local time of the processing unit at the latch (u64).
pub const DC_RECEIVE_TIME_PU: u16 = 0x0918;
/// System time offset (u64).
pub const DC_SYSTEM_TIME_OFFSET: u16 = 0x0920;
/// System time delay (u32): propagation delay from the reference clock.
pub const DC_SYSTEM_TIME_DELAY: u16 = 0x0928;
/// System time difference (u32, sign-magnitude: bit 31 set = local copy smaller).
pub const DC_SYSTEM_TIME_DIFFERENCE: u16 = 0x092C;
/// Control loop parameters 1–3 (3 × u16); writing them resets the control unit.
pub const DC_CONTROL_LOOP: u16 = 0x0930;
/// Cyclic unit control (u8).
pub const DC_CYCLIC_UNIT_CONTROL: u16 = 0x0980;
/// Sync activation (u8): bit 0 cyclic operation, bit 1 SYNC0, bit 2 SYNC1.
pub const DC_SYNC_ACTIVATION: u16 = 0x0981;
/// Start time of cyclic operation (u64, system time).
pub const DC_START_TIME: u16 = 0x0990;
/// SYNC0 cycle time in ns (u32).
pub const DC_SYNC0_CYCLE: u16 = 0x09A0;
/// SYNC1 cycle time in ns (u32).
pub const DC_SYNC1_CYCLE: u16 = 0x09A4;

/// Start of the process RAM.
pub const PROCESS_RAM: u16 = 0x1000;
/// Bytes the model holds: 4 KiB of registers and 8 KiB of process RAM, as an ET1100.
pub const MEMORY_SIZE: usize = 0x3000;

/// Byte ranges the master can read but not write (writes are counted and ignored, as in the
/// ESC). Side-effect registers (SII control, sync manager status, DC latches) are handled
/// apart.
pub(crate) const READ_ONLY: &[(u16, u16)] = &[
    (0x0000, 0x0010),
    (0x0012, 0x0014),
    (0x0110, 0x0112),
    (0x0130, 0x0140),
    (0x0210, 0x0230),
    (0x0440, 0x0442),
    (0x0501, 0x0502),
    (0x0900, 0x0920),
    (0x092C, 0x0930),
    (0x098E, 0x0990),
    (0x0998, 0x09A0),
    (0x0E00, 0x0F00),
];
