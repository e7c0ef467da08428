//! `modbot-ecat-sim`: a chain of emulated EtherCAT slaves on a network interface — CiA 402
//! servo drives on elastic joints (`modbot_ecat_sim::drive`) — for running the bus bridge's
//! EtherCAT backend without hardware: start it on one end of a veth pair, the master on the
//! other.
//!
//! Prints `serving N slaves on IF` once it answers frames. Reads commands on its standard
//! input, one per line, and answers each with one line (`ok ...` or `error ...`):
//! - `off P`: slave P loses power (it and every slave behind it stop answering);
//! - `on P`: slave P gets power back (it starts in INIT, as after a power cycle);
//! - `lose N`: the next N frames are lost;
//! - `status`: every slave's AL state.

use std::io::{BufRead, Write};
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use clap::Parser;
use modbot_bus::PlantParams;
use modbot_ecat_sim::chain::{Chain, ChainConfig};
use modbot_ecat_sim::clock::MonotonicClock;
use modbot_ecat_sim::drive::{Cia402Drive, DriveUnits};
use modbot_ecat_sim::pdo::PdoDefinition;
use modbot_ecat_sim::sii::Identity;
use modbot_ecat_sim::slave::{Slave, SlaveConfig};

/// A chain of emulated EtherCAT CiA 402 drives, served on a network interface.
#[derive(Debug, Parser)]
#[command(name = "modbot-ecat-sim", version)]
struct Cli {
    /// The interface to serve on (one end of a veth pair, say).
    #[arg(long)]
    interface: String,
    /// How many slaves (drives) the chain has.
    #[arg(long, default_value_t = 6)]
    slaves: usize,
    /// Every slave's vendor id (SII and 0x1018:1).
    #[arg(long, default_value = "0x00004d42", value_parser = parse_u32)]
    vendor: u32,
    /// Every slave's product code (SII and 0x1018:2).
    #[arg(long, default_value = "0x00000402", value_parser = parse_u32)]
    product: u32,
    /// Slaves of another product code: POSITION=CODE (repeatable), a wrongly wired cabinet.
    #[arg(long = "product-at", value_name = "POSITION=CODE", value_parser = parse_at)]
    product_at: Vec<(usize, u32)>,
    /// Every slave's name (the SII's).
    #[arg(long, default_value = "modbot-drive")]
    name: String,
    /// Encoder increments per motor revolution (0x608F).
    #[arg(long, default_value_t = 1 << 20)]
    increments_per_rev: u32,
    /// Motor rated torque, mNm (0x6076): torques are per mille of it.
    #[arg(long, default_value_t = 10_000)]
    rated_torque_mnm: u32,
    /// The drives' step without distributed clocks, µs (with DC: the SYNC0 cycle).
    #[arg(long, default_value_t = 1000)]
    period_us: u64,
    /// The joints' mechanics, as the bus simulator's `bus` params give them: one value for
    /// every slave or a comma-separated list of one per slave (the simulator's defaults
    /// otherwise), e.g. `--joint stiffness=1e5,1.2e5,6e4,2e4,2e4,2e4` (repeatable). Names:
    /// motor_inertia, link_inertia, stiffness, damping, viscous_friction, coulomb_friction,
    /// torque_limit.
    #[arg(long = "joint", value_name = "NAME=VALUES", value_parser = parse_joint)]
    joints: Vec<(String, Vec<f64>)>,
}

/// The joint parameters the emulator takes, as the bus component names them.
const JOINT_NAMES: [&str; 7] = [
    "motor_inertia",
    "link_inertia",
    "stiffness",
    "damping",
    "viscous_friction",
    "coulomb_friction",
    "torque_limit",
];

fn parse_joint(s: &str) -> Result<(String, Vec<f64>), String> {
    let (name, values) = s
        .split_once('=')
        .ok_or_else(|| format!("'{s}' is not NAME=VALUES"))?;
    if !JOINT_NAMES.contains(&name) {
        return Err(format!(
            "unknown joint parameter '{name}' (known: {})",
            JOINT_NAMES.join(", ")
        ));
    }
    let values = values
        .split(',')
        .map(|v| {
            v.trim()
                .parse::<f64>()
                .map_err(|e| format!("'{v}' in {name}: {e}"))
        })
        .collect::<Result<Vec<f64>, String>>()?;
    Ok((name.to_owned(), values))
}

/// The mechanics of the joint of slave `position` of `slaves`.
fn joint(cli: &Cli, position: usize) -> anyhow::Result<PlantParams> {
    let mut plant = PlantParams::default();
    for (name, values) in &cli.joints {
        let value = match values.len() {
            1 => values[0],
            n if n == cli.slaves => values[position],
            n => anyhow::bail!(
                "--joint {name}: {n} values for {} slaves (give 1 or one per slave)",
                cli.slaves
            ),
        };
        let slot = match name.as_str() {
            "motor_inertia" => &mut plant.motor_inertia,
            "link_inertia" => &mut plant.link_inertia,
            "stiffness" => &mut plant.stiffness,
            "damping" => &mut plant.damping,
            "viscous_friction" => &mut plant.viscous_friction,
            "coulomb_friction" => &mut plant.coulomb_friction,
            _ => &mut plant.torque_limit,
        };
        *slot = value;
    }
    plant
        .check()
        .map_err(|e| anyhow::anyhow!("the joint of slave {position}: {e}"))?;
    Ok(plant)
}

