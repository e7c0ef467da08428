//! `modbot-zenoh`: a domain's bridge to other hosts (see the crate's documentation). Started
//! by the supervisor from the description's `bridge { ... }`, or by hand:
//!
//! ```text
//! modbot-zenoh --domain robot --name bridge --addr 200 --listen tcp/10.0.0.1:7447 \
//!     --export high_level:patrol,stop --export mobility \
//!     --import control_station@30=station/control_station
//! ```

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

use clap::Parser;
use modbot_core::{Domain, ModuleArgs};
use modbot_zenoh::config::{Export, Import, Joining};
use modbot_zenoh::export::{Exporter, Work};
use modbot_zenoh::import::{self, ProxyContext};
use modbot_zenoh::keys;
use modbot_zenoh::link::Link;
use zenoh::sample::SampleKind;
use zenoh::Wait;

#[derive(Parser)]
#[command(about = "modbot's bridge to domains on other hosts, through Zenoh")]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    /// Zenoh's mode: peer or client.
    #[arg(long)]
    zenoh_mode: Option<String>,
    /// An endpoint to listen on (tcp/ADDRESS:PORT), repeatable.
    #[arg(long)]
    listen: Vec<String>,
    /// An endpoint to connect to, repeatable (retried until it answers, and again after the
    /// link was lost).
    #[arg(long)]
    connect: Vec<String>,
    /// A Zenoh configuration file (JSON5 or YAML): TLS, access control, ...; --zenoh-mode,
    /// --listen and --connect override what it says.
    #[arg(long)]
    zenoh_config: Option<PathBuf>,
    /// A module remote domains may call: MODULE (every method) or MODULE:METHOD,METHOD.
    #[arg(long)]
    export: Vec<String>,
    /// A remote module to put into this domain's phone book: LOCAL_NAME@ADDRESS=DOMAIN/MODULE.
    #[arg(long)]
    import: Vec<String>,
    /// How long a call through the link may take before its caller hears that no answer came
    /// (ms); a local call for a remote caller may take 500 ms less.
    #[arg(long, default_value_t = 1500)]
    call_timeout_ms: u64,
    /// How long a silent link lasts before it counts as down (Zenoh's lease, ms).
    #[arg(long, default_value_t = 2000)]
    lease_ms: u64,
    /// How often the exported modules' blackboard snapshots go to the remote domains that
    /// import them (per second; 0: never). Only a snapshot newer than the last one goes.
    #[arg(long, default_value_t = 10.0)]
    snapshot_hz: f64,
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "warn,zenoh=error".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    modbot_core::cli::exit("modbot-zenoh", run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let cli = Cli::parse();
    let exports = cli
        .export
        .iter()
        .map(|e| Export::parse(e))
        .collect::<Result<Vec<_>, _>>()?;
    let imports = cli
        .import
        .iter()
        .map(|i| Import::parse(i))
        .collect::<Result<Vec<_>, _>>()?;
    if !(cli.snapshot_hz >= 0.0 && cli.snapshot_hz <= 1000.0) {
        return Err(format!(
            "--snapshot-hz {}: expected 0 (never) to 1000 snapshots a second",
            cli.snapshot_hz
        )
        .into());
    }
    let joining = Joining {
        mode: cli.zenoh_mode.clone(),
        listen: cli.listen.clone(),
        connect: cli.connect.clone(),
        file: cli.zenoh_config.clone(),
        lease_ms: cli.lease_ms,
    };
    let zenoh_config = joining.zenoh()?;
    let domain = Domain::new(&cli.module.domain)?;
    let name = domain.name().to_owned();
    if let Err(e) = modbot_core::signals::install_termination_handler() {
        tracing::warn!("cannot handle SIGTERM/SIGINT: {e}");
    }
    let builder = cli.module.module::<()>("bridge", 0);
    let mut module = builder.open(cli.module.transport()?, ())?;
    let session = zenoh::open(zenoh_config)
        .wait()
        .map_err(|e| format!("cannot open the Zenoh session: {e}"))?;
    let _token = session
        .liveliness()
        .declare_token(keys::alive(&name))
        .wait()
        .map_err(|e| format!("Zenoh liveliness token: {e}"))?;

    let (work_tx, work) = mpsc::channel::<Work>();
    let calls_tx = work_tx.clone();
    let _calls = session
        .declare_queryable(keys::calls(&name))
        .callback(move |q| {
            let _ = calls_tx.send(Work::Call(q));
        })
        .wait()
        .map_err(|e| format!("Zenoh queryable: {e}"))?;
    let reports_name = name.clone();
    let _reports = session
        .declare_subscriber(keys::reports(&name))
        .callback(move |s| {
            let key = s.key_expr().as_str();
            if let Some((to, domain, from)) = keys::report_parts(&reports_name, key) {
                let _ = work_tx.send(Work::Report {
                    domain: domain.to_owned(),
                    to: to.to_owned(),
                    from: from.to_owned(),
                    bytes: s.payload().to_bytes().into_owned(),
                });
            }
        })
        .wait()
        .map_err(|e| format!("Zenoh subscriber: {e}"))?;

    // The link to each remote domain imported from: its bridge's liveliness token.
    let mut links: BTreeMap<String, Arc<Link>> = BTreeMap::new();
    let mut watchers = Vec::new();
    for i in &imports {
        if links.contains_key(&i.domain) {
            continue;
        }
        let link = Arc::new(Link::new(&i.domain));
        let seen = link.clone();
        let watcher = session
            .liveliness()
            .declare_subscriber(keys::alive(&i.domain))
            .history(true)
            .callback(move |s| seen.set(s.kind() == SampleKind::Put))
            .wait()
            .map_err(|e| format!("Zenoh liveliness subscriber: {e}"))?;
        watchers.push(watcher);
        links.insert(i.domain.clone(), link);
    }

    let stop = Arc::new(AtomicBool::new(false));
    let call_timeout = Duration::from_millis(cli.call_timeout_ms);
    let mut proxies = Vec::new();
    for i in &imports {
        let (ready_tx, ready) = mpsc::channel();
        let cx = ProxyContext {
            domain: domain.clone(),
            session: session.clone(),
            link: links[&i.domain].clone(),
            call_timeout,
            heartbeat: modbot_core::transport::launch::heartbeat_period(),
            stop: stop.clone(),
        };
        let import = i.clone();
        let thread = std::thread::Builder::new()
            .name(format!("import-{}", i.local))
            .spawn(move || import::serve(import, cx, ready_tx))?;
        match ready.recv() {
            Ok(Ok(())) => proxies.push(thread),
            Ok(Err(why)) => {
                stop.store(true, Ordering::Relaxed);
                return Err(why.into());
            }
            Err(_) => {
                stop.store(true, Ordering::Relaxed);
                return Err(format!("import '{}': its thread ended", i.local).into());
            }
        }
    }
    eprintln!(
        "modbot-zenoh: domain '{name}' bridged: exports [{}], imports [{}]",
        exports
            .iter()
            .map(|e| e.module.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        imports
            .iter()
            .map(|i| format!("{} = {}/{}", i.local, i.domain, i.module))
            .collect::<Vec<_>>()
            .join(", ")
    );

    let exporter = Exporter {
        domain: name,
        exports,
        imports,
        call_timeout: call_timeout
            .saturating_sub(Duration::from_millis(500))
            .max(Duration::from_millis(100)),
        snapshot_hz: cli.snapshot_hz,
    };
    let served = exporter.run(&mut module, &work, &session, &stop);
    stop.store(true, Ordering::Relaxed);
    for p in proxies {
        let _ = p.join();
    }
    drop(watchers);
    drop(module);
    let _ = session.close().wait();
    Ok(served?)
}
