#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mgmot_fuzz::targets::seadronessee::json(data));
