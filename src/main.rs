//! `modbot`: the command line of the modbot runtime.
//!
//! - `rvmf encode|decode`: build and read RVMF* frames (see `rvmf_cmd`).
//! - `ls`, `call`, `bb`, `activate`, `deactivate`: look at and talk to a running system (see
//!   `tool`).
//! - `check FILE`: load and check a system description (see `check_cmd`).
//! - `up FILE`, `down`: run a system under the supervisor, and stop it (see `up_cmd`).
//! - `program run FILE`, `program repl`: robot programs (see `program_cmd`); `data ls|get`:
//!   the assembly data they keep (see `data_cmd`).
//! - `robot`, `robot reset`, `bus inject`: the robot's state, an operator's reset, a drive
//!   fault injected in the simulation (see `robot_cmd`).

mod assembly_cmd;
mod check_cmd;
mod data_cmd;
mod mcap_export;
mod program_cmd;
mod record_cmd;
mod replay_cmd;
mod replay_keep;
mod robot_cmd;
mod rvmf_cmd;
mod tool;
mod up_cmd;
mod upgrade_cmd;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// modbot: zero-copy shared-memory IPC for modular robot controllers.
#[derive(Debug, Parser)]
#[command(name = "modbot", version, about)]
struct Cli {
    /// The system's domain (its shared-memory namespace) [default: default]. For `modbot up`
    /// it overrides the domain the description declares.
    #[arg(long, global = true, env = "MODBOT_DOMAIN")]
    domain: Option<String>,
    #[command(subcommand)]
    command: Command,
}

impl Cli {
    /// The domain given, or `default`.
    fn domain(&self) -> String {
        self.domain.clone().unwrap_or_else(|| "default".to_owned())
    }
}

