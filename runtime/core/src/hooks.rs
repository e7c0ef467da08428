//! What a module is made of, as its message manager sees it: the method table and hooks a
//! [`crate::ModuleBuilder`] declares (`Definition`), the reply a method fills ([`Reply`]), a
//! report as its hook gets it ([`Report`]). A leaf of the module core: the manager and the
//! module both use it.

use core::time::Duration;

use modbot_ipc_schema::{Addr, Args, Value};

use crate::calls::CallHandle;
use crate::ctx::Ctx;
use crate::error::{CallError, MethodError};

/// A local method: reads its arguments, may use the context, writes its results into `reply`
/// (no results: the caller gets an ACK).
pub type MethodFn<S> = fn(&mut S, &mut Ctx, &Args<'_>, &mut Reply) -> Result<(), MethodError>;

/// Receives a REPORT.
pub type ReportFn<S> = fn(&mut S, &mut Ctx, &Report<'_>);

/// Receives the answer to a call made with [`Ctx::call`].
pub type DoneFn<S> = fn(&mut S, &mut Ctx, CallHandle, Result<&Args<'_>, &CallError>);

/// Periodic work.
pub type TaskFn<S> = fn(&mut S, &mut Ctx);

/// Gives a live upgrade's new process the module's own state, as bytes (the old process, as
/// it hands over: see [`crate::ModuleBuilder::on_upgrade_out`]).
pub type UpgradeOutFn<S> = fn(&S) -> Vec<u8>;

/// Takes the state the old process's [`UpgradeOutFn`] gave, with the version that program
/// declared (the new process, before it serves): `Err` says why it cannot, and the module
/// starts from its defaults.
pub type UpgradeInFn<S> = fn(&mut S, &mut Ctx, u32, &[u8]) -> Result<(), String>;

/// Told that the operator activated (`true`) or deactivated (`false`) the module.
pub type ActivationFn<S> = fn(&mut S, &mut Ctx, bool);

/// A REPORT as the receiver sees it.
#[derive(Debug)]
pub struct Report<'a> {
    pub from: Addr,
    pub topic: u8,
    pub values: Args<'a>,
}

/// A method's results, encoded as they are pushed.
#[derive(Debug, Default)]
pub struct Reply {
    pub(crate) buf: Vec<u8>,
    pub(crate) count: usize,
}

impl Reply {
    pub fn push(&mut self, v: Value<'_>) {
        if v.encode_to_vec(&mut self.buf).is_ok() {
            self.count += 1;
        }
    }

    pub fn f64(&mut self, v: f64) {
        self.push(Value::F64(v));
    }

    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

/// The answer a blocking call gets.
pub(crate) type Waiter<'w> = Option<(CallHandle, &'w mut dyn FnMut(Result<&Args<'_>, &CallError>))>;

pub(crate) struct Definition<S> {
    pub(crate) methods: Vec<(String, MethodFn<S>)>,
    pub(crate) on_report: Option<ReportFn<S>>,
    pub(crate) on_done: Option<DoneFn<S>>,
    pub(crate) on_activation: Option<ActivationFn<S>>,
    pub(crate) tasks: Vec<(Duration, TaskFn<S>)>,
    pub(crate) peers: Vec<String>,
    pub(crate) snapshot_period_ns: u64,
    /// The state a live upgrade carries over, and its version.
    pub(crate) upgrade_out: Option<(u32, UpgradeOutFn<S>)>,
    pub(crate) upgrade_in: Option<UpgradeInFn<S>>,
}