fn parse_u32(s: &str) -> Result<u32, String> {
    let parsed = match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(hex, 16),
        None => s.parse(),
    };
    parsed.map_err(|e| format!("'{s}' is not a 32-bit number: {e}"))
}

fn parse_at(s: &str) -> Result<(usize, u32), String> {
    let (position, code) = s
        .split_once('=')
        .ok_or_else(|| format!("'{s}' is not POSITION=CODE"))?;
    let position = position
        .parse()
        .map_err(|e| format!("'{position}' is not a position: {e}"))?;
    Ok((position, parse_u32(code)?))
}

fn chain(cli: &Cli) -> anyhow::Result<Chain> {
    let units = DriveUnits {
        increments_per_rev: cli.increments_per_rev,
        rated_torque_mnm: cli.rated_torque_mnm,
    };
    let mut slaves = Vec::with_capacity(cli.slaves);
    for position in 0..cli.slaves {
        let product = cli
            .product_at
            .iter()
            .find(|(p, _)| *p == position)
            .map_or(cli.product, |(_, code)| *code);
        let identity = Identity {
            vendor_id: cli.vendor,
            product_code: product,
            revision: 1,
            serial: position as u32 + 1,
        };
        let drive = Cia402Drive::new(joint(cli, position)?, units)?;
        // A drive's usual default mapping (the master maps what it needs in PRE-OP).
        let config = SlaveConfig::new(identity, &cli.name)
            .with_rx_pdos(vec![PdoDefinition {
                index: 0x1600,
                entries: vec![(0x6040, 0), (0x6060, 0), (0x607A, 0)],
            }])
            .with_tx_pdos(vec![PdoDefinition {
                index: 0x1A00,
                entries: vec![(0x6041, 0), (0x6061, 0), (0x6064, 0)],
            }]);
        slaves.push(Slave::new(config, drive));
    }
    let config = ChainConfig {
        default_period_s: cli.period_us as f64 * 1e-6,
        ..ChainConfig::default()
    };
    Ok(Chain::with_config(
        slaves,
        MonotonicClock::default(),
        config,
    ))
}

/// Applies one command line to the chain: the answer line.
fn command(chain: &Mutex<Chain>, line: &str) -> String {
    let mut chain = chain.lock().unwrap_or_else(|p| p.into_inner());
    let words: Vec<&str> = line.split_whitespace().collect();
    let number = |i: usize| words.get(i).and_then(|w| w.parse::<usize>().ok());
    match (words.first().copied(), number(1)) {
        (Some("off"), Some(p)) if p < chain.len() => {
            chain.power_off(p);
            format!("ok slave {p} off")
        }
        (Some("on"), Some(p)) if p < chain.len() => {
            chain.power_on(p);
            format!("ok slave {p} on")
        }
        (Some("lose"), Some(n)) => {
            chain.lose_next_frames(n.min(u32::MAX as usize) as u32);
            format!("ok losing {n} frame(s)")
        }
        (Some("status"), _) => {
            let states: Vec<String> = (0..chain.len())
                .map(|p| match chain.slave(p) {
                    Some(s) => format!("{p}:{:?}", s.al_state()),
                    None => format!("{p}:?"),
                })
                .collect();
            format!("ok {}", states.join(" "))
        }
        (Some("off" | "on"), _) => format!(
            "error no such slave: the chain has {} (0 to {})",
            chain.len(),
            chain.len().saturating_sub(1)
        ),
        _ => format!("error unknown command '{line}' (off P, on P, lose N, status)"),
    }
}

fn run() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    anyhow::ensure!(cli.slaves >= 1, "--slaves must be at least 1");
    let chain = Arc::new(Mutex::new(chain(&cli)?));
    let stop = Arc::new(AtomicBool::new(false));
    let commands = {
        let chain = chain.clone();
        std::thread::Builder::new()
            .name("commands".into())
            .spawn(move || {
                let stdin = std::io::stdin();
                for line in stdin.lock().lines() {
                    let Ok(line) = line else { break };
                    if line.trim().is_empty() {
                        continue;
                    }
                    let answer = command(&chain, line.trim());
                    let mut out = std::io::stdout().lock();
                    let _ = writeln!(out, "{answer}");
                    let _ = out.flush();
                }
            })?
    };
    drop(commands);
    let ready = || {
        println!("serving {} slaves on {}", cli.slaves, cli.interface);
        let _ = std::io::stdout().flush();
    };
    modbot_ecat_sim::socket::serve_ready(&cli.interface, &chain, &stop, ready)?;
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("modbot-ecat-sim: {e:#}");
            ExitCode::FAILURE
        }
    }
}
