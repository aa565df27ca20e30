//! The integration tests of the `mgmot` crate: one test binary, as ripgrep has it, with one
//! module per area and one harness ([`common`]). One binary links the runtime crate (ort,
//! tract, v4l) once, not once per area. Run one area with a module filter, e.g.
//! `cargo test --release --test main -- runtime_link::`.

mod common;

mod cli_track;
mod cli_validation;
mod cli_validation_io;
mod detect_cli;
mod detect_model;
mod detect_ultralytics;
mod eval_cli;
mod eval_motmetrics;
mod eval_trackeval_fixtures;
mod firmware_config;
mod fuzz_decoders;
mod ground;
mod link_hardening;
mod real_data_geolocation;
mod recording;
mod review;
mod runtime_check_config;
mod runtime_cot;
mod runtime_faults;
mod runtime_heartbeat;
mod runtime_images;
mod runtime_link;
mod runtime_loopback;
mod runtime_pymavlink;
mod service_deploy;
mod service_notify;
mod track_scenarios;
mod track_seadronessee;
mod tracking_benchmark;
