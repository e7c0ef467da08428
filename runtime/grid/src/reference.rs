//! The reference run: the logical execution time (LET) semantics of a grid, computed in one
//! thread, with no clock and no IPC. The coordinator and the component hosts must produce
//! exactly these values, bit for bit, however the processes are scheduled.
//!
//! # Semantics
//! The base tick is n = 0, 1, 2, …. A component of period k is released at every n with
//! n % k == 0. Released at n, it reads for each input the output of its source that is valid
//! at n, and its own outputs become valid at n + k, never earlier. Before its first outputs
//! become valid (n < k), a component's outputs are its *initial outputs*
//! ([`Component::initial_outputs`]: a declared start value, an FMU's outputs after
//! initialisation; the zero values of their types unless it says otherwise). So at tick
//! n the valid outputs of X are those computed by X's release at the largest m with
//! m + k_X ≤ n, or X's initial outputs if there is none.
//!
//! Within a tick the order of the releases does not matter: a release at n writes outputs
//! valid from n + k > n, which no release at n can read. The run keeps two output buffers per
//! component (valid now, and pending until n + k) so that this holds by construction; a test
//! checks it by releasing in reverse order.

use thiserror::Error;

use super::component::{Component, ComponentError, PortValue, Registry, Released, Tick};
use super::spec::GridSpec;
use super::state_hash::{self, StateHasher};
use super::trace::TraceWriter;

/// Why the reference run could not be made.
#[derive(Debug, Error)]
pub enum ReferenceError {
    /// A component cannot be instantiated.
    #[error("component '{component}': {error}")]
    Instantiate {
        component: String,
        #[source]
        error: ComponentError,
    },
    /// An input has no connection (never in a spec from [`GridSpec::build`]).
    #[error("component '{component}': input {input} is not connected")]
    Unconnected { component: String, input: usize },
    /// The trace could not be written.
    #[error("the reference trace: {0}")]
    Trace(#[from] std::io::Error),
}

/// Why a trace's overrun and stale lines cannot be read ([`Overruns::from_trace`]).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum OverrunsError {
    #[error("'{line}' has no {key}")]
    NoField { line: String, key: &'static str },
    #[error("bad {key} in '{line}'")]
    BadNumber { line: String, key: &'static str },
    #[error("unknown component in '{line}'")]
    UnknownComponent { line: String },
}

/// Runs `spec` for `ticks` base ticks. For n in 0..ticks, in that order: calls
/// `sink(n, c, outputs valid at n)` for every component c in index order, then releases the
/// components due at n with the inputs valid at n. Fails if a component cannot be
/// instantiated (its error, naming the component).
pub fn reference_run(
    spec: &GridSpec,
    registry: &Registry,
    ticks: u64,
    sink: &mut dyn FnMut(u64, usize, &[PortValue]),
) -> Result<(), ReferenceError> {
    run(
        spec,
        registry,
        ticks,
        Order::Forward,
        &Overruns::default(),
        sink,
    )
}

/// Overruns to replay: what the hold policy did in a real run, as its trace records them
/// (`# overrun tick=T component=C release=M`, `# stale tick=M component=C`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Overruns {
    /// (component, release tick) of releases that finished late: the component stepped (its
    /// state moved on) but its outputs never became valid.
    pub late: std::collections::BTreeSet<(usize, u64)>,
    /// (component, tick) of due ticks at which it was not released (still running) or its
    /// release was not executed (stale).
    pub skipped: std::collections::BTreeSet<(usize, u64)>,
}

impl Overruns {
    /// Reads the overrun and stale lines of a trace of `spec`: `# overrun tick=T
    /// component=C release=M` (release M finished late, and C was not released at T) and
    /// `# stale tick=M component=C` (release M was not executed: an input's version was gone).
    pub fn from_trace(spec: &GridSpec, trace: &str) -> Result<Overruns, OverrunsError> {
        let mut out = Overruns::default();
        for line in trace.lines() {
            let overrun = line.starts_with("# overrun ");
            if !overrun && !line.starts_with("# stale ") {
                continue;
            }
            let field = |key: &'static str| {
                line.split_whitespace()
                    .find_map(|w| w.strip_prefix(key))
                    .ok_or_else(|| OverrunsError::NoField {
                        line: line.to_owned(),
                        key,
                    })
            };
            let number = |key: &'static str| -> Result<u64, OverrunsError> {
                field(key)?.parse().map_err(|_| OverrunsError::BadNumber {
                    line: line.to_owned(),
                    key,
                })
            };
            let name = field("component=")?;
            let c = spec
                .components
                .iter()
                .position(|x| x.name == name)
                .ok_or_else(|| OverrunsError::UnknownComponent {
                    line: line.to_owned(),
                })?;
            let tick = number("tick=")?;
            if overrun {
                out.late.insert((c, number("release=")?));
            }
            out.skipped.insert((c, tick));
        }
        Ok(out)
    }
}

