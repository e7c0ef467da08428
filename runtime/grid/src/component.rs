//! The component model: typed ports and parameters, the FMI-style lifecycle, and the registry
//! of component types.
//!
//! A component type is two functions: one that describes it ([`ComponentInfo`]: its ports and
//! parameters, where a port's type may depend on a parameter, such as an array's length) and
//! one that makes an instance. The [`Registry`] holds them by type name, checks parameters
//! against their declarations (unknown, missing, wrongly typed), fills in the defaults, and
//! instantiates: instantiate (the registry) → [`Component::initialise`] →
//! [`Component::step`] at every release → [`Component::terminate`].
//!
//! Every component's parameters also hold two *automatic* parameters, which the grid
//! description fills in and a description may not set: [`BASE_PERIOD_S`], the base tick in
//! seconds, and [`PERIOD_S`], the component's own period in seconds. Components never read a
//! clock: their time is the tick number they are released at.
//!
//! A component type that refuses its parameters says why with a [`ParamError`] (missing, of
//! the wrong type, out of range); everything its functions return is a [`ComponentError`],
//! into which `?` turns a [`ParamError`], so `params.f64("k")?` works in all of them.

use std::fmt;

use thiserror::Error;

pub use modbot_ipc_schema::grid::{Generation, ParamType, ParamValue, PortType, PortValue, Tick};

/// The automatic parameter holding the base tick, in seconds (f64).
pub const BASE_PERIOD_S: &str = "base_period_s";
/// The automatic parameter holding the component's own period, in seconds (f64).
pub const PERIOD_S: &str = "period_s";
/// The names of the automatic parameters.
pub const AUTOMATIC_PARAMS: [&str; 2] = [BASE_PERIOD_S, PERIOD_S];

/// `text` as a string that lives as long as the process: for the names of component types a
/// description declares ([`Registry::declare`]), whose [`ComponentInfo`] holds `&'static str`
/// like every registered type's. Each distinct text is kept once, so loading a description
/// again (an assembly switch) keeps nothing more.
pub fn intern(text: &str) -> &'static str {
    static KEPT: std::sync::Mutex<Vec<&'static str>> = std::sync::Mutex::new(Vec::new());
    let mut kept = KEPT.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(&k) = kept.iter().find(|k| **k == text) {
        return k;
    }
    let k: &'static str = Box::leak(text.to_owned().into_boxed_str());
    kept.push(k);
    k
}

/// A named input or output port and its type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PortDecl {
    /// The name used in connections (`A.y`).
    pub name: &'static str,
    /// The port's type; an array's length may come from a parameter.
    pub ty: PortType,
}

impl PortDecl {
    pub const fn new(name: &'static str, ty: PortType) -> PortDecl {
        PortDecl { name, ty }
    }
}

/// A declared parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamDecl {
    pub name: &'static str,
    pub ty: ParamType,
    /// The value when the description does not set it; `None`: the parameter is required.
    pub default: Option<ParamValue>,
}

impl ParamDecl {
    /// A parameter that must be given.
    pub const fn required(name: &'static str, ty: ParamType) -> ParamDecl {
        ParamDecl {
            name,
            ty,
            default: None,
        }
    }

    /// A parameter with a default.
    pub const fn optional(name: &'static str, ty: ParamType, default: ParamValue) -> ParamDecl {
        ParamDecl {
            name,
            ty,
            default: Some(default),
        }
    }
}

/// Parameter values by name, in a fixed order (the registry puts declared ones first, in
/// declaration order, then the automatic ones).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Params(Vec<(String, ParamValue)>);

impl Params {
    pub fn new() -> Params {
        Params::default()
    }

    /// Sets `name` (replacing its value, or adding it at the end).
    pub fn set(&mut self, name: impl Into<String>, value: ParamValue) {
        let name = name.into();
        match self.0.iter_mut().find(|(n, _)| *n == name) {
            Some(slot) => slot.1 = value,
            None => self.0.push((name, value)),
        }
    }

