//! The service thread's side of a scripted live upgrade (`modbot up --upgrade TICK:HOST`): at
//! the tick the tick thread says one is due, the supervisor is asked to upgrade the host's
//! module (`upgrade`), and its `upgrade_status` is followed until it is done or refused. The
//! tick thread holds a lockstep grid at that tick until the new process has taken over (see
//! `upgrade`); a refused upgrade lets it go on.

use std::sync::mpsc::Sender;
use std::time::{Duration, Instant};

use modbot_core::calls::CallOptions;
use modbot_core::{CallError, Module};
use modbot_ipc_schema::{NakCode, OwnedValue, Value};

use super::shared::Shared;
use super::tick_thread::ToTick;

/// How often the supervisor is asked how the upgrade goes.
const LOOK_EVERY: Duration = Duration::from_millis(100);

/// How long an upgrade due while the supervisor is busy with another of the same module (the
/// previous one's module handover, which follows the grid's) is asked for again.
const BUSY_LIMIT: Duration = Duration::from_secs(60);

/// A scripted upgrade under way: the host's module, and when its status was last asked.
#[derive(Default)]
pub struct UpgradeJob {
    under_way: Option<(String, Instant)>,
    /// Due, but the supervisor was busy: (host, module, first asked, last asked).
    busy: Option<(String, String, Instant, Instant)>,
}

impl UpgradeJob {
    /// The tick thread says the upgrade of `host` is due: the supervisor is asked for it.
    /// `hosts`: the running hosts and their modules.
    pub fn start(
        &mut self,
        module: &mut Module<Shared>,
        host: &str,
        hosts: &[(String, String)],
        to_tick: &Sender<ToTick>,
    ) {
        let Some((_, name)) = hosts.iter().find(|(h, _)| h == host) else {
            let known: Vec<&str> = hosts.iter().map(|(h, _)| h.as_str()).collect();
            tracing::error!(
                "the scripted upgrade of host {host} cannot be made: no such host runs (hosts: \
                 {})",
                known.join(", ")
            );
            let _ = to_tick.send(ToTick::UpgradeRefused);
            return;
        };
        let now = Instant::now();
        self.ask(module, host, name, now, to_tick);
    }

    /// Asks the supervisor for the upgrade of `host`'s module `name`, first asked at `first`.
    fn ask(
        &mut self,
        module: &mut Module<Shared>,
        host: &str,
        name: &str,
        first: Instant,
        to_tick: &Sender<ToTick>,
    ) {
        let asked = module.call_owned(
            "supervisor",
            "upgrade",
            &[Value::Text(name)],
            CallOptions::timeout(Duration::from_secs(5)),
        );
        match asked {
            Ok(_) => {
                tracing::info!("scripted upgrade of host {host} ({name}) asked for");
                self.under_way = Some((name.to_owned(), Instant::now()));
            }
            // The previous upgrade's module handover is not over yet: asked again soon.
            Err(CallError::Nak { code, .. })
                if code == NakCode::BUSY && first.elapsed() < BUSY_LIMIT =>
            {
                tracing::debug!("the supervisor is busy with {name}: the upgrade is asked again");
                self.busy = Some((host.to_owned(), name.to_owned(), first, Instant::now()));
            }
            Err(e) => {
                tracing::error!("the scripted upgrade of {name} cannot be made: {e}");
                let _ = to_tick.send(ToTick::UpgradeRefused);
            }
        }
    }

    /// Follows the upgrade under way: a refusal is logged and lets the grid go on.
    pub fn step(&mut self, module: &mut Module<Shared>, to_tick: &Sender<ToTick>) {
        if let Some((host, name, first, _)) =
            self.busy.take_if(|(.., last)| last.elapsed() >= LOOK_EVERY)
        {
            self.ask(module, &host, &name, first, to_tick);
        }
        let Some((name, looked)) = self.under_way.as_mut() else {
            return;
        };
        if looked.elapsed() < LOOK_EVERY {
            return;
        }
        *looked = Instant::now();
        let name = name.clone();
        let status = module.call_owned(
            "supervisor",
            "upgrade_status",
            &[Value::Text(&name)],
            CallOptions::timeout(Duration::from_secs(5)),
        );
        let (state, detail) = match status.as_deref() {
            Ok([OwnedValue::Text(state), OwnedValue::Text(detail)]) => {
                (state.clone(), detail.clone())
            }
            Ok(_) => return,
            Err(e) => {
                tracing::debug!("the status of {name}'s upgrade: {e}");
                return;
            }
        };
        match state.as_str() {
            "done" => {
                tracing::info!("scripted upgrade of {name}: {detail}");
                self.under_way = None;
            }
            "refused" => {
                tracing::error!("the scripted upgrade of {name} was refused: {detail}");
                self.under_way = None;
                let _ = to_tick.send(ToTick::UpgradeRefused);
            }
            _ => {}
        }
    }
}
