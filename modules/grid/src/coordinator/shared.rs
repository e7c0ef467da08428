//! What the coordinator's service thread keeps between its methods and its switch job.

use modbot_core::CallHandle;

use super::gate::{Gate, Setting};

/// The ledger as last encoded, for the `ledger` method, and the assembly switches.
pub struct Shared {
    pub(super) ledger: Vec<u8>,
    /// Whether the grid runs assemblies.
    pub(super) assemblies: bool,
    /// A switch asked for and not begun yet: (assembly, generation).
    pub(super) requested: Option<(String, u16)>,
    /// A switch is under way (asked for, or being prepared).
    pub(super) busy: bool,
    /// The supervisor's `load_assembly` call of the switch under way.
    pub(super) loading: Option<CallHandle>,
    /// Its answer: loaded (the checked grid is written), or why not.
    pub(super) loaded: Option<Result<(), String>>,
    /// The generation the next switch gets.
    pub(super) next_generation: u16,
    /// `assembly()`'s answer, encoded (`modbot_ipc_schema::switch`), kept current by the main
    /// loop.
    pub(super) status: Vec<u8>,
    /// The grid runs in lockstep (only such a grid has a gate).
    pub(super) lockstep: bool,
    /// The gate a robot program steps the grid with.
    pub(super) gate: Gate,
    /// A setting of the gate the main loop has still to send to the tick thread.
    pub(super) gate_changed: Option<Setting>,
    /// The grid's tick as the tick thread last said.
    pub(super) ticks: u64,
}
