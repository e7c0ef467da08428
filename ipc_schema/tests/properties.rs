//! Property tests: every encoder round-trips through its decoder, and no input makes a decoder
//! panic.

use modbot_ipc_schema::snapshot::ItemSpec;
use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::{
    Addr, Frame, FrameKind, FrameSpec, NakCode, OwnedValue, Seq, SnapshotLayout, SnapshotView,
    Value,
};
use proptest::prelude::*;

fn owned_value() -> impl Strategy<Value = OwnedValue> {
    prop_oneof![
        any::<f64>()
            .prop_filter("NaN is not equal to itself", |v| !v.is_nan())
            .prop_map(OwnedValue::F64),
        any::<i64>().prop_map(OwnedValue::I64),
        any::<bool>().prop_map(OwnedValue::Bool),
        ".{0,40}".prop_map(OwnedValue::Text),
        proptest::collection::vec(any::<u8>(), 0..300).prop_map(OwnedValue::Bytes),
        proptest::collection::vec(-1e9f64..1e9, 0..40).prop_map(OwnedValue::F64s),
    ]
}

fn frame_kind() -> impl Strategy<Value = FrameKind> {
    prop_oneof![
        Just(FrameKind::Ack),
        any::<u8>().prop_map(|method| FrameKind::Exec { method }),
        any::<u8>().prop_map(|method| FrameKind::Retry { method }),
        Just(FrameKind::Reply),
        any::<u8>().prop_map(|code| FrameKind::Nak {
            code: NakCode(code)
        }),
        any::<u8>().prop_map(|topic| FrameKind::Report { topic }),
    ]
}

fn spec() -> impl Strategy<Value = FrameSpec> {
    (1u8..=255, 1u8..=254, 0u8..=31, frame_kind()).prop_map(|(dst, src, seq, kind)| FrameSpec {
        dst: Addr(dst),
        src: Addr(src),
        seq: Seq::new(seq).unwrap(),
        kind,
    })
}

/// Any text: a reason, a last exit.
fn text() -> impl Strategy<Value = String> {
    "[a-z_]{0,12}|.{0,8}"
}

/// An assembly name (`modbot_ipc_schema::names`).
fn assembly_name() -> impl Strategy<Value = String> {
    "[a-z0-9_]{1,32}"
}

/// A module name (`modbot_ipc_schema::names`).
fn module_name() -> impl Strategy<Value = String> {
    "[a-zA-Z0-9_-]{1,48}"
}

fn switch_status() -> impl Strategy<Value = modbot_ipc_schema::switch::Status> {
    use modbot_ipc_schema::switch::{Outcome, State, Status};
    let tick = 0..=i64::MAX as u64;
    let state = prop_oneof![
        Just(State::Idle),
        (any::<u16>(), assembly_name()).prop_map(|(generation, assembly)| State::Preparing {
            generation,
            assembly
        }),
        (any::<u16>(), assembly_name(), tick.clone()).prop_map(|(generation, assembly, tick)| {
            State::Announced {
                generation,
                assembly,
                tick,
            }
        }),
    ];
    let outcome = prop_oneof![
        (any::<u16>(), assembly_name(), tick.clone(), tick).prop_map(
            |(generation, assembly, announced, tick)| Outcome::Switched {
                generation,
                assembly,
                announced,
                tick
            }
        ),
        (any::<u16>(), assembly_name(), text()).prop_map(|(generation, assembly, reason)| {
            Outcome::Failed {
                generation,
                assembly,
                reason,
            }
        }),
    ];
    (
        assembly_name(),
        any::<u16>(),
        state,
        proptest::collection::vec(outcome, 0..5),
    )
        .prop_map(|(assembly, generation, state, outcomes)| Status {
            assembly,
            generation,
            state,
            outcomes,
        })
}

fn status_row() -> impl Strategy<Value = modbot_ipc_schema::status::Row> {
    use modbot_ipc_schema::heartbeat::Counters;
    let count = 0..=i64::MAX as u64;
    (
        (
            module_name(),
            1..=254u8,
            proptest::sample::select(&modbot_ipc_schema::status::STATES[..]),
            any::<u32>(),
            any::<u32>(),
            text(),
        ),
        (
            count.clone(),
            count.clone(),
            count.clone(),
            proptest::option::of(count),
        ),
    )
        .prop_map(
            |(
                (name, addr, state, pid, restarts, last_exit),
                (dropped, rejected, replayed, heartbeat_age_ms),
            )| {
                modbot_ipc_schema::status::Row {
                    name,
                    addr,
                    state: state.to_owned(),
                    pid,
                    restarts,
                    last_exit,
                    counters: Counters {
                        dropped,
                        rejected,
                        replayed,
                    },
                    heartbeat_age_ms,
                }
            },
        )
}