/// `modbot bus` subcommands.
#[derive(Debug, Subcommand)]
enum BusCommand {
    /// The slaves on an EtherCAT segment: position, station address, AL state, distributed
    /// clocks, identity and name (like IgH's `ethercat slaves`). It resets the slaves to PRE-OP,
    /// so it is refused while another master runs the segment. Needs CAP_NET_RAW.
    Scan {
        /// The network interface of the segment.
        #[arg(long)]
        interface: String,
    },
    /// Injects a drive fault into an axis of the simulation (or an emulated EtherCAT slave's:
    /// see `modbot-ecat-sim`), for tests and demos: `following` (following error), `torque`
    /// (torque limit exceeded too long), `encoder` (encoder lost, until `--off`). The faulted
    /// drive disables itself and the bus bridge quick-stops the others; `modbot robot reset`
    /// brings them back.
    Inject {
        /// The axis (0-based).
        #[arg(long)]
        axis: u32,
        /// following, torque or encoder.
        #[arg(long)]
        fault: String,
        /// Takes a lasting cause away (the encoder back) instead.
        #[arg(long)]
        off: bool,
    },
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Encode or decode RVMF* frames.
    Rvmf {
        #[command(subcommand)]
        command: rvmf_cmd::RvmfCommand,
    },
    /// Check a system description (a Lua file) and print its modules.
    ///
    /// Exits with 2 and one `file:line: message` line on stderr when it is invalid.
    Check {
        /// The system description.
        file: PathBuf,
        /// A variable for the description (its table `vars`); repeatable.
        #[arg(long = "var", value_name = "KEY=VALUE", value_parser = parse_var)]
        vars: Vec<(String, String)>,
    },
    /// Start a system: every module of the description as its own process, supervised.
    ///
    /// Shows the modules' logs, prefixed with their names, and their status; stops on
    /// Ctrl-C, SIGTERM, `modbot down`, or after `--for`. Exits 0 if every module stopped
    /// cleanly, 1 with a summary otherwise, 2 if the description is invalid. `--domain` (or
    /// MODBOT_DOMAIN) overrides the domain the description declares: a second system from the
    /// same description runs beside the first.
    Up {
        /// The system description (a Lua file).
        file: PathBuf,
        /// Stop after this many seconds.
        #[arg(long = "for", value_name = "SECONDS")]
        run_for: Option<f64>,
        /// A variable for the description, which reads it as `vars.KEY` (a string); repeatable.
        #[arg(long = "var", value_name = "KEY=VALUE", value_parser = parse_var)]
        vars: Vec<(String, String)>,
        /// Run exactly this many base ticks of the grid, then stop.
        #[arg(long)]
        ticks: Option<u64>,
        /// Write every component output at every tick to this file (see the trace format in
        /// docs/grid.md), so runs can be compared byte for byte.
        #[arg(long, value_name = "OUT")]
        trace: Option<PathBuf>,
        /// Write the grid's state hash into the trace every N ticks and after the last (`#
        /// state_hash tick=… hash=…`; 0: never). Default 1000.
        #[arg(long, value_name = "N")]
        state_hash_every: Option<u64>,
        /// Run the grid in lockstep: each tick as soon as every release due at it can be
        /// made, as fast as the machine goes; no overruns, the same trace every run.
        #[arg(long)]
        lockstep: bool,
        /// Switch to assembly NAME at tick TICK (repeatable); with --lockstep the run is
        /// reproducible, switches included.
        #[arg(long = "switch", value_name = "TICK:NAME", value_parser = modbot_grid::switch::parse_scripted)]
        switches: Vec<(u64, String)>,
        /// Upgrade host HOST of the running assembly live at tick TICK (repeatable): a new
        /// process takes its components over, their state carried to the bit; with --lockstep
        /// the grid waits at TICK until it has, and the run is the same as one without.
        #[arg(long = "upgrade", value_name = "TICK:HOST", value_parser = modbot_grid::switch::parse_scripted)]
        upgrades: Vec<(u64, String)>,
        /// With --lockstep: hold the grid before tick TICK until a robot program takes the
        /// coordinator's gate and steps it (lifted by itself after 20 s without one).
        #[arg(long, value_name = "TICK")]
        gate: Option<u64>,
        /// Record to this HDF5 file: the description's `record { ... }` writes here, or, if it
        /// declares none, every output of the system's own components is recorded.
        #[arg(long, value_name = "FILE")]
        record: Option<PathBuf>,
        /// Make the recording replayable (`modbot replay`): it also holds the bus's every
        /// output and what the controllers commanded it, and the run's schedule.
        #[arg(long)]
        replayable: bool,
        /// Also serve the operator's control station for the system (`modbot station`), on
        /// ADDR:PORT (default 127.0.0.1:8080); it prints its address.
        #[arg(long, value_name = "ADDR:PORT", num_args = 0..=1, default_missing_value = "127.0.0.1:8080")]
        station: Option<String>,
    },
    /// The operator's control station: a web page with every module, the grid, the robot and
    /// the blackboards live, and commands to them (the program `modbot-station`; its options
    /// follow: `--listen ADDR:PORT`, default 127.0.0.1:8080, and `--token T`).
    Station {
        #[arg(
            trailing_var_arg = true,
            allow_hyphen_values = true,
            value_name = "OPTIONS"
        )]
        args: Vec<String>,
    },
    /// The system in this terminal, live: every module (state, activity, pid, restarts, last
    /// exit, counters, calls, latency), sortable, with a module's detail on Enter; the grid's
    /// components, the assembly and the robot's state. `q` quits.
    Top {
        /// Print the grid's ledger (per component host, period, execution time, overruns,
        /// jitter; the tick rate) and the robot's state once, for scripts, and exit.
        #[arg(long)]
        once: bool,
    },
    /// The bus ledger: bus cycles, missed cycles, a safe stop if there was one, and every
    /// drive's CiA 402 state and mode.
    Bus {
        #[command(subcommand)]
        command: Option<BusCommand>,
        /// Every assembly switch the bus saw instead: a line `max_step S max_velocity_step V`
        /// (the largest steps within an assembly), then per switch `GENERATION TICK STEP
        /// MISSED VSTEP` (the command's position step, the cycles missed within five ticks of
        /// it, its velocity step).
        #[arg(long)]
        switches: bool,
        /// How long to wait for the bus bridge's answer, in milliseconds.
        #[arg(long, global = true, default_value_t = 1000)]
        timeout_ms: u64,
    },
    /// The grid's assemblies: `modbot assembly` shows where they stand, `modbot assembly
    /// switch NAME` swaps the control structure while the robot runs.
    Assembly {
        #[command(subcommand)]
        command: Option<assembly_cmd::AssemblyCommand>,
    },
    /// Robot programs: `modbot program run FILE` runs one, `modbot program repl` reads
    /// commands one line at a time.
    Program {
        #[command(subcommand)]
        command: program_cmd::ProgramCommand,
    },
    /// The domain's assembly data, where robot programs keep their commands' parameters and
    /// results: `modbot data ls`, `modbot data get KEY`.
    Data {
        #[command(subcommand)]
        command: data_cmd::DataCommand,
    },
    /// Replays a replayable recording (`modbot up --record FILE --replayable`): its
    /// controllers run again in this process, the bus played back as recorded, and what the
    /// recorder got is compared with what it recorded, row by row, bit for bit: "replayed N
    /// ticks: identical" (exit 0) or the first tick, signal and component that differ (exit
    /// 1); 2: it cannot be replayed. `--param COMP.NAME=VALUE` replays a what-if (to the end,
    /// writing its own recording, `--out` or FILE.whatif.h5).
    Replay {
        file: PathBuf,
        /// Replay up to this tick.
        #[arg(long, value_name = "TICK")]
        until: Option<u64>,
        /// A controller's param changed for the replay (repeatable).
        #[arg(long = "param", value_name = "COMP.NAME=VALUE")]
        params: Vec<String>,
        /// The what-if's recording (default FILE.whatif.h5).
        #[arg(long, value_name = "OUT")]
        out: Option<PathBuf>,
    },
    /// Recordings (HDF5 files of the data recorder): `modbot record compare A.h5 B.h5`,
    /// `modbot record export FILE.h5 --mcap OUT.mcap`.
    Record {
        #[command(subcommand)]
        command: record_cmd::RecordCommand,
    },
    /// The robot's state as the bus bridge owns it (operational, safe stop, fault, disabled;
    /// since which tick and why), and `modbot robot reset`: an operator's reset after a safe
    /// stop or a drive fault, without a restart.
    Robot {
        #[command(subcommand)]
        command: Option<robot_cmd::RobotCommand>,
    },
    /// Stop the system running in the domain (from another terminal).
    Down,
    /// List the modules of the domain: address, name, pid, state, restarts, last exit,
    /// frame counters and methods.
    Ls {
        /// Tab-separated values with a header line, for scripts.
        #[arg(long)]
        tsv: bool,
    },
    /// Call a method: `modbot call MODULE.METHOD [ARGS...]`.
    ///
    /// Arguments: `1.5` is f64, `3` i64, `true` bool, `[1,2]` f64 array, `0x0a0b` bytes,
    /// anything else text; `f64:3` or `text:true` force a kind. Every module also answers the
    /// system methods `describe`, `bb_get`, `bb_set`, `bb_snapshot`, `stats` (shown as a
    /// table: traffic, calls, latency percentiles), `activate` and `deactivate`.
    Call {
        /// MODULE.METHOD
        target: String,
        /// The method's arguments (a negative number is one; text that starts with `-` is
        /// written `text:-x`). Options may follow them.
        #[arg(allow_negative_numbers = true)]
        args: Vec<String>,
        /// How long to wait for the answer, in milliseconds.
        #[arg(long, default_value_t = 2000)]
        timeout_ms: u64,
        /// If the module is down (restarting, say), wait for it until the timeout instead of
        /// failing at once with "not available".
        #[arg(long)]
        wait: bool,
    },
    /// Upgrade a running module live: a new process of PROGRAM (default: the module's own
    /// program, rebuilt in place) takes over its address, blackboard, state and the calls on
    /// their way; callers see a delay, never an error. Refused, the running process serving on,
    /// when the new program fails to start or its methods differ (unless --force).
    Upgrade {
        module: String,
        /// The new program.
        #[arg(long)]
        program: Option<PathBuf>,
        /// Take a program whose method table differs from the running one's.
        #[arg(long)]
        force: bool,
        /// How long to wait for the outcome, in seconds.
        #[arg(long, default_value_t = 60)]
        timeout_s: u64,
    },
    /// Activate a module the operator deactivated: it serves its methods and runs its tasks
    /// again (`modbot call MODULE.activate`).
    Activate { module: String },
    /// Deactivate a module: until `modbot activate`, it answers its own methods with NAK
    /// "not ready" and pauses its periodic tasks; its system methods, heartbeats and snapshots
    /// go on (`modbot call MODULE.deactivate`).
    Deactivate { module: String },
    /// Read a module's blackboard (one snapshot), read one item, or write one.
    Bb {
        module: String,
        item: Option<String>,
        #[arg(allow_hyphen_values = true)]
        value: Option<String>,
        /// Read the snapshot the module publishes in shared memory instead of asking it (it
        /// is not disturbed; an imported module's is the one its bridge mirrors). Waits up to
        /// 2 s for one.
        #[arg(long, conflicts_with = "value")]
        shared: bool,
    },
}

