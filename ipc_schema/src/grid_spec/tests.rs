use super::*;
use crate::fields::FieldError;
use crate::hex;

/// The README's golden image: one ramp `A` with output `y` and parameter `slope`.
fn golden() -> GridImage {
    let slope = ParamValue::F64(1.0);
    GridImage {
        base_period_ns: 1_000_000,
        cpus: vec![],
        priority: None,
        mlock: false,
        line: 1,
        clock: GridClock::RealTime,
        track_ticks: 50,
        spin_us: 0,
        assembly: None,
        declared: vec![],
        components: vec![ComponentImage {
            name: "A".into(),
            type_name: "ramp".into(),
            program: None,
            host: "h".into(),
            period: 1,
            policy: OverrunPolicy::Hold,
            line: 2,
            params: vec![("slope".into(), slope.clone())],
            info: InfoImage {
                type_name: "ramp".into(),
                doc: String::new(),
                inputs: vec![],
                outputs: vec![port("y", PortType::F64)],
                params: vec![ParamDeclImage {
                    name: "slope".into(),
                    ty: ParamType::F64,
                    default: Some(slope),
                }],
            },
        }],
        connections: vec![],
    }
}

fn port(name: &str, ty: PortType) -> PortImage {
    PortImage {
        name: name.into(),
        ty,
    }
}

fn at(component: usize, port: usize) -> PortAt {
    PortAt { component, port }
}

/// Every part an image has: an assembly, a declared type, pinned CPUs, ports of every type,
/// parameters of every kind, with and without defaults, and connections between them.
fn example() -> GridImage {
    let ports = || {
        vec![
            port("x", PortType::F64),
            port("q", PortType::F64s(6)),
            port("n", PortType::I64),
            port("on", PortType::Bool),
        ]
    };
    let info = |type_name: &str, inputs, outputs| InfoImage {
        type_name: String::from(type_name),
        doc: "what it computes".into(),
        inputs,
        outputs,
        params: vec![
            ParamDeclImage {
                name: "gain".into(),
                ty: ParamType::F64,
                default: Some(ParamValue::I64(2)),
            },
            ParamDeclImage {
                name: "path".into(),
                ty: ParamType::Text,
                default: None,
            },
            ParamDeclImage {
                name: "weights".into(),
                ty: ParamType::F64s,
                default: Some(ParamValue::F64s(vec![0.5, -1.0])),
            },
        ],
    };
    let params = vec![
        ("on".to_owned(), ParamValue::Bool(true)),
        ("n".to_owned(), ParamValue::I64(-3)),
        ("gain".to_owned(), ParamValue::F64(0.25)),
        ("weights".to_owned(), ParamValue::F64s(vec![1.0, 2.0, 3.0])),
        ("path".to_owned(), ParamValue::Text("traj.csv".into())),
    ];
    let source = ComponentImage {
        name: "source".into(),
        type_name: "reader".into(),
        program: Some("reader_host".into()),
        host: "io".into(),
        period: 4,
        policy: OverrunPolicy::Fault,
        line: 10,
        params: params.clone(),
        info: info("reader", vec![], ports()),
    };
    let sink = ComponentImage {
        name: "sink".into(),
        type_name: "writer".into(),
        program: None,
        host: "io-2".into(),
        period: u64::from(u32::MAX),
        policy: OverrunPolicy::Hold,
        line: 11,
        params,
        info: info("writer", ports(), vec![]),
    };
    GridImage {
        base_period_ns: 250_000,
        cpus: vec![0, 3, MAX_CPU],
        priority: Some(80),
        mlock: true,
        line: 3,
        clock: GridClock::Lockstep,
        track_ticks: 0,
        spin_us: 20,
        assembly: Some(AssemblyImage {
            name: "ptp".into(),
            generation: Generation(2),
            base: 1,
        }),
        declared: vec![DeclaredImage {
            program: "reader_host".into(),
            line: 7,
            info: source.info.clone(),
        }],
        connections: (0..4)
            .map(|p| ConnectionImage {
                from: at(0, p),
                to: at(1, p),
                line: 20 + p as u32,
            })
            .collect(),
        components: vec![source, sink],
    }
}

fn bytes(image: &GridImage) -> Vec<u8> {
    let mut out = Vec::new();
    encode(image, &mut out);
    out
}

#[test]
fn the_golden_image_has_the_documented_layout_and_reads_back() {
    let sut = golden();
    let bytes = bytes(&sut);
    assert_eq!(
        hex::encode(&bytes),
        concat!(
            "a44d424753 01",                                   // MBGS, version 1
            "ce000f4240 00 c2 00 01 a87265616c74696d65 32 00", // grid
            "00 00",                                           // no assembly, none declared
            "01 a141 a472616d70 a0 a168 01 a4686f6c64 02",     // component A
            "01 a5736c6f7065 cb3ff0000000000000",              // slope = 1.0
            "a472616d70 a0 00 01 a179 a3663634",               // ramp: no inputs, y: f64
            "01 a5736c6f7065 a3663634 c3 cb3ff0000000000000",  // slope: f64 = 1.0
            "00",                                              // no connections
        )
        .replace(' ', "")
    );
    assert_eq!(decode(&bytes), Ok(sut));
}

