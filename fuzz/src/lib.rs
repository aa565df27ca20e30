//! The bodies of the fuzz targets, shared with the stable harness `tests/fuzz_decoders.rs`.

#[path = "../targets/mod.rs"]
pub mod targets;
