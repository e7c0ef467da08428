//! What the supervisor and its module's method handlers share: the rows `status` answers, the
//! requests the handlers leave for the supervisor's loop (`down`, assembly hosts, upgrades),
//! relayed answers.

use modbot_core::domain::Domain;
use modbot_grid::component::Generation;
use modbot_grid::GridSpec;

use super::status::Row;

#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum HostRequest {
    Spawn {
        host: String,
        assembly: String,
        generation: Generation,
        /// The host's own program (a declared component type's), else the built-in one.
        program: Option<String>,
    },
    Retire(String),
    /// The grid switched to `assembly` (`generation`): a host of the system's components
    /// restarted from now on loads it.
    Current {
        assembly: String,
        generation: Generation,
    },
}

/// The supervisor module's state, shared with its method handlers.
#[derive(Debug, Default)]
pub(super) struct Shared {
    pub(super) rows: Vec<Row>,
    pub(super) down_requested: bool,
    /// Host processes of assemblies to start or stop, in the order asked.
    pub(super) requests: Vec<HostRequest>,
    /// Whether the system can start assembly hosts (it has a grid with assemblies).
    pub(super) hosts_allowed: bool,
    /// What loading the grid's assemblies needs (a grid with assemblies only).
    pub(super) assemblies: Option<AssemblyLoader>,
    /// Relayed calls that ended: their handles and the tools' answers.
    pub(super) relayed: Vec<(modbot_core::calls::CallHandle, Vec<u8>)>,
    /// Live upgrades asked for (`upgrade`), not started yet.
    pub(super) upgrade_requests: Vec<UpgradeRequest>,
    /// How each module's last upgrade went (`upgrade_status`).
    pub(super) upgrade_status: std::collections::BTreeMap<String, UpgradeStatus>,
}

/// What loading an assembly needs: the system's grid as the description gave it (with the
/// loader's context), and the domain the images go to.
#[derive(Debug)]
pub(super) struct AssemblyLoader {
    pub(super) grid: GridSpec,
    pub(super) domain: Domain,
}

/// An upgrade asked for, not started yet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct UpgradeRequest {
    pub(super) module: String,
    /// The new program; the module's own when `None` (a rebuilt binary at the same path).
    pub(super) program: Option<String>,
    /// Take a program whose method table differs.
    pub(super) force: bool,
}

/// How an upgrade goes, as `upgrade_status` answers it: `preparing`, `done` or `refused`,
/// with what happened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct UpgradeStatus {
    pub(super) state: &'static str,
    pub(super) detail: String,
}
