//! `mgmot_sim`: the simulated world behind `mgmot-sim` (scenarios, motion, metadata faults,
//! rendering, ground truth, detection simulation, MAVLink telemetry and frame framing).
//!
//! All projection goes through [`mgmot_core::geo`]: the simulator has no camera model of its own.
#![warn(missing_docs)]

pub mod detections;
pub mod follow;
pub mod framing;
pub mod monitor;
pub mod motion;
pub mod objects;
pub mod output;
pub mod render;
pub mod scenario;
pub mod telemetry;
pub mod truth;
pub mod world;