    /// `self` with `name` set.
    pub fn with(mut self, name: impl Into<String>, value: ParamValue) -> Params {
        self.set(name, value);
        self
    }

    /// Sets the automatic parameters for a component of period `period_ticks` on a grid whose
    /// base tick is `base_period_s` seconds.
    pub fn set_timing(&mut self, base_period_s: f64, period_ticks: u64) {
        self.set(BASE_PERIOD_S, ParamValue::F64(base_period_s));
        self.set(
            PERIOD_S,
            ParamValue::F64(period_ticks as f64 * base_period_s),
        );
    }

    pub fn get(&self, name: &str) -> Option<&ParamValue> {
        self.0.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }

    pub fn iter(&self) -> impl Iterator<Item = (&str, &ParamValue)> {
        self.0.iter().map(|(n, v)| (n.as_str(), v))
    }

    pub fn len(&self) -> usize {
        self.0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    fn typed<'a, T>(
        &'a self,
        name: &str,
        ty: ParamType,
        pick: impl FnOnce(&'a ParamValue) -> Option<T>,
    ) -> Result<T, ParamError> {
        match self.get(name) {
            None => Err(ParamError::Missing { name: name.into() }),
            Some(v) => pick(v).ok_or_else(|| ParamError::WrongType {
                name: name.into(),
                expected: ty,
                got: v.clone(),
            }),
        }
    }

    pub fn f64(&self, name: &str) -> Result<f64, ParamError> {
        self.typed(name, ParamType::F64, |v| match v {
            ParamValue::F64(x) => Some(*x),
            _ => None,
        })
    }

    pub fn i64(&self, name: &str) -> Result<i64, ParamError> {
        self.typed(name, ParamType::I64, |v| match v {
            ParamValue::I64(i) => Some(*i),
            _ => None,
        })
    }

    pub fn bool(&self, name: &str) -> Result<bool, ParamError> {
        self.typed(name, ParamType::Bool, |v| match v {
            ParamValue::Bool(b) => Some(*b),
            _ => None,
        })
    }

    pub fn f64s(&self, name: &str) -> Result<&[f64], ParamError> {
        self.typed(name, ParamType::F64s, |v| match v {
            ParamValue::F64s(xs) => Some(xs.as_slice()),
            _ => None,
        })
    }

    pub fn text(&self, name: &str) -> Result<&str, ParamError> {
        self.typed(name, ParamType::Text, |v| match v {
            ParamValue::Text(s) => Some(s.as_str()),
            _ => None,
        })
    }
}

impl FromIterator<(String, ParamValue)> for Params {
    fn from_iter<I: IntoIterator<Item = (String, ParamValue)>>(iter: I) -> Params {
        let mut params = Params::new();
        for (name, value) in iter {
            params.set(name, value);
        }
        params
    }
}

/// What a component type is: its ports and parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentInfo {
    /// The name descriptions use (`type = "gain"`).
    pub type_name: &'static str,
    /// One sentence on what it computes, for `modbot check` and error messages.
    pub doc: &'static str,
    /// Inputs in port order (the order of `step`'s `inputs`).
    pub inputs: Vec<PortDecl>,
    /// Outputs in port order (the order of `step`'s `outputs` and of the output record).
    pub outputs: Vec<PortDecl>,
    /// The parameters a description may set (the automatic ones are not listed).
    pub params: Vec<ParamDecl>,
}

impl ComponentInfo {
    pub fn input(&self, name: &str) -> Option<usize> {
        self.inputs.iter().position(|p| p.name == name)
    }

    pub fn output(&self, name: &str) -> Option<usize> {
        self.outputs.iter().position(|p| p.name == name)
    }

    pub fn input_types(&self) -> Vec<PortType> {
        self.inputs.iter().map(|p| p.ty).collect()
    }

    pub fn output_types(&self) -> Vec<PortType> {
        self.outputs.iter().map(|p| p.ty).collect()
    }

