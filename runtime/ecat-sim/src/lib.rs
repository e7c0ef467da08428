//! # modbot-ecat-sim: EtherCAT slaves in software
//!
//! A line of emulated EtherCAT slaves that a real master (ethercrab 0.7) brings from INIT to
//! OP and exchanges process data with, frame for frame, as with Beckhoff ET1100-based
//! slaves: in memory ([`Chain::process`] on a frame buffer) or on a Linux interface
//! ([`socket::serve`], a raw `AF_PACKET` socket).
//!
//! ```no_run
//! use modbot_ecat_sim::{Chain, ManualClock, NoApplication, Identity, Slave, SlaveConfig, Reply};
//!
//! let config = SlaveConfig::new(Identity { vendor_id: 0xB0B, ..Identity::default() }, "MB-IO");
//! let mut chain = Chain::new(vec![Slave::new(config, NoApplication)], ManualClock::new(0));
//! let mut frame = vec![0u8; 64]; // an EtherCAT frame from the master
//! match chain.process(&mut frame) {
//!     Ok(Reply::Frame) => { /* send `frame` back */ }
//!     Ok(Reply::Lost) => { /* send nothing */ }
//!     Err(error) => eprintln!("{error}"),
//! }
//! ```
//!
//! ## Layout
//!
//! From the wire inwards:
//!
//! - [`frame`]: Ethernet II + EtherCAT header + the chain of datagrams, decoded in place
//!   over `&mut [u8]`; a malformed frame is a typed [`FrameError`], never a panic.
//! - [`datagram`]: one datagram viewed in place (command, index, address, length, flags, IRQ,
//!   data, working counter) and the [`Command`] set with its addressing.
//! - [`chain`]: the line: every reachable slave processes every datagram in order; per-hop
//!   timing for the DC latches; faults (a slave losing power, lost frames).
//! - [`slave`]: one slave (ESC + SII + dictionary + mailbox + application): addressing,
//!   working counters (+1 read, +1 write, +1/+2/+3 for read-write commands, ARMW/FRMW read
//!   at the addressed slave and write at the others), and [`firmware`]: its reactions (AL
//!   state machine with the checks of a slave stack, mailbox, application steps, the sync
//!   manager watchdog).
//! - [`esc`]: the slave controller as the master sees it: 4 KiB of registers and 8 KiB of
//!   process RAM, read-only registers, sync managers (mailbox handshake, buffers, deactivation
//!   by the firmware), FMMUs, the SII interface ([`esc::sii_interface`]) and distributed
//!   clocks ([`esc::dc`]); [`esc::pdi`] is the firmware's side of it.
//! - [`sii`]: the EEPROM image built from the slave's identity, names, mailbox and PDOs.
//! - [`mailbox`] and [`coe`] (+ `coe_info`): the mailbox protocol on SM0/SM1 and the CoE
//!   SDO server with its abort codes.
//! - [`dictionary`]: the object dictionary ([`ObjectEntry`], [`ObjectDictionary`]).
//! - [`pdo`]: the standard communication objects, the rules for remapping PDOs in PRE-OP,
//!   and the process-data layout; [`process_data`] copies between buffers and dictionary.
//! - [`application`]: the device behind the process data ([`Application`]); [`drive`]: a
//!   CiA 402 servo drive on an elastic joint (the bus simulator's drive and plant), the
//!   device of the `modbot-ecat-sim` program (`src/main.rs`).
//! - [`al`]: AL states and status codes.
//! - [`clock`]: the injected time source ([`Clock`], [`ManualClock`], [`MonotonicClock`]).
//! - [`socket`]: serving a chain on a network interface (a raw link of `modbot_bus::link`).

pub mod al;
pub mod application;
pub mod chain;
pub mod clock;
pub mod coe;
mod coe_codes;
mod coe_info;
pub mod datagram;
pub mod dictionary;
pub mod drive;
pub mod esc;
pub mod firmware;
pub mod frame;
pub mod mailbox;
pub mod pdo;
pub mod process_data;
pub mod sii;
pub mod slave;
pub mod socket;

pub use al::AlState;
pub use application::{Application, NoApplication};
pub use chain::{Chain, ChainConfig, Reply};
pub use clock::{Clock, ManualClock, MonotonicClock};
pub use datagram::{Command, Datagram};
pub use dictionary::{
    Access, DataType, Object, ObjectDictionary, ObjectEntry, ObjectValue, OdError, PdoMappable,
};
pub use frame::{FrameBuilder, FrameError};
pub use pdo::PdoDefinition;
pub use sii::{Identity, MailboxLayout};
pub use slave::{Slave, SlaveConfig};
pub use socket::{serve, serve_ready, ServeError, ServeStats};
