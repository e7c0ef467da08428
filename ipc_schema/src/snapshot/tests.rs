//! The snapshot format's own tests: golden bytes, reading in place, rejections.

use super::*;
use crate::addr::Addr;
use crate::hex;
use crate::value::Value;

fn layout() -> SnapshotLayout {
    SnapshotLayout::new(vec![
        ItemSpec::new("y", ValueKind::F64, false),
        ItemSpec::new("moving", ValueKind::Bool, false),
        ItemSpec::new("x", ValueKind::F64, true),
    ])
    .unwrap()
}

fn golden() -> Vec<u8> {
    let sut = layout();
    let values = [Value::Bool(true), Value::F64(1.5), Value::F64(-2.0)];
    let mut out = vec![0; sut.encoded_len(&values)];
    sut.write(&mut out, Addr(2), 7, 1000, &values).unwrap();
    out
}

#[test]
fn a_snapshot_encodes_to_the_documented_golden_bytes() {
    let want = concat!(
        "4d424242",
        "0100",
        "02",
        "00",
        "0300",
        "0000",
        "71000000",
        "bba3101c6e56836a",
        "0700000000000000",
        "e803000000000000",
        "58000000",
        "0600",
        "03",
        "00",
        "60000000",
        "01000000",
        "5e000000",
        "0100",
        "01",
        "01",
        "61000000",
        "08000000",
        "5f000000",
        "0100",
        "01",
        "00",
        "69000000",
        "08000000",
        "6d6f76696e67",
        "78",
        "79",
        "01",
        "000000000000f83f",
        "00000000000000c0",
    );
    assert_eq!(hex::encode(&golden()), want);
}

#[test]
fn a_reader_finds_items_by_name_in_place() {
    let bytes = golden();
    let sut = SnapshotView::parse_expecting(&bytes, layout().hash()).unwrap();
    assert_eq!((sut.addr(), sut.seq(), sut.stamp_ns()), (Addr(2), 7, 1000));
    assert_eq!(sut.f64("x").unwrap(), 1.5);
    assert_eq!(sut.f64("y").unwrap(), -2.0);
    assert!(sut.bool("moving").unwrap());
    assert!(sut.get("x").unwrap().writable);
    assert_eq!(
        sut.value("z").unwrap_err(),
        SnapshotError::UnknownItem("z".into())
    );
}

#[test]
fn a_reader_rejects_a_wrong_version_or_layout() {
    let mut bytes = golden();
    assert!(matches!(
        SnapshotView::parse_expecting(&bytes, 1),
        Err(SnapshotError::LayoutMismatch { expected: 1, .. })
    ));
    bytes[4] = 2;
    assert_eq!(
        SnapshotView::parse(&bytes).unwrap_err(),
        SnapshotError::UnsupportedVersion {
            found: 2,
            supported: 1
        }
    );
}

/// A buffer that starts 64-byte aligned, as a shared-memory sample does.
#[repr(C, align(64))]
struct Aligned([u8; 256]);

fn with_bulk() -> SnapshotLayout {
    SnapshotLayout::new(vec![
        ItemSpec::bulk("img", false),
        ItemSpec::new("a", ValueKind::F64, false),
    ])
    .unwrap()
}

#[test]
fn a_bulk_item_starts_64_byte_aligned_and_encodes_to_the_documented_golden_bytes() {
    let sut = with_bulk();
    let img: [u16; 4] = [1, 2, 3, 0xffff];
    let values = [Value::F64(0.5), Value::Bytes(bytemuck::cast_slice(&img))];
    let len = sut.encoded_len(&values);
    let mut out = vec![0xee; len];
    sut.write(&mut out, Addr(3), 1, 2, &values).unwrap();
    let want = concat!(
        "4d424242",
        "0100",
        "03",
        "00",
        "0200",
        "0000",
        "88000000", // 136 bytes
        "fdf72b7c7c9d78d8",
        "0100000000000000",
        "0200000000000000",
        // "a": name at 72, f64, value at 76, 8 bytes
        "48000000",
        "0100",
        "01",
        "00",
        "4c000000",
        "08000000",
        // "img": name at 73, bytes, bulk, value at 128, 8 bytes
        "49000000",
        "0300",
        "05",
        "02",
        "80000000",
        "08000000",
        "61",
        "696d67",
        "000000000000e03f",
        // 44 zero bytes, up to offset 128
        "0000000000000000000000000000000000000000000000000000000000000000",
        "000000000000000000000000",
        "01000200",
        "0300ffff",
    );
    assert_eq!(hex::encode(&out), want);
}

