//! Wiring of the onboard runtime: capture -> newest-frame slot -> inference (detector, pose,
//! tracker) -> MAVLink outputs, with one shutdown signal for all stages.
//!
//! Status: frame source = the simulator's socket only; detector = the replay stand-in; no
//! operator-selected tracking (CAMERA_TRACKING_*) and no latency histograms yet.

mod detector;
pub mod operator;
mod run;
mod shutdown;
mod slot;

pub use detector::{Detector, DetectorError, ReplayDetector};
pub use run::{run, PipelineError, RunStats};
pub use shutdown::{shutdown_signal, Shutdown, Trigger};
pub use slot::{newest_slot, SlotReader, SlotWriter, Taken};
