//! `examples/arm.lua` under `modbot up`, as the fault, swap, arm, station and soak benchmarks
//! start it: six simulated CiA 402 drives behind the bus bridge, and its ledger (`modbot bus`).

use std::path::PathBuf;
use std::time::Duration;

use modbot_core::CallOptions;

use crate::opts::Opts;
use crate::procs::Scratch;
use crate::supervised::Supervised;

/// `examples/arm.lua` of this checkout.
pub fn arm_description() -> anyhow::Result<PathBuf> {
    crate::checkout::existing_example("arm.lua")
}

/// The drive lines of the bus ledger.
fn axes(ledger: &str) -> Vec<&str> {
    ledger
        .lines()
        .skip_while(|l| !l.starts_with("AXIS"))
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .collect()
}

/// Whether the bus ledger shows every one of six drives in `state`.
fn all_axes(ledger: &str, state: &str) -> bool {
    let axes = axes(ledger);
    axes.len() == 6 && axes.iter().all(|l| l.contains(state))
}

/// Starts `examples/arm.lua` in `scratch`'s domain with `vars` and waits until every drive is
/// enabled; returns the system and its start-up time.
pub fn start_arm(
    opts: &Opts,
    scratch: &Scratch,
    vars: &[&str],
) -> anyhow::Result<(Supervised, Duration)> {
    let arm = arm_description()?;
    let mut args = vec![
        "--var".to_owned(),
        format!("domain={}", scratch.domain.name()),
    ];
    for v in vars {
        args.extend(["--var".to_owned(), (*v).to_owned()]);
    }
    let mut sys = Supervised::start(opts, &scratch.domain, &arm, &args, Duration::from_secs(20))?;
    let startup = sys.wait_up(Duration::from_secs(60))?;
    wait_drives_enabled(&mut sys, Duration::from_secs(30))?;
    Ok((sys, startup))
}

/// Waits until the bus ledger shows every one of the six drives in operation enabled.
pub fn wait_drives_enabled(sys: &mut Supervised, timeout: Duration) -> anyhow::Result<()> {
    sys.wait_with_tool("every drive enabled", timeout, |t| {
        let ledger = bus_ledger(t);
        Ok(ledger
            .filter(|l| all_axes(l, "operation enabled"))
            .map(|_| ()))
    })
}

/// The bus ledger (`modbot bus`), if the bridge answers.
pub fn bus_ledger(tool: &mut modbot_core::Module<()>) -> Option<String> {
    tool.call_blocking(
        "host_bus",
        "bus",
        &[],
        CallOptions::timeout(Duration::from_millis(500)),
        |r| r.ok().and_then(|a| a.text(0).ok().map(str::to_owned)),
    )
}
