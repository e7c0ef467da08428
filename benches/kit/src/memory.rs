//! What a system takes of memory: a process's Pss and Rss, and a domain's /dev/shm files.

use modbot_core::Domain;

/// Bytes of /dev/shm the domain's files occupy (allocated blocks, not their sparse size).
pub fn shm_bytes(domain: &Domain) -> u64 {
    use std::os::unix::fs::MetadataExt;
    domain
        .files()
        .iter()
        .filter(|p| p.starts_with("/dev/shm"))
        .filter_map(|p| std::fs::symlink_metadata(p).ok())
        .map(|m| m.blocks() * 512)
        .sum()
}

/// Pss and Rss of process `pid`, in bytes.
pub fn memory_of(pid: u32) -> Option<(u64, u64)> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/smaps_rollup")).ok()?;
    let field = |name: &str| {
        text.lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|kb| kb.parse::<u64>().ok())
            .map(|kb| kb * 1024)
    };
    Some((field("Pss:")?, field("Rss:")?))
}
