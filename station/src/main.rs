//! `modbot-station` (and `modbot station`): the operator's control station for one domain, as
//! a web page. See the crate's documentation (`src/lib.rs`).

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use anyhow::Context;
use clap::Parser;
use modbot_core::domain::Domain;
use modbot_core::tool::Tool;
use modbot_station::access::{random_token, Access, Origin};
use modbot_station::server::{router, Shared};
use modbot_station::watcher::Watcher;

/// The operator's control station: every module, the grid and the robot live in a browser,
/// and commands to them.
#[derive(Parser)]
#[command(name = "modbot station")]
struct Args {
    /// The system's domain.
    #[arg(long, env = "MODBOT_DOMAIN", default_value = "default")]
    domain: String,
    /// Where the page is served. Anything but a loopback address needs the token to command.
    #[arg(long, default_value = "127.0.0.1:8080")]
    listen: SocketAddr,
    /// The token a page must show to command (`?token=…` in its address); without it on a
    /// non-loopback address the station makes one and prints it.
    #[arg(long, env = "MODBOT_STATION_TOKEN")]
    token: Option<String>,
    /// Show the system in this terminal instead (`modbot top`).
    #[arg(long)]
    top: bool,
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let args = Args::parse();
    let domain = Domain::new(&args.domain)?;
    if args.top {
        let tool = Tool::open(&domain, "top")
            .with_context(|| format!("modbot top cannot join domain '{}'", args.domain))?;
        modbot_station::top::run(Watcher::new(tool, &args.domain))?;
        return Ok(());
    }
    let (access, origin) = Access::new(args.listen, args.token, || {
        random_token().unwrap_or_else(|e| panic!("no random token: /dev/urandom: {e}"))
    });
    let listener = std::net::TcpListener::bind(args.listen)
        .with_context(|| format!("cannot listen on {}", args.listen))?;
    listener.set_nonblocking(true)?;
    let bound = listener.local_addr()?;
    let url = format!("http://{bound}/");

    let (states_tx, states) = tokio::sync::watch::channel::<Arc<str>>(Arc::from("{}"));
    let (inputs, inputs_rx) = crossbeam::channel::bounded(64);
    // The endpoint is the watcher thread's own (an endpoint stays on the thread that opened
    // it); whether it joined the domain comes back before anything is served.
    let stop = Arc::new(AtomicBool::new(false));
    let pages = Arc::new(AtomicUsize::new(0));
    let (joined_tx, joined) = std::sync::mpsc::channel();
    let watching = {
        let (stop, name, pages) = (stop.clone(), args.domain.clone(), pages.clone());
        std::thread::Builder::new()
            .name("watcher".into())
            .spawn(move || match Tool::open(&domain, "station") {
                Ok(tool) => {
                    let _ = joined_tx.send(Ok(()));
                    Watcher::new(tool, &name)
                        .with_pages(pages)
                        .run(inputs_rx, states_tx, &stop);
                }
                Err(e) => {
                    let _ = joined_tx.send(Err(e));
                }
            })?
    };
    joined
        .recv()
        .context("the watcher thread ended")?
        .with_context(|| format!("the station cannot join domain '{}'", args.domain))?;
    match (&origin, access.token()) {
        (Origin::Made, Some(t)) => println!(
            "modbot station: domain '{}' at {url}?token={t} (commands need this token; without it the page is read-only)",
            args.domain
        ),
        (Origin::Given, _) => println!(
            "modbot station: domain '{}' at {url} (commands need the token: {url}?token=…)",
            args.domain
        ),
        _ => println!("modbot station: domain '{}' at {url}", args.domain),
    }
    let shared = Shared {
        access: Arc::new(access),
        states,
        inputs,
        domain: Arc::from(args.domain.as_str()),
        map: Arc::from(serde_json::to_string(&modbot_station::map::moser())?),
        pages,
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let served: std::io::Result<()> = runtime.block_on(async move {
        use tokio::signal::unix::{signal, SignalKind};
        let listener = tokio::net::TcpListener::from_std(listener)?;
        let mut term = signal(SignalKind::terminate())?;
        tokio::select! {
            r = axum::serve(listener, router(shared)) => r,
            _ = tokio::signal::ctrl_c() => Ok(()),
            _ = term.recv() => Ok(()),
        }
    });
    // The watcher's endpoint leaves the domain before the process ends.
    stop.store(true, Ordering::Relaxed);
    let _ = watching.join();
    drop(runtime);
    served.context("serving the station")?;
    println!("modbot station: stopped");
    Ok(())
}
