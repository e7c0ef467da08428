//! The proof: ethercrab 0.7.1's real `MainDevice`, driven through its own `PduTx`/`PduRx`
//! by a thread that moves frames to and from a `Chain` in memory, brings six emulated slaves
//! INIT → PRE-OP (remapping RxPDO 0x1600 and reassigning 0x1C12 by SDO) → SAFE-OP → OP,
//! reads their identity and name as declared, and exchanges process data whose values and
//! working counter are checked every cycle.

mod support;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use ethercrab::error::{Error, MailboxError};
use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, SubDeviceState};
use futures_lite::future::block_on;
use modbot_ecat_sim::{AlState, ManualClock, MonotonicClock};
use support::{EchoIo, Wire};

const SLAVES: usize = 6;
const MAX_SUBDEVICES: usize = 8;
const MAX_PDI: usize = 128;
const MAX_FRAMES: usize = 16;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
const CYCLES: u16 = 200;

fn abort_code(result: Result<impl std::fmt::Debug, Error>) -> u32 {
    match result {
        Err(Error::Mailbox(MailboxError::Aborted { code, .. })) => u32::from(code),
        other => panic!("expected an SDO abort, got {other:?}"),
    }
}

/// INIT → OP with an SDO remap in PRE-OP, then `CYCLES` cycles of process data.
#[test]
fn ethercrab_brings_six_slaves_to_op_and_exchanges_process_data() {
    static PDU_STORAGE: PduStorage<MAX_FRAMES, MAX_PDU_DATA> = PduStorage::new();
    support::with_watchdog(Duration::from_secs(60), || {
        let chain = Arc::new(Mutex::new(support::chain(
            SLAVES,
            MonotonicClock::default(),
        )));
        let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split the PDU storage once");
        let wire = Wire::start(tx, rx, chain.clone());
        let maindevice =
            MainDevice::new(pdu_loop, support::timeouts(), MainDeviceConfig::default());

        block_on(async {
            let group = maindevice
                .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(ethercat_now)
                .await
                .expect("init to PRE-OP");
            assert_eq!(group.len(), SLAVES);

            for (position, subdevice) in group.iter(&maindevice).enumerate() {
                assert_eq!(subdevice.name(), support::name(position));
                assert_eq!(subdevice.configured_address(), 0x1000 + position as u16);
                let identity = subdevice.identity();
                let expected = support::identity(position);
                assert_eq!(identity.vendor_id, expected.vendor_id);
                assert_eq!(identity.product_id, expected.product_code);
                assert_eq!(identity.revision, expected.revision);
                assert_eq!(identity.serial, expected.serial);
                // The same identity over CoE, and the name in 0x1008 (a normal upload).
                assert_eq!(
                    subdevice.sdo_read::<u32>(0x1018, 2).await.unwrap(),
                    expected.product_code
                );
                assert_eq!(
                    subdevice.sdo_read::<u32>(0x1018, 4).await.unwrap(),
                    expected.serial
                );
                let name: [u8; 7] = subdevice.sdo_read(0x1008, 0).await.unwrap();
                assert_eq!(&name, support::name(position).as_bytes());

                // PRE-OP remap: add the mode byte to RxPDO 0x1600 and reassign 0x1C12.
                subdevice.sdo_write(0x1600, 0, 0u8).await.unwrap();
                subdevice
                    .sdo_write(0x1600, 3, 0x7000_0308u32)
                    .await
                    .unwrap();
                subdevice.sdo_write(0x1600, 0, 3u8).await.unwrap();
                subdevice
                    .sdo_write_array(0x1C12, [0x1600u16])
                    .await
                    .unwrap();
            }

            let first = group.subdevice(&maindevice, 0).unwrap();
            // Refusals, with the abort codes of a real slave stack.
            assert_eq!(
                abort_code(first.sdo_write(0x1600, 1, 0x7000_0110u32).await),
                0x0601_0003
            );
            first.sdo_write(0x1600, 0, 0u8).await.unwrap();
            assert_eq!(
                abort_code(first.sdo_write(0x1600, 4, 0x7777_0110u32).await),
                0x0604_0041
            );
            assert_eq!(
                abort_code(first.sdo_write(0x1600, 4, 0x8000_0120u32).await),
                0x0604_0041
            );
            assert_eq!(
                abort_code(first.sdo_write(0x1600, 0, 0u16).await),
                0x0607_0012
            );
            first.sdo_write(0x1600, 0, 3u8).await.unwrap();
            assert_eq!(
                abort_code(first.sdo_read::<u32>(0x5555, 0).await),
                0x0602_0000
            );
            assert_eq!(
                abort_code(first.sdo_read::<u32>(0x1018, 9).await),
                0x0609_0011
            );
            assert_eq!(
                abort_code(first.sdo_write(0x1018, 1, 5u32).await),
                0x0601_0002
            );
            first.sdo_write(0x8000, 1, 7u32).await.unwrap();
            assert_eq!(first.sdo_read::<u32>(0x8000, 1).await.unwrap(), 7);

            let group = group
                .into_op(&maindevice)
                .await
                .expect("PRE-OP -> SAFE-OP -> OP");
            {
                let chain = chain.lock().unwrap();
                for position in 0..SLAVES {
                    let slave = chain.slave(position).unwrap();
                    assert_eq!(slave.al_state(), AlState::Op);
                    assert_eq!(slave.outputs_layout().bytes(), 7);
                    assert_eq!(slave.inputs_layout().bytes(), 6);
                }
            }

            for cycle in 0..CYCLES {
                for (position, subdevice) in group.iter(&maindevice).enumerate() {
                    let mut outputs = subdevice.outputs_raw_mut();
                    assert_eq!(outputs.len(), 7);
                    outputs[0..2].copy_from_slice(&cycle.to_le_bytes());
                    let setpoint = position as i32 * 1000 - i32::from(cycle);
                    outputs[2..6].copy_from_slice(&setpoint.to_le_bytes());
                    outputs[6] = position as u8;
                }
                let response = group.tx_rx(&maindevice).await.expect("cycle");
                assert_eq!(response.working_counter, 3 * SLAVES as u16, "cycle {cycle}");
                assert!(response.all_op());
                for (position, subdevice) in group.iter(&maindevice).enumerate() {
                    let inputs = subdevice.inputs_raw();
                    assert_eq!(inputs.len(), 6);
                    let status = u16::from_le_bytes([inputs[0], inputs[1]]);
                    let actual = i32::from_le_bytes([inputs[2], inputs[3], inputs[4], inputs[5]]);
                    let setpoint = position as i32 * 1000 - i32::from(cycle);
                    assert_eq!(
                        status,
                        cycle.wrapping_add(1),
                        "slave {position}, cycle {cycle}"
                    );
                    assert_eq!(
                        actual,
                        2 * setpoint + position as i32,
                        "slave {position}, cycle {cycle}"
                    );
                }
            }

            let mut chain = chain.lock().unwrap();
            for position in 0..SLAVES {
                assert_eq!(chain.slave(position).unwrap().steps(), u64::from(CYCLES));
                let app = chain.application_as::<EchoIo>(position).unwrap();
                assert_eq!(app.last_dt_s, 0.001);
            }
        });
        drop(wire);
    });
}

