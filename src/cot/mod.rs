//! Cursor-on-Target output for TAK maps (ATAK, WinTAK, iTAK and TAK servers): one event per
//! geolocated track at a configured rate, the vehicle itself, and the end of a uid the
//! tracker retired. [`event`] writes the XML, [`vehicle`] a drone's and its footprint's events,
//! and [`publisher`] decides which events a frame makes (all pure); [`transport`] sends them over UDP, TCP or TLS without ever holding up
//! the frame path.

pub mod event;
pub mod publisher;
mod tls;
pub mod transport;
pub mod vehicle;

pub use publisher::{
    default_types, CotClock, CotMessage, CotPublisher, PublisherSettings, TypesByClass,
    VEHICLE_TYPE,
};
pub use tls::TlsError;
pub use transport::{CotOutput, CotStats, IdentityFn};
pub use vehicle::VehicleFix;
