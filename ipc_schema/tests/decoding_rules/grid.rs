//! Grid notices and output records. The golden release notice is 160 bytes (tick, released,
//! component 16..18, sources 18..20, generation, flags 22..24, version slots from 24, state
//! hash 152..160); the done notice 40 (tick, component 8..10, status 10..12, generation, flags
//! 14..16, exec, latency, state hash 32..40);
//! the prepare notice 64 (generation, name length 2..4, name from 4).

use modbot_ipc_schema::grid::{
    read_record, Done, GridWireError, PortValue, Prepare, PrepareNameError, Release, READY,
};

use crate::support::golden;

fn release() -> Vec<u8> {
    golden("release tick=5")
}

fn done() -> Vec<u8> {
    golden("done tick=5")
}

fn prepare() -> Vec<u8> {
    golden("prepare generation=4")
}

fn release_refused(bytes: &[u8]) -> Option<GridWireError> {
    Release::batch(bytes).err()
}

fn done_refused(bytes: &[u8]) -> Option<GridWireError> {
    Done::batch(bytes).err()
}

fn prepare_refused(bytes: &[u8]) -> Option<GridWireError> {
    Prepare::parse(bytes).err()
}

#[test]
fn a_release_sample_that_is_not_whole_notices_is_refused() {
    let mut bytes = release();
    bytes.push(0);
    assert_eq!(
        release_refused(&bytes),
        Some(GridWireError::Length {
            expected: 160,
            got: 161
        })
    );
}

#[test]
fn an_empty_sample_is_refused() {
    assert!(matches!(
        done_refused(&[]),
        Some(GridWireError::Length { got: 0, .. })
    ));
}

#[test]
fn a_release_naming_more_than_16_sources_is_refused() {
    let mut bytes = release();
    bytes[18] = 17;
    assert_eq!(
        release_refused(&bytes),
        Some(GridWireError::TooManySources(17))
    );
}

#[test]
fn one_malformed_notice_refuses_the_whole_sample() {
    let mut bytes = release();
    bytes.extend(release());
    bytes[160 + 18] = 17; // the second notice's sources
    assert_eq!(
        release_refused(&bytes),
        Some(GridWireError::TooManySources(17))
    );
}

#[test]
fn a_release_reader_ignores_the_unused_version_slots() {
    let mut bytes = release();
    bytes[24 + 8 * 2..].fill(0xee); // slots 2..16, past the 2 sources
    let read = Release::batch(&bytes).unwrap().next().unwrap();
    assert_eq!(read.versions().collect::<Vec<_>>(), [4, 3]);
}

#[test]
fn a_release_reader_ignores_unknown_flag_bits() {
    let mut bytes = release();
    bytes[23] |= 0x80; // bit 15
    let read = Release::batch(&bytes).unwrap().next().unwrap();
    assert_eq!(
        [Release::TRACK, Release::SAFE_STOP, Release::HELD].map(|f| read.has(f)),
        [false, true, false]
    );
}

#[test]
fn a_done_notice_with_an_unknown_status_is_refused() {
    let mut bytes = done();
    bytes[10] = 4;
    assert_eq!(
        done_refused(&bytes),
        Some(GridWireError::UnknownStatus {
            component: 2,
            status: 4
        })
    );
}

#[test]
fn a_ready_answer_with_a_status_other_than_0_or_1_is_refused() {
    let mut bytes = done();
    bytes[8..10].copy_from_slice(&READY.to_le_bytes());
    bytes[10] = 2;
    assert_eq!(
        done_refused(&bytes),
        Some(GridWireError::UnknownStatus {
            component: READY,
            status: 2
        })
    );
}

#[test]
fn a_done_reader_ignores_unknown_flag_bits() {
    let mut bytes = done();
    bytes[15] = 0x80; // bit 15
    let read = Done::batch(&bytes).unwrap().next().unwrap();
    assert!(!read.has(Done::HOLDING));
}

#[test]
fn a_done_reader_takes_the_state_hash_only_with_its_flag() {
    let mut bytes = done();
    bytes[32..40].fill(0xab); // a hash without HASHED
    let read = Done::batch(&bytes).unwrap().next().unwrap();
    assert_eq!(read.hash(), None);
    let hashed = golden("done tick=6");
    let read = Done::batch(&hashed).unwrap().next().unwrap();
    assert_eq!(read.hash(), Some(0x0123_4567_89ab_cdef));
}

#[test]
fn a_done_notice_of_the_older_32_byte_format_is_refused_for_its_length() {
    assert_eq!(
        done_refused(&done()[..32]),
        Some(GridWireError::Length {
            expected: 40,
            got: 32
        })
    );
}

#[test]
fn a_prepare_notice_of_another_length_is_refused() {
    assert_eq!(
        prepare_refused(&prepare()[..63]),
        Some(GridWireError::Length {
            expected: 64,
            got: 63
        })
    );
}

#[test]
fn a_prepare_notice_with_an_empty_name_is_refused() {
    let mut bytes = prepare();
    bytes[2] = 0;
    assert_eq!(
        prepare_refused(&bytes),
        Some(PrepareNameError::Length(0).into())
    );
}

#[test]
fn a_prepare_notice_with_a_name_longer_than_60_bytes_is_refused() {
    let mut bytes = prepare();
    bytes[2] = 61;
    assert_eq!(
        prepare_refused(&bytes),
        Some(PrepareNameError::Length(61).into())
    );
}

#[test]
fn a_prepare_notice_whose_name_is_not_utf8_is_refused() {
    let mut bytes = prepare();
    bytes[4] = 0xff;
    assert_eq!(
        prepare_refused(&bytes),
        Some(PrepareNameError::NotUtf8.into())
    );
}

#[test]
fn a_prepare_notice_with_nonzero_padding_after_its_name_is_refused() {
    let mut bytes = prepare();
    bytes[7] = b'x'; // right after "ptp"
    assert_eq!(
        prepare_refused(&bytes),
        Some(PrepareNameError::Padding.into())
    );
}

#[test]
fn a_record_bool_other_than_0_or_1_is_refused() {
    let mut bytes = golden("record bool=true");
    bytes[0] = 2;
    let mut values = [
        PortValue::Bool(false),
        PortValue::I64(0),
        PortValue::F64(0.0),
        PortValue::F64s(vec![0.0; 2]),
    ];
    assert_eq!(
        read_record(&bytes, &mut values),
        Err(GridWireError::BadBool(2))
    );
}

#[test]
fn a_record_of_another_length_than_its_ports_is_refused() {
    let bytes = golden("record bool=true");
    let mut values = [PortValue::Bool(false), PortValue::I64(0)];
    assert_eq!(
        read_record(&bytes, &mut values),
        Err(GridWireError::Length {
            expected: 16,
            got: 40
        })
    );
}

#[test]
fn a_record_f64_is_read_as_its_bits_so_infinity_is_a_value() {
    let mut bytes = golden("record bool=true");
    bytes[16..24].copy_from_slice(&f64::INFINITY.to_le_bytes());
    let mut values = [
        PortValue::Bool(false),
        PortValue::I64(0),
        PortValue::F64(0.0),
        PortValue::F64s(vec![0.0; 2]),
    ];
    read_record(&bytes, &mut values).unwrap();
    assert_eq!(values[2], PortValue::F64(f64::INFINITY));
}
