//! The project's own FMUs (crate `modbot-fmus`, built from source by the workspace's build),
//! checked by a tool no one here wrote: FMPy validates each and simulates it.

mod common;

use common::python::python;

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
