//! Fuzz target `relay`: see `modbot_ipc_schema::fuzz::relay`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::relay(data));
