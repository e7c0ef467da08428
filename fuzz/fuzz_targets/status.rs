//! Fuzz target `status`: see `modbot_ipc_schema::fuzz::status`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::status(data));