    /// The zero value of every output: what the outputs are before the first release's
    /// results become valid.
    pub fn zero_outputs(&self) -> Vec<PortValue> {
        self.outputs.iter().map(|p| p.ty.zero()).collect()
    }

    /// The zero value of every input: a buffer to gather inputs into without allocating.
    pub fn zero_inputs(&self) -> Vec<PortValue> {
        self.inputs.iter().map(|p| p.ty.zero()).collect()
    }
}

/// A release as the component it steps sees it: the tick, and what the release says beside.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Released {
    /// The tick the component is released at.
    pub tick: Tick,
    /// The assembly generation of the release (0 in a grid without assemblies).
    pub generation: Generation,
    /// The release's flags (`modbot_ipc_schema::grid::Release::SAFE_STOP`: the running
    /// assembly faulted; `TRACK`: the component tracks).
    pub flags: u16,
    /// The host's clock when it took the release, ns of CLOCK_MONOTONIC (the reference run:
    /// the tick's nominal time): for a component that drives hardware with a watchdog.
    pub now_ns: u64,
    /// The grid's state hash at the release tick (over the versions valid then; see
    /// [`crate::state_hash`]): what the recorder writes beside the tick's values.
    pub state_hash: u64,
}

impl Released {
    /// Whether the component is released to track because the robot is held under its
    /// assembly (a safe stop, a drive fault, a reset under way), not because its assembly is
    /// being prepared (flag `HELD`).
    pub fn held(&self) -> bool {
        self.flags & modbot_ipc_schema::grid::Release::HELD != 0
    }

    /// A release at `tick` and nothing more (generation 0, no flags, the clock at 0).
    pub fn at(tick: u64) -> Released {
        Released {
            tick: Tick(tick),
            ..Released::default()
        }
    }
}

/// A component instance, with the FMI-style lifecycle: instantiate (the [`Registry`]) →
/// initialise → step(tick)… → terminate.
pub trait Component: Send {
    /// Called once after instantiation with the complete parameters (defaults and automatic
    /// ones filled in). An error refuses the instance.
    fn initialise(&mut self, params: &Params) -> Result<(), ComponentError> {
        let _ = params;
        Ok(())
    }

    /// Called once after [`Component::initialise`], before any release: writes the outputs
    /// valid until its first release's are (`outputs` hold the declared types, as zeros) —
    /// its *initial outputs*: a declared start value, an FMU's outputs after initialisation.
    /// By default they stay zeros. Not on the real-time path.
    fn initial_outputs(&mut self, outputs: &mut [PortValue]) {
        let _ = outputs;
    }

    /// Released at `rel.tick`: `inputs` are the values valid then (in input port order, of
    /// the declared types); write every output (`outputs` hold the declared types, arrays at
    /// their lengths). Runs in the real-time path: must not allocate, block or read a clock
    /// (the host's is `rel.now_ns`), and gets everything else it needs in `at`.
    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]);

    /// Released while its assembly is being prepared: nothing obeys the outputs yet, and the
    /// component should follow the current state so that it takes over without a jump
    /// (bumpless: a trajectory generator rests where the robot is commanded to be). The same
    /// rules as [`Component::step`]; by default it is a step.
    fn track(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        self.step(rel, inputs, outputs);
    }

    /// Whether the component reports an unsafe state after its last step (a monitor's
    /// breach): the coordinator then faults its assembly and the bus stops the drives.
    fn unsafe_state(&self) -> bool {
        false
    }

    /// Whether the component holds the robot after its last step: the drives it owns are
    /// stopped, faulted or being brought back, and do not follow the running assembly (the
    /// bus, see `modbot_bus::bridge`). The coordinator then releases the running assembly's
    /// components to [`Component::track`] (flags `TRACK | HELD`) until it no longer does, so
    /// that they take over from where the robot is when it follows again.
    fn holding(&self) -> bool {
        false
    }

    /// Writes the hash of its state after its last step (or track), which the grid folds into
    /// the tick's hash (`# state_hash` in traces, dataset `state_hash` in recordings) so that
    /// two runs compare in one line: by default its outputs. A component with state its
    /// outputs do not show (a delay line's buffer) adds it; one whose outputs do not belong to
    /// the controlled system (the recorder) writes nothing and contributes no hash. Real-time
    /// path: no allocation, and nothing that differs run to run by design (a clock, a count
    /// of dropped rows).
    fn state_hash(&self, outputs: &[PortValue], hasher: &mut crate::StateHasher) {
        hasher.outputs(outputs);
    }

    /// Visits every field its steps depend on beyond its parameters, in one order, for
    /// [`crate::carry::Carry`] to measure, save or load: another instance of the type,
    /// initialised with the same parameters and loaded, steps on bit for bit as this one would
    /// have (a live upgrade of its host). By default the type cannot.
    fn carry(&mut self, c: &mut crate::carry::Carry<'_>) -> Result<(), crate::carry::CarryError> {
        let _ = c;
        Err(crate::carry::CarryError::Unsupported)
    }

    /// The grid stops (a normal stop: `modbot down`, its ticks done): no release follows.
    /// The bus quick-stops its drives here without taking the silence for a lost coordinator.
    fn stopping(&mut self) {}

    /// Called once when the instance is no longer stepped.
    fn terminate(&mut self) {}
}

