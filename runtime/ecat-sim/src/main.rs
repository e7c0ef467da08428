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
//! - `fault P KIND`: the drive of slave P faults (KIND `following`, `torque` or `encoder`),
//!   with the fault's error code in its 0x603F; an encoder stays lost, and the drive in
//!   fault, until `fault P encoder off`;
//! - `status`: every slave's AL state.

use std::io::{BufRead, Write};
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use clap::Parser;
use modbot_bus::{DriveFault, PlantParams};
use modbot_ecat_sim::chain::{Chain, ChainConfig};
use modbot_ecat_sim::clock::MonotonicClock;
use modbot_ecat_sim::drive::{drive_config, Cia402Drive, DriveUnits};
use modbot_ecat_sim::sii::Identity;
use modbot_ecat_sim::slave::Slave;

/// A chain of emulated EtherCAT CiA 402 drives, served on a network interface.
#[derive(Debug, Parser)]
#[command(name = "modbot-ecat-sim", version, after_help = COMMANDS)]
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
    /// The slaves' clock crystals run this many ppm off (positive: fast), one value for every
    /// slave or a comma-separated list of one per slave, e.g. `--drift-ppm 100,-100` (0: an
    /// ideal clock). Their time control loops correct it from the master's writes of the
    /// system time, as an ESC's does.
    #[arg(long = "drift-ppm", value_name = "PPM[,PPM...]", value_parser = parse_drift, allow_hyphen_values = true)]
    drift_ppm: Option<Vec<f64>>,
}

fn parse_drift(s: &str) -> Result<Vec<f64>, String> {
    s.split(',')
        .map(|v| {
            let ppm = v
                .trim()
                .parse::<f64>()
                .map_err(|e| format!("'{v}' in --drift-ppm: {e}"))?;
            if ppm.abs() > 1_000.0 {
                return Err(format!(
                    "--drift-ppm {ppm}: beyond ±1000 ppm no ESC's loop follows (crystals are ±100)"
                ));
            }
            Ok(ppm)
        })
        .collect()
}

/// The commands on standard input, for `--help`.
const COMMANDS: &str = "\
Commands on standard input, one per line, each answered with one line (`ok ...` or `error ...`):
  off P                slave P loses power (it and every slave behind it stop answering)
  on P                 slave P gets power back (in INIT)
  lose N               the next N frames are lost
  fault P KIND         the drive of slave P faults: following (0x8611), torque (0x8311) or
                       encoder (0x7305: it stays in fault until the encoder is back)
  fault P encoder off  the encoder of slave P is back (a fault reset then clears the fault)
  status               every slave's AL state";

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
        slaves.push(Slave::new(drive_config(identity, &cli.name), drive));
    }
    let config = ChainConfig {
        default_period_s: cli.period_us as f64 * 1e-6,
        ..ChainConfig::default()
    };
    let mut chain = Chain::with_config(slaves, MonotonicClock::default(), config);
    if let Some(drifts) = &cli.drift_ppm {
        if drifts.len() != 1 && drifts.len() != cli.slaves {
            anyhow::bail!(
                "--drift-ppm: {} values for {} slaves (one for every slave, or one each)",
                drifts.len(),
                cli.slaves
            );
        }
        for position in 0..cli.slaves {
            let ppm = drifts
                .get(position)
                .or(drifts.first())
                .copied()
                .unwrap_or(0.0);
            chain.set_clock_drift_ppm(position, ppm);
        }
    }
    Ok(chain)
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
        (Some("fault"), Some(p)) if p < chain.len() => fault(&mut chain, p, &words[2..]),
        (Some("status"), _) => {
            let states: Vec<String> = (0..chain.len())
                .map(|p| match chain.slave(p) {
                    Some(s) => format!("{p}:{:?}", s.al_state()),
                    None => format!("{p}:?"),
                })
                .collect();
            format!("ok {}", states.join(" "))
        }
        (Some("off" | "on" | "fault"), _) => format!(
            "error no such slave: the chain has {} (0 to {})",
            chain.len(),
            chain.len().saturating_sub(1)
        ),
        _ => format!(
            "error unknown command '{line}' (off P, on P, lose N, fault P KIND [off], status)"
        ),
    }
}

