//! The reference run: the logical execution time (LET) semantics of a grid, computed in one
//! thread, with no clock and no IPC. The coordinator and the component hosts must produce
//! exactly these values, bit for bit, however the processes are scheduled.
//!
//! # Semantics
//! The base tick is n = 0, 1, 2, …. A component of period k is released at every n with
//! n % k == 0. Released at n, it reads for each input the output of its source that is valid
//! at n, and its own outputs become valid at n + k, never earlier. Before its first outputs
//! become valid (n < k), a component's outputs are the zero values of their types. So at tick
//! n the valid outputs of X are those computed by X's release at the largest m with
//! m + k_X ≤ n, or zeros if there is none.
//!
//! Within a tick the order of the releases does not matter: a release at n writes outputs
//! valid from n + k > n, which no release at n can read. The run keeps two output buffers per
//! component (valid now, and pending until n + k) so that this holds by construction; a test
//! checks it by releasing in reverse order.

use super::component::{Component, PortValue, Registry};
use super::spec::GridSpec;
use super::trace::TraceWriter;

/// Runs `spec` for `ticks` base ticks. For n in 0..ticks, in that order: calls
/// `sink(n, c, outputs valid at n)` for every component c in index order, then releases the
/// components due at n with the inputs valid at n. Fails if a component cannot be
/// instantiated (its error, naming the component).
pub fn reference_run(
    spec: &GridSpec,
    registry: &Registry,
    ticks: u64,
    sink: &mut dyn FnMut(u64, usize, &[PortValue]),
) -> Result<(), String> {
    run(
        spec,
        registry,
        ticks,
        Order::Forward,
        &Overruns::default(),
        sink,
    )
}

/// Overruns to replay: what the hold policy did in a real run, as its trace records them
/// (`# overrun tick=T component=C release=M`, `# stale tick=M component=C`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Overruns {
    /// (component, release tick) of releases that finished late: the component stepped (its
    /// state moved on) but its outputs never became valid.
    pub late: std::collections::BTreeSet<(usize, u64)>,
    /// (component, tick) of due ticks at which it was not released (still running) or its
    /// release was not executed (stale).
    pub skipped: std::collections::BTreeSet<(usize, u64)>,
}

impl Overruns {
    /// Reads the overrun and stale lines of a trace of `spec`: `# overrun tick=T
    /// component=C release=M` (release M finished late, and C was not released at T) and
    /// `# stale tick=M component=C` (release M was not executed: an input's version was gone).
    pub fn from_trace(spec: &GridSpec, trace: &str) -> Result<Overruns, String> {
        let mut out = Overruns::default();
        for line in trace.lines() {
            let overrun = line.starts_with("# overrun ");
            if !overrun && !line.starts_with("# stale ") {
                continue;
            }
            let field = |key: &str| {
                line.split_whitespace()
                    .find_map(|w| w.strip_prefix(key))
                    .ok_or_else(|| format!("'{line}' has no {key}"))
            };
            let number = |key: &str| -> Result<u64, String> {
                field(key)?
                    .parse()
                    .map_err(|_| format!("bad {key} in '{line}'"))
            };
            let name = field("component=")?;
            let c = spec
                .components
                .iter()
                .position(|x| x.name == name)
                .ok_or_else(|| format!("unknown component in '{line}'"))?;
            let tick = number("tick=")?;
            if overrun {
                out.late.insert((c, number("release=")?));
            }
            out.skipped.insert((c, tick));
        }
        Ok(out)
    }
}

/// The trace of the reference run with the overruns of a real run replayed, to compare with
/// that run's trace (its `#` lines other than the header left out).
pub fn reference_trace_with(
    spec: &GridSpec,
    registry: &Registry,
    ticks: u64,
    overruns: &Overruns,
) -> Result<String, String> {
    let mut writer = TraceWriter::new(Vec::new(), spec);
    let mut failure = None;
    run(
        spec,
        registry,
        ticks,
        Order::Forward,
        overruns,
        &mut |n, c, outputs| {
            if let Err(e) = writer.tick(n, c, outputs) {
                failure.get_or_insert(e);
            }
        },
    )?;
    if let Some(e) = failure {
        return Err(e.to_string());
    }
    let bytes = writer.finish().map_err(|e| e.to_string())?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

/// The trace ([`super::trace`]) of the reference run of `spec` for `ticks` ticks.
///
/// # Panics
/// If a component cannot be instantiated (use [`reference_run`] to get the error instead).
pub fn reference_trace(spec: &GridSpec, registry: &Registry, ticks: u64) -> String {
    let mut writer = TraceWriter::new(Vec::new(), spec);
    let mut failure = None;
    let result = reference_run(spec, registry, ticks, &mut |n, c, outputs| {
        if let Err(e) = writer.tick(n, c, outputs) {
            failure.get_or_insert(e);
        }
    });
    if let Err(e) = result {
        panic!("reference run: {e}");
    }
    // Writing to a Vec only fails on a bad component index or output count, which the run
    // never passes.
    if let Some(e) = failure {
        panic!("reference trace: {e}");
    }
    match writer.finish() {
        Ok(bytes) => String::from_utf8_lossy(&bytes).into_owned(),
        Err(e) => panic!("reference trace: {e}"),
    }
}

/// The order in which the components due at a tick are stepped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Order {
    Forward,
    /// Used by the tests to show that the order does not matter.
    #[cfg_attr(not(test), allow(dead_code))]
    Reverse,
}

