//! Wiring of the onboard runtime: capture -> newest-frame slot -> inference (detector, pose,
//! tracker) -> MAVLink outputs, with one shutdown signal for all stages.
//!
//! Frame sources: V4L2, an image directory or the simulator's socket ([`crate::camera`]);
//! detector: the ONNX model or the replay of the simulator's detections (bench); per-stage
//! latency histograms in the logs ([`latency`]); operator-selected tracking (`operator_link`, on
//! the core's `operator`); systemd's READY / WATCHDOG / STATUS notifications (`service`).

mod camera_fov;
mod capture;
mod cot_step;
mod detect_stage;
mod error;
mod frame_step;
mod heartbeat;
pub mod latency;
mod operator_link;
mod recording;
mod run;
mod service;
mod shutdown;
mod slot;
mod stats;
mod telemetry;

pub use detect_stage::{DetectStage, DetectStageError, OnnxStage, ReplayStage};
pub use error::PipelineError;
pub use run::run;
pub use shutdown::{shutdown_signal, Shutdown, Trigger};
pub use slot::{newest_slot, SlotReader, SlotWriter, Taken};
pub use stats::RunStats;
