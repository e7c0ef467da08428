//! `modbot ls`, `call` and `bb`: a short-lived tool endpoint in the system's domain.

use std::process::ExitCode;
use std::time::Duration;

use anyhow::{anyhow, bail, Context};
use modbot_ipc_schema::{sysmethod, OwnedValue, SnapshotView, Value};
use modbot_runtime::{CallOptions, Domain, IpcTransport, Module, ModuleBuilder};

fn open(domain: &str) -> anyhow::Result<Module<()>> {
    let domain = Domain::new(domain)?;
    let transport = IpcTransport::new(&domain)?;
    ModuleBuilder::new("modbot-cli", 0)
        .open_tool(transport, ())
        .context("cannot join the domain")
}

/// `modbot ls`.
pub fn ls(domain: &str) -> anyhow::Result<ExitCode> {
    let mut tool = open(domain)?;
    let me = tool.addr();
    let modules = tool.list_modules()?;
    println!(
        "{:>4}  {:<16} {:>8}  {:<6} {:<10} METHODS",
        "ADDR", "NAME", "PID", "STATE", "MODE"
    );
    for m in modules.iter().filter(|m| m.addr != me) {
        let (state, methods) = if m.alive {
            let described = tool.call_blocking(
                &m.name,
                sysmethod::name(sysmethod::DESCRIBE).unwrap(),
                &[],
                CallOptions::timeout(Duration::from_millis(500)),
                |r| match r {
                    Ok(a) => a.text(3).map(str::to_owned).map_err(|e| e.to_string()),
                    Err(e) => Err(e.to_string()),
                },
            );
            match described {
                Ok(methods) => ("alive", methods.replace(',', " ")),
                Err(e) => ("alive", format!("(no answer: {e})")),
            }
        } else {
            ("dead", String::new())
        };
        println!(
            "{:>4}  {:<16} {:>8}  {:<6} {:<10} {}",
            m.addr,
            m.name,
            m.pid,
            state,
            m.mode.name(),
            methods
        );
    }
    tool.reap_dead();
    Ok(ExitCode::SUCCESS)
}

/// `modbot call MODULE.METHOD ARGS...`.
pub fn call(
    domain: &str,
    target: &str,
    args: &[String],
    timeout_ms: u64,
) -> anyhow::Result<ExitCode> {
    let (module, method) = target
        .split_once('.')
        .ok_or_else(|| anyhow!("'{target}' is not MODULE.METHOD"))?;
    let owned = args
        .iter()
        .map(|a| OwnedValue::parse(a).map_err(|e| anyhow!(e)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let values: Vec<Value<'_>> = owned.iter().map(OwnedValue::as_value).collect();
    let mut tool = open(domain)?;
    let result = tool.call_owned(
        module,
        method,
        &values,
        CallOptions::timeout(Duration::from_millis(timeout_ms)),
    );
    match result {
        Ok(values) if values.is_empty() => println!("ok"),
        Ok(values) => {
            for v in values {
                println!("{v}");
            }
        }
        Err(e) => {
            eprintln!("modbot call {target}: {e}");
            return Ok(ExitCode::from(1));
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `modbot bb MODULE [ITEM [VALUE]]`.
pub fn bb(
    domain: &str,
    module: &str,
    item: Option<&str>,
    value: Option<&str>,
) -> anyhow::Result<ExitCode> {
    let mut tool = open(domain)?;
    let opts = CallOptions::timeout(Duration::from_secs(2));
    let outcome: anyhow::Result<()> = match (item, value) {
        (None, _) => tool.call_blocking(module, "bb_snapshot", &[], opts, |r| {
            let args = r.map_err(|e| anyhow!("{e}"))?;
            let bytes = args.bytes(0).map_err(|e| anyhow!("{e}"))?;
            let view = SnapshotView::parse(bytes).map_err(|e| anyhow!("{e}"))?;
            println!(
                "# {module} (address {}), snapshot {}",
                view.addr(),
                view.seq()
            );
            for it in view.iter() {
                println!(
                    "{}: {}{}",
                    it.name,
                    it.value,
                    if it.writable { "  (writable)" } else { "" }
                );
            }
            Ok(())
        }),
        (Some(name), None) => {
            tool.call_blocking(module, "bb_get", &[Value::Text(name)], opts, |r| {
                let args = r.map_err(|e| anyhow!("{e}"))?;
                match args.get(0) {
                    Some(v) => println!("{v}"),
                    None => bail!("empty answer"),
                }
                Ok(())
            })
        }
        (Some(name), Some(text)) => {
            let v = OwnedValue::parse(text).map_err(|e| anyhow!(e))?;
            tool.call_blocking(
                module,
                "bb_set",
                &[Value::Text(name), v.as_value()],
                opts,
                |r| {
                    r.map_err(|e| anyhow!("{e}"))?;
                    println!("ok");
                    Ok(())
                },
            )
        }
    };
    match outcome {
        Ok(()) => Ok(ExitCode::SUCCESS),
        Err(e) => {
            eprintln!("modbot bb {module}: {e}");
            Ok(ExitCode::from(1))
        }
    }
}