/// One component's state in the run.
struct Slot {
    component: Box<dyn Component>,
    period: u64,
    /// The outputs valid now.
    valid: Vec<PortValue>,
    /// The outputs of the last release, valid from `pending_from`.
    pending: Vec<PortValue>,
    pending_from: Option<u64>,
    /// The inputs of a release, gathered here (no allocation per release).
    inputs: Vec<PortValue>,
    /// For each input: the (component, output port) feeding it.
    bindings: Vec<(usize, usize)>,
}

fn run(
    spec: &GridSpec,
    registry: &Registry,
    ticks: u64,
    order: Order,
    overruns: &Overruns,
    sink: &mut dyn FnMut(u64, usize, &[PortValue]),
) -> Result<(), String> {
    let mut slots = Vec::with_capacity(spec.components.len());
    for (index, c) in spec.components.iter().enumerate() {
        let component = registry
            .instantiate(&c.type_name, &c.params)
            .map_err(|e| format!("component '{}': {e}", c.name))?;
        let bindings = (0..c.info.inputs.len())
            .map(|i| {
                spec.source_of(index, i)
                    .map(|p| (p.component, p.port))
                    .ok_or_else(|| format!("component '{}': input {i} is not connected", c.name))
            })
            .collect::<Result<Vec<_>, String>>()?;
        slots.push(Slot {
            component,
            period: c.period.max(1),
            valid: c.info.zero_outputs(),
            pending: c.info.zero_outputs(),
            pending_from: None,
            inputs: c.info.zero_inputs(),
            bindings,
        });
    }
    let count = slots.len();
    for n in 0..ticks {
        for (c, slot) in slots.iter_mut().enumerate() {
            if slot.pending_from == Some(n) {
                std::mem::swap(&mut slot.valid, &mut slot.pending);
                slot.pending_from = None;
            }
            sink(n, c, &slot.valid);
        }
        for i in 0..count {
            let c = match order {
                Order::Forward => i,
                Order::Reverse => count - 1 - i,
            };
            if n % slots[c].period != 0 || overruns.skipped.contains(&(c, n)) {
                continue;
            }
            // Gather from the valid outputs: a release at n only writes `pending`.
            let mut inputs = std::mem::take(&mut slots[c].inputs);
            for (value, &(src, port)) in inputs.iter_mut().zip(&slots[c].bindings) {
                value.assign(&slots[src].valid[port]);
            }
            let slot = &mut slots[c];
            slot.component.step(n, &inputs, &mut slot.pending);
            slot.inputs = inputs;
            slot.pending_from = if overruns.late.contains(&(c, n)) {
                None // finished too late: the outputs never became valid
            } else {
                Some(n + slot.period)
            };
        }
    }
    for slot in &mut slots {
        slot.component.terminate();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system;

    /// The grid of a description whose body is `grid` (a domain is added).
    pub(crate) fn grid(body: &str) -> GridSpec {
        let source = format!("domain \"t\"\n{body}");
        let spec = system::load_str("grid.lua", &source, &|_: &str| None).unwrap();
        spec.grid.unwrap()
    }

    /// The outputs valid at every tick: `[tick][component]` → first output.
    fn table(spec: &GridSpec, ticks: u64, order: Order) -> Vec<Vec<PortValue>> {
        let mut rows = vec![Vec::new(); ticks as usize];
        run(
            spec,
            &Registry::builtin(),
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
        let trace = "# modbot trace v1\n# overrun tick=4 component=B release=2\n# stale tick=6 component=C\n";
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
    fn counter_chain_shows_zeros_before_first_validity() {
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
        assert_eq!(b, [0, 0, 0, 101, 101, 101, 102, 102]);
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
        let registry = Registry::builtin();
        let sut = reference_trace(&spec, &registry, 50);
        assert_eq!(sut, reference_trace(&spec, &registry, 50));
        let mut lines = sut.lines();
        assert_eq!(
            lines.next(),
            Some("# modbot trace v1 base_period_ns=1000000 components=A,B,C")
        );
        assert_eq!(lines.next(), Some("0 A.y=0.0 B.y=0.0 C.y=0.0"));
        assert_eq!(lines.nth(5), Some("6 A.y=5.0 B.y=6.0 C.y=0.0"));
        assert_eq!(sut.lines().count(), 51);
    }

    #[test]
    fn a_component_that_cannot_be_made_fails_the_run_by_name() {
        let mut spec = chain();
        spec.components[1].params = Default::default();
        let sut = reference_run(&spec, &Registry::builtin(), 1, &mut |_, _, _| {});
        assert_eq!(
            sut,
            Err("component 'B': param 'k' (f64) is required for type 'gain'".into())
        );
    }
}
