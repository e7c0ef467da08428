//! Distributed clocks as ethercrab's DC example configures them: static drift compensation
//! during init, system-time alignment in PRE-OP with the PDI (`tx_rx_sync_system_time` until
//! every slave's 0x092C difference settles), `configure_dc_sync` with SYNC0, SAFE-OP, a
//! requested OP reached while `tx_rx_dc` cycles, then cycles whose DC time advances and whose
//! process data the slaves step with dt = the SYNC0 cycle.

mod support;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::DcConfiguration;
use ethercrab::{DcSync, MainDevice, MainDeviceConfig, PduStorage, RegisterAddress};
use futures_lite::future::block_on;
use modbot_ecat_sim::MonotonicClock;
use support::{EchoIo, Wire};

const SLAVES: usize = 6;
const PERIOD: Duration = Duration::from_millis(1);
const CYCLES: usize = 100;

fn signed_difference(raw: u32) -> i64 {
    let magnitude = i64::from(raw & 0x7FFF_FFFF);
    if raw & 0x8000_0000 != 0 {
        -magnitude
    } else {
        magnitude
    }
}

#[test]
fn ethercrab_synchronises_six_slaves_with_distributed_clocks() {
    static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();
    support::with_watchdog(Duration::from_secs(60), || {
        let chain = Arc::new(Mutex::new(support::chain(
            SLAVES,
            MonotonicClock::default(),
        )));
        let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split the PDU storage once");
        let wire = Wire::start(tx, rx, chain.clone());
        let maindevice = MainDevice::new(
            pdu_loop,
            support::timeouts(),
            MainDeviceConfig {
                dc_static_sync_iterations: 1000,
                ..MainDeviceConfig::default()
            },
        );

        block_on(async {
            let mut group = maindevice
                .init_single_group::<8, 128>(ethercat_now)
                .await
                .expect("init to PRE-OP");
            for (position, mut subdevice) in group.iter_mut(&maindevice).enumerate() {
                assert!(subdevice.dc_support().any());
                // The propagation delay grows by one hop (700 ns) per slave.
                assert_eq!(subdevice.propagation_delay(), 700 * position as u32);
                subdevice.set_dc_sync(DcSync::Sync0);
            }
            let group = group
                .into_pre_op_pdi(&maindevice)
                .await
                .expect("PRE-OP with PDI");

            let mut settled = false;
            for _ in 0..200 {
                group
                    .tx_rx_sync_system_time(&maindevice)
                    .await
                    .expect("align");
                let mut worst = 0i64;
                for subdevice in group.iter(&maindevice) {
                    let raw: u32 = subdevice
                        .register_read(RegisterAddress::DcSystemTimeDifference)
                        .await
                        .expect("read 0x092C");
                    worst = worst.max(signed_difference(raw).abs());
                }
                if worst < 100 {
                    settled = true;
                    break;
                }
            }
            assert!(settled, "system times did not settle");

            let group = group
                .configure_dc_sync(
                    &maindevice,
                    DcConfiguration {
                        start_delay: Duration::from_millis(10),
                        sync0_period: PERIOD,
                        sync0_shift: Duration::ZERO,
                    },
                )
                .await
                .expect("configure DC sync");
            let group = group.into_safe_op(&maindevice).await.expect("SAFE-OP");
            let group = group
                .request_into_op(&maindevice)
                .await
                .expect("request OP");
            let mut in_op = false;
            for _ in 0..1000 {
                if group.tx_rx_dc(&maindevice).await.expect("cycle").all_op() {
                    in_op = true;
                    break;
                }
            }
            assert!(in_op, "slaves did not reach OP");

            let mut last_time = 0u64;
            for cycle in 0..CYCLES {
                for subdevice in group.iter(&maindevice) {
                    let mut outputs = subdevice.outputs_raw_mut();
                    outputs[0..2].copy_from_slice(&(cycle as u16).to_le_bytes());
                }
                let response = group.tx_rx_dc(&maindevice).await.expect("cycle");
                assert_eq!(response.working_counter, 3 * SLAVES as u16);
                let info = response.extra;
                assert!(info.dc_system_time > last_time, "DC time advances");
                assert!(info.next_cycle_wait <= PERIOD);
                last_time = info.dc_system_time;
                for subdevice in group.iter(&maindevice) {
                    let inputs = subdevice.inputs_raw();
                    assert_eq!(u16::from_le_bytes([inputs[0], inputs[1]]), cycle as u16 + 1);
                }
                std::thread::sleep(info.next_cycle_wait.min(PERIOD));
            }

            let mut chain = chain.lock().unwrap();
            for position in 0..SLAVES {
                let app = chain.application_as::<EchoIo>(position).unwrap();
                assert_eq!(app.last_dt_s, PERIOD.as_secs_f64());
            }
        });
        drop(wire);
    });
}
