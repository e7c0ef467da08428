//! What a replayable recording keeps beside its rows (`modbot up --record FILE --replayable`,
//! or `record { replay = true }`), so that `modbot replay` runs its controllers again: the group
//! `/replay`, written by `modbot up` once the run has ended and the recorder closed the file.
//!
//! ```text
//! /replay                attributes: format ("modbot-replay 1"), run_id (the run's:
//!                        `<domain>-<start, unix ns>-<pid of modbot up>`), recorder (the
//!                        recorder component's name), sources (the played-back components,
//!                        `;`-joined), clock ("lockstep" or "real_time")
//! /replay/spec.<g>       u8 (len,)  the checked grid of assembly generation g, as the
//!                        supervisor gave it to the grid's processes (`GridSpec::to_image`):
//!                        parameters, assembly data and all, exactly as they ran
//! /replay/file.<name>    u8 (len,)  the text of each assembly file that ran (`<name>.lua`), as
//!                        it was when the run ended (the system description's is the root
//!                        attribute `description`)
//! /replay/log            u8 (len,)  the coordinator's schedule of the run, UTF-8 text
//!                        (switches, held ranges, faults, overruns, stale releases: see
//!                        `modbot_grid_processes`' replay log)
//! ```
//! The rows hold the sources' every output (what the drives did) and every input of theirs as
//! `S<input` (what the controllers commanded), each tick.

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;

use super::file::text_attr;

/// The format this module writes and reads.
pub const FORMAT: &str = "modbot-replay 1";

/// What a replay needs beside the rows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReplayInfo {
    /// The run's id.
    pub run_id: String,
    /// The recorder component's name.
    pub recorder: String,
    /// The components played back.
    pub sources: Vec<String>,
    /// "lockstep" or "real_time".
    pub clock: String,
    /// The checked grid of each generation that ran: (generation, image).
    pub specs: Vec<(u16, Vec<u8>)>,
    /// The coordinator's schedule of the run.
    pub log: String,
    /// The assembly files that ran: (name, text).
    pub files: Vec<(String, String)>,
}

/// Why the replay part of a recording cannot be written or read.
#[derive(Debug, thiserror::Error)]
#[error("{}: {why}", .path.display())]
pub struct ReplayFileError {
    pub path: PathBuf,
    pub why: String,
}

/// Adds `/replay` to the closed recording at `path`.
pub fn write(path: &Path, info: &ReplayInfo) -> Result<(), ReplayFileError> {
    let failed = |why: String| ReplayFileError {
        path: path.to_path_buf(),
        why,
    };
    let file = hdf5::File::open_rw(path)
        .map_err(|e| failed(format!("does not open for writing the replay part: {e}")))?;
    let written = (|| -> hdf5::Result<()> {
        let group = file.create_group("replay")?;
        text_attr(&group, "format", FORMAT)?;
        text_attr(&group, "run_id", &info.run_id)?;
        text_attr(&group, "recorder", &info.recorder)?;
        text_attr(&group, "sources", &info.sources.join(";"))?;
        text_attr(&group, "clock", &info.clock)?;
        for (g, image) in &info.specs {
            bytes_dataset(&group, &format!("spec.{g}"), image)?;
        }
        for (name, text) in &info.files {
            bytes_dataset(&group, &format!("file.{name}"), text.as_bytes())?;
        }
        bytes_dataset(&group, "log", info.log.as_bytes())?;
        file.flush()
    })();
    written.map_err(|e| failed(format!("the replay part: {e}")))?;
    file.close()
        .map_err(|e| failed(format!("the replay part: {e}")))
}

/// Reads `/replay` of the recording at `path`: `Ok(None)` for a recording that is not
/// replayable.
pub fn read(path: &Path) -> Result<Option<ReplayInfo>, ReplayFileError> {
    let failed = |why: String| ReplayFileError {
        path: path.to_path_buf(),
        why,
    };
    let file =
        hdf5::File::open(path).map_err(|e| failed(format!("does not open as a recording: {e}")))?;
    let Ok(group) = file.group("replay") else {
        return Ok(None);
    };
    let text = |name: &str| -> Result<String, ReplayFileError> {
        let v: VarLenUnicode = group
            .attr(name)
            .and_then(|a| a.read_scalar())
            .map_err(|e| failed(format!("/replay has no {name}: {e}")))?;
        Ok(v.as_str().to_owned())
    };
    let format = text("format")?;
    if format != FORMAT {
        return Err(failed(format!(
            "its replay part is '{format}'; this modbot reads '{FORMAT}'"
        )));
    }
    let bytes = |name: &str| -> Result<Vec<u8>, ReplayFileError> {
        group
            .dataset(name)
            .and_then(|d| d.read_raw::<u8>())
            .map_err(|e| failed(format!("/replay/{name}: {e}")))
    };
    let mut specs = Vec::new();
    let mut files = Vec::new();
    let names = group
        .member_names()
        .map_err(|e| failed(format!("/replay cannot be listed: {e}")))?;
    for name in names {
        if let Some(g) = name
            .strip_prefix("spec.")
            .and_then(|g| g.parse::<u16>().ok())
        {
            specs.push((g, bytes(&name)?));
        } else if let Some(file) = name.strip_prefix("file.") {
            let text = String::from_utf8_lossy(&bytes(&name)?).into_owned();
            files.push((file.to_owned(), text));
        }
    }
    specs.sort_by_key(|(g, _)| *g);
    let log = String::from_utf8(bytes("log")?)
        .map_err(|_| failed("/replay/log is not UTF-8 text".into()))?;
    files.sort();
    Ok(Some(ReplayInfo {
        run_id: text("run_id")?,
        recorder: text("recorder")?,
        sources: text("sources")?
            .split(';')
            .filter(|s| !s.is_empty())
            .map(str::to_owned)
            .collect(),
        clock: text("clock")?,
        specs,
        log,
        files,
    }))
}

fn bytes_dataset(group: &hdf5::Group, name: &str, bytes: &[u8]) -> hdf5::Result<()> {
    group
        .new_dataset::<u8>()
        .shape(bytes.len())
        .create(name)?
        .write_raw(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::file::{Header, RecordFile};

    #[test]
    fn the_replay_part_reads_back_as_written_and_a_plain_recording_has_none() {
        let dir = std::env::temp_dir().join(format!("modbot-replay-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.h5");
        RecordFile::create(&path, &[], &Header::default(), 8)
            .unwrap()
            .close()
            .unwrap();
        assert_eq!(read(&path).unwrap(), None);
        let info = ReplayInfo {
            run_id: "arm-1-2".into(),
            recorder: "record".into(),
            sources: vec!["robot".into()],
            clock: "lockstep".into(),
            specs: vec![(1, vec![1, 2, 3]), (2, vec![])],
            log: "switch tick=300 generation=2\n".into(),
            files: vec![("hold".into(), "component \"hold\" {}\n".into())],
        };
        write(&path, &info).unwrap();
        assert_eq!(read(&path).unwrap(), Some(info));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
