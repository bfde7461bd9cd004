//! cargo-fuzz target `vtk`: see `tissuefit::fuzzing` for the invariants checked.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(problem) = tissuefit::fuzzing::tissue(data, "vtk") {
        panic!("{problem}");
    }
});
