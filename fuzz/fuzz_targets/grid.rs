//! Fuzz target `grid`: see `modbot_ipc_schema::fuzz::grid`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::grid(data));
