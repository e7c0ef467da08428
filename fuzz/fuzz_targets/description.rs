//! Fuzz target `description`: a system description, loaded and checked in the sandbox (its
//! memory and instruction limits, no patterns): it may be refused, never crash or hang.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        modbot_system::fuzz::description(text);
    }
});
