//! What can go wrong bringing up or scanning an EtherCAT segment, naming the slave.

use modbot_bus::link::LinkError;

/// A slave as an error names it: its position on the segment and its name from the SII.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlaveRef {
    pub position: u16,
    pub name: String,
}

impl std::fmt::Display for SlaveRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "slave {} ('{}')", self.position, self.name)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum EthercatError {
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error("one EtherCAT master per process: this process opened one already")]
    SecondMaster,
    #[error("interface '{0}' carries another master's EtherCAT frames: stop that master first (one master per segment)")]
    InterfaceInUse(String),
    #[error("the segment on '{interface}' did not answer: {source} (is the cable or the slave emulator there?)")]
    NoSegment {
        interface: String,
        #[source]
        source: ethercrab::error::Error,
    },
    #[error("axis {axis} is declared on slave {position}, but the segment on '{interface}' has {found} slave(s)")]
    SlaveMissing {
        axis: usize,
        position: u16,
        interface: String,
        found: usize,
    },
    #[error("axis {axis}: {slave} is vendor {found_vendor:#010x} product {found_product:#010x}, the description expects vendor {vendor:#010x} product {product:#010x}")]
    WrongIdentity {
        axis: usize,
        slave: SlaveRef,
        vendor: u32,
        product: u32,
        found_vendor: u32,
        found_product: u32,
    },
    #[error(
        "axis {axis}: {slave} refused writing {index:#06x}:{sub} of the PDO mapping: {source}"
    )]
    Mapping {
        axis: usize,
        slave: SlaveRef,
        index: u16,
        sub: u8,
        #[source]
        source: ethercrab::error::Error,
    },
    #[error("axis {axis}: {slave} maps {found_out} output and {found_in} input bytes, the backend's mapping is {out} and {inp}: the drive did not take the mapping")]
    WrongImage {
        axis: usize,
        slave: SlaveRef,
        out: usize,
        inp: usize,
        found_out: usize,
        found_in: usize,
    },
    #[error("axis {axis}: {slave} reports {what} {found}, the description says {declared}")]
    WrongScale {
        axis: usize,
        slave: SlaveRef,
        what: &'static str,
        found: f64,
        declared: f64,
    },
    #[error("bringing the segment on '{interface}' to {state} failed: {source}")]
    State {
        interface: String,
        state: &'static str,
        #[source]
        source: ethercrab::error::Error,
    },
    #[error("{slave} did not reach OP within {seconds} s (it is in {state})")]
    NotOperational {
        slave: SlaveRef,
        seconds: u64,
        state: String,
    },
}