/// `fault P KIND` and `fault P encoder off` for slave `p` (which exists); `args` are the
/// words after P.
fn fault(chain: &mut Chain, p: usize, args: &[&str]) -> String {
    let kinds = DriveFault::ALL.map(DriveFault::name).join(", ");
    let (fault, on) = match args {
        [kind] => (DriveFault::parse(kind), true),
        [kind @ "encoder", "off"] => (DriveFault::parse(kind), false),
        [_, "off"] => return "error only the encoder fault can be turned off".to_owned(),
        _ => return format!("error usage: fault P KIND [off] (KIND: {kinds})"),
    };
    let Some(fault) = fault else {
        return format!("error unknown fault '{}' (known: {kinds})", args[0]);
    };
    let Some(drive) = chain.application_as::<Cia402Drive>(p) else {
        return format!("error slave {p} is not a drive");
    };
    drive.inject(fault, on);
    match (fault, on) {
        (DriveFault::Encoder, false) => format!("ok slave {p} encoder back"),
        (DriveFault::Encoder, true) => format!(
            "ok slave {p} encoder lost (error code {:#06x})",
            fault.error_code()
        ),
        _ => format!(
            "ok slave {p} fault {} (error code {:#06x})",
            fault.name(),
            fault.error_code()
        ),
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

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_ecat_sim::application::Application;
    use modbot_ecat_sim::dictionary::ObjectDictionary;

    fn chain_of(slaves: usize) -> Mutex<Chain> {
        let slaves = slaves.to_string();
        let cli = Cli::parse_from(["modbot-ecat-sim", "--interface", "x", "--slaves", &slaves]);
        Mutex::new(chain(&cli).unwrap())
    }

    /// One step of the drive of slave `p` in a dictionary of its own: its error code.
    fn error_code_after_a_step(chain: &Mutex<Chain>, p: usize) -> Option<u16> {
        let mut chain = chain.lock().unwrap();
        let drive = chain.application_as::<Cia402Drive>(p).unwrap();
        let mut od = ObjectDictionary::new();
        for entry in drive.objects() {
            od.insert(entry);
        }
        drive.step(&mut od, 0.001);
        od.get::<u16>(0x603F, 0)
    }

    #[test]
    fn a_fault_command_faults_the_drive_with_the_faults_error_code() {
        let sut = chain_of(2);
        assert_eq!(
            command(&sut, "fault 1 torque"),
            "ok slave 1 fault torque (error code 0x8311)"
        );
        assert_eq!(error_code_after_a_step(&sut, 1), Some(0x8311));
        assert_eq!(error_code_after_a_step(&sut, 0), Some(0));
        assert_eq!(
            command(&sut, "fault 0 following"),
            "ok slave 0 fault following (error code 0x8611)"
        );
        assert_eq!(error_code_after_a_step(&sut, 0), Some(0x8611));
    }

    #[test]
    fn an_encoder_is_lost_until_a_fault_command_turns_it_off() {
        let sut = chain_of(1);
        let cause = |sut: &Mutex<Chain>| {
            let mut chain = sut.lock().unwrap();
            chain
                .application_as::<Cia402Drive>(0)
                .unwrap()
                .fault_cause()
        };
        assert_eq!(
            command(&sut, "fault 0 encoder"),
            "ok slave 0 encoder lost (error code 0x7305)"
        );
        assert_eq!(error_code_after_a_step(&sut, 0), Some(0x7305));
        assert!(cause(&sut).is_some());
        assert_eq!(
            command(&sut, "fault 0 encoder off"),
            "ok slave 0 encoder back"
        );
        assert_eq!(cause(&sut), None);
    }

    #[test]
    fn a_fault_command_that_makes_no_sense_is_answered_with_the_reason() {
        let sut = chain_of(2);
        for (line, reason) in [
            (
                "fault 2 torque",
                "error no such slave: the chain has 2 (0 to 1)",
            ),
            (
                "fault 0 overheat",
                "error unknown fault 'overheat' (known: following, torque, encoder)",
            ),
            (
                "fault 0 torque off",
                "error only the encoder fault can be turned off",
            ),
            (
                "fault 0",
                "error usage: fault P KIND [off] (KIND: following, torque, encoder)",
            ),
        ] {
            assert_eq!(command(&sut, line), reason, "{line}");
        }
    }
}
