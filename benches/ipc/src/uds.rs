//! The Unix-domain-socket baseline: a stream socket, blocking reads, each message a u32
//! length and the payload, copied in and out by the kernel.
//!
//! Child roles:
//! - `uds-echo PATH CORE PRIO`: sends every message back (the call baseline);
//! - `uds-sink PATH CORE PRIO`: answers every message with 8 bytes, the nanoseconds from the
//!   CLOCK_MONOTONIC stamp in the message's first 8 bytes to its full arrival (the snapshot
//!   baseline).
//!
//! `PRIO` is a SCHED_FIFO priority or `-`. Children exit when the benchmark closes the socket.

use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_kit::procs::{self, Proc};
use modbot_bench_kit::sample::now_ns;

/// The benchmark's end of the socket.
pub struct Client {
    stream: UnixStream,
    /// Where answers are copied to.
    sink: Vec<u8>,
}

impl Client {
    /// Connects to the child listening at `path`, retrying while it starts.
    pub fn connect(path: &Path, child: &mut Proc) -> anyhow::Result<Client> {
        let end = Instant::now() + Duration::from_secs(10);
        loop {
            match UnixStream::connect(path) {
                Ok(stream) => {
                    return Ok(Client {
                        stream,
                        sink: Vec::new(),
                    })
                }
                Err(e) if Instant::now() < end => {
                    child
                        .check_running()
                        .with_context(|| format!("connecting to {}", path.display()))?;
                    let _ = e;
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(e) => bail!("cannot connect to {} within 10 s: {e}", path.display()),
            }
        }
    }

    /// Sends `payload` and reads the echo back into the sink; returns the answer's length.
    pub fn echo(&mut self, payload: &[u8]) -> anyhow::Result<usize> {
        send(&mut self.stream, payload)?;
        recv(&mut self.stream, &mut self.sink)
    }

    /// Stamps `payload` with CLOCK_MONOTONIC, sends it and returns the delivery latency the
    /// sink measured.
    pub fn deliver(&mut self, payload: &mut [u8]) -> anyhow::Result<u64> {
        if payload.len() < 8 {
            bail!("a stamped payload needs at least 8 bytes");
        }
        payload[..8].copy_from_slice(&now_ns().to_le_bytes());
        send(&mut self.stream, payload)?;
        let mut ack = [0u8; 8];
        self.stream
            .read_exact(&mut ack)
            .context("reading the sink's answer")?;
        Ok(u64::from_le_bytes(ack))
    }
}

fn send(stream: &mut UnixStream, payload: &[u8]) -> anyhow::Result<()> {
    let len = u32::try_from(payload.len()).context("a message is limited to 4 GiB")?;
    stream.write_all(&len.to_le_bytes())?;
    stream.write_all(payload)?;
    Ok(())
}

/// Reads one message into `buf` (resized to it); returns its length.
fn recv(stream: &mut UnixStream, buf: &mut Vec<u8>) -> anyhow::Result<usize> {
    let mut len = [0u8; 4];
    stream.read_exact(&mut len)?;
    let len = u32::from_le_bytes(len) as usize;
    if buf.len() < len {
        buf.resize(len, 0);
    }
    stream.read_exact(&mut buf[..len])?;
    Ok(len)
}

/// The child roles of this baseline.
pub fn child(role: &str, args: &[String]) -> Option<anyhow::Result<()>> {
    let sink = match role {
        "uds-echo" => false,
        "uds-sink" => true,
        _ => return None,
    };
    Some(serve(args, sink))
}

fn serve(args: &[String], sink: bool) -> anyhow::Result<()> {
    let [path, core, prio] = args else {
        bail!("usage: child uds-echo|uds-sink PATH CORE PRIO");
    };
    let _pinned = procs::pin(procs::parse_core(core)?)?;
    let _fifo = procs::set_fifo(parse_prio(prio)?)?;
    let listener = UnixListener::bind(path).with_context(|| format!("cannot listen at {path}"))?;
    let (mut stream, _) = listener.accept().context("accept")?;
    let mut buf = Vec::new();
    loop {
        let len = match recv(&mut stream, &mut buf) {
            Ok(len) => len,
            Err(e) => {
                // The benchmark closed the socket (or stopped us): done.
                let closed = e.downcast_ref::<std::io::Error>().is_some_and(|io| {
                    matches!(io.kind(), ErrorKind::UnexpectedEof | ErrorKind::Interrupted)
                });
                if closed || procs::interrupted() {
                    return Ok(());
                }
                return Err(e);
            }
        };
        if sink {
            let now = now_ns();
            let stamp = buf
                .get(..8)
                .and_then(|b| <[u8; 8]>::try_from(b).ok())
                .map_or(now, u64::from_le_bytes);
            stream.write_all(&now.saturating_sub(stamp).to_le_bytes())?;
        } else {
            send(&mut stream, &buf[..len])?;
        }
    }
}

/// A SCHED_FIFO priority argument: a number or `-`.
pub fn parse_prio(text: &str) -> anyhow::Result<Option<u8>> {
    if text == "-" {
        return Ok(None);
    }
    text.parse()
        .map(Some)
        .with_context(|| format!("priority '{text}': expected 1..99 or -"))
}

/// [`parse_prio`]'s argument for `prio`.
pub fn prio_arg(prio: Option<u8>) -> String {
    prio.map_or_else(|| "-".to_owned(), |p| p.to_string())
}
