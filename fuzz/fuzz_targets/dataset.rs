//! Fuzzes the dataset reader (`support.rs`, `read_dataset`): any bytes must open as a dataset
//! and read node by node, or give clean errors and damage reports, never a panic.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    myriad_fuzz_support::read_dataset(data);
});

mod myriad_fuzz_support {
    include!("../support.rs");
}