#[test]
fn a_bulk_item_is_viewed_as_a_typed_slice_in_place() {
    let sut = with_bulk();
    let img: [u16; 4] = [1, 2, 3, 0xffff];
    let values = [Value::F64(0.5), Value::Bytes(bytemuck::cast_slice(&img))];
    let len = sut.encoded_len(&values);
    let mut buf = Aligned([0; 256]);
    sut.write(&mut buf.0, Addr(3), 1, 2, &values).unwrap();
    let view = SnapshotView::parse(&buf.0[..len]).unwrap();
    let pixels: &[u16] = view.bulk("img").unwrap();
    assert_eq!(pixels, &img);
    assert_eq!(
        pixels.as_ptr().cast::<u8>(),
        buf.0[128..].as_ptr(),
        "read in place"
    );
    assert!(view.get("img").unwrap().bulk);
    assert_eq!(
        view.bulk::<u16>("a").unwrap_err(),
        SnapshotError::NotBulk("a".into())
    );
    assert!(matches!(
        view.bulk::<[u8; 3]>("img"),
        Err(SnapshotError::BulkView { .. })
    ));
}

#[test]
fn a_bulk_item_in_a_snapshot_that_is_not_aligned_is_refused_with_the_reason() {
    let sut = with_bulk();
    let img = [7u64];
    let values = [Value::F64(0.5), Value::Bytes(bytemuck::cast_slice(&img))];
    let len = sut.encoded_len(&values);
    let mut buf = Aligned([0; 256]);
    sut.write(&mut buf.0[1..], Addr(3), 1, 2, &values).unwrap();
    let view = SnapshotView::parse(&buf.0[1..1 + len]).unwrap();
    let err = view.bulk::<u64>("img").unwrap_err().to_string();
    assert!(err.contains("not aligned"), "{err}");
    assert_eq!(view.bulk::<u8>("img").unwrap(), &7u64.to_le_bytes());
}

#[test]
fn a_layout_refuses_a_bulk_item_that_is_not_bytes() {
    let mut spec = ItemSpec::bulk("x", false);
    spec.kind = ValueKind::F64;
    assert!(matches!(
        SnapshotLayout::new(vec![spec]),
        Err(SnapshotError::WrongKind { .. })
    ));
}

/// The three items of [`layout`] with `x`, and the snapshot `seq` of them written whole.
fn whole(x: f64, moving: bool, seq: u64) -> Vec<u8> {
    let values = [Value::Bool(moving), Value::F64(x), Value::F64(-2.0)];
    let mut out = vec![0; layout().encoded_len(&values)];
    layout()
        .write(&mut out, Addr(2), seq, seq * 10, &values)
        .unwrap();
    out
}

#[test]
fn an_update_writes_only_the_items_changed_since_the_snapshot_in_the_buffer() {
    let sut = layout();
    let mut buf = whole(1.5, true, 4);
    // Snapshot 5 carries a new x (table order: moving, x, y).
    let values = [Value::Bool(true), Value::F64(9.0), Value::F64(-2.0)];
    let written = sut
        .update(&mut buf, Addr(2), 5, 50, &values, &[1, 5, 1], Some((4, 40)))
        .unwrap();
    assert_eq!(written, Written::Changed { items: 1 });
    assert_eq!(buf, whole(9.0, true, 5));
}

#[test]
fn an_update_of_a_buffer_that_does_not_hold_the_named_snapshot_writes_it_whole() {
    let sut = layout();
    let values = [Value::Bool(false), Value::F64(9.0), Value::F64(-2.0)];
    let changed_x = [1, 5, 1];
    let len = whole(0.0, false, 1).len();
    // Another stamp, another sequence number, no earlier snapshot named, garbage.
    for (mut buf, earlier) in [
        (whole(1.5, true, 4), Some((4, 41))),
        (whole(1.5, true, 3), Some((4, 40))),
        (whole(1.5, true, 4), None),
        (vec![0xa5; len], Some((4, 40))),
    ] {
        let written = sut
            .update(&mut buf, Addr(2), 5, 50, &values, &changed_x, earlier)
            .unwrap();
        assert_eq!(written, Written::Whole { len });
        assert_eq!(buf, whole(9.0, false, 5));
    }
}
