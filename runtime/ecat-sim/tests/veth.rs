//! On a real veth pair, in a network namespace this test creates (and deletes): ethercrab's
//! own raw-socket TX/RX task on one end, `socket::serve` on the other, three slaves brought
//! to OP and 50 cycles of process data checked. It needs root (to create the namespace and
//! open raw sockets); without it, it says so and passes as skipped.

mod support;

use std::fs::File;
use std::os::fd::AsRawFd;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use ethercrab::std::{ethercat_now, tx_rx_task};
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage};
use futures_lite::future::block_on;
use modbot_ecat_sim::{serve, MonotonicClock};

/// A namespace holding a veth pair, deleted on drop.
struct VethNamespace {
    name: String,
    master_end: String,
    slave_end: String,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let output = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("ip: {e}"))?;
    if output.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&output.stderr).trim()
        ))
    }
}

impl VethNamespace {
    fn create(tag: &str) -> Result<Self, String> {
        let id = std::process::id();
        let ns = Self {
            name: format!("ecatsim-{tag}-{id}"),
            master_end: format!("ecm{}", id % 100_000),
            slave_end: format!("ecs{}", id % 100_000),
        };
        ip(&["netns", "add", &ns.name])?;
        ip(&[
            "-n",
            &ns.name,
            "link",
            "add",
            &ns.master_end,
            "type",
            "veth",
            "peer",
            "name",
            &ns.slave_end,
        ])?;
        ip(&["-n", &ns.name, "link", "set", &ns.master_end, "up"])?;
        ip(&["-n", &ns.name, "link", "set", &ns.slave_end, "up"])?;
        // Wait for both ends to report carrier, or the first frames vanish.
        for _ in 0..200 {
            let up = [&ns.master_end, &ns.slave_end].iter().all(|end| {
                Command::new("ip")
                    .args(["-n", &ns.name, "link", "show", end])
                    .output()
                    .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("state UP"))
            });
            if up {
                return Ok(ns);
            }
            thread::sleep(Duration::from_millis(10));
        }
        Err(format!("the veth pair in {} did not come up", ns.name))
    }
}

/// Moves the calling thread into namespace `name` (sockets it opens live there).
fn enter(name: &str) {
    let file = File::open(format!("/var/run/netns/{name}")).expect("open the namespace");
    // SAFETY: setns(2) on a valid namespace descriptor; it only changes this thread's
    // network namespace.
    let rc = unsafe { libc::setns(file.as_raw_fd(), libc::CLONE_NEWNET) };
    assert_eq!(rc, 0, "setns: {}", std::io::Error::last_os_error());
}

impl Drop for VethNamespace {
    fn drop(&mut self) {
        let _ = ip(&["netns", "del", &self.name]);
    }
}

#[test]
fn ethercrab_brings_slaves_to_op_over_a_veth_pair() {
    // SAFETY: geteuid(2) has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        eprintln!("skipped: the veth test needs root (ip netns, raw sockets)");
        return;
    }
    let ns = match VethNamespace::create("op") {
        Ok(ns) => ns,
        Err(error) => {
            eprintln!("skipped: cannot create a network namespace with a veth pair: {error}");
            return;
        }
    };
    static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

    let chain = Arc::new(Mutex::new(support::chain(3, MonotonicClock::default())));
    let stop = Arc::new(AtomicBool::new(false));
    let server = {
        let (name, end, chain, stop) = (
            ns.name.clone(),
            ns.slave_end.clone(),
            chain.clone(),
            stop.clone(),
        );
        thread::spawn(move || {
            enter(&name);
            serve(&end, &chain, &stop)
        })
    };

    let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split the PDU storage once");
    {
        // ethercrab's TX/RX task runs until the process ends; the namespace is deleted
        // under it when the test is done (its socket keeps it alive until then).
        let (name, end) = (ns.name.clone(), ns.master_end.clone());
        thread::spawn(move || {
            enter(&name);
            let task = tx_rx_task(&end, tx, rx).expect("open ethercrab's raw socket");
            let _ = block_on(task);
        });
    }
    // Both raw sockets must be open before the first frame: ethercrab does not retry.
    thread::sleep(Duration::from_millis(200));
    let maindevice = MainDevice::new(
        pdu_loop,
        support::timeouts(),
        MainDeviceConfig {
            dc_static_sync_iterations: 100,
            ..MainDeviceConfig::default()
        },
    );

    support::with_watchdog(Duration::from_secs(60), move || {
        block_on(async {
            let group = maindevice
                .init_single_group::<8, 64>(ethercat_now)
                .await
                .expect("init over the veth pair");
            assert_eq!(group.len(), 3);
            for (position, subdevice) in group.iter(&maindevice).enumerate() {
                assert_eq!(subdevice.name(), support::name(position));
            }
            let group = group.into_op(&maindevice).await.expect("to OP");
            for cycle in 0..50u16 {
                for subdevice in group.iter(&maindevice) {
                    subdevice.outputs_raw_mut()[0..2].copy_from_slice(&cycle.to_le_bytes());
                }
                let response = group.tx_rx(&maindevice).await.expect("cycle");
                assert_eq!(response.working_counter, 9);
                for subdevice in group.iter(&maindevice) {
                    let inputs = subdevice.inputs_raw();
                    assert_eq!(u16::from_le_bytes([inputs[0], inputs[1]]), cycle + 1);
                }
            }
        });
    });

    stop.store(true, Ordering::Relaxed);
    let stats = server.join().expect("server thread").expect("serve");
    assert!(stats.frames > 50);
    assert_eq!(stats.refused, 0);
    drop(ns);
}

#[test]
fn serving_on_a_missing_interface_names_it() {
    let chain = Mutex::new(support::chain(1, MonotonicClock::default()));
    let stop = AtomicBool::new(true);
    match serve("no-such-if0", &chain, &stop) {
        Err(error) => {
            let text = error.to_string();
            assert!(
                text.contains("no-such-if0") || text.contains("CAP_NET_RAW"),
                "{text}"
            );
        }
        Ok(_) => panic!("serving on a missing interface succeeded"),
    }
}
