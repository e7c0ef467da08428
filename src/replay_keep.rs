//! A replayable recording under `modbot up` (`--replayable`, or `record { replay = true }`):
//! the coordinator writes the run's schedule to a log beside the file, and once the run has
//! ended (the recorder closed the file) the log and every generation's checked grid go into
//! the recording's `/replay` ([`modbot_record::replay_file`]), for `modbot replay`.

use std::path::{Path, PathBuf};

use modbot_core::Domain;
use modbot_grid::record_type;
use modbot_grid::GridSpec;
use modbot_record::replay_file::{self, ReplayInfo};

/// The replayable recorder of a run.
#[derive(Debug, Clone)]
pub struct Replayable {
    /// The recorder component.
    recorder: String,
    sources: Vec<String>,
    /// The recording.
    pub file: PathBuf,
    /// The coordinator's log of the schedule, beside it.
    pub log: PathBuf,
    clock: &'static str,
    first_generation: u16,
    /// Where the assembly files are (a grid with assemblies).
    assemblies: Option<PathBuf>,
    run_id: String,
}

impl Replayable {
    /// The replayable recorder of `grid`, if it has one that writes a file.
    pub fn of(grid: &GridSpec) -> Option<Replayable> {
        grid.components.iter().find_map(|c| {
            if c.type_name != record_type::TYPE {
                return None;
            }
            let sources = c.params.text(record_type::REPLAY).ok()?;
            let file = c.params.text(record_type::FILE).ok()?;
            if sources.is_empty() || file.is_empty() {
                return None;
            }
            let file = PathBuf::from(file);
            let mut log = file.clone().into_os_string();
            log.push(".replay.log");
            Some(Replayable {
                recorder: c.name.clone(),
                sources: sources.split(';').map(str::to_owned).collect(),
                log: PathBuf::from(log),
                file,
                clock: match grid.timing.clock {
                    modbot_grid::GridClock::Lockstep => "lockstep",
                    modbot_grid::GridClock::RealTime => "real_time",
                },
                first_generation: grid.generation().0,
                assemblies: grid
                    .assembly
                    .as_ref()
                    .and_then(|a| a.source.as_ref())
                    .map(|s| s.dir.clone()),
                run_id: String::new(),
            })
        })
    }

    /// The same, for the run `run_id`.
    pub fn of_run(mut self, run_id: String) -> Replayable {
        self.run_id = run_id;
        self
    }

    /// Puts the log and the checked grids of the generations that ran (from `domain`) into the
    /// recording, and removes the log.
    pub fn keep(&self, domain: &Domain) -> anyhow::Result<()> {
        let log = std::fs::read_to_string(&self.log).map_err(|e| {
            anyhow::anyhow!(
                "the coordinator's schedule {} is not there ({e}): the recording is not replayable",
                self.log.display()
            )
        })?;
        let mut generations = vec![self.first_generation];
        generations.extend(log.lines().filter_map(switched_to));
        let mut specs = Vec::new();
        let mut files: Vec<(String, String)> = Vec::new();
        for g in generations {
            let image = domain.read_spec_image(g).map_err(|e| {
                anyhow::anyhow!("the checked grid of generation {g} is gone ({e}): not replayable")
            })?;
            let assembly = modbot_grid::GridSpec::from_image(&image)
                .ok()
                .and_then(|s| s.assembly.map(|a| a.name));
            if let (Some(name), Some(dir)) = (assembly, &self.assemblies) {
                if !files.iter().any(|(n, _)| *n == name) {
                    let path = dir.join(format!("{name}.lua"));
                    match std::fs::read_to_string(&path) {
                        Ok(text) => files.push((name, text)),
                        Err(e) => tracing::warn!("{} is not kept: {e}", path.display()),
                    }
                }
            }
            specs.push((g, image));
        }
        let info = ReplayInfo {
            run_id: self.run_id.clone(),
            recorder: self.recorder.clone(),
            sources: self.sources.clone(),
            clock: self.clock.to_owned(),
            specs,
            log,
            files,
        };
        replay_file::write(&self.file, &info)?;
        let _ = std::fs::remove_file(&self.log);
        Ok(())
    }

    /// The recording, as the message after the run names it.
    pub fn path(&self) -> &Path {
        &self.file
    }
}

/// The generation a `switch tick=N generation=G` line of the log names.
fn switched_to(line: &str) -> Option<u16> {
    line.strip_prefix("switch ")?
        .split_whitespace()
        .find_map(|w| w.strip_prefix("generation="))?
        .parse()
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_switch_line_names_the_generation_that_took_over() {
        assert_eq!(switched_to("switch tick=300 generation=2"), Some(2));
        assert_eq!(
            switched_to("announce tick=1 generation=2 from=3 at=9"),
            None
        );
    }
}
