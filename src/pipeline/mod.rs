//! Wiring of the onboard runtime: capture -> newest-frame slot -> inference (detector, pose,
//! tracker) -> MAVLink outputs, with one shutdown signal for all stages.
//!
//! Status: frame source = the simulator's socket only; detector = the ONNX model or the
//! replay of the simulator's detections (bench); per-stage latency histograms in the logs
//! ([`latency`]); no operator-selected tracking (CAMERA_TRACKING_*) yet.

mod capture;
mod detector;
pub mod latency;
mod run;
mod shutdown;
mod slot;

pub use detector::{Detector, DetectorError, OnnxDetector, ReplayDetector};
pub use run::{run, PipelineError, RunStats};
pub use shutdown::{shutdown_signal, Shutdown, Trigger};
pub use slot::{newest_slot, SlotReader, SlotWriter, Taken};
