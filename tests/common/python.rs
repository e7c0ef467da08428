//! Python, for the checks made by tools no one here wrote: h5py reads the recordings, FMPy
//! validates and simulates the FMUs, Foxglove's `mcap` package reads the MCAP exports. The
//! README's test command installs them (`./test.sh`).

use std::process::Command;

/// What `script` printed, run by `python3` with `args` (`sys.argv[1:]`); fails the test with
/// Python's error if it fails.
pub fn python(script: &str, args: &[&str]) -> String {
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run python3 ({e}): ./test.sh installs what the tests need")
        });
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "python3 failed ({}):\n{stderr}\n(./test.sh installs h5py, FMPy and mcap)",
        out.status
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// What the Python file `path` printed with `args`; fails the test as [`python`] does.
pub fn python_file(path: &std::path::Path, args: &[&str]) -> String {
    let script = format!(
        "import runpy, sys; sys.argv = [{path:?}] + sys.argv[1:]; runpy.run_path({path:?}, run_name='__main__')",
        path = path.display().to_string()
    );
    python(&script, args)
}
