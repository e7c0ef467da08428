//! Blackboard snapshots. The golden snapshot holds `moving` (bool), `x` (f64, writable) and `y`
//! (f64): its header is bytes 0..40, its entries 40..88 (16 bytes each: name offset, name
//! length, kind, flags, value offset, value length), its names 88..96 and its values 96..113.

use modbot_ipc_schema::snapshot::{ItemSpec, SnapshotError};
use modbot_ipc_schema::{Addr, SnapshotLayout, SnapshotView, Value, ValueKind};

use crate::support::golden;

/// The golden snapshot of three plain items.
fn plain() -> Vec<u8> {
    golden("snapshot addr=2")
}

/// The golden snapshot of `a` (f64) and the bulk item `img` (value at 128, after 44 bytes of
/// padding).
fn bulk() -> Vec<u8> {
    golden("snapshot addr=3")
}

/// Entry `index`'s field at `offset` (0 name offset, 4 name length, 6 kind, 7 flags, 8 value
/// offset, 12 value length).
fn entry(index: usize, offset: usize) -> usize {
    40 + 16 * index + offset
}

fn put_u32(bytes: &mut [u8], at: usize, value: u32) {
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}

fn refused(bytes: &[u8]) -> Option<SnapshotError> {
    SnapshotView::parse(bytes).err()
}

#[test]
fn a_buffer_longer_than_the_snapshots_total_length_is_refused() {
    let mut bytes = plain();
    bytes.push(0);
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::LengthMismatch {
            declared: 113,
            actual: 114
        })
    );
}

#[test]
fn a_total_length_past_the_end_of_the_last_value_is_refused() {
    let mut bytes = plain();
    bytes.push(0);
    put_u32(&mut bytes, 12, 114);
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::TrailingBytes {
            end: 113,
            declared: 114
        })
    );
}

#[test]
fn a_snapshot_of_another_magic_is_refused() {
    let mut bytes = plain();
    bytes[0] = b'X';
    assert!(matches!(refused(&bytes), Some(SnapshotError::BadMagic(_))));
}

#[test]
fn a_snapshot_of_another_version_is_refused() {
    let mut bytes = plain();
    bytes[4] = 2;
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::UnsupportedVersion {
            found: 2,
            supported: 1
        })
    );
}

#[test]
fn an_item_table_that_does_not_fit_in_the_buffer_is_refused() {
    let mut bytes = plain();
    bytes[8..10].copy_from_slice(&u16::MAX.to_le_bytes());
    assert!(matches!(
        refused(&bytes),
        Some(SnapshotError::Truncated { .. })
    ));
}

#[test]
fn an_unknown_kind_code_is_refused() {
    let mut bytes = plain();
    bytes[entry(0, 6)] = 7;
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::BadItemKind { index: 0, code: 7 })
    );
}

#[test]
fn a_bulk_flag_on_an_item_that_is_not_bytes_is_refused() {
    let mut bytes = plain();
    bytes[entry(0, 7)] |= 2;
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::BulkNotBytes {
            index: 0,
            kind: ValueKind::Bool
        })
    );
}

#[test]
fn a_name_that_overlaps_another_is_refused() {
    let mut bytes = plain();
    put_u32(&mut bytes, entry(1, 0), 88); // x's name on moving's
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::NameMisplaced {
            index: 1,
            expected: 94,
            found: 88
        })
    );
}

#[test]
fn a_value_that_overlaps_another_is_refused() {
    let mut bytes = plain();
    put_u32(&mut bytes, entry(2, 8), 97); // y's value on x's
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::ValueMisplaced {
            index: 2,
            expected: 105,
            found: 97
        })
    );
}

#[test]
fn a_bulk_value_off_its_64_byte_boundary_is_refused() {
    let mut bytes = bulk();
    put_u32(&mut bytes, entry(1, 8), 120);
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::ValueMisplaced {
            index: 1,
            expected: 128,
            found: 120
        })
    );
}

#[test]
fn a_value_that_runs_past_the_buffer_is_refused() {
    let mut bytes = plain();
    put_u32(&mut bytes, entry(2, 12), 9);
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::ItemOutOfBounds { index: 2 })
    );
}

#[test]
fn a_name_that_is_not_utf8_is_refused() {
    let mut bytes = plain();
    bytes[88] = 0xff;
    assert_eq!(refused(&bytes), Some(SnapshotError::BadName { index: 0 }));
}

#[test]
fn names_out_of_byte_order_are_refused() {
    let mut bytes = plain();
    bytes[94] = b'a'; // moving, a, y
    assert_eq!(refused(&bytes), Some(SnapshotError::Unsorted { index: 1 }));
}

#[test]
fn an_f64_of_another_length_is_refused() {
    let mut bytes = plain();
    put_u32(&mut bytes, entry(2, 12), 7);
    assert!(matches!(
        refused(&bytes),
        Some(SnapshotError::BadItemSize { len: 7, .. })
    ));
}

#[test]
fn a_bool_byte_other_than_0_or_1_is_refused() {
    let mut bytes = plain();
    bytes[96] = 2;
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::BadBool {
            name: "moving".into(),
            byte: 2
        })
    );
}

#[test]
fn a_text_value_that_is_not_utf8_is_refused() {
    let layout = SnapshotLayout::new(vec![ItemSpec::new("t", ValueKind::Text, false)]).unwrap();
    let values = [Value::Text("ok")];
    let mut bytes = vec![0; layout.encoded_len(&values)];
    layout.write(&mut bytes, Addr(1), 1, 1, &values).unwrap();
    bytes[57] = 0xff;
    assert_eq!(
        refused(&bytes),
        Some(SnapshotError::BadText { name: "t".into() })
    );
}

#[test]
fn an_f64_item_is_read_as_its_bits_so_nan_is_a_value() {
    let mut bytes = plain();
    bytes[97..105].copy_from_slice(&f64::NAN.to_le_bytes());
    assert!(SnapshotView::parse(&bytes)
        .unwrap()
        .f64("x")
        .unwrap()
        .is_nan());
}

#[test]
fn a_layout_hash_that_does_not_match_the_items_is_refused() {
    let mut bytes = plain();
    bytes[16] ^= 1;
    assert!(matches!(
        refused(&bytes),
        Some(SnapshotError::HashMismatch { .. })
    ));
}

#[test]
fn a_reader_expecting_another_layout_refuses_the_snapshot() {
    let bytes = plain();
    assert!(matches!(
        SnapshotView::parse_expecting(&bytes, 1).err(),
        Some(SnapshotError::LayoutMismatch { expected: 1, .. })
    ));
}

#[test]
fn a_snapshot_reader_ignores_header_flags_reserved_bytes_and_unknown_entry_flags() {
    let mut bytes = plain();
    bytes[7] = 0xff; // header flags
    bytes[10] = 0xff; // reserved
    bytes[entry(0, 7)] |= 0xfc; // entry 0's flags, bits 2..7
    let view = SnapshotView::parse(&bytes).unwrap();
    assert_eq!(view.iter().count(), 3);
}

#[test]
fn a_snapshot_reader_ignores_the_padding_before_a_bulk_value() {
    let mut bytes = bulk();
    bytes[84..128].fill(0xaa);
    assert_eq!(
        SnapshotView::parse(&bytes)
            .unwrap()
            .bulk::<u8>("img")
            .unwrap(),
        &bulk()[128..136]
    );
}
