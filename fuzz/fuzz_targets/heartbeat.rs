//! Fuzz target `heartbeat`: see `modbot_ipc_schema::fuzz::heartbeat`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::heartbeat(data));
