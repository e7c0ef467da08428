//! Swapping assemblies from a program: [`switch`] asks the coordinator to prepare an assembly
//! and waits until it took over (or until the coordinator says why not); [`status`] reads
//! where the assemblies stand. `modbot assembly` is built on these.
//!
//! The coordinator answers `assembly()` with lines of text: `current NAME GENERATION`,
//! `state idle` / `state preparing GEN NAME` / `state announced GEN NAME TICK`, then one line
//! per recent outcome: `switched GEN NAME ANNOUNCED_TICK TICK` or `failed GEN NAME REASON`.

use core::time::Duration;
use std::time::Instant;

use thiserror::Error;

use super::spec::COORDINATOR;
use modbot_core::calls::CallOptions;
use modbot_core::error::CallError;
use modbot_core::tool::Calls;

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
    Answer(String),
}

/// Where the assemblies stand.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Status {
    /// The running assembly and its generation.
    pub current: (String, u16),
    /// The state line as the coordinator wrote it (`idle`, `preparing ...`, `announced ...`).
    pub state: String,
    /// Recent outcomes.
    pub outcomes: Vec<Outcome>,
}

/// A switch's outcome: generation, assembly, and (announced tick, actual tick) or the reason.
pub type Outcome = (u16, String, Result<(u64, u64), String>);

/// Reads the coordinator's answer to `assembly()`.
pub fn parse_status(text: &str) -> Result<Status, String> {
    let mut status = Status::default();
    for line in text.lines() {
        let mut words = line.splitn(2, ' ');
        let (kind, rest) = (words.next().unwrap_or(""), words.next().unwrap_or(""));
        let fields: Vec<&str> = rest.split(' ').collect();
        let num = |i: usize| -> Result<u64, String> {
            fields
                .get(i)
                .and_then(|f| f.parse().ok())
                .ok_or_else(|| format!("bad line '{line}'"))
        };
        let gen = |i: usize| num(i).and_then(|g| u16::try_from(g).map_err(|e| e.to_string()));
        match kind {
            "current" => status.current = (fields.first().unwrap_or(&"").to_string(), gen(1)?),
            "state" => status.state = rest.to_owned(),
            "switched" => status.outcomes.push((
                gen(0)?,
                fields.get(1).unwrap_or(&"").to_string(),
                Ok((num(2)?, num(3)?)),
            )),
            "failed" => {
                let parts: Vec<&str> = rest.splitn(3, ' ').collect();
                status.outcomes.push((
                    gen(0)?,
                    parts.get(1).unwrap_or(&"").to_string(),
                    Err(parts.get(2).unwrap_or(&"").to_string()),
                ));
            }
            "" => {}
            other => return Err(format!("unknown line kind '{other}'")),
        }
    }
    Ok(status)
}

/// Asks the coordinator where the assemblies stand.
pub fn status(module: &mut impl Calls) -> Result<Status, SwitchError> {
    let text = module.call_blocking(
        COORDINATOR,
        "assembly",
        &[],
        CallOptions::timeout(Duration::from_secs(3)),
        |r| -> Result<String, SwitchError> {
            let args = r.map_err(|e| SwitchError::Call(e.clone()))?;
            args.text(0)
                .map(str::to_owned)
                .map_err(|e| SwitchError::Answer(e.to_string()))
        },
    )?;
    parse_status(&text).map_err(SwitchError::Answer)
}

/// Switches to assembly `name`: the coordinator prepares it while the running one goes on,
/// then switches at an announced tick. Waits up to `timeout` for the outcome.
pub fn switch(
    module: &mut impl Calls,
    name: &str,
    timeout: Duration,
) -> Result<Switched, SwitchError> {
    let asked = Instant::now();
    let generation = module.call_blocking(
        COORDINATOR,
        "switch",
        &[modbot_ipc_schema::Value::Text(name)],
        CallOptions::timeout(Duration::from_secs(5)),
        |r| -> Result<u16, SwitchError> {
            let args = r.map_err(|e| SwitchError::Call(e.clone()))?;
            let g = args
                .i64(0)
                .map_err(|e| SwitchError::Answer(e.to_string()))?;
            u16::try_from(g).map_err(|e| SwitchError::Answer(e.to_string()))
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
        if let Some((_, assembly, outcome)) = now.outcomes.iter().find(|o| o.0 == generation) {
            return match outcome {
                Ok((announced, tick)) => Ok(Switched {
                    assembly: assembly.clone(),
                    generation,
                    announced: *announced,
                    tick: *tick,
                    took: asked.elapsed(),
                }),
                Err(reason) => Err(SwitchError::Failed {
                    assembly: assembly.clone(),
                    generation,
                    reason: reason.clone(),
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

/// An assembly name: 1 to 32 characters of `a-z`, `0-9` and `_` (it names a file).
pub fn check_assembly_name(name: &str) -> Result<(), String> {
    if super::spec::is_plain_name(name) {
        Ok(())
    } else {
        Err(format!(
            "assembly name '{name}' is invalid: use 1 to 32 characters of a-z, 0-9 and _"
        ))
    }
}

/// `TICK:NAME`, a switch to assembly NAME at tick TICK (`modbot up --switch`).
pub fn parse_scripted(text: &str) -> Result<(u64, String), String> {
    let (tick, name) = text
        .split_once(':')
        .ok_or_else(|| format!("'{text}' is not TICK:NAME"))?;
    let tick = tick
        .parse()
        .map_err(|_| format!("'{tick}' in '{text}' is not a tick number"))?;
    check_assembly_name(name)?;
    Ok((tick, name.to_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_status_answer_reads_back_with_outcomes_and_reasons() {
        let text = "current ptp 3\nstate announced 4 hold 1234\nswitched 3 ptp 900 900\nfailed 2 nope no assembly named 'nope' in /x (assemblies: hold, ptp)\n";
        let s = parse_status(text).unwrap();
        assert_eq!(s.current, ("ptp".to_owned(), 3));
        assert_eq!(s.state, "announced 4 hold 1234");
        assert_eq!(s.outcomes[0], (3, "ptp".to_owned(), Ok((900, 900))));
        assert_eq!(
            s.outcomes[1],
            (
                2,
                "nope".to_owned(),
                Err("no assembly named 'nope' in /x (assemblies: hold, ptp)".to_owned())
            )
        );
        assert!(parse_status("current x y").is_err());
        assert!(parse_status("bogus 1").is_err());
    }
}
