//! Before a system starts in a domain: refuse it if another system runs there, and clear what
//! dead processes left.

use super::SupervisorError;
use modbot_core::domain::Domain;
use modbot_core::transport::Directory;

/// Refuses a domain where another system runs (a live supervisor, or live modules at the
/// addresses this description needs); cleans what dead processes left, and removes the
/// domain's files if nothing of it lives.
pub(super) fn sweep(
    domain: &Domain,
    dir: &dyn Directory,
    used: &[u8],
) -> Result<(), SupervisorError> {
    // A tool may be starting in the domain while we look (`modbot ls` polling for the system to
    // come up): only files older than this look are removed, so what it creates meanwhile stays.
    let before = std::time::SystemTime::now();
    let mut conflicts = Vec::new();
    let mut live = 0;
    dir.list(&mut |p| {
        if p.alive {
            live += 1;
            if p.name == "supervisor" || used.contains(&p.addr.0) {
                conflicts.push(format!("{} at address {} (pid {})", p.name, p.addr, p.pid));
            }
        }
    })?;
    if !conflicts.is_empty() {
        return Err(SupervisorError::DomainInUse {
            domain: domain.name().to_owned(),
            modules: conflicts.join(", "),
        });
    }
    let reaped = dir.reap_dead();
    let removed = if live == 0 {
        domain.remove_files_older_than(before)
    } else {
        0
    };
    if reaped + removed > 0 {
        tracing::info!(
            "swept domain '{}': {reaped} dead node(s), {removed} stale file(s)",
            domain.name()
        );
    }
    Ok(())
}
