//! Swapping assemblies from a program: [`switch`] asks the coordinator to prepare an assembly
//! and waits until it took over (or until the coordinator says why not); [`status`] reads
//! where the assemblies stand. `modbot assembly` is built on these.
//!
//! The coordinator's answers to `switch(name)` and `assembly()` are in the format of
//! `modbot_ipc_schema::switch`, whose types are re-exported here.

use core::time::Duration;
use std::time::Instant;

use thiserror::Error;

use super::spec::COORDINATOR;
use modbot_core::calls::CallOptions;
use modbot_core::error::CallError;
use modbot_core::tool::Calls;
use modbot_ipc_schema::switch::{decode, decode_generation};

pub use modbot_ipc_schema::switch::{Outcome, State, Status, SwitchAnswerError};

/// The outcome of one switch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Switched {
    pub assembly: String,
    pub generation: u16,
    /// The tick the coordinator announced for the switch, and the tick it happened at.
    pub announced: u64,
    pub tick: u64,
    /// From the request to the switch.
    pub took: Duration,
}

/// Why a switch did not happen.
#[derive(Debug, Error)]
pub enum SwitchError {
    #[error("the coordinator does not answer: {0}")]
    Call(#[from] CallError),
    #[error("assembly {assembly} (generation {generation}) was not switched to: {reason}; the running assembly stays")]
    Failed {
        assembly: String,
        generation: u16,
        reason: String,
    },
    #[error("no outcome for generation {generation} within {waited_ms} ms")]
    Timeout { generation: u16, waited_ms: u64 },
    #[error("the coordinator's answer is not understood: {0}")]
    Answer(#[from] SwitchAnswerError),
    /// A program stepping a gated grid could not run it to the announced tick.
    #[error("the grid could not be run to the switch's tick {tick}: {why}")]
    Stepping { tick: u64, why: String },
}

/// Asks the coordinator where the assemblies stand.
pub fn status(module: &mut impl Calls) -> Result<Status, SwitchError> {
    module.call_blocking(
        COORDINATOR,
        "assembly",
        &[],
        CallOptions::timeout(Duration::from_secs(3)),
        |r| -> Result<Status, SwitchError> {
            let args = r.map_err(|e| SwitchError::Call(e.clone()))?;
            let bytes = args.bytes(0).map_err(SwitchAnswerError::from)?;
            Ok(decode(bytes)?)
        },
    )
}

/// Switches to assembly `name`: the coordinator prepares it while the running one goes on,
/// then switches at an announced tick. Waits up to `timeout` for the outcome.
pub fn switch<M: Calls>(
    module: &mut M,
    name: &str,
    timeout: Duration,
) -> Result<Switched, SwitchError> {
    switch_with(module, name, timeout, &mut |_, _| Ok(()))
}

/// As [`switch`], calling `announced` with the tick the switch is announced at, once per
/// announcement (again if it is postponed): a program that steps a gated grid runs it to that
/// tick there, or the switch would wait for a tick that never comes.
pub fn switch_with<M: Calls>(
    module: &mut M,
    name: &str,
    timeout: Duration,
    announced: &mut dyn FnMut(&mut M, u64) -> Result<(), SwitchError>,
) -> Result<Switched, SwitchError> {
    let asked = Instant::now();
    let mut followed = None;
    let generation = module.call_blocking(
        COORDINATOR,
        "switch",
        &[modbot_ipc_schema::Value::Text(name)],
        CallOptions::timeout(Duration::from_secs(5)),
        |r| -> Result<u16, SwitchError> {
            let args = r.map_err(|e| SwitchError::Call(e.clone()))?;
            Ok(decode_generation(args.as_slice())?)
        },
    )?;
    loop {
        // The coordinator's service thread runs at normal priority: on a loaded machine one
        // answer may be slow, which is no reason to give up before `timeout`.
        let now = match status(module) {
            Ok(now) => now,
            Err(SwitchError::Call(CallError::Timeout { .. })) if asked.elapsed() < timeout => {
                continue
            }
            Err(e) => return Err(e),
        };
        if let State::Announced {
            generation: g,
            tick,
            ..
        } = now.state
        {
            if g == generation && followed != Some(tick) {
                followed = Some(tick);
                announced(module, tick)?;
                continue;
            }
        }
        if let Some(outcome) = now
            .outcomes
            .into_iter()
            .find(|o| o.generation() == generation)
        {
            return match outcome {
                Outcome::Switched {
                    assembly,
                    announced,
                    tick,
                    ..
                } => Ok(Switched {
                    assembly,
                    generation,
                    announced,
                    tick,
                    took: asked.elapsed(),
                }),
                Outcome::Failed {
                    assembly, reason, ..
                } => Err(SwitchError::Failed {
                    assembly,
                    generation,
                    reason,
                }),
            };
        }
        if asked.elapsed() > timeout {
            return Err(SwitchError::Timeout {
                generation,
                waited_ms: timeout.as_millis() as u64,
            });
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// An assembly name that is not one.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("assembly name '{0}' is invalid: use 1 to 32 characters of a-z, 0-9 and _")]
pub struct AssemblyNameError(pub String);

/// An assembly name: 1 to 32 characters of `a-z`, `0-9` and `_` (it names a file).
pub fn check_assembly_name(name: &str) -> Result<(), AssemblyNameError> {
    if super::spec::is_plain_name(name) {
        Ok(())
    } else {
        Err(AssemblyNameError(name.to_owned()))
    }
}

/// A scripted switch that is not `TICK:NAME`.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ScriptedSwitchError {
    #[error("'{0}' is not TICK:NAME")]
    NotTickName(String),
    #[error("'{tick}' in '{text}' is not a tick number")]
    Tick { tick: String, text: String },
    #[error(transparent)]
    Name(#[from] AssemblyNameError),
}

/// `TICK:NAME`, a switch to assembly NAME at tick TICK (`modbot up --switch`).
pub fn parse_scripted(text: &str) -> Result<(u64, String), ScriptedSwitchError> {
    let (tick, name) = text
        .split_once(':')
        .ok_or_else(|| ScriptedSwitchError::NotTickName(text.to_owned()))?;
    let tick = tick.parse().map_err(|_| ScriptedSwitchError::Tick {
        tick: tick.to_owned(),
        text: text.to_owned(),
    })?;
    check_assembly_name(name)?;
    Ok((tick, name.to_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scripted_switches_are_tick_colon_name() {
        assert_eq!(parse_scripted("900:ptp"), Ok((900, "ptp".to_owned())));
        assert!(parse_scripted("ptp").is_err());
        assert!(parse_scripted("x:ptp").is_err());
        assert!(parse_scripted("900:Bad-Name").is_err());
    }
}
