//! Your first module: a counter that others add to, and that adds 1 to a peer every second.
use modbot_core::{Args, Blackboard, CallError, CallHandle, Ctx, MethodError};
use modbot_core::{ModuleArgs, OwnedValue, Reply, Value};

/// What the supervisor passes (`--domain`, `--name`, `--addr`, `--mode`), and `--peer`.
#[derive(clap::Parser)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    #[arg(long)]
    peer: Option<String>,
}

struct Counter {
    total: i64,
    peer: Option<String>,
}

/// `add(n)`: adds n to the total, keeps it on the blackboard, answers it.
fn add(c: &mut Counter, ctx: &mut Ctx, args: &Args, reply: &mut Reply) -> Result<(), MethodError> {
    c.total += args.i64(0)?;
    let _ = ctx.bb.write("total", Value::I64(c.total));
    reply.push(Value::I64(c.total));
    Ok(())
}

/// Every second: `PEER.add(1)`; its answer comes to `added`.
fn tick(c: &mut Counter, ctx: &mut Ctx) {
    if let Some(peer) = c.peer.clone() {
        let _ = ctx.call(&peer, "add", &[Value::I64(1)]);
    }
}

fn added(_: &mut Counter, ctx: &mut Ctx, _: CallHandle, answer: Result<&Args, &CallError>) {
    if let Ok(Ok(total)) = answer.map(|a| a.i64(0)) {
        let _ = ctx.bb.write("peer_total", Value::I64(total));
    }
}

fn main() -> std::process::ExitCode {
    modbot_core::cli::exit("modbot-first-module", run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let cli: Cli = clap::Parser::parse();
    let bb = Blackboard::builder()
        .item("total", OwnedValue::I64(0))
        .item("peer_total", OwnedValue::I64(0))
        .build()?;
    let counter = Counter {
        total: 0,
        peer: cli.peer,
    };
    let module = cli
        .module
        .module("counter", 1)
        .method("add", add)
        .every(std::time::Duration::from_secs(1), tick)
        .on_done(added)
        .blackboard(bb);
    Ok(cli.module.serve(module, counter)?)
}
