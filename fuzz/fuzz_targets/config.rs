//! Any text as a cohort config: parsing must answer with a config or an error, never panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = destair::job::config::Config::parse(text, std::path::Path::new("fuzz.toml"));
    }
});
