//! Two "hosts" for the remote tests: two network namespaces of the test's own with a veth
//! pair between them (10.77.0.1 in the first, 10.77.0.2 in the second), removed on drop. The
//! link can be cut and restored (`ip link set ... down/up`) like a cable.

use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use super::segment::{ip, Netns};

pub struct TwoHosts {
    pub a: Netns,
    pub b: Netns,
    /// The veth ends: in `a`, in `b`.
    pub ends: (String, String),
}

/// The first host's address on the link.
pub const A_IP: &str = "10.77.0.1";
/// The second host's.
pub const B_IP: &str = "10.77.0.2";

impl TwoHosts {
    pub fn new() -> TwoHosts {
        assert!(
            nix::unistd::Uid::effective().is_root(),
            "the remote tests make network namespaces: run them as root (CI does)"
        );
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let id = format!(
            "{:x}{}",
            std::process::id() & 0xfffff,
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        let (na, nb) = (format!("modbot-ra-{id}"), format!("modbot-rb-{id}"));
        let (ea, eb) = (format!("rva{id}"), format!("rvb{id}"));
        ip(&["netns", "add", &na]);
        let a = Netns(na.clone());
        ip(&["netns", "add", &nb]);
        let b = Netns(nb.clone());
        ip(&[
            "-n", &na, "link", "add", &ea, "type", "veth", "peer", "name", &eb,
        ]);
        ip(&["-n", &na, "link", "set", &eb, "netns", &nb]);
        ip(&["-n", &na, "addr", "add", &format!("{A_IP}/24"), "dev", &ea]);
        ip(&["-n", &nb, "addr", "add", &format!("{B_IP}/24"), "dev", &eb]);
        for (ns, dev) in [
            (&na, "lo"),
            (&nb, "lo"),
            (&na, ea.as_str()),
            (&nb, eb.as_str()),
        ] {
            ip(&["-n", ns, "link", "set", dev, "up"]);
        }
        let hosts = TwoHosts {
            a,
            b,
            ends: (ea, eb),
        };
        for _ in 0..500 {
            if hosts.carrier() {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        hosts
    }

    fn carrier(&self) -> bool {
        let up = |ns: &str, dev: &str| {
            Command::new("ip")
                .args(["-n", ns, "link", "show", dev])
                .output()
                .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("state UP"))
        };
        up(&self.a.0, &self.ends.0) && up(&self.b.0, &self.ends.1)
    }

    /// Cuts the link (`up = false`) or restores it.
    pub fn link(&self, up: bool) {
        let state = if up { "up" } else { "down" };
        ip(&["-n", &self.a.0, "link", "set", &self.ends.0, state]);
        if up {
            for _ in 0..500 {
                if self.carrier() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    }
}
