//! The bus bridge's record of switches. The golden record: a 24-byte header (magic, version,
//! reserved 5, count 6..8, max step 8..16, max velocity step 16..24), then one 40-byte record
//! (generation, 6 reserved bytes, tick 32..40, missed, step 48..56, velocity step 56..64).

use modbot_ipc_schema::bus::{decode, SwitchesError};

use crate::support::golden;

fn record() -> Vec<u8> {
    golden("switches max_step=")
}

fn with_step(step: f64) -> Option<SwitchesError> {
    let mut bytes = record();
    bytes[48..56].copy_from_slice(&step.to_le_bytes());
    decode(&bytes).err()
}

#[test]
fn bytes_shorter_than_the_header_are_refused() {
    assert_eq!(decode(&record()[..23]), Err(SwitchesError::Size(23)));
}

#[test]
fn a_record_of_another_magic_is_refused() {
    let mut bytes = record();
    bytes[0] = b'X';
    assert!(matches!(decode(&bytes), Err(SwitchesError::Magic(_))));
}

#[test]
fn a_record_of_another_version_is_refused() {
    let mut bytes = record();
    bytes[4] = 2;
    assert_eq!(decode(&bytes), Err(SwitchesError::Version(2)));
}

#[test]
fn a_byte_after_the_last_record_is_refused() {
    let mut bytes = record();
    bytes.push(0);
    assert_eq!(
        decode(&bytes),
        Err(SwitchesError::Count {
            count: 1,
            expected: 64,
            len: 65
        })
    );
}

#[test]
fn a_step_that_is_nan_is_refused() {
    assert!(matches!(
        with_step(f64::NAN),
        Some(SwitchesError::Step { .. })
    ));
}

#[test]
fn an_infinite_step_is_refused() {
    assert!(matches!(
        with_step(f64::INFINITY),
        Some(SwitchesError::Step { .. })
    ));
}

#[test]
fn a_negative_step_is_refused() {
    assert!(matches!(with_step(-0.5), Some(SwitchesError::Step { .. })));
}

#[test]
fn a_reader_of_the_bus_bridges_switches_ignores_its_reserved_bytes() {
    let mut bytes = record();
    let golden = decode(&bytes).unwrap();
    bytes[5] = 0xaa; // header
    bytes[24 + 2..24 + 8].fill(0xbb); // the record's
    assert_eq!(decode(&bytes), Ok(golden));
}

#[test]
fn records_need_not_be_in_tick_order() {
    let mut bytes = record();
    bytes[6] = 2;
    bytes.extend_from_within(24..64);
    bytes[64 + 8..64 + 16].copy_from_slice(&0u64.to_le_bytes()); // the second at tick 0
    let read = decode(&bytes).unwrap();
    assert_eq!(
        read.switches.iter().map(|s| s.tick).collect::<Vec<_>>(),
        [5114, 0]
    );
}