/// Carries `from`'s state into `to`, another instance of its type initialised with the same
/// parameters ([`Component::carry`]: measured, saved, loaded, every byte taken); the state's
/// size.
pub fn carry_state(
    from: &mut dyn Component,
    to: &mut dyn Component,
) -> Result<usize, crate::carry::CarryError> {
    use crate::carry::Carry;
    let mut measure = Carry::measure();
    from.carry(&mut measure)?;
    let mut buf = vec![0; measure.len()];
    from.carry(&mut Carry::save(&mut buf))?;
    let mut load = Carry::load(&buf);
    to.carry(&mut load)?;
    load.finish()?;
    Ok(buf.len())
}

/// A component type a system description declares (`component_type`): its interface, and
/// the host program that makes it.
#[derive(Debug, Clone, PartialEq)]
pub struct DeclaredType {
    pub info: ComponentInfo,
    pub program: String,
    /// The line of its declaration.
    pub line: u32,
}

/// A declared component type differs from the one the process registered itself.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("component type '{type_name}' of program '{program}': {mismatch}")]
pub struct DeclaredTypeError {
    pub type_name: String,
    pub program: String,
    pub line: u32,
    #[source]
    pub mismatch: InterfaceMismatch,
}

/// What differs between a type's declared interface and its registered one: its `inputs`,
/// `outputs` or `params`, each written `name:type, ...`.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("its {what} are declared as [{declared}], the program registers [{registered}]")]
pub struct InterfaceMismatch {
    pub what: &'static str,
    pub declared: String,
    pub registered: String,
}

/// Describes a component type for the given (complete) parameters.
pub type InfoFn = fn(&Params) -> Result<ComponentInfo, ComponentError>;
/// Makes an instance for the given (complete) parameters.
pub type MakeFn = fn(&Params) -> Result<Box<dyn Component>, ComponentError>;
/// Makes an instance with what it was given when registered (see [`Registry::register_with`]).
type Maker =
    std::sync::Arc<dyn Fn(&Params) -> Result<Box<dyn Component>, ComponentError> + Send + Sync>;
/// Describes a type: a registered function, or what a description declared.
type Describer =
    std::sync::Arc<dyn Fn(&Params) -> Result<ComponentInfo, ComponentError> + Send + Sync>;

#[derive(Clone)]
struct Entry {
    /// What the type says about itself without parameters: its name and parameter list.
    probe: ComponentInfo,
    info: Describer,
    make: Maker,
    /// For a type a description declares ([`Registry::declare`]): the host program that
    /// makes it. `None`: this process makes it.
    program: Option<String>,
    /// Whether it takes parameters it does not list without parameters (an FMU's are its
    /// model's): [`Registry::complete`] passes them on, and its `info` checks them.
    open: bool,
}

