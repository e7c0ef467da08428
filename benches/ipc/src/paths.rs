//! The paths of benchmark 1's round trips, each to an echo server in a process of its own: a
//! modbot call to the echo module ([`ModbotPath`]), and the baselines, raw iceoryx2
//! ([`RawPath`]) and a Unix stream socket ([`UdsPath`]). Each keeps its domain and files in a
//! scratch of its own. The grid's lockstep run and the station benchmark use them too.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Proc, Scratch};
use modbot_bench_kit::report::{format_value, Report};
use modbot_bench_kit::sample::{self, size_label};
use modbot_core::{CallOptions, Module, ModuleBuilder, ReceiveMode};
use modbot_ipc_schema::Value;

use crate::echo::{copy_answer, two_module_system, wait_for_echo};
use crate::raw::{RawPorts, Wait};
use crate::uds;

/// One way to make a round trip with a payload, and the server process that answers.
pub trait Path {
    /// One round trip of `payload`, in ns.
    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64>;
    fn server(&mut self) -> &mut Proc;
}

/// How long modbot's blocking side looks before sleeping: the default of [`CallOptions::spin`]
/// and of [`ModuleBuilder::linger`], which is defined as the same.
pub const LOOK: Duration = modbot_core::module::DEFAULT_LINGER;

/// Starts the server side of a round trip, child role `role`: its arguments `first`, the core
/// it runs on (the second of `--pin`) and its SCHED_FIFO priority, then `last`.
pub(crate) fn spawn_server(
    opts: &Opts,
    role: &str,
    first: &[String],
    fifo: Option<u8>,
    last: &[String],
) -> anyhow::Result<Proc> {
    let mut args = first.to_vec();
    args.push(procs::core_arg(procs::core_for(opts, 1)));
    args.push(uds::prio_arg(fifo));
    args.extend_from_slice(last);
    procs::spawn_role(opts, role, &args)
}

fn mode_arg(mode: ReceiveMode) -> &'static str {
    match mode {
        ReceiveMode::BusyPoll => "busy",
        ReceiveMode::Blocking => "blocking",
    }
}

/// A modbot call to the echo module, in a domain of its own.
pub struct ModbotPath {
    tool: Module<()>,
    child: Proc,
    mode: ReceiveMode,
    /// How long a blocking call looks for its answer before sleeping ([`CallOptions::spin`]).
    spin: Duration,
    /// The answer, copied out of shared memory.
    sink: Vec<u8>,
    // Declared last, dropped last: after the processes, nothing of the run stays behind.
    scratch: Scratch,
}

impl ModbotPath {
    /// `look`: how long the caller looks for an answer and the echo module for the next call
    /// before sleeping (blocking mode: [`CallOptions::spin`], [`ModuleBuilder::linger`]).
    pub fn open(
        opts: &Opts,
        mode: ReceiveMode,
        max_frame: usize,
        fifo: Option<u8>,
        look: Duration,
    ) -> anyhow::Result<ModbotPath> {
        let what = format!(
            "calls_{}_{}_{}",
            mode_arg(mode),
            max_frame >> 10,
            look.as_micros()
        );
        let scratch = Scratch::new(&what, Some(max_frame))?;
        let domain = scratch.domain.clone();
        let mut child = spawn_server(
            opts,
            "calls-echo",
            &[
                domain.name().to_owned(),
                max_frame.to_string(),
                mode_arg(mode).to_owned(),
            ],
            fifo,
            &[look.as_micros().to_string()],
        )?;
        let mut tool = ModuleBuilder::new("bench", 0)
            .mode(mode)
            .open_tool(two_module_system(&domain)?, ())
            .context("opening the benchmark's module")?;
        wait_for_echo(&mut tool, &mut child)?;
        Ok(ModbotPath {
            tool,
            child,
            mode,
            spin: look,
            sink: Vec::new(),
            scratch,
        })
    }

    /// Notes the shared memory a big domain took, and stops the echo module.
    pub fn close(self, report: &mut Report, sizes: &[usize]) -> anyhow::Result<()> {
        let max_frame = self.scratch.domain.max_frame();
        if max_frame > modbot_core::domain::DEFAULT_MAX_FRAME {
            let (reserved, used) = procs::shm_usage(&self.scratch.domain);
            report.note(format!(
                "calls: the {} domain with a max frame of {} (two modules, {} mode) reserved {} \
                 of /dev/shm, {} of it touched",
                size_label(*sizes.last().unwrap_or(&0)),
                format_value(max_frame as u64, Some("bytes")),
                self.mode.name(),
                format_value(reserved, Some("bytes")),
                format_value(used, Some("bytes")),
            ));
        }
        let ModbotPath {
            tool,
            child,
            scratch,
            ..
        } = self;
        drop(tool);
        child.stop()?;
        drop(scratch);
        Ok(())
    }
}

