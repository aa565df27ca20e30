//! The MAVLink edge: the project's dialect, connections, typed telemetry samples and outputs.

include!(concat!(env!("OUT_DIR"), "/mavlink-bindings/declare.rs"));
pub use self::mgmot as dialect;
