//! Traces of grids from descriptions: one line per tick once every component is in.

use modbot_grid::component::PortValue;
use modbot_grid::spec::GridSpec;
use modbot_grid::trace::*;

fn spec() -> GridSpec {
    let source = r#"domain "t"
grid { base_period = 0.0005 }
component "A" { type = "counter", host = "h" }
component "P" { type = "pack", host = "h", period = 2 }
component "Z" { type = "ramp", host = "h" }
connect("Z.y", "P.a")
connect "Z.y -> P.b"
"#;
    let spec = crate::load_str("t.lua", source, &|_: &str| None).unwrap();
    spec.grid.unwrap()
}

#[test]
fn a_line_is_written_once_when_every_component_is_in_whatever_the_order() {
    let spec = spec();
    let mut sut = TraceWriter::new(Vec::new(), &spec);
    let pair = PortValue::F64s(vec![0.5, -0.0]);
    sut.tick(0, 2, &[PortValue::F64(0.1)]).unwrap();
    sut.tick(0, 1, std::slice::from_ref(&pair)).unwrap();
    sut.tick(0, 0, &[PortValue::I64(3)]).unwrap();
    sut.end_tick(0).unwrap();
    sut.tick(1, 0, &[PortValue::I64(4)]).unwrap();
    sut.end_tick(1).unwrap();
    sut.tick(2, 1, &[pair]).unwrap();
    let text = String::from_utf8(sut.finish().unwrap()).unwrap();
    assert_eq!(
        text,
        "# modbot trace v1 base_period_ns=500000 components=A,P,Z\n\
         0 A.y=3 P.v=[0.5,-0.0] Z.y=0.1\n\
         1 A.y=4 P.v=? Z.y=?\n\
         2 A.y=? P.v=[0.5,-0.0] Z.y=?\n"
    );
}

#[test]
fn wrong_component_or_output_count_is_refused_and_an_empty_trace_has_its_header() {
    let spec = spec();
    let mut sut = TraceWriter::new(Vec::new(), &spec);
    assert!(sut.tick(0, 3, &[]).is_err());
    assert!(sut.tick(0, 0, &[]).is_err());
    let text = String::from_utf8(sut.finish().unwrap()).unwrap();
    assert_eq!(text, format!("{}\n", header(&spec)));
}

#[test]
fn first_difference_names_the_line() {
    let spec = spec();
    let registry = modbot_components::builtin();
    let a = modbot_grid::reference::reference_trace(&spec, &registry, 5);
    assert_eq!(first_difference(&a, &a), None);
    let b = a.replacen("4 A.y=4", "4 A.y=5", 1);
    let (line, x, y) = first_difference(&a, &b).unwrap();
    assert_eq!(line, 6);
    assert!(x.starts_with("4 A.y=4") && y.starts_with("4 A.y=5"));
    let short: String = a.lines().take(2).map(|l| format!("{l}\n")).collect();
    assert_eq!(first_difference(&a, &short).unwrap().0, 3);
}

#[test]
fn the_state_hash_is_written_every_n_ticks_after_the_ticks_line_and_after_the_last() {
    let spec = spec();
    let lines = |every: u64, ticks: u64| {
        let mut sut = TraceWriter::new(Vec::new(), &spec).with_state_hash_every(every);
        for n in 0..ticks {
            sut.tick(n, 0, &[PortValue::I64(n as i64)]).unwrap();
            sut.state_hash(n, 0xab00 + n).unwrap();
        }
        let text = String::from_utf8(sut.finish().unwrap()).unwrap();
        text.lines()
            .filter(|l| l.starts_with("# state_hash"))
            .map(str::to_owned)
            .collect::<Vec<_>>()
    };
    assert_eq!(
        lines(2, 6),
        [
            "# state_hash tick=2 hash=0x000000000000ab02",
            "# state_hash tick=4 hash=0x000000000000ab04",
            "# state_hash tick=5 hash=0x000000000000ab05",
        ]
    );
    assert_eq!(
        lines(5, 6),
        ["# state_hash tick=5 hash=0x000000000000ab05"],
        "not at 0 (the initial outputs), once at 5, which is also the last"
    );
    assert!(lines(0, 6).is_empty(), "0: never");
    let mut sut = TraceWriter::new(Vec::new(), &spec).with_state_hash_every(1);
    sut.tick(1, 0, &[PortValue::I64(1)]).unwrap();
    sut.state_hash(1, 7).unwrap();
    let text = String::from_utf8(sut.finish().unwrap()).unwrap();
    assert!(
        text.ends_with("1 A.y=1 P.v=? Z.y=?\n# state_hash tick=1 hash=0x0000000000000007\n"),
        "the tick's line first: {text}"
    );
}
