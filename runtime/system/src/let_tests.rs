//! LET from descriptions: the reference run's outputs per tick, its independence of the
//! release order within a tick, and overruns replayed from a trace.

use modbot_grid::component::PortValue;
use modbot_grid::reference::{reference_run, reference_trace, run, Order, Overruns};
use modbot_grid::spec::GridSpec;

/// The grid of a description whose body is `grid` (a domain is added).
pub(crate) fn grid(body: &str) -> GridSpec {
    let source = format!("domain \"t\"\n{body}");
    let spec = crate::load_str("grid.lua", &source, &|_: &str| None).unwrap();
    spec.grid.unwrap()
}

/// The outputs valid at every tick: `[tick][component]` → first output.
fn table(spec: &GridSpec, ticks: u64, order: Order) -> Vec<Vec<PortValue>> {
    let mut rows = vec![Vec::new(); ticks as usize];
    run(
        spec,
        &modbot_components::builtin(),
        ticks,
        order,
        &Overruns::default(),
        &mut |n, _, out| rows[n as usize].push(out[0].clone()),
    )
    .unwrap();
    rows
}

fn column(rows: &[Vec<PortValue>], c: usize) -> Vec<f64> {
    rows.iter().map(|r| r[c].as_f64()).collect()
}

/// A → B → C with periods 1, 2, 5. A ramp rather than a counter feeds the gain: port
/// types must match exactly, and a counter's output is i64.
fn chain() -> GridSpec {
    let source = r#"grid {}
component "A" { type = "ramp", host = "h", period = 1, params = { slope = 1000 } }
component "B" { type = "gain", host = "h", period = 2, params = { k = 2 } }
component "C" { type = "delay", host = "h", period = 5 }
connect "A.y -> B.u"
connect "B.y -> C.u"
"#;
    grid(source)
}

#[test]
fn overrun_and_stale_lines_of_a_trace_become_the_releases_to_replay() {
    let spec = chain();
    let trace =
        "# modbot trace v1\n# overrun tick=4 component=B release=2\n# stale tick=6 component=C\n";
    let got = Overruns::from_trace(&spec, trace).unwrap();
    let (b, c) = (
        spec.components.iter().position(|x| x.name == "B").unwrap(),
        spec.components.iter().position(|x| x.name == "C").unwrap(),
    );
    assert_eq!(got.late.iter().copied().collect::<Vec<_>>(), vec![(b, 2)]);
    assert_eq!(
        got.skipped.iter().copied().collect::<Vec<_>>(),
        vec![(b, 4), (c, 6)]
    );
    assert!(Overruns::from_trace(&spec, "# stale tick=x component=C").is_err());
    assert!(Overruns::from_trace(&spec, "# stale tick=1 component=Z").is_err());
}

#[test]
fn chain_of_periods_1_2_5_matches_hand_computed_values() {
    // A (ramp, 1000 per second at 1 ms): released at n, y = n, valid at n + 1: A(n) = n - 1.
    let rows = table(&chain(), 13, Order::Forward);
    let a = column(&rows, 0);
    assert_eq!(a[..6], [0.0, 0.0, 1.0, 2.0, 3.0, 4.0]);
    // B (period 2) released at 0, 2, 4, … reads A valid then: 0, 1, 3, 5 (times 2),
    // valid two ticks later.
    let b = column(&rows, 1);
    assert_eq!(b[..7], [0.0, 0.0, 0.0, 0.0, 2.0, 2.0, 6.0]);
    // C (delay, period 5) released at 0, 5, 10, 15 reads B valid then: 0, 2, 14, 22 and
    // outputs the input of its previous release: 0 (initial), 0, 2, 14, valid five ticks
    // later: zeros up to tick 14, then 2 from 15, 14 from 20.
    let c = column(&rows, 2);
    assert_eq!(c, [0.0; 13]);
    let rows = table(&chain(), 21, Order::Forward);
    assert_eq!(column(&rows, 1)[10], 14.0);
    assert_eq!(column(&rows, 2)[14..], [0.0, 2.0, 2.0, 2.0, 2.0, 2.0, 14.0]);
}

#[test]
fn counter_chain_shows_its_start_before_first_validity() {
    let spec = grid(
        r#"grid {}
component "A" { type = "counter", host = "h", period = 1 }
component "B" { type = "counter", host = "h", period = 3, params = { start = 100 } }
"#,
    );
    let rows = table(&spec, 8, Order::Forward);
    let a: Vec<i64> = rows.iter().map(|r| r[0].as_f64() as i64).collect();
    assert_eq!(a, [0, 1, 2, 3, 4, 5, 6, 7]);
    let b: Vec<i64> = rows.iter().map(|r| r[1].as_f64() as i64).collect();
    // Its initial output is its declared start (issue 31): valid until its first release's.
    assert_eq!(b, [100, 100, 100, 101, 101, 101, 102, 102]);
}