fn bus_switch() -> impl Strategy<Value = modbot_ipc_schema::bus::Switch> {
    (
        any::<u16>(),
        any::<u64>(),
        0.0..1e3f64,
        0.0..1e3f64,
        any::<u64>(),
    )
        .prop_map(|(generation, tick, step, velocity_step, missed_near)| {
            modbot_ipc_schema::bus::Switch {
                generation,
                tick,
                step,
                velocity_step,
                missed_near,
            }
        })
}

proptest! {
    #[test]
    fn frames_round_trip_through_encode_and_decode(
        spec in spec(),
        values in proptest::collection::vec(owned_value(), 0..6),
    ) {
        let values: Vec<Value<'_>> = if spec.kind == FrameKind::Ack { vec![] } else { values.iter().map(OwnedValue::as_value).collect() };
        let bytes = spec.to_vec(&values).unwrap();
        prop_assert_eq!(bytes.len(), spec.encoded_len(modbot_ipc_schema::value::encoded_len(&values)));
        let frame = Frame::decode_strict(&bytes).unwrap();
        prop_assert_eq!(frame.spec(), spec);
        let decoded: Vec<Value<'_>> = frame.values().map(Result::unwrap).collect();
        prop_assert_eq!(&decoded, &values);
        // decode → encode → decode is stable
        let again = frame.spec().encode(frame.payload(), &mut vec![0; bytes.len()]).unwrap();
        prop_assert_eq!(again, bytes.len());
    }

    #[test]
    fn decoding_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        if let Ok(frame) = Frame::decode(&bytes) {
            for v in frame.values() { let _ = v; }
            // what decodes re-encodes to the same bytes
            let mut out = vec![0; bytes.len()];
            if frame.spec().encode(frame.payload(), &mut out).is_ok() {
                prop_assert_eq!(out, bytes.clone());
            }
        }
        for v in Values::new(&bytes, 0) { let _ = v; }
        if let Ok(view) = SnapshotView::parse(&bytes) {
            for item in view.iter() { let _ = view.get(item.name); }
        }
        if let Ok(hb) = modbot_ipc_schema::heartbeat::Heartbeat::parse(&bytes) {
            let _ = (hb.addr(), hb.state(), hb.counters());
        }
        // Every fuzz target's entry point, round trips included.
        for (_, decode) in modbot_ipc_schema::fuzz::TARGETS {
            decode(&bytes);
        }
    }

    #[test]
    fn mutated_frames_and_snapshots_never_panic(
        values in proptest::collection::vec(owned_value(), 1..4),
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6),
        cut in any::<usize>(),
    ) {
        let vals: Vec<Value<'_>> = values.iter().map(OwnedValue::as_value).collect();
        let spec = FrameSpec { dst: Addr(2), src: Addr(1), seq: Seq::new(3).unwrap(), kind: FrameKind::Reply };
        let mut frame = spec.to_vec(&vals).unwrap();
        let items: Vec<ItemSpec> = values.iter().enumerate().map(|(i, v)| ItemSpec::new(&format!("item{i}"), v.kind(), false)).collect();
        let layout = SnapshotLayout::new(items).unwrap();
        let mut snap = vec![0; layout.encoded_len(&vals)];
        layout.write(&mut snap, Addr(1), 1, 2, &vals).unwrap();
        prop_assert_eq!(SnapshotView::parse(&snap).unwrap().len(), vals.len());
        for (at, byte) in &flips {
            let i = at % frame.len();
            frame[i] ^= byte;
            let j = at % snap.len();
            snap[j] ^= byte;
        }
        let _ = Frame::decode_strict(&frame);
        let _ = Frame::decode_strict(&frame[..cut % (frame.len() + 1)]);
        if let Ok(view) = SnapshotView::parse(&snap) { for item in view.iter() { let _ = item; } }
        let _ = SnapshotView::parse(&snap[..cut % (snap.len() + 1)]);
    }

    #[test]
    fn snapshots_round_trip_through_write_and_parse(values in proptest::collection::vec(owned_value(), 0..8), seq in any::<u64>()) {
        let vals: Vec<Value<'_>> = values.iter().map(OwnedValue::as_value).collect();
        let items: Vec<ItemSpec> = values.iter().enumerate().map(|(i, v)| ItemSpec::new(&format!("n{i:02}"), v.kind(), i % 2 == 0)).collect();
        let layout = SnapshotLayout::new(items).unwrap();
        let mut out = vec![0; layout.encoded_len(&vals)];
        layout.write(&mut out, Addr(9), seq, 5, &vals).unwrap();
        let view = SnapshotView::parse_expecting(&out, layout.hash()).unwrap();
        prop_assert_eq!(view.seq(), seq);
        for (i, v) in vals.iter().enumerate() {
            prop_assert_eq!(view.value(&format!("n{i:02}")).unwrap(), *v);
        }
    }

    /// Writing only what changed since the snapshot in the buffer gives the same bytes as
    /// writing the whole snapshot, whatever the buffer held, whichever items changed (bulk
    /// items among them), and whether or not the caller named the right earlier snapshot.
    #[test]
    fn a_snapshot_updated_in_place_equals_the_snapshot_written_whole(
        before in proptest::collection::vec(owned_value(), 1..6),
        changes in proptest::collection::vec(proptest::option::of(owned_value()), 1..6),
        bulk in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..100), 0..3),
        garbage in any::<bool>(),
        wrong_stamp in any::<bool>(),
    ) {
        let mut items: Vec<ItemSpec> = before.iter().enumerate().map(|(i, v)| ItemSpec::new(&format!("v{i}"), v.kind(), false)).collect();
        items.extend((0..bulk.len()).map(|i| ItemSpec::bulk(&format!("b{i}"), false)));
        let layout = SnapshotLayout::new(items).unwrap();
        // Values in table order (names sort as b*, v*).
        let mut old: Vec<OwnedValue> = bulk.iter().map(|b| OwnedValue::Bytes(b.clone())).collect();
        old.extend(before.iter().cloned());
        let mut new = old.clone();
        let mut written_at = vec![1u64; new.len()];
        for (i, change) in changes.iter().enumerate() {
            let i = i % new.len();
            // A change keeps the item's kind (a bulk item's bytes are rewritten in place).
            let replacement = match (&new[i], change) {
                (OwnedValue::Bytes(b), _) if layout.items()[i].bulk => OwnedValue::Bytes(b.iter().map(|x| x.wrapping_add(1)).collect()),
                (_, Some(v)) if v.kind() == new[i].kind() => v.clone(),
                _ => continue,
            };
            new[i] = replacement;
            written_at[i] = 2;
        }
        let whole_new = {
            let mut out = vec![0; layout.encoded_len(&new)];
            layout.write(&mut out, Addr(4), 2, 20, &new).unwrap();
            out
        };
        let mut buf = vec![0x5a; layout.encoded_len(&old).max(whole_new.len())];
        if !garbage {
            layout.write(&mut buf, Addr(4), 1, 10, &old).unwrap();
        }
        let stamp = if wrong_stamp { 11 } else { 10 };
        layout.update(&mut buf, Addr(4), 2, 20, &new, &written_at, Some((1, stamp))).unwrap();
        prop_assert_eq!(&buf[..whole_new.len()], &whole_new[..]);
    }

    #[test]
    fn switch_answers_status_rows_and_bus_records_round_trip_and_survive_mutation(
        status in switch_status(),
        rows in proptest::collection::vec(status_row(), 0..4),
        switches in proptest::collection::vec(bus_switch(), 0..4),
        max_step in 0.0..1.0f64,
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6),
        cut in any::<usize>(),
    ) {
        use modbot_ipc_schema::{bus, fuzz, status as rows_format, switch};
        let mut answer = Vec::new();
        status.encode(&mut answer);
        prop_assert_eq!(switch::decode(&answer), Ok(status));
        let mut table = Vec::new();
        rows_format::encode(&rows, &mut table);
        prop_assert_eq!(rows_format::decode(&table), Ok(rows));
        let mut record = Vec::new();
        bus::encode(max_step, max_step * 4.0, &switches, &mut record).unwrap();
        let back = bus::decode(&record).unwrap();
        prop_assert_eq!(back.switches, switches);
        for (bytes, decode) in [
            (&mut answer, fuzz::switch as fn(&[u8])),
            (&mut table, fuzz::status),
            (&mut record, fuzz::bus),
        ] {
            decode(&bytes[..cut % (bytes.len() + 1)]);
            if !bytes.is_empty() {
                for (at, byte) in &flips {
                    let i = at % bytes.len();
                    bytes[i] ^= byte;
                }
            }
            decode(bytes);
        }
    }
}