/// The trace of the reference run with the overruns of a real run replayed, to compare with
/// that run's trace (its `#` lines other than the header left out).
pub fn reference_trace_with(
    spec: &GridSpec,
    registry: &Registry,
    ticks: u64,
    overruns: &Overruns,
) -> Result<String, ReferenceError> {
    let writer = std::cell::RefCell::new(TraceWriter::new(Vec::new(), spec));
    let mut failure = None;
    let mut hash_failure = None;
    run_hashed(
        spec,
        registry,
        ticks,
        Order::Forward,
        overruns,
        &mut |n, c, outputs| {
            if let Err(e) = writer.borrow_mut().tick(n, c, outputs) {
                failure.get_or_insert(e);
            }
        },
        &mut |n, hash| {
            if let Err(e) = writer.borrow_mut().state_hash(n, hash) {
                hash_failure.get_or_insert(e);
            }
        },
    )?;
    if let Some(e) = failure.or(hash_failure) {
        return Err(e.into());
    }
    let bytes = writer.into_inner().finish()?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

/// The trace ([`super::trace`]) of the reference run of `spec` for `ticks` ticks.
///
/// # Panics
/// If a component cannot be instantiated (use [`reference_run`] to get the error instead).
pub fn reference_trace(spec: &GridSpec, registry: &Registry, ticks: u64) -> String {
    // Writing to a Vec only fails on a bad component index or output count, which the run
    // never passes.
    match reference_trace_with(spec, registry, ticks, &Overruns::default()) {
        Ok(trace) => trace,
        Err(e) => panic!("reference run: {e}"),
    }
}

/// The order in which the components due at a tick are stepped: under LET it does not
/// matter, which [`run`] lets a test show.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    Forward,
    Reverse,
}

/// One component's state in the run.
struct Slot {
    component: Box<dyn Component>,
    period: u64,
    /// The outputs valid now.
    valid: Vec<PortValue>,
    /// The outputs of the last release, valid from `pending_from`.
    pending: Vec<PortValue>,
    pending_from: Option<u64>,
    /// The state hash of the valid outputs' release (none for the initial outputs) and of the
    /// pending one's.
    valid_hash: Option<u64>,
    pending_hash: Option<u64>,
    /// The inputs of a release, gathered here (no allocation per release).
    inputs: Vec<PortValue>,
    /// For each input: the (component, output port) feeding it.
    bindings: Vec<(usize, usize)>,
}

/// Runs `spec` for `ticks` base ticks in one thread, stepping the components due at a tick
/// in `order` and replaying `overruns`; `sink(tick, component, outputs)` sees every release's
/// outputs. [`reference_run`] is this in the forward order.
pub fn run(
    spec: &GridSpec,
    registry: &Registry,
    ticks: u64,
    order: Order,
    overruns: &Overruns,
    sink: &mut dyn FnMut(u64, usize, &[PortValue]),
) -> Result<(), ReferenceError> {
    run_hashed(spec, registry, ticks, order, overruns, sink, &mut |_, _| {})
}

/// [`run`], also giving `on_hash(n, hash)` the grid's state hash at every tick n after the
/// outputs valid at n (see [`crate::state_hash`]): the components' hashes of the versions
/// valid at n, combined in component order, as the coordinator combines them.
pub fn run_hashed(
    spec: &GridSpec,
    registry: &Registry,
    ticks: u64,
    order: Order,
    overruns: &Overruns,
    sink: &mut dyn FnMut(u64, usize, &[PortValue]),
    on_hash: &mut dyn FnMut(u64, u64),
) -> Result<(), ReferenceError> {
    let base_ns = u64::try_from(spec.base_period.as_nanos()).unwrap_or(u64::MAX);
    let mut slots = Vec::with_capacity(spec.components.len());
    for (index, c) in spec.components.iter().enumerate() {
        let mut component = registry
            .instantiate(&c.type_name, &c.params)
            .map_err(|error| ReferenceError::Instantiate {
                component: c.name.clone(),
                error,
            })?;
        let bindings = (0..c.info.inputs.len())
            .map(|input| {
                spec.source_of(index, input)
                    .map(|p| (p.component, p.port))
                    .ok_or_else(|| ReferenceError::Unconnected {
                        component: c.name.clone(),
                        input,
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut initial = c.info.zero_outputs();
        component.initial_outputs(&mut initial);
        slots.push(Slot {
            component,
            period: c.period.max(1),
            valid: initial.clone(),
            pending: initial,
            pending_from: None,
            valid_hash: None,
            pending_hash: None,
            inputs: c.info.zero_inputs(),
            bindings,
        });
    }
    let count = slots.len();
    for n in 0..ticks {
        for (c, slot) in slots.iter_mut().enumerate() {
            if slot.pending_from == Some(n) {
                std::mem::swap(&mut slot.valid, &mut slot.pending);
                slot.pending_from = None;
                slot.valid_hash = slot.pending_hash.take();
            }
            sink(n, c, &slot.valid);
        }
        let tick_hash = state_hash::combine(
            slots
                .iter()
                .enumerate()
                .filter_map(|(c, slot)| Some((c, slot.valid_hash?))),
        );
        on_hash(n, tick_hash);
        for i in 0..count {
            let c = match order {
                Order::Forward => i,
                Order::Reverse => count - 1 - i,
            };
            if n % slots[c].period != 0 || overruns.skipped.contains(&(c, n)) {
                continue;
            }
            // Gather from the valid outputs: a release at n only writes `pending`.
            let mut inputs = std::mem::take(&mut slots[c].inputs);
            for (value, &(src, port)) in inputs.iter_mut().zip(&slots[c].bindings) {
                value.assign(&slots[src].valid[port]);
            }
            let slot = &mut slots[c];
            let rel = Released {
                tick: Tick(n),
                generation: spec.generation_of(c),
                flags: 0,
                now_ns: n.saturating_mul(base_ns),
                state_hash: tick_hash,
            };
            slot.component.step(&rel, &inputs, &mut slot.pending);
            slot.inputs = inputs;
            let mut hasher = StateHasher::new();
            slot.component.state_hash(&slot.pending, &mut hasher);
            (slot.pending_from, slot.pending_hash) = if overruns.late.contains(&(c, n)) {
                (None, None) // finished too late: the outputs never became valid
            } else {
                (Some(n + slot.period), hasher.finish())
            };
        }
    }
    for slot in &mut slots {
        slot.component.terminate();
    }
    Ok(())
}
