//! The project's own FMUs (crate `modbot-fmus`, built from source by the workspace's build),
//! checked by a tool no one here wrote — FMPy validates each and simulates it, and its
//! outputs agree with modbot's for the same inputs, from the initial outputs on, with arrays
//! sized by structural parameters and matrix parameters — FMU components under `modbot
//! check` (ranges, shapes), an FMU that asks to terminate, and an i64 into an Int32 input.

mod common;

use common::python::python;
use common::TestDomain;

/// The project's FMUs pass FMPy's validation (modelDescription.xml against the standard's
/// rules), and FMPy simulates the feed-forward and the filter: the FMI 3 filter's step
/// response is the closed form k·(1 − e^(−t/T)), the FMI 2 feed-forward at rest asks for no
/// torque and under a constant acceleration for (Jm + Jl)·q̈ once its filter has settled.
#[test]
fn fmpy_validates_and_simulates_the_projects_fmus() {
    let (ff2, filter3) = (
        common::bin("modbot_ff2.fmu"),
        common::bin("modbot_filter3.fmu"),
    );
    let out = python(
        r#"
import sys, fmpy, numpy as np
from fmpy.validation import validate_fmu
for fmu in sys.argv[1:]:
    problems = validate_fmu(fmu)
    assert problems == [], (fmu, problems)
ff2, filter3 = sys.argv[1:3]
assert fmpy.read_model_description(ff2).fmiVersion == "2.0"
assert fmpy.read_model_description(filter3).fmiVersion == "3.0"

t = np.arange(0, 0.1, 0.001)
u = np.zeros(len(t), dtype=[("time", float), ("u", float)])
u["time"], u["u"] = t, 1.0
r = fmpy.simulate_fmu(filter3, stop_time=0.1, output_interval=0.001, input=u,
                      start_values={"k": 2.0, "T": 0.02}, output=["y"])
assert np.allclose(r["y"], 2.0 * (1 - np.exp(-r["time"] / 0.02)), rtol=0, atol=1e-12), r[:5]

names = [f"{v}[{i}]" for v in ("q", "qd", "qdd") for i in range(1, 7)]
a = np.zeros(len(t), dtype=[("time", float)] + [(n, float) for n in names])
a["time"] = t
for i in range(1, 7):
    a[f"qdd[{i}]"] = np.where(t >= 0.05, 1.0, 0.0)
r = fmpy.simulate_fmu(ff2, stop_time=0.1, output_interval=0.001, input=a,
                      output=[f"tau[{i}]" for i in range(1, 7)])
assert (r["tau[1]"][r["time"] <= 0.05] == 0).all(), "no torque at rest"
settled = r["tau[3]"][-1]
print(settled)
"#,
        &[
            ff2.to_str().unwrap(),
            filter3.to_str().unwrap(),
            common::bin("modbot_ss3.fmu").to_str().unwrap(),
            common::bin("modbot_stair2.fmu").to_str().unwrap(),
        ],
    );
    // (Jm + Jl)·q̈ = 2.5 N·m, and b·q̇m + Coulomb on the estimated motor speed, nearly 0 by then.
    let settled: f64 = out.trim().parse().unwrap();
    assert!((settled - 2.5).abs() < 0.05, "{settled}");
}