#[test]
fn periods_1_2_5_10_together_read_what_was_valid_at_their_release() {
    let spec = grid(
        r#"grid {}
component "A" { type = "ramp", host = "a", period = 1, params = { slope = 1000 } }
component "B" { type = "gain", host = "b", period = 2, params = { k = 1 } }
component "C" { type = "gain", host = "b", period = 5, params = { k = 1 } }
component "D" { type = "sum", host = "c", period = 10 }
connect "A.y -> B.u"
connect "A.y -> C.u"
connect "B.y -> D.a"
connect "C.y -> D.b"
"#,
    );
    let rows = table(&spec, 40, Order::Forward);
    // A(n) = n - 1 (0 at n = 0); X of period k at n: its input at m = k * floor(n / k) - k.
    let a = |n: i64| (n - 1).max(0) as f64;
    let let_of = |k: i64, n: i64, input: &dyn Fn(i64) -> f64| {
        let m = n / k * k - k;
        if m < 0 {
            0.0
        } else {
            input(m)
        }
    };
    let b = |n: i64| let_of(2, n, &a);
    let c = |n: i64| let_of(5, n, &a);
    let d = |n: i64| let_of(10, n, &|m| b(m) + c(m));
    for n in 0..40 {
        let expected = [a(n), b(n), c(n), d(n)];
        let got: Vec<f64> = rows[n as usize].iter().map(PortValue::as_f64).collect();
        assert_eq!(got, expected, "tick {n}");
    }
    // D at 20: its release at 10 read B (A at 8 = 7) and C (A at 5 = 4).
    assert_eq!(rows[20][3].as_f64(), 11.0);
}

#[test]
fn release_order_within_a_tick_does_not_matter() {
    let spec = grid(
        r#"grid {}
component "A" { type = "sine", host = "h", period = 1, params = { freq = 7 } }
component "L" { type = "delay", host = "h", period = 1 }
component "B" { type = "integrator", host = "h", period = 2 }
component "S" { type = "sum", host = "h", period = 3 }
connect "A.y -> L.u"
connect "L.y -> B.u"
connect "B.y -> S.a"
connect "S.y -> S.b"
"#,
    );
    let forward = table(&spec, 200, Order::Forward);
    let reverse = table(&spec, 200, Order::Reverse);
    assert_eq!(forward, reverse);
    assert_ne!(forward[199][3], PortValue::F64(0.0));
}

#[test]
fn two_reference_traces_are_identical() {
    let spec = chain();
    let registry = modbot_components::builtin();
    let sut = reference_trace(&spec, &registry, 50);
    assert_eq!(sut, reference_trace(&spec, &registry, 50));
    let mut lines = sut.lines();
    assert_eq!(
        lines.next(),
        Some("# modbot trace v1 base_period_ns=1000000 components=A,B,C")
    );
    assert_eq!(lines.next(), Some("0 A.y=0.0 B.y=0.0 C.y=0.0"));
    assert_eq!(lines.nth(5), Some("6 A.y=5.0 B.y=6.0 C.y=0.0"));
    assert_eq!(
        sut.lines().count(),
        52,
        "the header, 50 ticks, the state hash after the last"
    );
}

#[test]
fn a_component_that_cannot_be_made_fails_the_run_by_name() {
    let mut spec = chain();
    spec.components[1].params = Default::default();
    let sut =
        reference_run(&spec, &modbot_components::builtin(), 1, &mut |_, _, _| {}).unwrap_err();
    assert_eq!(
        sut.to_string(),
        "component 'B': param 'k' (f64) is required for type 'gain'"
    );
    let source = std::error::Error::source(&sut).map(|s| s.to_string());
    assert_eq!(
        source.as_deref(),
        Some("param 'k' (f64) is required for type 'gain'")
    );
}

/// The grid's state hash at every tick of the run of `spec` in `order`, replaying `overruns`.
fn hashes(spec: &GridSpec, ticks: u64, order: Order, overruns: &Overruns) -> Vec<u64> {
    let mut out = Vec::new();
    modbot_grid::reference::run_hashed(
        spec,
        &modbot_components::builtin(),
        ticks,
        order,
        overruns,
        &mut |_, _, _| {},
        &mut |n, hash| {
            assert_eq!(n, out.len() as u64);
            out.push(hash);
        },
    )
    .unwrap();
    out
}

#[test]
fn the_state_hash_changes_only_when_a_version_becomes_valid_and_not_with_the_release_order() {
    let spec = chain();
    let forward = hashes(&spec, 60, Order::Forward, &Overruns::default());
    assert_eq!(
        forward,
        hashes(&spec, 60, Order::Reverse, &Overruns::default())
    );
    // Periods 1, 2, 5: A's version changes every tick from 1 on; tick 0 has only the initial
    // outputs, which carry no hash.
    assert_eq!(
        forward[0],
        modbot_grid::state_hash::combine(std::iter::empty())
    );
    assert!(forward.windows(2).all(|w| w[0] != w[1]));
    // A ramp and a delay, both of period 5: the hash changes at 5, 10, … only.
    let spec = grid(
        r#"grid {}
component "A" { type = "ramp", host = "h", period = 5, params = { slope = 1000 } }
component "C" { type = "delay", host = "h", period = 5 }
connect "A.y -> C.u"
"#,
    );
    let h = hashes(&spec, 30, Order::Forward, &Overruns::default());
    for n in 1..30 {
        assert_eq!(h[n] != h[n - 1], n % 5 == 0, "tick {n}");
    }
}

#[test]
fn a_late_release_replayed_keeps_the_previous_state_hash() {
    let spec = chain();
    let b = spec.components.iter().position(|x| x.name == "B").unwrap();
    let on_time = hashes(&spec, 20, Order::Forward, &Overruns::default());
    let mut overruns = Overruns::default();
    overruns.late.insert((b, 4)); // B's release at 4 finishes late: its version 6 never counts
    overruns.skipped.insert((b, 6));
    let late = hashes(&spec, 20, Order::Forward, &overruns);
    assert_eq!(late[..6], on_time[..6]);
    assert_ne!(late[6], on_time[6]);
    // From 6 until B's release at 8 counts (at 10) the grids are in different states; B is
    // a gain, with no memory, and nothing read its late version: from 10 on they agree.
    assert!((6..10).all(|n| late[n] != on_time[n]));
    assert_eq!(late[10..], on_time[10..]);
}
