//! Fuzz target `switch`: see `modbot_ipc_schema::fuzz::switch`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| modbot_ipc_schema::fuzz::switch(data));
