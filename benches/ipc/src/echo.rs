//! The echo module of benchmark 1: its method, which answers with its arguments, the child
//! role that runs it in a process of its own, and what its callers share (the transport of a
//! two-module system, the answer copied out of shared memory).
//!
//! Child role `calls-echo DOMAIN MAX_FRAME MODE CORE PRIO LOOK_US`: the echo module (LOOK_US:
//! how long it lingers after a frame in blocking mode).

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_kit::procs::{self, Proc};
use modbot_core::transport::launch::inbox_senders_for;
use modbot_core::{
    CallError, CallOptions, Ctx, Domain, IpcTransport, MethodError, Module, ModuleBuilder,
    ReceiveMode, Reply,
};
use modbot_ipc_schema::{Args, Value};

use crate::uds;

/// The child role `calls-echo`.
pub fn child(role: &str, args: &[String]) -> Option<anyhow::Result<()>> {
    (role == "calls-echo").then(|| echo_module(args))
}

/// The echo module's method `echo`: answers with its arguments.
pub fn echo(
    _: &mut (),
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    for v in args.as_slice() {
        reply.push(*v);
    }
    Ok(())
}

fn echo_module(args: &[String]) -> anyhow::Result<()> {
    let [domain, max_frame, mode, core, prio, look_us] = args else {
        bail!("usage: child calls-echo DOMAIN MAX_FRAME busy|blocking CORE PRIO LOOK_US");
    };
    let look = Duration::from_micros(
        look_us
            .parse()
            .with_context(|| format!("look '{look_us}' (µs)"))?,
    );
    let _pinned = procs::pin(procs::parse_core(core)?)?;
    let mode = match mode.as_str() {
        "busy" => ReceiveMode::BusyPoll,
        "blocking" => ReceiveMode::Blocking,
        other => bail!("mode '{other}': expected busy or blocking"),
    };
    let _fifo = procs::set_fifo(uds::parse_prio(prio)?)?;
    let max_frame: usize = max_frame
        .parse()
        .with_context(|| format!("max frame '{max_frame}'"))?;
    let domain = Domain::new(domain)?.with_max_frame(max_frame);
    let module = ModuleBuilder::new("echo", 1)
        .mode(mode)
        .method("echo", echo)
        .linger(look)
        .open(two_module_system(&domain)?, ())?;
    module.run()?;
    Ok(())
}

/// Copies the echo module's answer (its first value, bytes) out of shared memory into `sink`;
/// its length, or why there is none.
pub fn copy_answer(
    answer: Result<&Args<'_>, &CallError>,
    sink: &mut Vec<u8>,
) -> Result<usize, String> {
    match answer {
        Ok(args) => match args.as_slice().first() {
            Some(Value::Bytes(b)) => {
                sink.clear();
                sink.extend_from_slice(b);
                Ok(b.len())
            }
            other => Err(format!("unexpected answer {other:?}")),
        },
        Err(e) => Err(e.to_string()),
    }
}

/// The transport of either side: inboxes with the sender slots a supervisor gives a system of
/// two modules, as `modbot up` would run them.
pub fn two_module_system(domain: &Domain) -> anyhow::Result<IpcTransport> {
    Ok(IpcTransport::new(domain)?.with_inbox_senders(inbox_senders_for(2)))
}

/// Calls until the echo module answers (it is starting, and the tool must learn its methods).
pub(crate) fn wait_for_echo(tool: &mut Module<()>, child: &mut Proc) -> anyhow::Result<()> {
    let end = Instant::now() + Duration::from_secs(15);
    loop {
        let answer = tool.call_owned(
            "echo",
            "echo",
            &[],
            CallOptions::timeout(Duration::from_millis(200)),
        );
        match answer {
            Ok(_) => return Ok(()),
            Err(e) => {
                child
                    .check_running()
                    .context("waiting for the echo module")?;
                procs::check_interrupted()?;
                if Instant::now() > end {
                    bail!("the echo module did not answer within 15 s: {e}");
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    }
}
