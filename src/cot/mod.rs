//! Cursor-on-Target output for TAK maps (ATAK, WinTAK, iTAK and TAK servers): one event per
//! geolocated track at a configured rate, the vehicle itself, and the end of a uid the
//! tracker retired. [`event`] writes the XML and [`publisher`] decides which events a frame
//! makes (both pure); [`transport`] sends them over UDP, TCP or TLS without ever holding up
//! the frame path.

pub mod event;
pub mod publisher;
mod tls;
pub mod transport;

pub use publisher::{
    default_types, CotClock, CotMessage, CotPublisher, PublisherSettings, TypesByClass, VehicleFix,
    VEHICLE_TYPE,
};
pub use tls::TlsError;
pub use transport::{CotOutput, CotStats, IdentityFn};
