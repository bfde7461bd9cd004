//! cargo-fuzz target `fit_config`: see `tissuefit::fuzzing` for the invariants checked.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(problem) = tissuefit::fuzzing::fit_config(data) {
        panic!("{problem}");
    }
});