/// Faults seen by the real master: lost frames time out, a slave that loses power drops out
/// with every slave behind it (working counter, states), and returns in INIT; outputs that
/// stop for longer than the sync manager watchdog (100 ms) send the slaves to SAFE-OP with
/// error 0x001B.
#[test]
fn ethercrab_sees_lost_frames_a_slave_losing_power_and_the_watchdog() {
    static PDU_STORAGE: PduStorage<MAX_FRAMES, MAX_PDU_DATA> = PduStorage::new();
    support::with_watchdog(Duration::from_secs(60), || {
        let clock = ManualClock::new(1_000_000_000);
        let chain = Arc::new(Mutex::new(support::chain(SLAVES, clock.clone())));
        let (tx, rx, pdu_loop) = PDU_STORAGE.try_split().expect("split the PDU storage once");
        let wire = Wire::start(tx, rx, chain.clone());
        let maindevice =
            MainDevice::new(pdu_loop, support::timeouts(), MainDeviceConfig::default());

        block_on(async {
            let group = maindevice
                .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(ethercat_now)
                .await
                .expect("init to PRE-OP");
            let group = group.into_op(&maindevice).await.expect("to OP");
            let response = group.tx_rx(&maindevice).await.unwrap();
            assert_eq!(response.working_counter, 18);

            chain.lock().unwrap().lose_next_frames(1);
            assert!(matches!(
                group.tx_rx(&maindevice).await,
                Err(Error::Timeout(_))
            ));
            assert_eq!(group.tx_rx(&maindevice).await.unwrap().working_counter, 18);

            chain.lock().unwrap().power_off(4);
            let response = group.tx_rx(&maindevice).await.unwrap();
            // Slaves 4 and 5 no longer count; their state-check datagrams come back
            // unanswered (ethercrab reads states from the data without looking at their
            // working counter, so the working counter is the observable here).
            assert_eq!(response.working_counter, 12);

            chain.lock().unwrap().power_on(4);
            let response = group.tx_rx(&maindevice).await.unwrap();
            // Slave 4 is back in INIT with station address 0: it no longer answers to its
            // old address nor maps process data; slave 5 answers again.
            assert_eq!(response.working_counter, 15);
            assert_eq!(
                chain.lock().unwrap().slave(4).unwrap().al_state(),
                AlState::Init
            );
            assert_eq!(response.subdevice_states[5], SubDeviceState::Op);

            clock.advance(50_000_000);
            assert!(
                group.tx_rx(&maindevice).await.unwrap().subdevice_states[0] == SubDeviceState::Op
            );
            clock.advance(150_000_000);
            let response = group.tx_rx(&maindevice).await.unwrap();
            assert_eq!(response.subdevice_states[0], SubDeviceState::SafeOp);
            let chain = chain.lock().unwrap();
            let first = chain.slave(0).unwrap();
            assert_eq!(first.al_state(), AlState::SafeOp);
            assert!(first.al_error());
            assert_eq!(first.al_status_code(), 0x001B);
        });
        drop(wire);
    });
}
