//! `modbot-fmu-host`: the host of FMU components — steps the `fmu` components of one host name
//! (an FMI 2.0 or 3.0 co-simulation FMU each, loaded through the `fmi` crate; see `modbot_fmu`),
//! beside the built-in component types. The supervisor starts it for every host whose
//! components are FMUs, so a crashing FMU takes only its own host down.

fn main() -> std::process::ExitCode {
    let mut registry = modbot_components::builtin();
    modbot_fmu::register(&mut registry);
    modbot_grid_processes::host_process::host_main("modbot-fmu-host", registry)
}