#[test]
fn an_image_with_every_part_reads_back() {
    let sut = example();
    assert_eq!(sut.check(), Ok(()));
    assert_eq!(decode(&bytes(&sut)), Ok(sut));
}

#[test]
fn a_cut_image_is_refused_with_the_missing_field() {
    let good = bytes(&golden());
    assert_eq!(
        decode(&good[..good.len() - 1 - 9]),
        Err(GridSpecError::Field(FieldError::Missing {
            what: "a parameter's value"
        }))
    );
    assert!(matches!(
        decode(&good[..good.len() - 2]),
        Err(GridSpecError::Field(FieldError::Malformed(_)))
    ));
    assert!(matches!(decode(&[]), Err(GridSpecError::Field(_))));
}

#[test]
fn a_count_larger_than_the_bytes_left_can_hold_is_refused_before_reading_on() {
    let mut bytes = bytes(&golden());
    // The components' count, after 26 bytes of header and grid and 2 of assembly and declared.
    assert_eq!(bytes[28], 0x01);
    bytes.splice(
        28..29,
        [0xcf, 0x7f, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff],
    );
    assert!(matches!(
        decode(&bytes),
        Err(GridSpecError::Count {
            what: "the components",
            count,
            ..
        }) if count == i64::MAX as usize
    ));
}

#[test]
fn check_refuses_what_the_encoder_writes_and_the_decoder_would_refuse() {
    let refused = |change: fn(&mut GridImage)| {
        let mut sut = example();
        change(&mut sut);
        let err = sut.check().unwrap_err();
        assert_eq!(decode(&bytes(&sut)), Err(err.clone()), "the decoder agrees");
        err
    };
    assert_eq!(refused(|i| i.base_period_ns = 0), GridSpecError::BasePeriod);
    assert_eq!(
        refused(|i| i.priority = Some(100)),
        GridSpecError::Priority { priority: 100 }
    );
    assert_eq!(
        refused(|i| i.cpus.push(MAX_CPU + 1)),
        GridSpecError::Cpu { cpu: MAX_CPU + 1 }
    );
    assert_eq!(
        refused(|i| i.assembly.as_mut().unwrap().generation = Generation(0)),
        GridSpecError::Generation
    );
    assert_eq!(
        refused(|i| i.assembly.as_mut().unwrap().base = 3),
        GridSpecError::Base {
            base: 3,
            components: 2
        }
    );
    assert!(matches!(
        refused(|i| i.assembly.as_mut().unwrap().name = "P-t-p".into()),
        GridSpecError::Name {
            at: Place::Assembly,
            ..
        }
    ));
    assert_eq!(
        refused(|i| i.components[1].period = 0),
        GridSpecError::Period {
            component: 1,
            period: 0
        }
    );
    assert_eq!(
        refused(|i| i.components[1].period = 1 << 32),
        GridSpecError::Period {
            component: 1,
            period: 1 << 32
        }
    );
    assert!(matches!(
        refused(|i| i.components[0].host = "i o".into()),
        GridSpecError::Name {
            at: Place::Component(0),
            what: "the host",
            ..
        }
    ));
    assert!(matches!(
        refused(|i| i.declared[0].program.clear()),
        GridSpecError::Name {
            at: Place::Declared(0),
            what: "the program",
            ..
        }
    ));
    assert!(matches!(
        refused(|i| i.components[1].params[2].0.clear()),
        GridSpecError::Name {
            at: Place::Component(1),
            what: "a parameter's name",
            ..
        }
    ));
    assert_eq!(
        refused(|i| {
            i.components[0].info.outputs[1].ty = PortType::F64s(MAX_ARRAY + 1);
            i.components[1].info.inputs[1].ty = PortType::F64s(MAX_ARRAY + 1);
        }),
        GridSpecError::ArrayLength {
            at: Place::Component(0),
            port: "q".into(),
            len: MAX_ARRAY + 1
        }
    );
    assert_eq!(
        refused(|i| {
            i.connections[3].to.port = 2;
        }),
        GridSpecError::TypeMismatch {
            connection: 3,
            from: "source.on".into(),
            from_ty: PortType::Bool,
            to: "sink.n".into(),
            to_ty: PortType::I64
        }
    );
}

#[test]
fn a_program_of_none_is_written_empty_and_an_empty_program_is_refused() {
    let mut sut = example();
    sut.components[0].program = Some(String::new());
    assert!(matches!(
        sut.check(),
        Err(GridSpecError::Name {
            what: "the program",
            ..
        })
    ));
    sut.components[0].program = None;
    assert_eq!(decode(&bytes(&sut)), Ok(sut));
}

#[test]
fn errors_name_the_part_and_the_ports() {
    let err = GridSpecError::TypeMismatch {
        connection: 3,
        from: "source.on".into(),
        from_ty: PortType::Bool,
        to: "sink.q".into(),
        to_ty: PortType::F64s(6),
    };
    assert_eq!(
        err.to_string(),
        "grid spec: connection 3: source.on is bool but sink.q is f64[6]"
    );
    let err = GridSpecError::Name {
        at: Place::Component(2),
        what: "the host",
        name: "a b".into(),
        rule: "a module name (1 to 48 of a-z A-Z 0-9 _ -)",
    };
    assert_eq!(
        err.to_string(),
        "grid spec: component 2: the host 'a b' is not a module name (1 to 48 of a-z A-Z 0-9 _ -)"
    );
}
