//! `modbot replay FILE.h5 [--until TICK] [--param COMP.NAME=VALUE]... [--out WHATIF.h5]`: a
//! replayable recording's controllers run again in this process, against what the bus really
//! did: the grids of every generation as they ran (from the recording), the switches, holds,
//! faults and overruns as the coordinator logged them, the bus played back from its recorded
//! outputs, and what the recorder got compared row by row, bit for bit, with what it recorded.
//! Exit 0: identical; 1: it differs (the first tick, the signals and the component that fed
//! them); 2: it cannot be replayed (why).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};

use modbot_grid::component::{Component, ComponentError, ParamType, ParamValue, Registry};
use modbot_grid::record_type;
use modbot_grid::replay::{self, Make, Schedule};
use modbot_grid::GridSpec;
use modbot_record::replay::{Comparer, Player, Recording, Verdict};
use modbot_record::replay_file;

/// What `modbot replay` is asked.
pub struct ReplayArgs {
    pub file: PathBuf,
    pub until: Option<u64>,
    /// `comp.name=value`.
    pub params: Vec<String>,
    pub out: Option<PathBuf>,
}

pub fn run(args: &ReplayArgs) -> anyhow::Result<ExitCode> {
    match replay(args) {
        Ok(code) => Ok(code),
        Err(e) => {
            eprintln!("modbot replay: {e:#}");
            Ok(ExitCode::from(2))
        }
    }
}