/// The component types a system can use, by name.
#[derive(Default, Clone)]
pub struct Registry {
    entries: Vec<Entry>,
}

impl fmt::Debug for Registry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.type_names()).finish()
    }
}

impl Registry {
    /// An empty registry.
    pub fn new() -> Registry {
        Registry::default()
    }

    /// Adds a component type (replacing one of the same name).
    ///
    /// `info_fn` is first called with empty [`Params`] to learn the type's name and its
    /// parameters; a port type that depends on a parameter may then be a placeholder. Later
    /// it is only called with complete, checked parameters.
    ///
    /// # Panics
    /// If `info_fn` fails with empty parameters: that is a bug in the component type.
    pub fn register(&mut self, info_fn: InfoFn, make: MakeFn) {
        self.register_with(info_fn, make);
    }

    /// Adds a component type whose instances are made by a closure: for a type that needs
    /// something of the process that registers it (the bus bridge's drives, say), handed in
    /// here rather than reached through a global. Otherwise as [`Registry::register`].
    pub fn register_with(
        &mut self,
        info_fn: InfoFn,
        make: impl Fn(&Params) -> Result<Box<dyn Component>, ComponentError> + Send + Sync + 'static,
    ) {
        let make: Maker = std::sync::Arc::new(make);
        let probe = probe(info_fn);
        let entry = Entry {
            probe,
            info: std::sync::Arc::new(info_fn),
            make,
            program: None,
            open: false,
        };
        self.insert(entry);
    }

    /// Adds a type that a host program of its own makes (a system description's
    /// `component_type`): `info` is its interface as declared, the same whatever the
    /// parameters (the declared defaults filled in); this process can describe and check it,
    /// not make it. A type this process registered itself is kept (see
    /// [`Registry::agrees_with`]).
    pub fn declare(&mut self, info: ComponentInfo, program: &str) {
        if self
            .entry(info.type_name)
            .is_ok_and(|e| e.program.is_none())
        {
            return;
        }
        let (type_name, made_by) = (info.type_name, program.to_owned());
        let declared = info.clone();
        self.insert(Entry {
            probe: info,
            info: std::sync::Arc::new(move |_| Ok(declared.clone())),
            make: std::sync::Arc::new(move |_| {
                Err(ComponentError::MadeElsewhere {
                    type_name: type_name.to_owned(),
                    program: made_by.clone(),
                })
            }),
            program: Some(program.to_owned()),
            open: false,
        });
    }

    /// Adds a type that the host program `program` makes, described by `info_fn` (whose ports
    /// may depend on the parameters, as a registered type's): the types the runtime knows and
    /// a program of its own makes (the data recorder, FMUs). A type this process registered
    /// itself is kept.
    ///
    /// # Panics
    /// If `info_fn` fails with empty parameters (see [`Registry::register`]).
    pub fn declare_with(&mut self, info_fn: InfoFn, program: &str) {
        self.declare_entry(info_fn, program, false);
    }

    /// Like [`Registry::declare_with`], for a type whose parameters depend on what a
    /// parameter names (an FMU's are its model's): [`Registry::complete`] passes parameters it
    /// does not list on, and `info_fn` checks them.
    pub fn declare_open(&mut self, info_fn: InfoFn, program: &str) {
        self.declare_entry(info_fn, program, true);
    }

    /// Like [`Registry::register`], for a type whose parameters depend on what a parameter
    /// names (see [`Registry::declare_open`]).
    pub fn register_open(&mut self, info_fn: InfoFn, make: MakeFn) {
        self.register(info_fn, make);
        if let Some(e) = self
            .entries
            .iter_mut()
            .find(|e| e.probe.type_name == probe(info_fn).type_name)
        {
            e.open = true;
        }
    }