/// `--var KEY=VALUE`; a malformed one is a usage error (exit 2).
fn parse_var(text: &str) -> Result<(String, String), modbot_system::VarError> {
    modbot_system::parse_var(text)
}

/// `vars` with `--record FILE` as the variable every process of the run loads the description
/// with ([`modbot_system::RECORD_VAR`]), the file made absolute.
fn with_record(
    mut vars: Vec<(String, String)>,
    record: Option<PathBuf>,
    replayable: bool,
) -> Vec<(String, String)> {
    if let Some(file) = record {
        let file = std::path::absolute(&file).unwrap_or(file);
        let key = modbot_system::RECORD_VAR.to_owned();
        vars.push((key, file.display().to_string()));
    }
    if replayable {
        vars.push((modbot_system::REPLAY_VAR.to_owned(), "true".to_owned()));
    }
    vars
}

/// `modbot bus scan --interface IF`.
fn bus_scan(interface: &str) -> anyhow::Result<ExitCode> {
    let slaves = modbot_ethercat::scan::scan(interface)?;
    print!("{}", modbot_ethercat::scan::render(&slaves));
    Ok(ExitCode::SUCCESS)
}

/// `modbot station`: runs `modbot-station` (next to this program) in the domain, in this
/// process's place.
fn station(domain: &str, args: &[String]) -> anyhow::Result<ExitCode> {
    use std::os::unix::process::CommandExt;
    let me = std::env::current_exe()?;
    let program = me.with_file_name("modbot-station");
    let err = std::process::Command::new(&program)
        .arg("--domain")
        .arg(domain)
        .args(args)
        .exec();
    anyhow::bail!("cannot run {}: {err}", program.display())
}

