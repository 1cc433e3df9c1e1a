//! Fuzzes the LAS reader: any bytes must give points or a clean error, never a panic.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    myriad_fuzz_support::read_all(data, "las");
});

mod myriad_fuzz_support {
    include!("../support.rs");
}
