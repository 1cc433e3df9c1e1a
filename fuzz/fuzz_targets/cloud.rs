//! Fuzzes `cloud` of `parsers.rs`: any bytes must parse, or give a clean error, never a panic
//! (and what parses keeps the invariants that function asserts).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    myriad_fuzz_parsers::cloud(data);
});

#[allow(dead_code)]
mod myriad_fuzz_parsers {
    include!("../parsers.rs");
}
