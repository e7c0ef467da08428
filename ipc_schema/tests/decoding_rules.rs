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

#[test]
fn a_grid_record_refuses_a_bool_that_is_neither_0_nor_1_and_a_wrong_length() {
    use modbot_ipc_schema::grid::{read_record, GridWireError, PortValue};
    let mut values = [PortValue::Bool(false), PortValue::I64(0)];
    let mut bytes = golden("record bool=true");
    assert_eq!(bytes.len(), 40);
    bytes.truncate(16);
    read_record(&bytes, &mut values).unwrap();
    assert_eq!(values, [PortValue::Bool(true), PortValue::I64(-2)]);
    bytes[0] = 2;
    assert_eq!(
        read_record(&bytes, &mut values),
        Err(GridWireError::BadBool(2))
    );
    assert!(matches!(
        read_record(&bytes[..15], &mut values),
        Err(GridWireError::Length { .. })
    ));
}

#[test]
fn relayed_calls_refuse_bad_names_values_statuses_and_reasons() {
    use modbot_ipc_schema::relay::{RelayError, Request, Response};
    let request = golden("relay_request module=nav");
    assert!(Request::parse(&request).is_ok());
    let mut bad_name = request.clone();
    bad_name[1] = b'/';
    assert!(matches!(
        Request::parse(&bad_name),
        Err(RelayError::BadName { what: "module" })
    ));
    let mut bad_value = request.clone();
    *bad_value.last_mut().unwrap() = 0xc1;
    assert!(matches!(
        Request::parse(&bad_value),
        Err(RelayError::Values(_))
    ));
    assert_eq!(Response::parse(&[2]), Err(RelayError::Status(2)));
    assert!(matches!(
        Response::parse(&[0, 0xc1]),
        Err(RelayError::Values(_))
    ));
    assert_eq!(Response::parse(&[1, 0xff]), Err(RelayError::Text));
}

#[test]
fn a_directory_reader_ignores_its_reserved_bytes() {
    use modbot_ipc_schema::directory::{View, IMAGE_LEN};
    let mut image = golden("directory generation=5");
    image.resize(IMAGE_LEN, 0);
    let listing = View::parse(&image).unwrap().entries()[0].listing();
    image[5] = 0xaa; // the header's
    image[16 + 12..16 + 16].fill(0xbb); // the entry's
    let view = View::parse(&image).unwrap();
    assert_eq!(
        (view.generation(), view.entries()[0].listing()),
        (5, listing)
    );
}