    fn declare_entry(&mut self, info_fn: InfoFn, program: &str, open: bool) {
        let probe = probe(info_fn);
        if self
            .entry(probe.type_name)
            .is_ok_and(|e| e.program.is_none())
        {
            return;
        }
        let (type_name, made_by) = (probe.type_name, program.to_owned());
        self.insert(Entry {
            probe,
            info: std::sync::Arc::new(info_fn),
            make: std::sync::Arc::new(move |_| {
                Err(ComponentError::MadeElsewhere {
                    type_name: type_name.to_owned(),
                    program: made_by.clone(),
                })
            }),
            program: Some(program.to_owned()),
            open,
        });
    }

    /// This registry with the types a description declares: each is [declared](Self::declare),
    /// or, if this process registered it itself, checked against what it registered.
    pub fn with_declared(&self, types: &[DeclaredType]) -> Result<Registry, DeclaredTypeError> {
        let mut registry = self.clone();
        for t in types {
            let native = self
                .entry(t.info.type_name)
                .is_ok_and(|e| e.program.is_none());
            if native {
                if let Err(mismatch) = self.agrees_with(&t.info) {
                    return Err(DeclaredTypeError {
                        type_name: t.info.type_name.to_owned(),
                        program: t.program.clone(),
                        line: t.line,
                        mismatch,
                    });
                }
            } else {
                registry.declare(t.info.clone(), &t.program);
            }
        }
        Ok(registry)
    }

    /// The host program that makes `type_name`, if a description declared it (`None`: this
    /// process makes it, or it is unknown).
    pub fn program_of(&self, type_name: &str) -> Option<&str> {
        self.entry(type_name).ok()?.program.as_deref()
    }

    /// Whether `declared`, the interface a description declares for a type this process
    /// registered itself, is the registered one: the same ports (names and types, in order)
    /// and parameters (names and types). `Err` says what differs.
    pub fn agrees_with(&self, declared: &ComponentInfo) -> Result<(), InterfaceMismatch> {
        let Ok(own) = self.entry(declared.type_name) else {
            return Ok(());
        };
        let own = &own.probe;
        let ports = |ps: &[PortDecl]| {
            ps.iter()
                .map(|p| format!("{}:{}", p.name, p.ty))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let params = |ps: &[ParamDecl]| {
            let mut all: Vec<String> = ps.iter().map(|p| format!("{}:{}", p.name, p.ty)).collect();
            all.sort();
            all.join(", ")
        };
        for (what, mine, theirs) in [
            ("inputs", ports(&own.inputs), ports(&declared.inputs)),
            ("outputs", ports(&own.outputs), ports(&declared.outputs)),
            ("params", params(&own.params), params(&declared.params)),
        ] {
            if mine != theirs {
                return Err(InterfaceMismatch {
                    what,
                    declared: theirs,
                    registered: mine,
                });
            }
        }
        Ok(())
    }

    fn insert(&mut self, entry: Entry) {
        match self
            .entries
            .iter_mut()
            .find(|e| e.probe.type_name == entry.probe.type_name)
        {
            Some(slot) => *slot = entry,
            None => self.entries.push(entry),
        }
    }

    /// The registered type names, in registration order.
    pub fn type_names(&self) -> Vec<&'static str> {
        self.entries.iter().map(|e| e.probe.type_name).collect()
    }

    /// What `type_name` declares without parameters (its parameter list, its doc).
    pub fn describe(&self, type_name: &str) -> Option<&ComponentInfo> {
        self.entry(type_name).ok().map(|e| &e.probe)
    }

