//! Frames and values.

use modbot_ipc_schema::{hex, Frame, FrameError, FrameKind, Value, ValueError};

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
fn an_f64_value_is_read_as_its_bits_so_nan_is_a_value() {
    let nan = hex::decode("cb 7ff8000000000000").unwrap();
    assert!(matches!(Value::decode(&nan, 0), Ok((Value::F64(x), 9)) if x.is_nan()));
}
