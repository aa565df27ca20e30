//! The wire contract between `mgmot` and `mgmot-sim`, with no heavy dependency (no detector,
//! camera or async runtime), so that the simulator builds without the runtime:
//!
//! - [`dialect`]: the mgmot MAVLink dialect (common + development + ardupilotmega +
//!   `firmware-config/mavlink/mgmot.xml`), generated at build time;
//! - [`sim_framing`]: the simulator's frame-stream framing, written by `mgmot-sim run --frames
//!   unix:PATH` and read by `mgmot run`'s simulator frame source.

#![warn(missing_docs)]

pub mod dialect;
pub mod sim_framing;
