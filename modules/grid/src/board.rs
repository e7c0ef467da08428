//! A host process's blackboard: the latest outputs of its components, as items
//! `<component>.<output>` (f64, i64, bool, f64 arrays), `tick` (the newest release tick it
//! served) and `base_period_s` (the grid's base tick, s), copied from the serving thread's [`OutputsView`] by the module's thread. So
//! `modbot bb host_ctrl_g3` shows what an assembly's components do, and a robot program reads
//! them (`read("settle.settled")`).

use std::sync::Mutex;

use modbot_core::blackboard::{BlackboardError, ItemId};
use modbot_core::{Args, Blackboard, Ctx, MethodError, OwnedValue, Reply, Value};
use modbot_grid::outputs_view::{copy_port, OutputsView, SharedOutputs};
use modbot_grid::PortValue;

/// The blackboard's side of the view.
pub struct Board {
    view: SharedOutputs,
    /// The grid's base tick, s: the unit of `tick`.
    base_period_s: f64,
    /// The refresh last shown.
    seen: u64,
    /// A copy taken under the lock, written to the blackboard after it.
    copy: Vec<PortValue>,
    tick: u64,
    /// The items: `tick`, then one per output in the view's order.
    tick_id: Option<ItemId>,
    ids: Vec<ItemId>,
}

impl Board {
    pub fn new(view: SharedOutputs, base_period_s: f64) -> Board {
        let copy = lock(&view).values.clone();
        Board {
            view,
            base_period_s,
            seen: 0,
            copy,
            tick: 0,
            tick_id: None,
            ids: Vec::new(),
        }
    }

    /// The blackboard with an item per output, `tick` and `base_period_s`.
    pub fn blackboard(&mut self) -> Result<Blackboard, BlackboardError> {
        let view = lock(&self.view).clone();
        let mut builder = Blackboard::builder()
            .item("tick", OwnedValue::I64(0))
            .item("base_period_s", OwnedValue::F64(self.base_period_s));
        for (name, value) in view.names.iter().zip(&view.values) {
            builder = builder.item(name, owned(value));
        }
        let bb = builder.build()?;
        self.tick_id = Some(bb.id("tick")?);
        self.ids = view
            .names
            .iter()
            .map(|n| bb.id(n))
            .collect::<Result<_, _>>()?;
        Ok(bb)
    }

    /// Writes what changed since the last call to `bb`.
    pub fn refresh(&mut self, bb: &mut Blackboard) {
        {
            let view = lock(&self.view);
            if view.seq == self.seen {
                return;
            }
            self.seen = view.seq;
            self.tick = view.tick;
            for (to, from) in self.copy.iter_mut().zip(&view.values) {
                copy_port(to, from);
            }
        }
        if let Some(id) = self.tick_id {
            let _ = bb.write_id(id, Value::I64(i64::try_from(self.tick).unwrap_or(i64::MAX)));
        }
        for (id, value) in self.ids.iter().zip(&self.copy) {
            let written = match value {
                PortValue::Bool(b) => bb.write_id(*id, Value::Bool(*b)),
                PortValue::I64(i) => bb.write_id(*id, Value::I64(*i)),
                PortValue::F64(x) => bb.write_id(*id, Value::F64(*x)),
                PortValue::F64s(xs) => {
                    bb.write_id(*id, Value::F64s(modbot_ipc_schema::F64s::from_slice(xs)))
                }
            };
            if let Err(e) = written {
                tracing::debug!("blackboard item not written: {e}");
            }
        }
    }
}

/// The views of the host modules of this process, by module name, for [`latest_method`] (a
/// method is a plain function: it finds its module's view by the name it serves under).
static VIEWS: Mutex<Vec<(String, SharedOutputs, f64)>> = Mutex::new(Vec::new());

/// Makes `view` the one `latest` answers from for the module `name`.
pub fn register_view(name: &str, view: SharedOutputs, base_period_s: f64) {
    let mut views = VIEWS.lock().unwrap_or_else(|p| p.into_inner());
    views.retain(|(n, _, _)| n != name);
    views.push((name.to_owned(), view, base_period_s));
}

/// `latest(item)`: the item (`tick`, `base_period_s` or `<component>.<output>`) as the serving
/// thread left it, read from its view at the moment of the call — not from the blackboard,
/// which the module's thread copies between rounds of calls. In lockstep the view is current
/// before each done notice, so a program that saw a gated grid held reads the outputs of every
/// release before the gate (see `coordinator::gate`).
pub fn latest_method<S>(
    _: &mut S,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let item = args.text(0)?;
    let views = VIEWS.lock().unwrap_or_else(|p| p.into_inner());
    let (_, view, base_period_s) = views
        .iter()
        .find(|(n, _, _)| n == ctx.name())
        .ok_or_else(|| MethodError::Failed("this module shows no grid outputs".into()))?;
    let view = lock(view);
    if item == "base_period_s" {
        reply.push(Value::F64(*base_period_s));
        return Ok(());
    }
    if item == "tick" {
        reply.push(Value::I64(i64::try_from(view.tick).unwrap_or(i64::MAX)));
        return Ok(());
    }
    let at = view
        .names
        .iter()
        .position(|n| n == item)
        .ok_or_else(|| MethodError::UnknownItem(format!("no output '{item}' here")))?;
    match &view.values[at] {
        PortValue::Bool(b) => reply.push(Value::Bool(*b)),
        PortValue::I64(i) => reply.push(Value::I64(*i)),
        PortValue::F64(x) => reply.push(Value::F64(*x)),
        PortValue::F64s(xs) => reply.push(Value::F64s(modbot_ipc_schema::F64s::from_slice(xs))),
    }
    Ok(())
}

fn lock(view: &SharedOutputs) -> std::sync::MutexGuard<'_, OutputsView> {
    view.lock().unwrap_or_else(|p| p.into_inner())
}

fn owned(value: &PortValue) -> OwnedValue {
    match value {
        PortValue::Bool(b) => OwnedValue::Bool(*b),
        PortValue::I64(i) => OwnedValue::I64(*i),
        PortValue::F64(x) => OwnedValue::F64(*x),
        PortValue::F64s(xs) => OwnedValue::F64s(xs.clone()),
    }
}
