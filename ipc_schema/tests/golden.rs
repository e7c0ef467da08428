//! The golden vectors written in `ipc_schema/README.md` match the encoders and decoders: each
//! line's description, encoded, gives its bytes, and the bytes decode back to it.

use modbot_ipc_schema::snapshot::ItemSpec;
use modbot_ipc_schema::{
    hex, Addr, Frame, FrameKind, FrameSpec, NakCode, OwnedValue, Seq, SnapshotLayout, SnapshotView,
    Value,
};

mod support;

use support::{field, snapshot_items, values};

/// The snapshot a description lists: its items (`NAME:KIND[:writable][:bulk]=VALUE`) with the
/// address, sequence number and stamp it gives; checked to read back item by item.
fn snapshot_of(desc: &str) -> Vec<u8> {
    let items = snapshot_items(desc);
    let specs = items
        .iter()
        .map(|i| match i.bulk {
            true => ItemSpec::bulk(&i.name, i.writable),
            false => ItemSpec::new(&i.name, i.value.kind(), i.writable),
        })
        .collect();
    let layout = SnapshotLayout::new(specs).unwrap();
    // Values in table order: the layout sorts the items by name.
    let vals: Vec<Value<'_>> = layout
        .items()
        .iter()
        .map(|spec| {
            let item = items.iter().find(|i| i.name == spec.name).unwrap();
            item.value.as_value()
        })
        .collect();
    let mut out = vec![0; layout.encoded_len(&vals)];
    layout
        .write(
            &mut out,
            Addr(field(desc, "addr").parse().unwrap()),
            field(desc, "seq").parse().unwrap(),
            field(desc, "stamp").parse().unwrap(),
            &vals,
        )
        .unwrap();
    let view = SnapshotView::parse_expecting(&out, layout.hash()).unwrap();
    for item in &items {
        let read = view.get(&item.name).unwrap();
        assert_eq!(
            (read.value, read.writable, read.bulk),
            (item.value.as_value(), item.writable, item.bulk),
            "{}",
            item.name
        );
    }
    out
}

