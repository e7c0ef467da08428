//! Fuzz target `directory`: see `modbot_ipc_schema::fuzz::directory`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::directory(data));