fn main() -> ExitCode {
    // Output piped into `head` and closed: end quietly, as Unix tools do, rather than panic
    // on the failed write.
    // SAFETY: restoring the default disposition of SIGPIPE, before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let filter =
        tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
    let cli = Cli::parse();
    let domain = cli.domain();
    let given_domain = cli.domain.clone();
    let result = match cli.command {
        Command::Rvmf { command } => return rvmf_cmd::run(command),
        Command::Check { file, vars } => return check_cmd::run(&file, &vars),
        Command::Up {
            file,
            run_for,
            vars,
            ticks,
            trace,
            state_hash_every,
            lockstep,
            switches,
            upgrades,
            gate,
            record,
            replayable,
            station,
        } => up_cmd::up(
            &file,
            given_domain.as_deref(),
            run_for,
            &with_record(vars, record, replayable),
            &modbot_supervisor::processes::GridRun {
                ticks,
                trace,
                state_hash_every,
                replay_log: None,
                lockstep,
                switches,
                upgrades,
                gate,
            },
            station.as_deref(),
        ),
        Command::Top { once: true } => tool::top(&domain, true),
        Command::Top { once: false } => station(&domain, &["--top".to_owned()]),
        Command::Station { args } => station(&domain, &args),
        Command::Bus {
            command: Some(BusCommand::Scan { interface }),
            ..
        } => bus_scan(&interface),
        Command::Bus {
            command: Some(BusCommand::Inject { axis, fault, off }),
            timeout_ms,
            ..
        } => robot_cmd::inject(&domain, axis, &fault, off, timeout_ms),
        Command::Robot { command } => robot_cmd::run(&domain, command),
        Command::Bus {
            command: None,
            switches,
            timeout_ms,
        } => tool::bus(&domain, switches, timeout_ms),
        Command::Assembly { command } => assembly_cmd::run(&domain, command),
        Command::Program { command } => program_cmd::run(&domain, command),
        Command::Data { command } => data_cmd::run(&domain, command),
        Command::Record { command } => record_cmd::run(command),
        Command::Replay {
            file,
            until,
            params,
            out,
        } => replay_cmd::run(&replay_cmd::ReplayArgs {
            file,
            until,
            params,
            out,
        }),
        Command::Down => tool::down(&domain),
        Command::Ls { tsv } => tool::ls(&domain, tsv),
        Command::Call {
            target,
            args,
            timeout_ms,
            wait,
        } => tool::call(&domain, &target, &args, timeout_ms, wait),
        Command::Upgrade {
            module,
            program,
            force,
            timeout_s,
        } => upgrade_cmd::run(
            &domain,
            &upgrade_cmd::UpgradeArgs {
                module: &module,
                program: program.as_deref(),
                force,
                timeout: std::time::Duration::from_secs(timeout_s),
            },
        ),
        Command::Activate { module } => {
            tool::call(&domain, &format!("{module}.activate"), &[], 2000, false)
        }
        Command::Deactivate { module } => {
            tool::call(&domain, &format!("{module}.deactivate"), &[], 2000, false)
        }
        Command::Bb {
            module,
            item,
            value,
            shared: false,
        } => tool::bb(&domain, &module, item.as_deref(), value.as_deref()),
        Command::Bb {
            module,
            item,
            shared: true,
            ..
        } => tool::bb_shared(&domain, &module, item.as_deref()),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("modbot: {e:#}");
            ExitCode::from(1)
        }
    }
}
