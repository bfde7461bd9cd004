//! cargo-fuzz target `units`: see `tissuefit::fuzzing` for the invariants checked.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(problem) = tissuefit::fuzzing::units(data) {
        panic!("{problem}");
    }
});
