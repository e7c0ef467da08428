//! `modbot-recorder`: the data recorder's host — steps the `record` components of one host
//! name (a description's `record { ... }`), which write the run's signals to HDF5 (see
//! `modbot_record`), beside the built-in component types.

fn main() -> std::process::ExitCode {
    let mut registry = modbot_runtime::grid::component::Registry::builtin();
    modbot_record::register(&mut registry);
    modbot_grid_processes::host_process::host_main("modbot-recorder", registry)
}
