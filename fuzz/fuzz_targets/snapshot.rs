//! Fuzz target `snapshot`: see `modbot_ipc_schema::fuzz::snapshot`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::snapshot(data));