/// A grid in lockstep drives both FMUs — the FMI 3 filter with a sine, the FMI 2 feed-forward
/// with a point-to-point trajectory of 6 axes — and traces every output; FMPy steps each FMU,
/// through its own FMI bindings, with the inputs the trace says they were given (released at
/// tick n, a component reads its inputs as valid at n, and its outputs are valid at n + 1,
/// after one step of 1 ms): every output of every step agrees within 1e-12. So does the
/// native `lowpass`, the filter's arithmetic as a built-in component (the benchmark's baseline).
#[test]
fn fmpy_and_modbot_give_the_same_outputs_for_the_same_inputs() {
    let (ff2, filter3) = (
        common::bin("modbot_ff2.fmu"),
        common::bin("modbot_filter3.fmu"),
    );
    let mut sut = TestDomain::new("fmucmp");
    let system = sut.write_system(&format!(
        r#"grid {{ base_period = 0.001, clock = "lockstep" }}
component "wave" {{ type = "sine", host = "src", params = {{ amplitude = 1, freq = 3 }} }}
component "lp"   {{ type = "fmu", fmu = "{filter3}", host = "h_lp", params = {{ k = 2.0, T = 0.02 }} }}
component "native" {{ type = "lowpass", host = "src", params = {{ k = 2.0, T = 0.02 }} }}
component "path" {{ type = "waypoints", host = "src", period = 10,
                    params = {{ axes = 6, dwell = 0,
                                points = {{ 0, 0, 0, 0, 0, 0, 0.5, -0.4, 0.3, 0.6, -0.5, 0.8 }} }} }}
component "ptp"  {{ type = "ptp", host = "src", params = {{ axes = 6, v_max = 1.0, a_max = 4.0 }} }}
component "rest" {{ type = "vec_gain", host = "src", params = {{ n = 6, k = 0 }} }}
component "ff"   {{ type = "fmu", fmu = "{ff2}", host = "h_ff", params = {{ Tf = 0.004 }} }}
connect "wave.y -> lp.u"
connect "wave.y -> native.u"
connect "ptp.done -> path.done"
connect "path.goal -> ptp.goal"
connect "ptp.q -> rest.u"
connect "rest.y -> ptp.start"
connect "ptp.q -> ff.q"
connect "ptp.qd -> ff.qd"
connect "ptp.qdd -> ff.qdd"
"#,
        ff2 = ff2.display(),
        filter3 = filter3.display()
    ));
    let (trace, _) = sut.traced_up(&system, 3000, &[], "cmp");
    let trace_file = std::env::temp_dir().join(format!("{}.trace", sut.name()));
    std::fs::write(&trace_file, &trace).unwrap();
    let out = python(
        r##"
import sys, fmpy
from fmpy import read_model_description, extract, instantiate_fmu
ff2, filter3, trace = sys.argv[1:]
ticks = {}
for line in open(trace):
    if line.startswith("#"):
        continue
    words = line.split()
    values = {}
    for w in words[1:]:
        name, value = w.split("=", 1)
        if value.startswith("["):
            values[name] = [float(x) for x in value.strip("[]").split(",")]
        elif value not in ("true", "false"):
            values[name] = float(value)
    ticks[int(words[0])] = values
n = max(ticks) + 1

def run(path, params, inputs, outputs):
    """Steps the FMU at `path` with FMPy's FMI bindings as a co-simulation master does: each
    step sets the inputs of tick k (inputs(k): name -> value), does one step of 1 ms and gets
    the outputs, which are those valid at tick k + 1."""
    md = read_model_description(path)
    refs = {v.name: v.valueReference for v in md.modelVariables}
    fmu = instantiate_fmu(extract(path), md, "CoSimulation")
    fmi3 = md.fmiVersion.startswith("3")
    set_, get = (fmu.setFloat64, fmu.getFloat64) if fmi3 else (fmu.setReal, fmu.getReal)
    set_([refs[p] for p in params], list(params.values()))
    if fmi3:
        fmu.enterInitializationMode(startTime=0.0)
    else:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    got, t = {}, 0.0
    for k in range(n - 1):
        given = inputs(k)
        set_([refs[v] for v in given], list(given.values()))
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=0.001)
        t += 0.001
        got[k + 1] = dict(zip(outputs, get([refs[v] for v in outputs])))
    fmu.terminate()
    fmu.freeInstance()
    return got

worst = 0.0
got = run(filter3, {"k": 2.0, "T": 0.02}, lambda k: {"u": ticks[k]["wave.y"]}, ["y"])
for k, out in got.items():
    worst = max(worst, abs(out["y"] - ticks[k]["lp.y"]))

def trajectory(k):
    return {f"{v}[{i + 1}]": ticks[k][f"ptp.{v}"][i] for v in ("q", "qd", "qdd") for i in range(6)}
outputs = [f"{v}[{i}]" for v in ("tau", "qm") for i in range(1, 7)]
got = run(ff2, {"Tf": 0.004}, trajectory, outputs)
moved = 0.0
for k, out in got.items():
    for v in ("tau", "qm"):
        for i in range(6):
            worst = max(worst, abs(out[f"{v}[{i + 1}]"] - ticks[k][f"ff.{v}"][i]))
    moved = max(moved, abs(ticks[k]["ff.tau"][5]))
assert len(got) == n - 1, (len(got), n)
assert moved > 1.0, f"the feed-forward asked for torque: {moved}"
native = max(abs(ticks[k]["native.y"] - ticks[k]["lp.y"]) for k in range(n))
print(worst, native)
"##,
        &[
            ff2.to_str().unwrap(),
            filter3.to_str().unwrap(),
            trace_file.to_str().unwrap(),
        ],
    );
    let _ = std::fs::remove_file(&trace_file);
    let numbers: Vec<f64> = out
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    let [worst, native] = numbers[..] else {
        panic!("two numbers, not {out}");
    };
    println!("largest difference between FMPy and modbot: {worst:e}; FMU and native: {native:e}");
    assert!(worst <= 1e-12, "FMPy and modbot differ by {worst:e}");
    assert!(
        native <= 1e-12,
        "the FMU and the native lowpass differ by {native:e}"
    );
}

