//! Test fixture: a fresh domain per test, real module processes killed on drop, and a check
//! that the domain's shared memory is gone afterwards.

#![allow(dead_code)]

pub mod arm;
pub mod hosts;
pub mod python;
pub mod segment;

use std::path::PathBuf;
use std::process::{Child, Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

static BUILT: OnceLock<Result<(), String>> = OnceLock::new();

/// Where cargo put the workspace's binaries.
///
/// `cargo test` only builds the binaries of the package under test, and the module programs
/// live in other packages; so the first call builds every program of the workspace with the
/// same cargo and profile (a no-op when they are up to date). This keeps the tests from
/// silently running a stale program left over from an earlier build.
pub fn bin(name: &str) -> PathBuf {
    let built = BUILT.get_or_init(|| {
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let out = Command::new(cargo)
            .args(["build", "--workspace", "--bins", "--quiet"])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .map_err(|e| format!("cannot run cargo: {e}"))?;
        if out.status.success() {
            Ok(())
        } else {
            Err(String::from_utf8_lossy(&out.stderr).into_owned())
        }
    });
    if let Err(e) = built {
        panic!("building the workspace's programs failed:\n{e}");
    }
    let modbot = PathBuf::from(env!("CARGO_BIN_EXE_modbot"));
    modbot.with_file_name(name)
}

/// A domain of its own, with the processes started in it.
pub struct TestDomain {
    /// Removes its files when dropped (after the processes are killed).
    pub domain: modbot_testkit::TestDomain,
    children: Vec<(String, Child)>,
    /// Files this test wrote (system descriptions, captured output); removed on drop.
    files: Vec<PathBuf>,
    /// Variables every process this test starts gets (`MODBOT_DATA_DIR`, say).
    env: Vec<(String, String)>,
    /// The command that runs the programs this test starts (`ip netns exec NS`), if any.
    wrapper: Vec<String>,
}

impl TestDomain {
    pub fn new(test: &str) -> TestDomain {
        TestDomain {
            domain: modbot_testkit::TestDomain::new("t", test),
            children: Vec::new(),
            files: Vec::new(),
            env: Vec::new(),
            wrapper: Vec::new(),
        }
    }

    /// Starts every program of this test from now on in the network namespace `ns`.
    pub fn run_in_netns(&mut self, ns: &str) {
        self.wrapper = ["ip", "netns", "exec", ns].map(String::from).to_vec();
    }

    /// The command that starts `program` (in this test's network namespace, if it has one).
    fn command(&self, program: &str) -> Command {
        match self.wrapper.split_first() {
            Some((first, rest)) => {
                let mut command = Command::new(first);
                command.args(rest).arg(bin(program));
                command
            }
            None => Command::new(bin(program)),
        }
    }

    /// Gives every process this test starts from now on the variable `key` = `value`.
    pub fn set_env(&mut self, key: &str, value: &str) {
        self.env.push((key.to_owned(), value.to_owned()));
    }

    /// Removes `path` (a file, or a directory with what it holds) when the test ends, passed
    /// or failed.
    pub fn remove_at_end(&mut self, path: PathBuf) {
        self.files.push(path);
    }

    /// Writes a system description for this domain (`domain "..."` followed by `body`).
    pub fn write_system(&mut self, body: &str) -> PathBuf {
        let path = std::env::temp_dir().join(format!("{}.lua", self.name()));
        std::fs::write(&path, format!("domain \"{}\"\n{body}", self.name())).unwrap();
        self.files.push(path.clone());
        path
    }

    /// Starts `program ARGS` in this domain with its output captured to a file.
    pub fn spawn_logged(&mut self, program: &str, args: &[&str]) -> u32 {
        let log = std::env::temp_dir().join(format!("{}.{}.log", self.name(), self.files.len()));
        let out = std::fs::File::create(&log).unwrap();
        let child = self
            .command(program)
            .args(args)
            .env("MODBOT_DOMAIN", self.name())
            .env("RUST_LOG", "info")
            .envs(self.env.iter().map(|(k, v)| (k, v)))
            .stdout(out.try_clone().unwrap())
            .stderr(out)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {program}: {e}"));
        self.files.push(log.clone());
        let pid = child.id();
        self.children
            .push((format!("{program}|{}", log.display()), child));
        pid
    }

    /// `modbot up FILE --var domain=<this domain> --ticks N --trace OUT` with `more`
    /// arguments: waits for it to exit 0 and leave no files behind; returns the trace and what
    /// `modbot up` printed.
    pub fn traced_up(
        &mut self,
        file: &std::path::Path,
        ticks: u64,
        more: &[&str],
        tag: &str,
    ) -> (String, String) {
        let trace = std::env::temp_dir().join(format!("{}.{tag}.trace", self.name()));
        let domain = format!("domain={}", self.name());
        let n = ticks.to_string();
        let mut args = vec![
            "up",
            file.to_str().unwrap(),
            "--var",
            &domain,
            "--ticks",
            &n,
            "--trace",
            trace.to_str().unwrap(),
        ];
        args.extend_from_slice(more);
        let up = self.spawn_logged("modbot", &args);
        let status = self.wait_exit(up, Duration::from_secs(120));
        let output = self.output_of(up);
        assert_eq!(status.code(), Some(0), "{output}");
        assert_eq!(self.leftover_files(), Vec::<PathBuf>::new());
        let text = std::fs::read_to_string(&trace).unwrap_or_default();
        let _ = std::fs::remove_file(&trace);
        (text, output)
    }

    /// What the process `pid`, started with [`TestDomain::spawn_logged`], printed so far.
    pub fn output_of(&self, pid: u32) -> String {
        let (name, _) = self
            .children
            .iter()
            .find(|(_, c)| c.id() == pid)
            .expect("a child of this test");
        let path = name.split_once('|').map(|(_, p)| p).unwrap_or_default();
        std::fs::read_to_string(path).unwrap_or_default()
    }

    /// Waits until the child `pid` exits, at most `timeout`; returns its status.
    pub fn wait_exit(&mut self, pid: u32, timeout: Duration) -> std::process::ExitStatus {
        let i = self
            .children
            .iter()
            .position(|(_, c)| c.id() == pid)
            .expect("a child of this test");
        let start = Instant::now();
        loop {
            if let Some(status) = self.children[i].1.try_wait().unwrap() {
                return status;
            }
            assert!(
                start.elapsed() < timeout,
                "{} did not exit within {timeout:?}",
                self.children[i].0
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// How the child `pid` ended, if it has (without waiting).
    pub fn exited(&mut self, pid: u32) -> Option<std::process::ExitStatus> {
        let (_, child) = self
            .children
            .iter_mut()
            .find(|(_, c)| c.id() == pid)
            .expect("a child of this test");
        child.try_wait().unwrap()
    }

    /// One field of `modbot ls` for `module`, by column title (`ADDR`, `NAME`, `PID`, `STATE`,
    /// `MODE`, `RESTARTS`, `LAST EXIT`, `DROPPED`, `REJECT`, `REPLAY`, `METHODS`).
    pub fn ls_field(&self, module: &str, column: &str) -> Option<String> {
        let out = self.modbot(&["ls", "--tsv"]);
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        ls_field(&text, module, column)
    }

    pub fn name(&self) -> &str {
        self.domain.name()
    }

    /// Starts a module program in this domain.
    pub fn spawn(&mut self, program: &str, args: &[&str]) -> u32 {
        let child = self
            .command(program)
            .args(args)
            .env("MODBOT_DOMAIN", self.name())
            .env("RUST_LOG", "info")
            .envs(self.env.iter().map(|(k, v)| (k, v)))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {program}: {e}"));
        let pid = child.id();
        self.children.push((program.to_owned(), child));
        pid
    }

    /// Runs `modbot ARGS` in this domain. A tool's short default wait (`call` 2 s, `bus` 1 s,
    /// `assembly switch` 30 s) is what an operator wants, not what a loaded machine gives a
    /// test: unless the test chooses one, these wait up to 60 s (an answer still returns at
    /// once).
    pub fn modbot(&self, args: &[&str]) -> Output {
        self.modbot_with_input(args, "")
    }

    /// `modbot record compare A B`: its exit code and what it printed.
    pub fn record_compare(
        &self,
        a: &std::path::Path,
        b: &std::path::Path,
    ) -> (Option<i32>, String) {
        let out = self.modbot(&[
            "record",
            "compare",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
        ]);
        let said = String::from_utf8_lossy(&out.stdout).into_owned();
        (out.status.code(), said)
    }

    /// Runs `modbot ARGS` in this domain with `input` on its standard input.
    pub fn modbot_with_input(&self, args: &[&str], input: &str) -> Output {
        self.modbot_at(None, args, input)
    }

    /// Runs `modbot ARGS` in this domain in the directory `dir` (what it writes to relative
    /// paths goes there).
    pub fn modbot_in(&self, dir: &std::path::Path, args: &[&str]) -> Output {
        self.modbot_at(Some(dir), args, "")
    }

    fn modbot_at(&self, dir: Option<&std::path::Path>, args: &[&str], input: &str) -> Output {
        use std::io::Write;
        let mut command = self.command("modbot");
        if let Some(dir) = dir {
            command.current_dir(dir);
        }
        let mut child = command
            .args(args)
            .args(generous_wait(args))
            .env("MODBOT_DOMAIN", self.name())
            .envs(self.env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut stdin = child.stdin.take().unwrap();
        stdin.write_all(input.as_bytes()).unwrap();
        drop(stdin);
        child.wait_with_output().unwrap()
    }

    /// Runs `modbot ARGS` and returns stdout, asserting success.
    pub fn modbot_ok(&self, args: &[&str]) -> String {
        let out = self.modbot(args);
        assert!(
            out.status.success(),
            "modbot {args:?} failed: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    }

    /// Waits until `f` holds, or panics after `timeout`.
    pub fn wait_for(&self, what: &str, timeout: Duration, mut f: impl FnMut() -> bool) {
        modbot_testkit::wait_until(
            what,
            timeout,
            || {
                if f() {
                    Ok(())
                } else {
                    Err("no".into())
                }
            },
        );
    }

    /// Waits until `f` says yes, or panics after `timeout` with what `f` saw last.
    pub fn wait_until(&self, what: &str, timeout: Duration, f: impl FnMut() -> Result<(), String>) {
        modbot_testkit::wait_until(what, timeout, f);
    }

    /// Sends `signal` to the child with `pid`.
    pub fn signal(&self, pid: u32, signal: nix::sys::signal::Signal) {
        nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid as i32), signal).unwrap();
    }

    /// Reaps the child with `pid` (after it was killed), returning how it ended.
    pub fn reap(&mut self, pid: u32) -> std::process::ExitStatus {
        let i = self
            .children
            .iter()
            .position(|(_, c)| c.id() == pid)
            .expect("a child of this test");
        let (_, mut child) = self.children.remove(i);
        child.wait().unwrap()
    }

    /// Stops every module with SIGTERM and checks each exits cleanly (status 0).
    pub fn stop_all_cleanly(&mut self) {
        for (_, c) in &self.children {
            let _ = nix::sys::signal::kill(
                nix::unistd::Pid::from_raw(c.id() as i32),
                nix::sys::signal::Signal::SIGTERM,
            );
        }
        for (name, mut c) in self.children.drain(..) {
            let status = c.wait().unwrap();
            assert!(status.success(), "{name} did not exit cleanly: {status}");
        }
    }

    /// The domain's files still in /dev/shm or /tmp/iceoryx2.
    pub fn leftover_files(&self) -> Vec<PathBuf> {
        self.domain.files()
    }
}

/// The wait option to add to `modbot ARGS` when the test gives none (see [`TestDomain::modbot`]).
fn generous_wait(args: &[&str]) -> Vec<&'static str> {
    let has = |opt: &str| args.contains(&opt);
    match args {
        ["call" | "bus", ..] if !has("--timeout-ms") => vec!["--timeout-ms", "60000"],
        ["assembly", "switch", ..] if !has("--timeout") => vec!["--timeout", "60"],
        _ => Vec::new(),
    }
}

impl Drop for TestDomain {
    fn drop(&mut self) {
        for (_, c) in &mut self.children {
            let _ = c.kill();
            let _ = c.wait();
        }
        // The domain's files go when `domain` is dropped, after this.
        for f in &self.files {
            if f.is_dir() {
                let _ = std::fs::remove_dir_all(f);
            } else {
                let _ = std::fs::remove_file(f);
            }
        }
    }
}

/// One field of `modbot ls --tsv` output for `module`, by column title.
pub fn ls_field(tsv: &str, module: &str, column: &str) -> Option<String> {
    let mut lines = tsv.lines();
    let header: Vec<&str> = lines.next()?.split('\t').collect();
    let i = header.iter().position(|t| *t == column)?;
    let row = lines.find(|l| l.split('\t').nth(1) == Some(module))?;
    row.split('\t').nth(i).map(str::to_owned)
}
