//! Fuzz target `bus`: see `modbot_ipc_schema::fuzz::bus`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::bus(data));