    /// `params` checked against `type_name`'s declarations and completed: declared parameters
    /// in declaration order (defaults filled in, integers made f64 where f64 is declared),
    /// then the automatic parameters that were given.
    pub fn complete(&self, type_name: &str, params: &Params) -> Result<Params, ComponentError> {
        let entry = self.entry(type_name)?;
        let decls = &entry.probe.params;
        let mut complete = Params::new();
        for (name, value) in params.iter() {
            let ty = if AUTOMATIC_PARAMS.contains(&name) {
                ParamType::F64
            } else {
                match decls.iter().find(|d| d.name == name) {
                    Some(d) => d.ty,
                    None if entry.open => {
                        complete.set(name, value.clone());
                        continue;
                    }
                    None => {
                        return Err(ParamError::Unknown {
                            name: name.into(),
                            type_name: type_name.into(),
                            known: decls.iter().map(|d| d.name).collect(),
                        }
                        .into())
                    }
                }
            };
            if value.coerce(ty).is_none() {
                return Err(ParamError::WrongType {
                    name: name.into(),
                    expected: ty,
                    got: value.clone(),
                }
                .into());
            }
        }
        for d in decls {
            let value = match (params.get(d.name), &d.default) {
                (Some(v), _) => v.coerce(d.ty),
                (None, Some(default)) => Some(default.clone()),
                (None, None) => {
                    return Err(ParamError::Required {
                        name: d.name,
                        ty: d.ty,
                        type_name: type_name.into(),
                    }
                    .into())
                }
            };
            if let Some(value) = value {
                complete.set(d.name, value);
            }
        }
        for name in AUTOMATIC_PARAMS {
            if let Some(value) = params.get(name).and_then(|v| v.coerce(ParamType::F64)) {
                complete.set(name, value);
            }
        }
        Ok(complete)
    }

    /// The ports and parameters of `type_name` with these parameters (checked and completed
    /// first: an error says what is wrong with them).
    pub fn info(&self, type_name: &str, params: &Params) -> Result<ComponentInfo, ComponentError> {
        let params = self.complete(type_name, params)?;
        (self.entry(type_name)?.info)(&params)
    }

    /// A new instance of `type_name`, initialised with the completed `params`.
    pub fn instantiate(
        &self,
        type_name: &str,
        params: &Params,
    ) -> Result<Box<dyn Component>, ComponentError> {
        let params = self.complete(type_name, params)?;
        let entry = self.entry(type_name)?;
        (entry.info)(&params)?;
        let mut component = (entry.make)(&params)?;
        component.initialise(&params)?;
        Ok(component)
    }

    fn entry(&self, type_name: &str) -> Result<&Entry, ComponentError> {
        self.entries
            .iter()
            .find(|e| e.probe.type_name == type_name)
            .ok_or_else(|| ComponentError::UnknownType {
                type_name: type_name.into(),
                known: self.type_names(),
            })
    }
}

/// Why a parameter is refused: which one, and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ParamError {
    /// A component read a parameter its parameters do not hold.
    #[error("param '{name}' is missing")]
    Missing { name: String },
    /// The value is not of the type the parameter is declared (or read) with.
    #[error("param '{name}' must be {expected}, not {got}")]
    WrongType {
        name: String,
        expected: ParamType,
        got: ParamValue,
    },
    /// The value is of the right type but not one the component takes; `why` says what it
    /// must be ("must be from 1 to 64, not 0").
    #[error("param '{name}' {why}")]
    Invalid { name: String, why: String },
    /// The description sets a parameter the component type does not declare.
    #[error("unknown param '{name}' for type '{type_name}' (params: {})", list_or_none(.known))]
    Unknown {
        name: String,
        type_name: String,
        /// The parameters the type declares.
        known: Vec<&'static str>,
    },
    /// A parameter without a default is not given.
    #[error("param '{name}' ({ty}) is required for type '{type_name}'")]
    Required {
        name: &'static str,
        ty: ParamType,
        type_name: String,
    },
}

impl ParamError {
    /// Param `name` is refused: it `why` ("must be positive, not -1").
    pub fn invalid(name: impl Into<String>, why: impl Into<String>) -> ParamError {
        ParamError::Invalid {
            name: name.into(),
            why: why.into(),
        }
    }
}

