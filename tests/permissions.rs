//! A domain is one user's: another user's tools, modules and `modbot up` are refused with a
//! line that says whose it is and what to do, leave nothing behind and take nothing away, and
//! no file of a domain is open to other users. Needs root (to start a system and then act as `nobody`), as CI runs.

mod common;

use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use common::TestDomain;

/// The uid and gid of `nobody`.
const NOBODY: u32 = 65534;

/// `program` copied where `nobody` may run it (the build directory may be closed to it).
fn runnable_by_nobody(dir: &Path, program: &str) -> PathBuf {
    let to = dir.join(program);
    std::fs::copy(common::bin(program), &to).unwrap();
    std::fs::set_permissions(&to, std::fs::Permissions::from_mode(0o755)).unwrap();
    to
}

/// `program` run as `nobody`; `None` where this machine cannot switch users (a container
/// without the capability).
fn as_nobody(program: &Path, args: &[&str]) -> Option<Output> {
    match Command::new(program)
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .uid(NOBODY)
        .gid(NOBODY)
        .output()
    {
        Ok(out) => Some(out),
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => None,
        Err(e) => panic!("cannot run {} as nobody: {e}", program.display()),
    }
}

/// `nobody` in root's running domain: `modbot ls`, `modbot call`, a module and `modbot up` are
/// each refused in one line naming the owner, even with RUST_BACKTRACE=1; none leaves a file,
/// the running system keeps answering, and no file of the domain is writable by others.
#[test]
fn another_users_tools_modules_and_systems_are_refused_with_whose_domain_it_is_and_leave_nothing() {
    if !nix::unistd::geteuid().is_root() {
        eprintln!("skipped: needs root to start a system and act as another user");
        return;
    }
    let mut sut = TestDomain::new("perm");
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/first_module/counters.lua");
    let domain = format!("domain={}", sut.name());
    let up = sut.spawn_logged("modbot", &["up", file.to_str().unwrap(), "--var", &domain]);
    sut.wait_for("b running", Duration::from_secs(60), || {
        String::from_utf8_lossy(&sut.modbot(&["ls", "--tsv"]).stdout).contains("\tb\t")
    });
    let dir = std::env::temp_dir().join(format!("{}_bin", sut.name()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755)).unwrap();
    let (modbot, module) = (
        runnable_by_nobody(&dir, "modbot"),
        runnable_by_nobody(&dir, "modbot-first-module"),
    );
    let expected = format!(
        "permission denied: domain '{}' belongs to uid 0 (run as that user)",
        sut.name()
    );
    // The same description, where `nobody` may read it.
    let description = dir.join("counters.lua");
    std::fs::copy(&file, &description).unwrap();
    std::fs::set_permissions(&description, std::fs::Permissions::from_mode(0o644)).unwrap();
    let attempts = [
        (
            "modbot ls",
            as_nobody(&modbot, &["ls", "--domain", sut.name()]),
        ),
        (
            "modbot call",
            as_nobody(&modbot, &["call", "b.add", "1", "--domain", sut.name()]),
        ),
        (
            "modbot up",
            as_nobody(
                &modbot,
                &["up", description.to_str().unwrap(), "--var", &domain],
            ),
        ),
        (
            "a module",
            as_nobody(
                &module,
                &["--domain", sut.name(), "--name", "intruder", "--addr", "77"],
            ),
        ),
    ];
    if attempts.iter().any(|(_, out)| out.is_none()) {
        eprintln!("skipped: this machine does not let root run a program as nobody");
        sut.modbot_ok(&["down"]);
        sut.wait_exit(up, Duration::from_secs(60));
        std::fs::remove_dir_all(&dir).unwrap();
        return;
    }
    for (what, out) in attempts {
        let out = out.unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{what} was let in");
        assert!(stderr.contains(&expected), "{what}: {stderr}");
        assert_eq!(
            stderr.lines().count(),
            1,
            "{what}: one line, no backtrace: {stderr}"
        );
    }
    // The refused start of another system removed nothing of the running one.
    assert!(
        String::from_utf8_lossy(&sut.modbot(&["ls", "--tsv"]).stdout).contains("\tb\t"),
        "the running system is still listed"
    );
    sut.modbot_ok(&["call", "b.add", "1"]);
    let files = sut.leftover_files();
    let nobodys: Vec<&PathBuf> = files
        .iter()
        .filter(|f| std::fs::metadata(f).is_ok_and(|m| m.uid() == NOBODY))
        .collect();
    assert!(nobodys.is_empty(), "the refused starts left {nobodys:?}");
    let open: Vec<&PathBuf> = files
        .iter()
        .filter(|f| f.is_file() && std::fs::metadata(f).is_ok_and(|m| m.mode() & 0o002 != 0))
        .collect();
    assert!(
        open.is_empty(),
        "files of the domain anyone may write: {open:?}"
    );
    sut.modbot_ok(&["down"]);
    let status = sut.wait_exit(up, Duration::from_secs(60));
    assert_eq!(status.code(), Some(0), "{}", sut.output_of(up));
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
    std::fs::remove_dir_all(&dir).unwrap();
}
