//! An EtherCAT segment for the tests: a veth pair in a network namespace of the test's own,
//! the slave emulator `modbot-ecat-sim` on one end, the master's end named; all removed on drop.

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use super::bin;

/// A network namespace this test made: deleted when dropped (with the veth pair in it), also
/// when the test fails half-way.
pub struct Netns(pub String);

impl Drop for Netns {
    fn drop(&mut self) {
        let _ = Command::new("ip").args(["netns", "del", &self.0]).status();
    }
}

/// A veth pair in a network namespace of its own, with the slave emulator on one end.
pub struct Segment {
    pub emulator: Child,
    /// Deleted after the emulator is killed (`Drop for Segment` kills it first).
    pub netns: Netns,
    /// The master's end.
    pub master: String,
    pub commands: ChildStdin,
    pub answers: mpsc::Receiver<String>,
}

pub fn ip(args: &[&str]) {
    let out = Command::new("ip").args(args).output().unwrap_or_else(|e| {
        panic!("cannot run `ip` (iproute2; ./setup.sh --tests installs it): {e}")
    });
    assert!(
        out.status.success(),
        "ip {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

impl Segment {
    /// A segment of `slaves` emulated drives, with more arguments for the emulator.
    pub fn new(slaves: usize, more: &[&str]) -> Segment {
        assert!(
            nix::unistd::Uid::effective().is_root(),
            "the EtherCAT tests make network namespaces and raw sockets: run them as root (CI does)"
        );
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let id = format!(
            "{:x}{}",
            std::process::id() & 0xfffff,
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        let (ns, master, slave) = (
            format!("modbot-ec-{id}"),
            format!("ecm{id}"),
            format!("ecs{id}"),
        );
        // Everything that can fail before the namespace exists comes first.
        let emulator_program = bin("modbot-ecat-sim");
        ip(&["netns", "add", &ns]);
        let netns = Netns(ns.clone());
        ip(&[
            "-n", &ns, "link", "add", &master, "type", "veth", "peer", "name", &slave,
        ]);
        ip(&["-n", &ns, "link", "set", &master, "up"]);
        ip(&["-n", &ns, "link", "set", &slave, "up"]);
        // Frames sent before both ends have carrier vanish.
        let carrier = |end: &str| {
            Command::new("ip")
                .args(["-n", &ns, "link", "show", end])
                .output()
                .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("state UP"))
        };
        for _ in 0..500 {
            if carrier(&master) && carrier(&slave) {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let n = slaves.to_string();
        let mut emulator = Command::new("ip")
            .args(["netns", "exec", &ns])
            .arg(&emulator_program)
            .args(["--interface", &slave, "--slaves", &n])
            .args(more)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start modbot-ecat-sim");
        let commands = emulator.stdin.take().unwrap();
        let out = emulator.stdout.take().unwrap();
        let (tx, answers) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut segment = Segment {
            emulator,
            netns,
            master,
            commands,
            answers,
        };
        let ready = segment.answer();
        assert!(ready.starts_with("serving"), "the emulator said: {ready}");
        segment
    }

    pub fn answer(&mut self) -> String {
        self.answers
            .recv_timeout(Duration::from_secs(60))
            .expect("an answer of the emulator")
    }

    /// Sends the emulator a command: its answer.
    pub fn command(&mut self, line: &str) -> String {
        writeln!(self.commands, "{line}").unwrap();
        self.commands.flush().unwrap();
        let answer = self.answer();
        assert!(answer.starts_with("ok"), "{line}: {answer}");
        answer
    }

    /// Runs `modbot ARGS` inside the namespace: its output.
    pub fn modbot(&self, args: &[&str]) -> std::process::Output {
        Command::new("ip")
            .args(["netns", "exec", &self.netns.0])
            .arg(bin("modbot"))
            .args(args)
            .output()
            .unwrap()
    }
}

impl Drop for Segment {
    fn drop(&mut self) {
        let _ = self.emulator.kill();
        let _ = self.emulator.wait();
        // Then `netns` deletes the namespace, and the veth pair in it.
    }
}