#[test]
fn the_readme_golden_vectors_match_the_encoders() {
    let lines = support::lines();
    assert!(lines.len() >= 10, "the README lists the golden vectors");
    for (desc, want) in lines {
        let kind_word = desc.split_whitespace().next().unwrap();
        let got = match kind_word {
            "value" => {
                let v = values(&desc);
                let mut out = vec![0; v[0].as_value().encoded_len()];
                v[0].as_value().encode(&mut out).unwrap();
                out
            }
            "heartbeat" => {
                use modbot_ipc_schema::heartbeat::{Counters, Heartbeat, ModuleState};
                use zerocopy::IntoBytes;
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let state = match n("state") {
                    1 => ModuleState::Starting,
                    2 => ModuleState::Running,
                    _ => ModuleState::Stopping,
                };
                let counters = Counters {
                    dropped: n("dropped"),
                    rejected: n("rejected"),
                    replayed: n("replayed"),
                };
                let hb = Heartbeat::new(
                    Addr(n("addr") as u8),
                    n("pid") as u32,
                    state,
                    n("beat"),
                    counters,
                )
                .with_methods_digest(n("digest") as u32);
                let bytes = hb.as_bytes().to_vec();
                let back = Heartbeat::parse(&bytes).unwrap();
                assert_eq!((back.beat(), back.counters()), (n("beat"), counters));
                bytes
            }
            "directory" => {
                use modbot_ipc_schema::directory::{self, Listing, View, IMAGE_LEN};
                use modbot_ipc_schema::heartbeat::ModuleState;
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let listing = Listing {
                    addr: Addr(n("addr") as u8),
                    mode: field(&desc, "mode").as_bytes()[0],
                    state: ModuleState::Running,
                    pid: n("pid") as u32,
                    methods_digest: n("digest") as u32,
                    upgrades: 0,
                    name: field(&desc, "name").to_owned(),
                };
                let mut image = vec![0u8; IMAGE_LEN];
                let len =
                    directory::write(&mut image, n("generation"), std::slice::from_ref(&listing))
                        .unwrap();
                let view = View::parse(&image).unwrap();
                assert_eq!(view.entries()[0].listing(), listing);
                image.truncate(len);
                image
            }
            "release" => {
                use modbot_ipc_schema::grid::Release;
                use zerocopy::IntoBytes;
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let versions: Vec<u64> = field(&desc, "versions")
                    .split(',')
                    .map(|v| v.parse().unwrap())
                    .collect();
                let notice =
                    Release::new(n("tick"), n("released"), n("component") as u16, &versions)
                        .unwrap()
                        .with(n("generation") as u16, n("flags") as u16)
                        .with_state_hash(hex_u64(field(&desc, "state_hash")));
                let bytes = notice.as_bytes().to_vec();
                let back = Release::batch(&bytes).unwrap().next().unwrap();
                assert_eq!(back.state_hash.get(), 0x0123_4567_89ab_cdef);
                assert_eq!(back.versions().collect::<Vec<_>>(), versions);
                assert_eq!(u64::from(back.sources.get()), n("sources"));
                assert!(back.has(Release::SAFE_STOP) && !back.has(Release::TRACK));
                bytes
            }
            "done" => {
                use modbot_ipc_schema::grid::Done;
                use zerocopy::IntoBytes;
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let notice = Done::new(
                    n("tick"),
                    n("component") as u16,
                    n("status") as u16,
                    n("exec"),
                    n("latency"),
                )
                .of_generation(n("generation") as u16)
                .with_flags(n("flags") as u16 & !Done::HASHED);
                let hash = desc.contains("state_hash=");
                let notice = match hash {
                    true => notice.with_state_hash(Some(hex_u64(field(&desc, "state_hash")))),
                    false => notice,
                };
                let bytes = notice.as_bytes().to_vec();
                let back = Done::batch(&bytes).unwrap().next().unwrap();
                assert_eq!(
                    (back.status.get(), back.latency_ns.get(), back.flags.get()),
                    (n("status") as u16, n("latency"), n("flags") as u16)
                );
                assert_eq!(back.hash().is_some(), hash);
                bytes
            }
            "prepare" => {
                use modbot_ipc_schema::grid::Prepare;
                use zerocopy::IntoBytes;
                let notice = Prepare::new(
                    field(&desc, "generation").parse().unwrap(),
                    field(&desc, "name"),
                )
                .unwrap();
                let bytes = notice.as_bytes().to_vec();
                assert_eq!(
                    Prepare::parse(&bytes).unwrap().name(),
                    Some(field(&desc, "name"))
                );
                bytes
            }
            "out" => {
                use modbot_ipc_schema::grid::{OutHeader, OUT_HEADER_LEN};
                use zerocopy::IntoBytes;
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let header = OutHeader {
                    valid_from: n("valid_from").into(),
                    release: n("release").into(),
                };
                let bytes = header.as_bytes().to_vec();
                assert_eq!(bytes.len(), OUT_HEADER_LEN);
                bytes
            }
            "record" => {
                use modbot_ipc_schema::grid::{read_record, record_len, write_record, PortValue};
                let written: Vec<PortValue> = values(&desc)
                    .into_iter()
                    .map(|v| match v {
                        OwnedValue::Bool(b) => PortValue::Bool(b),
                        OwnedValue::I64(i) => PortValue::I64(i),
                        OwnedValue::F64(x) => PortValue::F64(x),
                        OwnedValue::F64s(xs) => PortValue::F64s(xs),
                        other => panic!("no port holds {other:?}"),
                    })
                    .collect();
                let types: Vec<_> = written.iter().map(PortValue::port_type).collect();
                let mut bytes = vec![0; record_len(&types)];
                write_record(&written, &mut bytes).unwrap();
                let mut read: Vec<PortValue> = types.iter().map(|t| t.zero()).collect();
                read_record(&bytes, &mut read).unwrap();
                assert_eq!(read, written);
                bytes
            }
            "relay_request" => {
                use modbot_ipc_schema::relay::{encode_request, Request};
                let owned = values(&desc);
                let args: Vec<Value<'_>> = owned.iter().map(OwnedValue::as_value).collect();
                let (module, method) = (field(&desc, "module"), field(&desc, "method"));
                let timeout = field(&desc, "timeout").parse().unwrap();
                let bytes = encode_request(module, method, timeout, &args).unwrap();
                let back = Request::parse(&bytes).unwrap();
                assert_eq!(
                    (back.module, back.method, back.timeout_ms),
                    (module, method, timeout)
                );
                assert_eq!(back.values().unwrap().as_slice(), &args[..]);
                bytes
            }
            "relay_answered" => {
                use modbot_ipc_schema::relay::{encode_answered, Response};
                let owned = values(&desc);
                let answer: Vec<Value<'_>> = owned.iter().map(OwnedValue::as_value).collect();
                let bytes = encode_answered(&answer).unwrap();
                assert_eq!(
                    Response::parse(&bytes).unwrap(),
                    Response::Answered(&bytes[1..])
                );
                bytes
            }
            "relay_failed" => {
                use modbot_ipc_schema::relay::{encode_failed, Response};
                let why = field(&desc, "why");
                let bytes = encode_failed(why);
                assert_eq!(Response::parse(&bytes).unwrap(), Response::Failed(why));
                bytes
            }
            "ledger" => {
                use modbot_ipc_schema::ledger::{decode, encode, ComponentRow, GridRow};
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let list = |k| -> Vec<u64> {
                    field(&desc, k)
                        .split(',')
                        .map(|x| x.parse().unwrap())
                        .collect()
                };
                let (err, exec, latency) = (list("tick_error"), list("exec"), list("latency"));
                let grid = GridRow {
                    state: field(&desc, "state").to_owned(),
                    fault: field(&desc, "fault").to_owned(),
                    ticks: n("ticks"),
                    missed: n("missed"),
                    rate_hz: field(&desc, "rate").parse().unwrap(),
                    tick_err_p50: err[0],
                    tick_err_p99: err[1],
                    tick_err_max: err[2],
                };
                let row = ComponentRow {
                    name: field(&desc, "name").to_owned(),
                    host: field(&desc, "host").to_owned(),
                    period: n("period"),
                    policy: field(&desc, "policy").to_owned(),
                    releases: n("releases"),
                    overruns: n("overruns"),
                    late: n("late"),
                    failed: n("failed"),
                    stale: n("stale"),
                    exec_min: exec[0],
                    exec_p50: exec[1],
                    exec_p99: exec[2],
                    exec_max: exec[3],
                    latency_p50: latency[0],
                    latency_p99: latency[1],
                };
                let mut bytes = Vec::new();
                encode(&grid, std::slice::from_ref(&row), &mut bytes);
                assert_eq!(decode(&bytes).unwrap(), (grid, vec![row]));
                bytes
            }
            "assembly" => {
                use modbot_ipc_schema::switch::{decode, Outcome, State, Status};
                let parts = |k| -> Vec<&str> { field(&desc, k).split(':').collect() };
                let (announced, switched, failed) =
                    (parts("announced"), parts("switched"), parts("failed"));
                let status = Status {
                    assembly: field(&desc, "name").to_owned(),
                    generation: field(&desc, "generation").parse().unwrap(),
                    state: State::Announced {
                        generation: announced[0].parse().unwrap(),
                        assembly: announced[1].to_owned(),
                        tick: announced[2].parse().unwrap(),
                    },
                    outcomes: vec![
                        Outcome::Switched {
                            generation: switched[0].parse().unwrap(),
                            assembly: switched[1].to_owned(),
                            announced: switched[2].parse().unwrap(),
                            tick: switched[3].parse().unwrap(),
                        },
                        Outcome::Failed {
                            generation: failed[0].parse().unwrap(),
                            assembly: failed[1].to_owned(),
                            reason: failed[2].to_owned(),
                        },
                    ],
                };
                let mut bytes = Vec::new();
                status.encode(&mut bytes);
                assert_eq!(decode(&bytes).unwrap(), status);
                bytes
            }
            "switches" => {
                use modbot_ipc_schema::bus::{decode, encode, Switch, Switches};
                let x = |k| field(&desc, k).parse::<f64>().unwrap();
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let record = Switches {
                    max_step: x("max_step"),
                    max_velocity_step: x("max_velocity_step"),
                    switches: vec![Switch {
                        generation: n("generation") as u16,
                        tick: n("tick"),
                        step: x("step"),
                        velocity_step: x("velocity_step"),
                        missed_near: n("missed"),
                    }],
                };
                let mut bytes = Vec::new();
                encode(
                    record.max_step,
                    record.max_velocity_step,
                    &record.switches,
                    &mut bytes,
                )
                .unwrap();
                assert_eq!(decode(&bytes).unwrap(), record);
                bytes
            }
            "status" => {
                use modbot_ipc_schema::heartbeat::Counters;
                use modbot_ipc_schema::status::{decode, encode, Row};
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let row = Row {
                    name: field(&desc, "name").to_owned(),
                    addr: n("addr") as u8,
                    state: field(&desc, "state").to_owned(),
                    pid: n("pid") as u32,
                    restarts: n("restarts") as u32,
                    last_exit: field(&desc, "last_exit").to_owned(),
                    counters: Counters {
                        dropped: n("dropped"),
                        rejected: n("rejected"),
                        replayed: n("replayed"),
                    },
                    heartbeat_age_ms: Some(n("heartbeat_age_ms")),
                    upgrades: n("upgrades") as u16,
                };
                let mut bytes = Vec::new();
                encode(std::slice::from_ref(&row), &mut bytes);
                assert_eq!(decode(&bytes).unwrap(), vec![row]);
                bytes
            }
            "latency" => {
                use modbot_ipc_schema::latency::{bucket_of, encode, View, BUCKETS};
                let values: Vec<u64> = field(&desc, "values")
                    .split(',')
                    .map(|v| v.parse().unwrap())
                    .collect();
                let mut counts = [0u64; BUCKETS];
                for v in &values {
                    counts[bucket_of(*v)] += 1;
                }
                let max = field(&desc, "max").parse().unwrap();
                let mut bytes = Vec::new();
                encode(&counts, max, &mut bytes);
                let view = View::parse(&bytes).unwrap();
                assert_eq!((view.max(), view.total()), (max, values.len() as u64));
                bytes
            }
            "grid_spec" => {
                use modbot_ipc_schema::grid::{
                    GridClock, OverrunPolicy, ParamType, ParamValue, PortType,
                };
                use modbot_ipc_schema::grid_spec::{
                    decode, encode, ComponentImage, GridImage, InfoImage, ParamDeclImage, PortImage,
                };
                let n = |k| field(&desc, k).parse::<u64>().unwrap();
                let list = |k| field(&desc, k).split(',').filter(|w| !w.is_empty());
                // `NAME:TYPE=VALUE`, the value an f64 (the golden line's one kind).
                let param = |w: &str| {
                    let (name, rest) = w.split_once(':').unwrap();
                    let (ty, value) = rest.split_once('=').unwrap();
                    assert_eq!(ty, "f64", "{w}");
                    let value = ParamValue::F64(value.parse().unwrap());
                    (name.to_owned(), ParamType::F64, value)
                };
                let ports = |k| -> Vec<PortImage> {
                    list(k)
                        .map(|w| {
                            let (name, ty) = w.split_once(':').unwrap();
                            PortImage {
                                name: name.to_owned(),
                                ty: PortType::parse(ty).unwrap(),
                            }
                        })
                        .collect()
                };
                for none in ["assembly", "declared", "connections"] {
                    assert_eq!(n(none), 0, "the golden image has no {none}");
                }
                let info = InfoImage {
                    type_name: field(&desc, "type").to_owned(),
                    doc: field(&desc, "doc").to_owned(),
                    inputs: ports("inputs"),
                    outputs: ports("outputs"),
                    params: list("param_decls")
                        .map(param)
                        .map(|(name, ty, default)| ParamDeclImage {
                            name,
                            ty,
                            default: Some(default),
                        })
                        .collect(),
                };
                let component = ComponentImage {
                    name: field(&desc, "name").to_owned(),
                    type_name: field(&desc, "type").to_owned(),
                    program: Some(field(&desc, "program").to_owned()).filter(|p| !p.is_empty()),
                    host: field(&desc, "host").to_owned(),
                    period: n("period"),
                    policy: OverrunPolicy::from_name(field(&desc, "policy")).unwrap(),
                    line: n("component_line") as u32,
                    params: list("params")
                        .map(param)
                        .map(|(name, _, value)| (name, value))
                        .collect(),
                    info,
                };
                let image = GridImage {
                    base_period_ns: n("base_period_ns"),
                    cpus: list("cpus").map(|c| c.parse().unwrap()).collect(),
                    priority: Some(n("priority") as u8).filter(|&p| p != 0),
                    mlock: field(&desc, "mlock").parse().unwrap(),
                    line: n("line") as u32,
                    clock: GridClock::from_name(field(&desc, "clock")).unwrap(),
                    track_ticks: n("track_ticks"),
                    spin_us: n("spin_us"),
                    assembly: None,
                    declared: vec![],
                    components: vec![component],
                    connections: vec![],
                };
                let mut bytes = Vec::new();
                encode(&image, &mut bytes);
                assert_eq!(decode(&bytes).unwrap(), image);
                bytes
            }
            "snapshot" => snapshot_of(&desc),
            _ => {
                let num = |k| field(&desc, k).parse::<u8>().unwrap();
                let kind = match kind_word {
                    "ack" => FrameKind::Ack,
                    "exec" => FrameKind::Exec {
                        method: num("method"),
                    },
                    "retry" => FrameKind::Retry {
                        method: num("method"),
                    },
                    "reply" => FrameKind::Reply,
                    "nak" => FrameKind::Nak {
                        code: NakCode(num("code")),
                    },
                    "report" => FrameKind::Report {
                        topic: num("topic"),
                    },
                    other => panic!("unknown golden kind {other}"),
                };
                let spec = FrameSpec {
                    dst: Addr(num("dst")),
                    src: Addr(num("src")),
                    seq: Seq::new(num("seq")).unwrap(),
                    kind,
                };
                let owned = values(&desc);
                let vals: Vec<Value<'_>> = owned.iter().map(OwnedValue::as_value).collect();
                let bytes = spec.to_vec(&vals).unwrap();
                let frame = Frame::decode_strict(&bytes).unwrap();
                assert_eq!(frame.spec(), spec, "{desc}");
                bytes
            }
        };
        assert_eq!(hex::encode(&got), hex::encode(&want), "{desc}");
    }
}

/// A `0x…` hexadecimal number of a golden description.
fn hex_u64(text: &str) -> u64 {
    let digits = text.strip_prefix("0x").unwrap_or(text);
    u64::from_str_radix(digits, 16).unwrap_or_else(|e| panic!("{text}: {e}"))
}
