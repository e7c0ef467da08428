//! The decoding rules `ipc_schema/README.md` states ("What decoders accept"), one assertion
//! each, so that the text, the code and this test agree.

use modbot_ipc_schema::heartbeat::Heartbeat;
use modbot_ipc_schema::{hex, Frame, FrameError, FrameKind, SnapshotView, Value, ValueError};

fn frame(text: &str) -> Result<FrameKind, FrameError> {
    let bytes = hex::decode(text).unwrap();
    Frame::decode_strict(&bytes).map(|f| f.kind())
}

#[test]
fn frames_take_a_one_byte_operand_module_sources_and_any_destination_but_zero() {
    // EXEC of method 0xF4 (stats): the operand is one byte, the body's first.
    assert_eq!(frame("030125 01 f4"), Ok(FrameKind::Exec { method: 0xf4 }));
    assert_eq!(frame("000125 01 07"), Err(FrameError::BadDestination));
    assert_eq!(
        frame("ff0185 01 09"),
        Ok(FrameKind::Report { topic: 9 }),
        "255: broadcast"
    );
    assert_eq!(frame("030025 01 07"), Err(FrameError::BadSource(0)));
    assert_eq!(frame("03ff25 01 07"), Err(FrameError::BadSource(255)));
    assert_eq!(frame("0301c5"), Err(FrameError::UnknownKind(6)));
    // A NAK's detail: any values after the code (a text first is what callers show).
    assert!(frame("030165 05 01 a2 6e6f 2a").is_ok());
}

#[test]
fn values_take_any_integer_form_but_not_float32_nil_or_containers() {
    // 30000 as int16 (d1): not the shortest form (uint16, cd), accepted.
    assert_eq!(
        Value::decode(&hex::decode("d17530").unwrap(), 0),
        Ok((Value::I64(30000), 3))
    );
    for marker in [0xca_u8, 0xc0, 0x91, 0x81] {
        assert!(
            matches!(
                Value::decode(&[marker, 0, 0, 0, 0], 0),
                Err(ValueError::Unsupported { .. })
            ),
            "{marker:#x}"
        );
    }
    // An f64 array is ext type 1 in any ext form: fixext 8 here (one f64).
    let one = hex::decode("d701 000000000000f03f").unwrap();
    assert!(matches!(Value::decode(&one, 0), Ok((Value::F64s(_), 10))));
}

#[test]
fn a_heartbeat_reader_ignores_its_reserved_byte() {
    let golden = "4d424842 01 07 02 00 34120000 efbeadde 0500000000000000 0100000000000000 0200000000000000 0300000000000000";
    let mut bytes = hex::decode(&golden.split_whitespace().collect::<String>()).unwrap();
    bytes[7] = 0xaa;
    assert_eq!(Heartbeat::parse(&bytes).unwrap().beat(), 5);
}

/// The bytes of the README's golden vector whose description starts with `description`.
fn golden(description: &str) -> Vec<u8> {
    let readme = include_str!("../README.md");
    let line = readme
        .lines()
        .find(|l| l.starts_with(description))
        .unwrap_or_else(|| panic!("the golden vector '{description}'"));
    let (_, text) = line.split_once("   ").unwrap();
    hex::decode(text).unwrap()
}

#[test]
fn a_snapshot_reader_ignores_reserved_bits_and_requires_names_in_byte_order() {
    let golden = golden("snapshot addr=2");
    let mut bytes = golden.clone();
    bytes[7] = 0xff; // header flags
    bytes[10] = 0xff; // reserved
    bytes[40 + 7] |= 0xfe; // entry 0's flags, bits 1..7
    let view = SnapshotView::parse(&bytes).unwrap();
    assert_eq!(view.iter().count(), 3);
    // Entries 0 and 1 swapped: out of name order, refused.
    let mut swapped = golden.clone();
    let (a, b) = (40..56, 56..72);
    let first: Vec<u8> = swapped[a.clone()].to_vec();
    swapped.copy_within(b.clone(), a.start);
    swapped[b].copy_from_slice(&first);
    assert!(SnapshotView::parse(&swapped).is_err());
}

#[test]
fn a_reader_of_the_bus_bridges_switches_ignores_its_reserved_bytes() {
    let mut bytes = golden("switches max_step=");
    let golden = modbot_ipc_schema::bus::decode(&bytes).unwrap();
    bytes[5] = 0xaa; // header
    bytes[24 + 2..24 + 8].fill(0xbb); // the record's
    assert_eq!(modbot_ipc_schema::bus::decode(&bytes), Ok(golden));
}
