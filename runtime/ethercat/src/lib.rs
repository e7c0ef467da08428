//! modbot-ethercat: the `ethercat` backend of the bus bridge — CiA 402 drives on an EtherCAT
//! segment through the [`ethercrab`] master, on a raw Linux interface.
//!
//! The bus bridge (`modbot-bus`) serves its backend every base tick; this backend makes each
//! tick one exchange of process data with the drives. The description chooses it on the `bus`
//! component (`backend = "ethercat", interface = "eth1"`, per drive its slave, identity and
//! units: [`config`]). Tested against modbot's own slave emulator (`modbot-ecat-sim`) on a veth
//! pair; the same frames go to real slaves.
//!
//! Who leads: the grid. The coordinator's tick releases the bus, and the release is the cycle:
//! the frame goes out when the grid serves the bus. With distributed clocks, the slaves' SYNC0
//! runs at the base period from their own clock (the first DC slave's, which the master
//! keeps the others locked to every cycle), and the master writes each tick's time into that
//! reference clock, so SYNC0 keeps a fixed phase to the grid's tick ([`dc`]); the backend
//! measures where in the SYNC0 cycle each frame arrives and whether it is locked
//! (`Backend::sync0_phase`, shown by `modbot bus`).
//!
//! # Layout
//! - [`config`]: the description's `bus` params for EtherCAT ([`EthercatConfig`]).
//! - [`pdo`]: the drives' process data: the mapping written by SDO, the units, packing.
//! - [`pump`]: ethercrab's frames moved on the calling thread over the raw link.
//! - [`dc`]: the phase lock of SYNC0 to the grid's tick ([`dc::GridLock`]).
//! - [`master`]: the master and the bring-up of a segment (identities, mapping, DC, OP).
//! - [`backend`]: [`EthercatBackend`], the bus bridge's backend: one cycle per release.
//! - [`scan`]: `modbot bus scan`.
//! - [`error`]: what bring-up and scans refuse for, naming the slave.

pub mod backend;
pub mod config;
pub mod dc;
pub mod error;
pub mod master;
pub mod pdo;
pub mod pump;
pub mod scan;

pub use backend::EthercatBackend;
pub use config::{DriveConfig, EthercatConfig};
pub use error::EthercatError;
pub use master::SlaveInfo;