fn replay(args: &ReplayArgs) -> anyhow::Result<ExitCode> {
    let file = &args.file;
    let Some(info) = replay_file::read(file)? else {
        anyhow::bail!(
            "{}: not replayable (record it with modbot up --record FILE --replayable, or \
             record {{ replay = true }})",
            file.display()
        );
    };
    let mut specs = info
        .specs
        .iter()
        .map(|(g, image)| {
            GridSpec::from_image(image)
                .map_err(|e| anyhow::anyhow!("{}: the grid of generation {g}: {e}", file.display()))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let schedule =
        Schedule::parse(&info.log).map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))?;
    let what_if: Vec<(String, String, String)> = args
        .params
        .iter()
        .map(|p| parse_param(p))
        .collect::<anyhow::Result<_>>()?;
    for (comp, name, value) in &what_if {
        set_param(&mut specs, &info, comp, name, value)?;
    }
    let first = specs
        .first()
        .ok_or_else(|| anyhow::anyhow!("{}: the recording holds no grid", file.display()))?;
    let recorder = first.component(&info.recorder).ok_or_else(|| {
        anyhow::anyhow!(
            "{}: its recorder '{}' is not in its grid",
            file.display(),
            info.recorder
        )
    })?;
    let signals = record_type::parse_signals(
        first.components[recorder]
            .params
            .text(record_type::SIGNALS)
            .unwrap_or_default(),
    )?;
    let names: Vec<String> = signals.iter().map(|s| s.name.clone()).collect();
    let recording = Arc::new(Recording::read(file, &names)?);
    let Some(last) = recording.last_tick() else {
        anyhow::bail!("{}: the recording has no rows", file.display());
    };
    if schedule.ended.is_none() {
        anyhow::bail!(
            "{}: the run's schedule is incomplete (its coordinator did not end cleanly): a \
             replay could not tell what it missed",
            file.display()
        );
    }
    let mut ticks = args.until.map_or(last, |u| u.min(last)) + 1;
    // A host restarted: its components began anew, from nothing a replay has.
    let restart = schedule
        .restarts
        .first()
        .filter(|(t, _)| *t < ticks)
        .cloned();
    if let Some((t, _)) = &restart {
        ticks = *t;
    }
    let verdict = Arc::new(Mutex::new(Verdict::default()));
    let base_period_s = first.base_period.as_secs_f64();
    let out = (!what_if.is_empty()).then(|| {
        args.out
            .clone()
            .unwrap_or_else(|| file.with_extension("whatif.h5"))
    });
    let registry = modbot_components::builtin();
    let mut make = Maker {
        registry: &registry,
        recording: recording.clone(),
        sources: &info.sources,
        recorder: &info.recorder,
        verdict: verdict.clone(),
        what_if: out.clone().map(|p| (p, base_period_s)),
    };
    let stop_at_first = what_if.is_empty();
    let seen = verdict.clone();
    // A what-if runs to the end; a replay stops at its first difference, and each before a
    // tick whose source outputs the recording lacks.
    replay::run(&specs, &schedule, &mut make, ticks, &mut |n, _| {
        seen.lock()
            .is_ok_and(|v| v.gap.is_none_or(|g| n < g) && (!stop_at_first || v.first.is_none()))
    })?;
    let verdict = verdict
        .lock()
        .map_err(|_| anyhow::anyhow!("the comparer failed"))?
        .clone();
    let overruns = schedule.late.len();
    let switched = schedule
        .switches
        .iter()
        .filter(|s| s.took_over.is_some_and(|t| t < ticks))
        .count();
    let last_compared = verdict.last.unwrap_or(0);
    match &verdict.first {
        None => {
            println!(
                "replayed {} ticks (0..{last_compared}, {switched} switch(es), {overruns} \
                 overrun(s) replayed): identical",
                last_compared + 1
            );
        }
        Some(d) => {
            println!(
                "replayed to tick {last_compared}: {}",
                describe(d, &specs, &info.recorder)
            );
        }
    }
    println!("recorded in run {}", info.run_id);
    if let Some((t, host)) = &restart {
        println!(
            "note: host {host} was restarted at tick {t} (its components began anew): the \
             replay ends there"
        );
    }
    if let Some(t) = verdict.gap {
        println!(
            "note: the recording has no row for tick {t} (its recorder overran in real time): \
             what the bus put out then is unknown, so the replay ends there"
        );
    }
    if let Some(t) = verdict.missing {
        println!(
            "note: the recording has no row for tick {t} (its recorder dropped it): not compared"
        );
    }
    if let Some(p) = &out {
        println!(
            "what-if recording: {} (the bus is played as recorded: it does not answer the \
             changed commands)",
            p.display()
        );
    }
    Ok(if verdict.first.is_none() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// The first divergence in one line, naming the component that fed each mirrored input.
fn describe(d: &modbot_record::replay::Divergence, specs: &[GridSpec], recorder: &str) -> String {
    let spec = specs
        .iter()
        .find(|s| s.generation().0 == d.generation)
        .or(specs.first());
    let fed_by = |signal: &str| -> Option<String> {
        let spec = spec?;
        let r = spec.component(recorder)?;
        let input = spec.components[r]
            .info
            .inputs
            .iter()
            .position(|p| p.name == signal)?;
        let from = spec.source_of(r, input)?;
        let c = &spec.components[from.component];
        Some(format!("{}.{}", c.name, c.info.outputs[from.port].name))
    };
    let mut text = format!("differs at tick {}", d.tick);
    match d.signals.first() {
        Some((signal, index, recorded, replayed)) => {
            let by = fed_by(signal)
                .map(|c| format!(" from {c}"))
                .unwrap_or_default();
            text += &format!(": {signal}[{index}]{by} recorded {recorded:?} replayed {replayed:?}");
            if d.signals.len() > 1 {
                let more: Vec<String> = d.signals[1..]
                    .iter()
                    .take(5)
                    .map(|(s, i, _, _)| format!("{s}[{i}]"))
                    .collect();
                text += &format!(" (also {}", more.join(", "));
                if d.signals.len() > 6 {
                    text += &format!(" and {} more", d.signals.len() - 6);
                }
                text += ")";
            }
        }
        None => {
            if let Some((recorded, replayed)) = d.state_hash {
                text += &format!(
                    ": the state hash recorded {recorded:#018x} replayed {replayed:#018x} (no \
                     recorded signal differs yet: a component's state)"
                );
            }
        }
    }
    text
}

/// `comp.name=value` → (comp, name, value).
fn parse_param(p: &str) -> anyhow::Result<(String, String, String)> {
    let parsed = p.split_once('=').and_then(|(key, value)| {
        let (comp, name) = key.split_once('.')?;
        Some((comp.to_owned(), name.to_owned(), value.to_owned()))
    });
    parsed.ok_or_else(|| anyhow::anyhow!("--param {p}: expected COMP.NAME=VALUE"))
}

/// Sets param `name` of component `comp` to `value` in every generation that has it.
fn set_param(
    specs: &mut [GridSpec],
    info: &replay_file::ReplayInfo,
    comp: &str,
    name: &str,
    value: &str,
) -> anyhow::Result<()> {
    if info.sources.iter().any(|s| s == comp) || info.recorder == comp {
        anyhow::bail!(
            "--param {comp}.{name}: '{comp}' is played back or compared, not run: change a \
             controller"
        );
    }
    let mut found = false;
    for spec in specs.iter_mut() {
        let Some(c) = spec.component(comp) else {
            continue;
        };
        let component = &mut spec.components[c];
        let Some(decl) = component.info.params.iter().find(|d| d.name == name) else {
            let known: Vec<&str> = component.info.params.iter().map(|d| d.name).collect();
            anyhow::bail!(
                "--param {comp}.{name}: '{comp}' ({}) has no param '{name}' (params: {})",
                component.type_name,
                known.join(", ")
            );
        };
        let parsed = parse_value(decl.ty, value)
            .ok_or_else(|| anyhow::anyhow!("--param {comp}.{name}={value}: not {}", decl.ty))?;
        component.params.set(name.to_owned(), parsed);
        found = true;
    }
    if !found {
        let mut known: Vec<&str> = specs
            .iter()
            .flat_map(|s| s.components.iter().map(|c| c.name.as_str()))
            .collect();
        known.sort();
        known.dedup();
        anyhow::bail!(
            "--param {comp}.{name}: no component '{comp}' ran (components: {})",
            known.join(", ")
        );
    }
    Ok(())
}

/// `text` as a param of type `ty`.
fn parse_value(ty: ParamType, text: &str) -> Option<ParamValue> {
    Some(match ty {
        ParamType::Bool => ParamValue::Bool(text.parse().ok()?),
        ParamType::I64 => ParamValue::I64(text.parse().ok()?),
        ParamType::F64 => ParamValue::F64(text.parse().ok()?),
        ParamType::F64s => ParamValue::F64s(
            text.trim_matches(|c| c == '[' || c == ']')
                .split(',')
                .map(|x| x.trim().parse().ok())
                .collect::<Option<Vec<f64>>>()?,
        ),
        ParamType::Text => ParamValue::Text(text.to_owned()),
    })
}

/// Makes the replay's components: the sources as players, the recorder as the comparer, the
/// rest from the registry with the parameters they ran with.
struct Maker<'a> {
    registry: &'a Registry,
    recording: Arc<Recording>,
    sources: &'a [String],
    recorder: &'a str,
    verdict: Arc<Mutex<Verdict>>,
    what_if: Option<(PathBuf, f64)>,
}

impl Make for Maker<'_> {
    fn make(&mut self, spec: &GridSpec, c: usize) -> Result<Box<dyn Component>, ComponentError> {
        let cs = &spec.components[c];
        if self.sources.contains(&cs.name) {
            let outputs: Vec<&str> = cs.info.outputs.iter().map(|p| p.name).collect();
            let player = Player::new(
                self.recording.clone(),
                self.verdict.clone(),
                &cs.name,
                &outputs,
                cs.period.max(1),
            )
            .map_err(|missing| {
                ComponentError::Other(
                    format!("the recording has no '{missing}' to play back").into(),
                )
            })?;
            return Ok(Box::new(player));
        }
        if cs.name == self.recorder {
            let signals = record_type::parse_signals(
                cs.params.text(record_type::SIGNALS).unwrap_or_default(),
            )?;
            let comparer = Comparer::new(
                self.recording.clone(),
                signals,
                self.verdict.clone(),
                self.what_if.take(),
            )
            .map_err(|e| ComponentError::Other(Box::new(e)))?;
            return Ok(Box::new(comparer));
        }
        if let Some(program) = &cs.program {
            // A replay runs the built-in types in this process; a type its own program makes
            // (an FMU's host, a user's component host) is not replayed yet.
            return Err(ComponentError::MadeElsewhere {
                type_name: cs.type_name.clone(),
                program: program.clone(),
            });
        }
        self.registry.instantiate(&cs.type_name, &cs.params)
    }
}
