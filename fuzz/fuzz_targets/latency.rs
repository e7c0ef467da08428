//! Fuzz target `latency`: see `modbot_ipc_schema::fuzz::latency`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::latency(data));
