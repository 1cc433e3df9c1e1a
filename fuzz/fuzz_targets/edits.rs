//! Fuzzes `edits` of `parsers.rs`: an edits file or a ground surface must parse and apply, or
//! give a clean error, never a panic.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    myriad_fuzz_parsers::edits(data);
});

#[allow(dead_code)]
mod myriad_fuzz_parsers {
    include!("../parsers.rs");
}
