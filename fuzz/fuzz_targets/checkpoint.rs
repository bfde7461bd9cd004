//! cargo-fuzz target `checkpoint`: see `tissuefit::fuzzing` for the invariants checked.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(problem) = tissuefit::fuzzing::checkpoint(data) {
        panic!("{problem}");
    }
});
