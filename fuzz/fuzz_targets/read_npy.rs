//! The NumPy (.npy) reader alone on arbitrary bytes (see `read_format` in the shared checks).
#![no_main]

#[path = "../../crates/isotopo/tests/fuzz_checks/mod.rs"]
mod fuzz_checks;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    fuzz_checks::read_format("npy", data, &fuzz_checks::scratch_dir());
});
