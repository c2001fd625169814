#![no_main]
//! Fuzz target: unitac_bag::fuzzing::cdr (must never panic or allocate without bound).
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| unitac_bag::fuzzing::cdr(data));
