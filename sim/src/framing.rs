//! The frame-stream framing used on the Unix-domain socket (documented in `sim/README.md`).
//!
//! One implementation serves both ends: this module re-exports the wire crate's
//! [`mgmot_wire::sim_framing`], which the runtime's reader uses too.

pub use mgmot_wire::sim_framing::{
    FrameHeader, FramingError, FOURCC_RGB3, HEADER_LEN, MAGIC, VERSION,
};
