//! `modbot-zenoh-probe`: raw Zenoh, no modbot — the baseline of the remote-call benchmark
//! (`modbot-benches remote`). `serve` answers every query on a key with its payload; `query`
//! asks it N times with a payload of B bytes, one query at a time, and prints each round
//! trip's nanoseconds on one line.
//!
//! ```text
//! modbot-zenoh-probe serve --listen tcp/10.77.0.1:7450 --key bench/echo
//! modbot-zenoh-probe query --connect tcp/10.77.0.1:7450 --key bench/echo -n 1000 --bytes 16
//! ```

use std::time::{Duration, Instant};

use clap::Parser;
use modbot_zenoh::config::Joining;
use zenoh::query::ConsolidationMode;
use zenoh::Wait;

#[derive(Parser)]
enum Probe {
    /// Answers queries on KEY with their payload until killed.
    Serve {
        #[arg(long)]
        listen: String,
        #[arg(long)]
        key: String,
    },
    /// Queries KEY N times and prints the round trips (ns), space separated.
    Query {
        #[arg(long)]
        connect: String,
        #[arg(long)]
        key: String,
        #[arg(short, default_value_t = 1000)]
        n: usize,
        #[arg(long, default_value_t = 16)]
        bytes: usize,
    },
}

fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let probe = Probe::parse();
    let joining = |listen: Vec<String>, connect: Vec<String>| Joining {
        mode: Some("peer".into()),
        listen,
        connect,
        file: None,
        lease_ms: 2000,
    };
    match probe {
        Probe::Serve { listen, key } => {
            let session = zenoh::open(joining(vec![listen], Vec::new()).zenoh()?).wait()?;
            let _q = session
                .declare_queryable(key.as_str())
                .callback(|q| {
                    let p = q
                        .payload()
                        .map(|p| p.to_bytes().into_owned())
                        .unwrap_or_default();
                    let _ = q.reply(q.key_expr().clone(), p).wait();
                })
                .wait()?;
            println!("serving");
            loop {
                std::thread::sleep(Duration::from_secs(3600));
            }
        }
        Probe::Query {
            connect,
            key,
            n,
            bytes,
        } => {
            let session = zenoh::open(joining(Vec::new(), vec![connect]).zenoh()?).wait()?;
            let payload = vec![0x5a; bytes];
            // Until the server answers (the link and its queryable known).
            let deadline = Instant::now() + Duration::from_secs(30);
            loop {
                let rx = session
                    .get(key.as_str())
                    .payload(payload.clone())
                    .timeout(Duration::from_secs(1))
                    .wait()?;
                if rx.recv().is_ok_and(|r| r.result().is_ok()) {
                    break;
                }
                if Instant::now() > deadline {
                    return Err("no answer from the server within 30 s".into());
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let mut took = Vec::with_capacity(n);
            for _ in 0..n {
                let started = Instant::now();
                let rx = session
                    .get(key.as_str())
                    .payload(payload.clone())
                    .consolidation(ConsolidationMode::None)
                    .timeout(Duration::from_secs(2))
                    .wait()?;
                let reply = rx.recv().map_err(|e| format!("no reply: {e}"))?;
                if reply.result().is_err() {
                    return Err("the server answered an error".into());
                }
                took.push(started.elapsed().as_nanos().to_string());
            }
            println!("{}", took.join(" "));
            drop(session);
            Ok(())
        }
    }
}