/// Why a component type cannot be described or instantiated with some parameters: what its
/// [`InfoFn`], [`MakeFn`] and [`Component::initialise`] return.
#[derive(Debug, Error)]
pub enum ComponentError {
    /// A parameter is missing, of the wrong type or out of range.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// A parameter's value is refused by what it sets up (a filter its cutoff, say), which
    /// says why.
    #[error("param '{name}': {source}")]
    ParamRefused {
        name: String,
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// No component type of this name is registered.
    #[error("unknown component type '{type_name}' (known: {})", .known.join(", "))]
    UnknownType {
        type_name: String,
        known: Vec<&'static str>,
    },
    /// The type is declared by the description and made by a host program of its own: this
    /// process cannot make it.
    #[error("component type '{type_name}' is made by the program '{program}', not by this one (give its components a host of their own, which that program runs)")]
    MadeElsewhere { type_name: String, program: String },
    /// Anything else a component type refuses for (a device that cannot be opened, say): for
    /// component types outside this crate, with their own errors.
    #[error(transparent)]
    Other(Box<dyn std::error::Error + Send + Sync>),
}

impl ComponentError {
    /// Param `name` is refused by what it sets up, for `source`.
    pub fn param_refused(
        name: impl Into<String>,
        source: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> ComponentError {
        ComponentError::ParamRefused {
            name: name.into(),
            source: source.into(),
        }
    }

    /// Any other refusal: an error of the component type's own, or a message.
    pub fn other(source: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> ComponentError {
        ComponentError::Other(source.into())
    }
}

/// What `info_fn` says without parameters: the type's name and parameter list.
///
/// # Panics
/// If it fails: that is a bug in the component type.
fn probe(info_fn: InfoFn) -> ComponentInfo {
    match info_fn(&Params::new()) {
        Ok(probe) => probe,
        Err(e) => panic!("a component type must describe itself without parameters: {e}"),
    }
}

/// `a, b, c`, or `none` for an empty list.
pub(crate) fn list_or_none(names: &[&str]) -> String {
    if names.is_empty() {
        "none".to_owned()
    } else {
        names.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A type whose parameter is checked when an instance is initialised.
    struct Checked;

    impl Component for Checked {
        fn initialise(&mut self, params: &Params) -> Result<(), ComponentError> {
            let k = params.f64("k")?;
            if k < 0.0 {
                return Err(ParamError::invalid("k", format!("must be 0 or more, not {k}")).into());
            }
            if k > 1.0 {
                let io = std::io::Error::other("the device is busy");
                return Err(ComponentError::other(io));
            }
            Ok(())
        }

        fn step(&mut self, _: &Released, _: &[PortValue], _: &mut [PortValue]) {}
    }

    fn checked_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
        Ok(ComponentInfo {
            type_name: "checked",
            doc: "refuses k < 0 when initialised",
            inputs: vec![],
            outputs: vec![],
            params: vec![ParamDecl::required("k", ParamType::F64)],
        })
    }

    #[test]
    fn initialise_refuses_with_the_params_own_error_and_keeps_other_errors() {
        let mut registry = Registry::new();
        registry.register(checked_info, |_| Ok(Box::new(Checked)));
        let k = |k: f64| Params::new().with("k", ParamValue::F64(k));
        assert!(registry.instantiate("checked", &k(0.5)).is_ok());
        let Err(sut) = registry.instantiate("checked", &k(-1.0)) else {
            panic!("k = -1 was accepted");
        };
        assert!(
            matches!(&sut, ComponentError::Param(ParamError::Invalid { name, .. }) if name == "k"),
            "{sut:?}"
        );
        assert_eq!(sut.to_string(), "param 'k' must be 0 or more, not -1");
        let Err(sut) = registry.instantiate("checked", &k(2.0)) else {
            panic!("k = 2 was accepted");
        };
        let ComponentError::Other(inner) = &sut else {
            panic!("{sut:?}");
        };
        assert!(inner.downcast_ref::<std::io::Error>().is_some(), "{sut:?}");
        assert_eq!(sut.to_string(), "the device is busy");
    }
}
