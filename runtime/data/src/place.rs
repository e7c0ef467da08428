//! Where a domain's assembly data lives: one file per domain, `<domain>.redb`, in the
//! directory `$MODBOT_DATA_DIR` names, by default the user's data directory
//! (`$XDG_DATA_HOME/modbot`, else `~/.local/share/modbot`). Every process of a system finds
//! it from the domain alone, so `modbot data` and a program need no system description, and a
//! supervisor's modules inherit the variable.

use std::path::PathBuf;

/// The variable that names the directory of the assembly data files.
pub const DATA_DIR_ENV: &str = "MODBOT_DATA_DIR";

/// The assembly data file of `domain`.
pub fn path_for(domain: &str) -> PathBuf {
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    let dir = var(DATA_DIR_ENV).map(PathBuf::from).unwrap_or_else(|| {
        var("XDG_DATA_HOME")
            .map(PathBuf::from)
            .or_else(|| var("HOME").map(|h| PathBuf::from(h).join(".local/share")))
            .unwrap_or_else(std::env::temp_dir)
            .join("modbot")
    });
    dir.join(format!("{domain}.redb"))
}
