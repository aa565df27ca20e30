//! Wiring of the onboard runtime: capture -> newest-frame slot -> inference (detector, pose,
//! tracker) -> MAVLink outputs, with one shutdown signal for all stages.
//!
//! Status: the building blocks (slot, shutdown, detector trait and its replay stand-in) are
//! here; the `pipeline::run` that wires them to the MAVLink link is not written yet.

mod detector;
mod shutdown;
mod slot;

pub use detector::{Detector, DetectorError, ReplayDetector};
pub use shutdown::{shutdown_signal, Shutdown, Trigger};
pub use slot::{newest_slot, SlotReader, SlotWriter, Taken};
