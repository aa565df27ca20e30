//! `mgmot ground`: the ground picture of several drones, on the coordinator's laptop or the
//! GCS machine.
//!
//! MAVLink from mavlink-router or a GCS forward in ([`ingest`]); the drones' tracks fused into
//! one id per object by the pure fuser ([`mgmot_core::fuse`]); the picture out as a live map
//! and GeoJSON over HTTP ([`http`]), a GeoJSON file, a recording `mgmot review` opens
//! ([`record`]) and fused Cursor-on-Target ([`cot`]).

pub mod config;
pub mod cot;
pub mod geojson;
pub mod http;
pub mod ingest;
pub mod record;
mod run;

pub use config::{GroundConfig, GroundSettings};
pub use run::{run, CotCounters, GroundError, GroundStats};