/// `modbot check` reads every FMU when it checks a description: a file that is not an FMU, a
/// missing one, a parameter the FMU does not have and a connection to a port it does not have
/// are each refused naming the description's file and line (exit 2), and no process starts.
#[test]
fn a_broken_or_missing_fmu_or_a_port_mismatch_fails_modbot_check_with_file_and_line() {
    let sut = TestDomain::new("fmucheck");
    let dir = std::env::temp_dir().join(sut.name());
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("broken.fmu"), b"not a zip archive").unwrap();
    let filter3 = common::bin("modbot_filter3.fmu");
    let cases = [
        (
            "fmu = \"broken.fmu\"",
            "u",
            "4: component 'F': param 'fmu': ",
        ),
        ("fmu = \"missing.fmu\"", "u", "missing.fmu: no such file"),
        (
            "fmu = \"FILTER3\", params = { K = 1 }",
            "u",
            "4: component 'F': unknown param 'K'",
        ),
        (
            "fmu = \"FILTER3\"",
            "x",
            "5: component 'F' has no input 'x' (inputs: u)",
        ),
    ];
    for (fields, input, expected) in cases {
        let fields = fields.replace("FILTER3", filter3.to_str().unwrap());
        let file = dir.join("system.lua");
        std::fs::write(
            &file,
            format!(
                "domain \"x\"\ngrid {{}}\ncomponent \"A\" {{ type = \"sine\", host = \"h\" }}\n\
                 component \"F\" {{ type = \"fmu\", host = \"h_f\", {fields} }}\n\
                 connect \"A.y -> F.{input}\"\n"
            ),
        )
        .unwrap();
        let out = sut.modbot(&["check", file.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{fields}: {err}");
        let at = format!("{}:", file.display());
        assert!(
            err.contains(&at) && err.contains(expected),
            "{fields}: {err} lacks {expected}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Python that reads a trace (`sys.argv` names it) into `ticks`: tick → `{"comp.port": value}`,
/// numbers as floats and arrays as lists of floats.
const READ_TRACE: &str = r##"
def read_trace(path):
    ticks = {}
    for line in open(path):
        if line.startswith("#"):
            continue
        words = line.split()
        values = {}
        for w in words[1:]:
            name, value = w.split("=", 1)
            if value.startswith("["):
                values[name] = [float(x) for x in value.strip("[]").split(",")]
            elif value not in ("true", "false"):
                values[name] = float(value)
        ticks[int(words[0])] = values
    return ticks
"##;

/// Runs `script` (after [`READ_TRACE`]) with the trace `trace` written to a file of the test's
/// own as its last argument, after `args`.
fn python_on_trace(sut: &TestDomain, script: &str, args: &[&str], trace: &str) -> String {
    let file = std::env::temp_dir().join(format!("{}.trace", sut.name()));
    std::fs::write(&file, trace).unwrap();
    let mut all: Vec<&str> = args.to_vec();
    all.push(file.to_str().unwrap());
    let out = python(&format!("{READ_TRACE}\n{script}"), &all);
    let _ = std::fs::remove_file(&file);
    out
}

/// The numbers `out` printed, separated by white space.
fn numbers(out: &str) -> Vec<f64> {
    out.split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect()
}

/// The FMI 3 state space, sized by its structural parameters as the description sets them (3
/// states, 2 inputs, 2 outputs: ports u and y are f64[2]; the matrices, two-dimensional
/// parameters, given row by row), runs on a grid in lockstep; FMPy sets the same sizes in
/// Configuration Mode and the same matrices, steps the FMU with the inputs the trace says it
/// was given, and gets every output modbot traced — within 1e-12, from the output after
/// initialisation valid at tick 0 on.
#[test]
fn fmpy_and_modbot_agree_on_a_state_space_fmu_its_structural_parameters_size() {
    let ss3 = common::bin("modbot_ss3.fmu");
    let mut sut = TestDomain::new("fmuss");
    let system = sut.write_system(&format!(
        r#"grid {{ base_period = 0.001, clock = "lockstep" }}
component "w"  {{ type = "sine", host = "src", params = {{ amplitude = 1, freq = 3 }} }}
component "w2" {{ type = "sine", host = "src", params = {{ amplitude = 0.5, freq = 7 }} }}
component "p"  {{ type = "pack", host = "src" }}
component "ss" {{ type = "fmu", fmu = "{ss3}", host = "h_ss",
                 params = {{ nx = 3, nu = 2, ny = 2,
                             A = {{ 0, 1, 0,  0, 0, 1,  -8, -12, -6 }},
                             B = {{ 0, 0,  0, 0,  1, 0.5 }},
                             C = {{ 1, 0, 0,  0, 1, 0 }},
                             D = {{ 0, 0,  0.1, 0 }},
                             x0 = {{ 1, -1, 0.5 }} }} }}
connect "w.y -> p.a"
connect "w2.y -> p.b"
connect "p.v -> ss.u"
"#,
        ss3 = ss3.display()
    ));
    let (trace, _) = sut.traced_up(&system, 400, &[], "ss");
    let out = python_on_trace(
        &sut,
        r##"
import sys
from fmpy import read_model_description, extract, instantiate_fmu
path, trace = sys.argv[1:]
ticks = read_trace(trace)
n = max(ticks) + 1
md = read_model_description(path)
refs = {v.name: v.valueReference for v in md.modelVariables}
fmu = instantiate_fmu(extract(path), md, "CoSimulation")
fmu.enterConfigurationMode()
fmu.setUInt64([refs["nx"], refs["nu"], refs["ny"]], [3, 2, 2])
fmu.exitConfigurationMode()
params = {"A": [0, 1, 0, 0, 0, 1, -8, -12, -6], "B": [0, 0, 0, 0, 1, 0.5],
          "C": [1, 0, 0, 0, 1, 0], "D": [0, 0, 0.1, 0], "x0": [1, -1, 0.5]}
for name, values in params.items():
    fmu.setFloat64([refs[name]], [float(x) for x in values])
fmu.enterInitializationMode(startTime=0.0)
fmu.exitInitializationMode()
got = {0: list(fmu.getFloat64([refs["y"]], 2))}
t = 0.0
for k in range(n - 1):
    fmu.setFloat64([refs["u"]], ticks[k]["p.v"])
    fmu.doStep(currentCommunicationPoint=t, communicationStepSize=0.001)
    t += 0.001
    got[k + 1] = list(fmu.getFloat64([refs["y"]], 2))
fmu.terminate()
fmu.freeInstance()
assert len(got) == n, (len(got), n)
worst = max(abs(a - b) for k, y in got.items() for a, b in zip(y, ticks[k]["ss.y"]))
moved = max(abs(y[0] - got[0][0]) for y in got.values())
print(worst, moved, got[0][0], got[0][1])
"##,
        &[ss3.to_str().unwrap()],
        &trace,
    );
    let [worst, moved, y0, y1] = numbers(&out)[..] else {
        panic!("four numbers, not {out}");
    };
    println!("largest difference between FMPy and modbot: {worst:e}");
    assert!(worst <= 1e-12, "FMPy and modbot differ by {worst:e}");
    assert!(moved > 0.1, "the state space moved: {moved}");
    assert_eq!((y0, y1), (1.0, -1.0), "y = C x0 after initialisation");
}

/// Before a component's first release is done, its readers read its initial output, in every
/// process: the FMI 3 state space (period 5) reads 2 at ticks 0 to 4 — what FMPy reports at
/// t = 0, C·x0 — and a `vec_gain` on another host, released at tick 0, puts out 2 at tick 1;
/// the FMI 2 staircase (period 4) reads its `start` at ticks 0 to 3, as FMPy has it at t = 0;
/// a built-in `counter` (period 3) reads its `start` at ticks 0 to 2.
#[test]
fn an_fmus_initial_output_is_what_its_readers_read_before_its_first_release_is_done() {
    let (ss3, stair2) = (
        common::bin("modbot_ss3.fmu"),
        common::bin("modbot_stair2.fmu"),
    );
    let mut sut = TestDomain::new("fmuinit");
    let system = sut.write_system(&format!(
        r#"grid {{ base_period = 0.001, clock = "lockstep" }}
component "c"  {{ type = "counter", host = "src", period = 3, params = {{ start = 5 }} }}
component "g"  {{ type = "vec_gain", host = "src", params = {{ n = 1, k = 1 }} }}
component "ss" {{ type = "fmu", fmu = "{ss3}", host = "h_ss", period = 5 }}
component "st" {{ type = "fmu", fmu = "{stair2}", host = "h_st", period = 4, params = {{ start = 7 }} }}
connect "ss.y -> g.u"
connect "g.y -> ss.u"
connect "c.y -> st.step"
"#,
        ss3 = ss3.display(),
        stair2 = stair2.display()
    ));
    let (trace, _) = sut.traced_up(&system, 12, &[], "init");
    let out = python_on_trace(
        &sut,
        r##"
import sys, fmpy
ss3, stair2, trace = sys.argv[1:]
ticks = read_trace(trace)
y0 = fmpy.simulate_fmu(ss3, stop_time=0.01, output_interval=0.001)["y"][0][0]
counter0 = fmpy.simulate_fmu(stair2, stop_time=0.01, output_interval=0.001,
                             start_values={"start": 7})["counter"][0]
before = lambda name, ticks_before: [ticks[k][name] for k in range(ticks_before)]
assert all(y == [y0] for y in before("ss.y", 5)), (y0, before("ss.y", 6))
assert ticks[5]["ss.y"] != [y0], "its first release's output is valid at 5"
assert ticks[1]["g.y"] == [y0], ("read at tick 0 in another process", ticks[1]["g.y"])
assert all(c == counter0 for c in before("st.counter", 4)), (counter0, before("st.counter", 5))
assert all(c == 5 for c in before("c.y", 3)), before("c.y", 4)
print(y0, counter0)
"##,
        &[ss3.to_str().unwrap(), stair2.to_str().unwrap()],
        &trace,
    );
    assert_eq!(numbers(&out), [2.0, 7.0], "FMPy's outputs at t = 0");
}

/// An FMU that asks to terminate fails the run: the project's FMI 2 staircase with
/// `t_stop = 0.05` discards the step from 0.05 s, logs why and says fmi2Terminated (FMPy's
/// simulation of it ends at 0.05 s too); `modbot up --lockstep --ticks 200` exits 1, and what
/// it prints names the call, its status, the time, the request to terminate and what the FMU
/// logged, and the tick the grid faulted at.
#[test]
fn an_fmu_that_asks_to_terminate_fails_the_run_naming_its_status_and_what_it_logged() {
    let stair2 = common::bin("modbot_stair2.fmu");
    let out = python(
        r#"
import sys, fmpy
r = fmpy.simulate_fmu(sys.argv[1], stop_time=0.2, output_interval=0.001,
                      start_values={"t_stop": 0.05})
print(r["time"][-1])
"#,
        &[stair2.to_str().unwrap()],
    );
    // FMPy prints what the FMU logged first.
    let fmpy_end: f64 = out.lines().last().unwrap_or_default().parse().unwrap();
    assert_eq!(fmpy_end, 0.05, "FMPy's last row: {out}");
    assert!(out.contains("the stair ends at t_stop = 0.05 s"), "{out}");
    let mut sut = TestDomain::new("fmustop");
    let system = sut.write_system(&format!(
        r#"grid {{ base_period = 0.001 }}
component "c"  {{ type = "counter", host = "src" }}
component "st" {{ type = "fmu", fmu = "{stair2}", host = "h_st", params = {{ t_stop = 0.05 }} }}
connect "c.y -> st.step"
"#,
        stair2 = stair2.display()
    ));
    let up = sut.spawn_logged(
        "modbot",
        &[
            "up",
            system.to_str().unwrap(),
            "--lockstep",
            "--ticks",
            "200",
        ],
    );
    let status = sut.wait_exit(up, std::time::Duration::from_secs(120));
    let output = sut.output_of(up);
    assert_eq!(status.code(), Some(1), "{output}");
    for expected in [
        "fmi2DoStep failed with fmi2Discard: the FMU asks to terminate (fmi2Terminated) at t = 0.05 s",
        "the FMU logged: \"the stair ends at t_stop = 0.05 s: the step from t = 0.05 s is not taken",
        "the grid faulted, so the run of 200 ticks failed: component st reports an unsafe state at tick 50",
    ] {
        assert!(output.contains(expected), "{output}\nlacks: {expected}");
    }
    assert!(!output.contains("every module stopped cleanly"), "{output}");
}

/// An i64 port into an FMI Int32 input is converted visibly: a `counter` from -2^40 feeds the
/// staircase's Integer input `step`, which gets the nearest Int32, -2^31 (its counter reads
/// 3 + -2^31 after its first step, then stays at the least Integer), and the FMU's host says
/// so once.
#[test]
fn an_i64_beyond_an_fmi_int32_input_is_clamped_and_said_once() {
    let stair2 = common::bin("modbot_stair2.fmu");
    let mut sut = TestDomain::new("fmuclamp");
    let system = sut.write_system(&format!(
        r#"grid {{ base_period = 0.001, clock = "lockstep" }}
component "c"  {{ type = "counter", host = "src", params = {{ start = -1099511627776 }} }}
component "st" {{ type = "fmu", fmu = "{stair2}", host = "h_st" }}
connect "c.y -> st.step"
"#,
        stair2 = stair2.display()
    ));
    let (trace, output) = sut.traced_up(&system, 20, &[], "clamp");
    let counter: Vec<&str> = trace
        .lines()
        .filter(|l| !l.starts_with('#'))
        .filter_map(|l| {
            l.split_whitespace()
                .find_map(|w| w.strip_prefix("st.counter="))
        })
        .collect();
    assert_eq!(counter[..3], ["3", "-2147483645", "-2147483648"], "{trace}");
    let said = "input 'step' is an FMI Int32: -1099511627776 is clamped to -2147483648";
    assert_eq!(output.matches(said).count(), 1, "{output}");
    assert_eq!(output.matches("is clamped to").count(), 1, "{output}");
}

/// `modbot check` checks an FMU's parameters against what the FMU declares, naming the
/// description's file and line: a value outside its `min`..`max`, a matrix given with another
/// number of elements (its shape named), a structural parameter outside its range, and a port
/// whose size a structural parameter sets fed by a port of another size.
#[test]
fn a_parameter_outside_its_range_or_shape_fails_modbot_check_with_file_and_line() {
    let sut = TestDomain::new("fmurange");
    let dir = std::env::temp_dir().join(sut.name());
    std::fs::create_dir_all(&dir).unwrap();
    let (ss3, stair2) = (
        common::bin("modbot_ss3.fmu"),
        common::bin("modbot_stair2.fmu"),
    );
    let (ss3, stair2) = (ss3.to_str().unwrap(), stair2.to_str().unwrap());
    // (the FMU, its fields, the other components and connections, the error expected)
    let ss3_body =
        "component \"B\" { type = \"vec_gain\", host = \"h\", params = { n = 1, k = 1 } }\n\
                    connect \"B.y -> F.u\"\nconnect \"F.y -> B.u\"\n";
    let stair2_body =
        "component \"A\" { type = \"counter\", host = \"h\" }\nconnect \"A.y -> F.step\"\n";
    let cases = [
        (
            stair2,
            "params = { start = 5000 }",
            stair2_body,
            "3: component 'F': param 'start' must be from -1000 to 1000 (the FMU's declared range), not 5000",
        ),
        (
            ss3,
            "params = { A = { 1, 2, 3 } }",
            ss3_body,
            "3: component 'F': param 'A' is a 2×2 matrix (nx×nx): give its 4 numbers, row by row, not 3",
        ),
        (
            ss3,
            "params = { nx = 9 }",
            ss3_body,
            "3: component 'F': param 'nx' must be from 1 to 8 (the FMU's declared range), not 9",
        ),
        (ss3, "params = { nu = 2 }", ss3_body, "f64[2]"),
    ];
    for (fmu, fields, body, expected) in cases {
        let file = dir.join("system.lua");
        std::fs::write(
            &file,
            format!(
                "domain \"x\"\ngrid {{}}\n\
                 component \"F\" {{ type = \"fmu\", host = \"h_f\", fmu = \"{fmu}\", {fields} }}\n{body}"
            ),
        )
        .unwrap();
        let out = sut.modbot(&["check", file.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{fields}: {err}");
        let at = format!("{}:", file.display());
        assert!(
            err.contains(&at) && err.contains(expected),
            "{fields}: {err} lacks {expected}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
