//! Every reader on arbitrary bytes: a clear error or a volume, never a panic, never an
//! allocation the file cannot back (see `read_volume` in the shared checks).
#![no_main]

#[path = "../../crates/isotopo/tests/fuzz_checks/mod.rs"]
mod fuzz_checks;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    fuzz_checks::read_volume(data, &fuzz_checks::scratch_dir());
});
