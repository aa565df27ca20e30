//! mgmot: metadata-guided multi-object tracking for maritime search and rescue drones.
//!
//! The pure core lives in its own crate, `mgmot-core` (no IO dependencies, so the compiler
//! keeps it pure); its modules are re-exported here under their usual names: [`geo`],
//! [`track`], [`eval`], [`telemetry`], [`frame`], [`report`], [`operator`], [`health`],
//! [`digest`]. The wire contract with the simulator (the generated MAVLink dialect, the frame
//! framing) is the `mgmot-wire` crate's, re-exported as [`mavlink::dialect`] and
//! [`camera::sim_framing`]. This crate holds
//! the edges and the wiring (the layers and a frame's route: the README's "Layout"):
//!
//! - [`formats`]: readers and writers for MOTChallenge txt, SeaDronesSee / COCO JSON.
//! - [`detect`]: ONNX detector through `ort` (tract or ONNX Runtime), letterbox.
//! - [`mavlink`]: the MAVLink link (connection, signing, streams, TIMESYNC) and the
//!   translation between MAVLink messages and domain events and outputs.
//! - [`camera`]: frame sources (V4L2, image directories, the simulator's socket).
//! - [`clock`]: the companion's monotonic clock, read at the edges only.
//! - [`config`]: the runtime's TOML configuration, validated into typed settings.
//! - [`cot`]: Cursor-on-Target events for TAK maps, and their UDP/TCP/TLS transports.
//! - [`pipeline`]: the onboard runtime's wiring: capture, one frame's step, outputs.
//! - [`firmware`]: autopilot parameter files checked against parameter metadata tables.
//! - [`record`]: the flight record; [`review`]: a recorded flight as an HTML report, GeoJSON
//!   and KML.
#![warn(missing_docs)]

pub mod camera;
pub mod clock;
pub mod config;
pub mod cot;
pub mod detect;
pub mod firmware;
pub mod formats;
pub mod ground;
pub mod logging;
pub mod mavlink;
pub mod pipeline;
pub mod record;
pub mod review;

pub use mgmot_core::{digest, eval, frame, geo, health, operator, report, telemetry, track};
