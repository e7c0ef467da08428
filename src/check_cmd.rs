//! `modbot check FILE`: load a system description and print what it declares.
//!
//! Exit status 0 when the description is valid; 2 with one `file:line: message` line on
//! stderr when it is not, so scripts and editors can jump to the problem.

use std::path::Path;
use std::process::ExitCode;

use modbot_core::ReceiveMode;
use modbot_system::{self as system, DefaultResolver, ModuleSpec, SystemSpec};

/// `modbot check FILE [--var KEY=VALUE]...`.
pub fn run(file: &Path, vars: &[(String, String)]) -> ExitCode {
    match system::load_with_vars(file, &DefaultResolver::for_file(file), vars) {
        Ok(spec) => {
            print!("{}", summary(&spec));
            if let Some(grid) = spec.grid.as_ref().filter(|g| g.assembly.is_some()) {
                if let Err(e) = check_assemblies(grid) {
                    eprintln!("{e}");
                    return ExitCode::from(2);
                }
            }
            if !vars.is_empty() {
                let given: Vec<String> = vars.iter().map(|(k, v)| format!("{k}={v:?}")).collect();
                println!("vars: {}", given.join(", "));
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("{e}");
            ExitCode::from(2)
        }
    }
}

/// Loads every assembly of the grid's directory; prints one line each, or the first error.
fn check_assemblies(grid: &modbot_grid::GridSpec) -> Result<(), system::SystemError> {
    let Some((a, source)) = grid
        .assembly
        .as_ref()
        .and_then(|a| Some((a, a.source.as_ref()?)))
    else {
        return Ok(());
    };
    let registry = modbot_components::builtin();
    for name in system::assembly_names(&source.dir) {
        let spec = system::load_assembly(grid, &name, a.generation, &registry)?;
        let hosts = spec.assembly_hosts();
        println!(
            "assembly {name}: {} components on host(s) {}, {} connections{}",
            spec.components.len() - a.base,
            hosts.join(", "),
            spec.connections.len(),
            if name == a.name { " (the first)" } else { "" }
        );
    }
    Ok(())
}

/// The description as `modbot check` prints it.
fn summary(spec: &SystemSpec) -> String {
    let s = &spec.supervision;
    let mut out = format!(
        "{}: domain {}, {} modules, {} groups\n\
         supervision: start_timeout {:?}, heartbeat_period {:?}, heartbeat_timeout {:?}, \
         stop_grace {:?}\n",
        spec.file.display(),
        spec.domain,
        spec.modules.len(),
        spec.groups.len(),
        s.start_timeout,
        s.heartbeat_period,
        s.heartbeat_timeout,
        s.stop_grace,
    );
    let name_width = spec
        .modules
        .iter()
        .map(|m| m.name.len())
        .fold(4, usize::max);
    let groups: Vec<String> = spec.modules.iter().map(|m| list(&m.groups)).collect();
    let group_width = groups.iter().map(String::len).fold(6, usize::max);
    out += &format!(
        "{:>4}  {:<name_width$}  {:<10}  {:<group_width$}  PROGRAM\n",
        "ADDR", "NAME", "RESTART", "GROUPS"
    );
    for (m, groups) in spec.modules.iter().zip(&groups) {
        out += &format!(
            "{:>4}  {:<name_width$}  {:<10}  {:<group_width$}  {}\n",
            m.addr,
            m.name,
            m.restart.when,
            groups,
            command_line(m)
        );
        let settings = settings(m);
        if !settings.is_empty() {
            out += &format!("      {}\n", settings.join(", "));
        }
    }
    if let Some(grid) = &spec.grid {
        out += &grid_summary(grid);
    }
    out
}

/// The grid as `modbot check` prints it: base period, components, connections.
fn grid_summary(grid: &modbot_grid::GridSpec) -> String {
    let mut out = format!(
        "grid: base period {:?}, {} components on hosts {}, {} connections\n",
        grid.base_period,
        grid.components.len(),
        grid.hosts().join(", "),
        grid.connections.len()
    );
    for t in &grid.declared {
        let ports = |ps: &[modbot_grid::component::PortDecl]| {
            ps.iter()
                .map(|p| format!("{}:{}", p.name, p.ty))
                .collect::<Vec<_>>()
                .join(", ")
        };
        out += &format!(
            "type {} (program {}): inputs [{}], outputs [{}]\n",
            t.info.type_name,
            t.program,
            ports(&t.info.inputs),
            ports(&t.info.outputs)
        );
    }
    let width = grid
        .components
        .iter()
        .map(|c| c.name.len())
        .fold(9, usize::max);
    out += &format!(
        "{:<width$}  {:<14} {:<10} {:>6}  POLICY\n",
        "COMPONENT", "TYPE", "HOST", "PERIOD"
    );
    for c in &grid.components {
        out += &format!(
            "{:<width$}  {:<14} {:<10} {:>6}  {}\n",
            c.name,
            c.type_name,
            c.host,
            c.period,
            c.policy.name()
        );
    }
    for conn in &grid.connections {
        let (from, to) = (
            &grid.components[conn.from.component],
            &grid.components[conn.to.component],
        );
        out += &format!(
            "  {}.{} -> {}.{}\n",
            from.name,
            from.info.outputs[conn.from.port].name,
            to.name,
            to.info.inputs[conn.to.port].name
        );
    }
    out
}

fn list(items: &[String]) -> String {
    if items.is_empty() {
        "-".to_owned()
    } else {
        items.join(",")
    }
}

/// The program and its arguments, quoted where a shell would need it.
fn command_line(m: &ModuleSpec) -> String {
    let mut words = vec![m.program.display().to_string()];
    for arg in &m.args {
        let plain = !arg.is_empty()
            && arg
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.,:/=+@%".contains(c));
        words.push(if plain {
            arg.clone()
        } else {
            format!("{arg:?}")
        });
    }
    words.join(" ")
}

/// The settings that differ from the defaults: restart limits, real-time settings, env.
fn settings(m: &ModuleSpec) -> Vec<String> {
    let mut out = Vec::new();
    if m.restart != Default::default() && m.restart.when != system::Restart::Never {
        out.push(format!("restart {}", m.restart));
    }
    if !m.cpus.is_empty() {
        let cpus: Vec<String> = m.cpus.iter().map(usize::to_string).collect();
        out.push(format!("cpus {}", cpus.join(",")));
    }
    if let Some(p) = m.priority {
        out.push(format!("SCHED_FIFO {p}"));
    }
    if m.mlock {
        out.push("mlock".to_owned());
    }
    if m.mode == ReceiveMode::BusyPoll {
        out.push("busy-poll".to_owned());
    }
    for (k, v) in &m.env {
        out.push(format!("{k}={v}"));
    }
    out
}
