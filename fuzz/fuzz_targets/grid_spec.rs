//! Fuzz target `grid_spec`: see `modbot_ipc_schema::fuzz::grid_spec`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::grid_spec(data));
