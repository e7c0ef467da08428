//! Fuzz target `values`: see `modbot_ipc_schema::fuzz::values`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::values(data));
