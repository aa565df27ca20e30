#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| mgmot_fuzz::targets::mavlink::frames(data));
