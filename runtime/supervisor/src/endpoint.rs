//! The supervisor's own module, `supervisor` in the domain: its methods (`status`, `down`,
//! the coordinator's `load_assembly`, and the hosts' `spawn_host`, `retire` and
//! `current_assembly`; the live upgrades' `upgrade` and `upgrade_status`) and the state they
//! share with the supervisor.

use modbot_ipc_schema::{Addr, Args, Value};

use super::assemblies::load_assembly_method;
use super::hosts::{current_assembly_method, retire_method, spawn_host_method};
use super::shared::Shared;
use super::status;
use super::upgrades::{upgrade_method, upgrade_status_method};
use super::{relay, SupervisorError};
use modbot_core::ctx::Ctx;
use modbot_core::error::MethodError;
use modbot_core::module::{Module, ModuleBuilder, Reply};
use modbot_core::transport::ipc::IpcTransport;
use modbot_core::transport::{ReceiveMode, TransportError};

/// Opens the supervisor's own module endpoint at the highest address the description leaves
/// free (a tool such as `modbot ls` may hold one for a moment: then the next one).
pub(super) fn open_endpoint(
    transport: &IpcTransport,
    used: &[u8],
) -> Result<Module<Shared>, SupervisorError> {
    let mut last = SupervisorError::NoAddressLeft;
    for addr in (Addr::FIRST..=Addr::LAST)
        .rev()
        .filter(|a| !used.contains(a))
    {
        let opened = ModuleBuilder::new("supervisor", addr)
            .mode(ReceiveMode::Blocking)
            .method("status", status_method)
            .method("down", down_method)
            .method("spawn_host", spawn_host_method)
            .method("retire", retire_method)
            .method("current_assembly", current_assembly_method)
            .method("load_assembly", load_assembly_method)
            .method("upgrade", upgrade_method)
            .method("upgrade_status", upgrade_status_method)
            .on_done(relay::on_done)
            .open(transport.clone(), Shared::default());
        match opened {
            Ok(m) => return Ok(m),
            Err(modbot_core::error::ModuleError::Open {
                source: TransportError::AddressTaken { .. },
                ..
            }) => continue,
            Err(modbot_core::error::ModuleError::Open {
                source: TransportError::NameTaken { pid, .. },
                ..
            }) => {
                return Err(SupervisorError::another_supervisor(
                    transport.domain(),
                    Some(pid),
                ))
            }
            Err(e) => last = e.into(),
        }
    }
    Err(last)
}

fn status_method(
    shared: &mut Shared,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let mut bytes = Vec::with_capacity(64 * shared.rows.len());
    status::encode(&shared.rows, &mut bytes);
    reply.push(Value::Bytes(&bytes));
    Ok(())
}

fn down_method(
    shared: &mut Shared,
    _: &mut Ctx,
    _: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    shared.down_requested = true;
    Ok(())
}