impl Path for ModbotPath {
    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64> {
        let sink = &mut self.sink;
        let t = Instant::now();
        let got = self.tool.call_blocking(
            "echo",
            "echo",
            &[Value::Bytes(payload)],
            CallOptions::default().with_spin(self.spin),
            |r| copy_answer(r, sink),
        );
        let ns = sample::since(t);
        match got {
            Ok(len) if len == payload.len() => Ok(ns),
            Ok(len) => bail!("echo answered {len} bytes for {}", payload.len()),
            Err(e) => bail!("echo call: {e}"),
        }
    }

    fn server(&mut self) -> &mut Proc {
        &mut self.child
    }
}

/// The client end of a baseline's echo: one round trip of a payload; the answer's length.
pub trait EchoClient {
    fn round_trip(&mut self, payload: &[u8]) -> anyhow::Result<usize>;
}

/// A baseline's echo server, in a process of its own, and the client end talking to it.
pub struct EchoPath<C> {
    client: C,
    child: Proc,
    /// What answers, for errors: `raw echo`, `uds echo`.
    what: &'static str,
    _scratch: Scratch,
}

impl<C> EchoPath<C> {
    /// Closes the client end, then stops the server.
    pub fn close(self) -> anyhow::Result<()> {
        let EchoPath {
            client,
            child,
            _scratch,
            ..
        } = self;
        drop(client);
        child.stop()?;
        Ok(())
    }
}

impl<C: EchoClient> Path for EchoPath<C> {
    fn one(&mut self, payload: &[u8]) -> anyhow::Result<u64> {
        let t = Instant::now();
        let len = self.client.round_trip(payload)?;
        let ns = sample::since(t);
        if len != payload.len() {
            bail!("{} answered {len} bytes for {}", self.what, payload.len());
        }
        Ok(ns)
    }

    fn server(&mut self) -> &mut Proc {
        &mut self.child
    }
}

/// A raw iceoryx2 round trip (publish-subscribe both ways, the payload written into the loaned
/// sample), in a scratch domain of its own.
pub type RawPath = EchoPath<RawClient>;

/// Raw iceoryx2's client end: its ports, and where the answer is copied.
pub struct RawClient {
    ports: RawPorts,
    sink: Vec<u8>,
}

impl EchoClient for RawClient {
    fn round_trip(&mut self, payload: &[u8]) -> anyhow::Result<usize> {
        self.ports.round_trip(payload, &mut self.sink)
    }
}

impl RawPath {
    pub fn open(
        opts: &Opts,
        wait: Wait,
        max_frame: usize,
        sizes: &[usize],
        fifo: Option<u8>,
    ) -> anyhow::Result<RawPath> {
        let max = sizes.iter().copied().max().unwrap_or(8);
        let scratch = Scratch::new(&format!("raw_{}_{}", wait.arg(), max_frame >> 10), None)?;
        let domain = scratch.domain.clone();
        let mut child = spawn_server(
            opts,
            "raw-echo",
            &[
                domain.name().to_owned(),
                max.to_string(),
                wait.arg().to_owned(),
            ],
            fifo,
            &[],
        )?;
        let ports = RawPorts::open(&domain, "ping", "pong", max, wait)?;
        ports.handshake(&mut child)?;
        Ok(EchoPath {
            client: RawClient {
                ports,
                sink: vec![0u8; max],
            },
            child,
            what: "raw echo",
            _scratch: scratch,
        })
    }
}

/// A Unix stream socket round trip to an echo process that sleeps in a blocking read.
pub type UdsPath = EchoPath<uds::Client>;

impl EchoClient for uds::Client {
    fn round_trip(&mut self, payload: &[u8]) -> anyhow::Result<usize> {
        self.echo(payload)
    }
}

impl UdsPath {
    pub fn open(opts: &Opts, sizes: &[usize], fifo: Option<u8>) -> anyhow::Result<UdsPath> {
        let max = sizes.iter().copied().max().unwrap_or(8);
        let mut scratch = Scratch::new(&format!("uds_{}", max >> 10), None)?;
        let path = scratch.path("echo.sock");
        let mut child = spawn_server(opts, "uds-echo", &[path.display().to_string()], fifo, &[])?;
        let client = uds::Client::connect(&path, &mut child)?;
        Ok(EchoPath {
            client,
            child,
            what: "uds echo",
            _scratch: scratch,
        })
    }
}
