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
            any::<u16>(),
        ),
    )
        .prop_map(
            |(
                (name, addr, state, pid, restarts, last_exit),
                (dropped, rejected, replayed, heartbeat_age_ms, upgrades),
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
                    upgrades,
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

fn port_type() -> impl Strategy<Value = modbot_ipc_schema::grid::PortType> {
    use modbot_ipc_schema::grid::PortType;
    prop_oneof![
        Just(PortType::Bool),
        Just(PortType::I64),
        Just(PortType::F64),
        (1usize..=8).prop_map(PortType::F64s),
    ]
}

fn param_value() -> impl Strategy<Value = modbot_ipc_schema::grid::ParamValue> {
    use modbot_ipc_schema::grid::ParamValue;
    prop_oneof![
        any::<bool>().prop_map(ParamValue::Bool),
        any::<i64>().prop_map(ParamValue::I64),
        (-1e9..1e9f64).prop_map(ParamValue::F64),
        proptest::collection::vec(-1e9..1e9f64, 0..4).prop_map(ParamValue::F64s),
        text().prop_map(ParamValue::Text),
    ]
}

fn param_decl() -> impl Strategy<Value = modbot_ipc_schema::grid_spec::ParamDeclImage> {
    use modbot_ipc_schema::grid::ParamType;
    let ty = proptest::sample::select(vec![
        ParamType::Bool,
        ParamType::I64,
        ParamType::F64,
        ParamType::F64s,
        ParamType::Text,
    ]);
    ("[a-z]{1,6}", ty, proptest::option::of(param_value())).prop_map(|(name, ty, default)| {
        modbot_ipc_schema::grid_spec::ParamDeclImage { name, ty, default }
    })
}

/// An interface with these inputs, and outputs and parameters of its own.
fn info(
    inputs: Vec<modbot_ipc_schema::grid::PortType>,
) -> impl Strategy<Value = modbot_ipc_schema::grid_spec::InfoImage> {
    use modbot_ipc_schema::grid_spec::{InfoImage, PortImage};
    let ports = |types: Vec<modbot_ipc_schema::grid::PortType>, prefix: &str| -> Vec<PortImage> {
        types
            .into_iter()
            .enumerate()
            .map(|(i, ty)| PortImage {
                name: format!("{prefix}{i}"),
                ty,
            })
            .collect()
    };
    (
        "[a-z_]{1,8}",
        text(),
        proptest::collection::vec(port_type(), 0..4),
        proptest::collection::vec(param_decl(), 0..3),
    )
        .prop_map(move |(type_name, doc, outputs, params)| InfoImage {
            type_name,
            doc,
            inputs: ports(inputs.clone(), "u"),
            outputs: ports(outputs, "y"),
            params,
        })
}

/// A valid checked grid: components whose inputs are each fed by one output of its type
/// (chosen by `feeds`), declared types, perhaps an assembly.
fn grid_image() -> impl Strategy<Value = modbot_ipc_schema::grid_spec::GridImage> {
    use modbot_ipc_schema::grid::{Generation, GridClock, OverrunPolicy};
    use modbot_ipc_schema::grid_spec::{
        AssemblyImage, ComponentImage, ConnectionImage, DeclaredImage, GridImage, PortAt,
    };
    let count = 0..=i64::MAX as u64;
    let component = (
        (
            "[a-z]{0,6}",
            "[a-z_]{1,8}",
            proptest::option::of("[a-z_]{1,8}"),
            module_name(),
            1..=u64::from(u32::MAX),
            any::<bool>(),
            any::<u32>(),
        ),
        proptest::collection::vec(("[a-z]{1,6}", param_value()), 0..4),
        info(vec![]),
        // Each input: which output (modulo all outputs) feeds it.
        proptest::collection::vec(any::<usize>(), 0..5),
    );
    let declared = ("[a-z_]{1,8}", any::<u32>(), info(vec![])).prop_map(|(program, line, info)| {
        DeclaredImage {
            program,
            line,
            info,
        }
    });
    (
        (
            1..=i64::MAX as u64,
            proptest::collection::vec(0usize..=4095, 0..4),
            proptest::option::of(1u8..=99),
            any::<bool>(),
            any::<u32>(),
            any::<bool>(),
            count.clone(),
            count,
        ),
        proptest::option::of((assembly_name(), 1..=u16::MAX, any::<usize>())),
        proptest::collection::vec(declared, 0..3),
        proptest::collection::vec(component, 0..5),
        any::<u32>(),
    )
        .prop_map(
            |(
                (base_period_ns, cpus, priority, mlock, line, lockstep, track_ticks, spin_us),
                assembly,
                declared,
                components,
                connection_line,
            )| {
                let mut image = GridImage {
                    base_period_ns,
                    cpus,
                    priority,
                    mlock,
                    line,
                    clock: if lockstep {
                        GridClock::Lockstep
                    } else {
                        GridClock::RealTime
                    },
                    track_ticks,
                    spin_us,
                    assembly: None,
                    declared,
                    components: Vec::new(),
                    connections: Vec::new(),
                };
                let mut feeds = Vec::new();
                for (
                    i,
                    ((name, type_name, program, host, period, fault, line), params, info, inputs),
                ) in components.into_iter().enumerate()
                {
                    image.components.push(ComponentImage {
                        name: format!("c{i}{name}"),
                        type_name,
                        program,
                        host,
                        period,
                        policy: if fault {
                            OverrunPolicy::Fault
                        } else {
                            OverrunPolicy::Hold
                        },
                        line,
                        params,
                        info,
                    });
                    feeds.push(inputs);
                }
                let outputs: Vec<(usize, usize)> = image
                    .components
                    .iter()
                    .enumerate()
                    .flat_map(|(c, comp)| (0..comp.info.outputs.len()).map(move |p| (c, p)))
                    .collect();
                for (c, inputs) in feeds.into_iter().enumerate() {
                    if outputs.is_empty() {
                        break;
                    }
                    for (port, pick) in inputs.into_iter().enumerate() {
                        let (from_c, from_p) = outputs[pick % outputs.len()];
                        let ty = image.components[from_c].info.outputs[from_p].ty;
                        image.components[c].info.inputs.push(
                            modbot_ipc_schema::grid_spec::PortImage {
                                name: format!("u{port}"),
                                ty,
                            },
                        );
                        image.connections.push(ConnectionImage {
                            from: PortAt {
                                component: from_c,
                                port: from_p,
                            },
                            to: PortAt { component: c, port },
                            line: connection_line,
                        });
                    }
                }
                image.assembly = assembly.map(|(name, generation, base)| AssemblyImage {
                    name,
                    generation: Generation(generation),
                    base: base % (image.components.len() + 1),
                });
                image
            },
        )
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
    /// Generated valid grids read back, and cut or flipped images are refused or read as an
    /// image whose connections index existing ports (the fuzz target's walk), never a panic.
    #[test]
    fn checked_grids_round_trip_and_survive_mutation(
        image in grid_image(),
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6),
        cut in any::<usize>(),
    ) {
        use modbot_ipc_schema::{fuzz, grid_spec};
        prop_assert_eq!(image.check(), Ok(()));
        let mut bytes = Vec::new();
        grid_spec::encode(&image, &mut bytes);
        prop_assert_eq!(grid_spec::decode(&bytes), Ok(image));
        fuzz::grid_spec(&bytes[..cut % (bytes.len() + 1)]);
        for (at, byte) in &flips {
            let i = at % bytes.len();
            bytes[i] ^= byte;
        }
        fuzz::grid_spec(&bytes);
    }
}
