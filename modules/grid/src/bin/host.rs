//! `modbot-host`: a component host of the time grid — steps the components of one host name,
//! of the built-in component types (see [`modbot_grid_processes::host_process::host_main`]).

fn main() -> std::process::ExitCode {
    modbot_grid_processes::host_process::host_main("modbot-host", modbot_components::builtin())
}
