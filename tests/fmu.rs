//! The project's own FMUs (crate `modbot-fmus`, built from source by the workspace's build),
//! checked by a tool no one here wrote — FMPy validates each and simulates it, and its
//! outputs agree with modbot's for the same inputs — and FMU components under `modbot check`.

mod common;

use common::python::python;
use common::TestDomain;

/// Both FMUs pass FMPy's validation (modelDescription.xml against the standard's rules, and
/// the binary's exported functions), and FMPy simulates each: the FMI 3 filter's step
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
ff2, filter3 = sys.argv[1:]
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
        &[ff2.to_str().unwrap(), filter3.to_str().unwrap()],
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
