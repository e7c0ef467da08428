//! Fuzz target `frame`: see `modbot_ipc_schema::fuzz::frame`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::frame(data));
