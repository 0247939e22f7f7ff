//! The whole pipeline on small arbitrary volumes, checking its guarantees, not only that it
//! does not crash (see `simplify_volume` in the shared checks).
#![no_main]

#[path = "../../crates/isotopo/tests/fuzz_checks/mod.rs"]
mod fuzz_checks;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| fuzz_checks::simplify_volume(data));
