//! The MAVLink edge: the project's dialect, connection strings, typed telemetry samples decoded
//! from incoming messages, and the messages mgmot sends.
//!
//! Everything past this module sees domain types: the pipeline talks to [`bridge`] (telemetry
//! updates and operator requests in; core reports, statuses and notices out), never to a
//! MAVLink message.

mod address;
pub mod bridge;
mod decode;
pub use mgmot_wire::dialect;
pub(crate) mod encode;
pub mod link;
pub mod signing;

pub use address::{parse_connection, AddressError};
pub use bridge::{Inbox, LinkInput, OperatorRequest, Outputs, ReplyTo, TelemetryUpdate};
pub use decode::{decode, decode_mount_status, CameraCommand, Incoming};
pub use encode::{
    camera_information, camera_tracking_geo_status, camera_tracking_geo_status_lost,
    camera_tracking_image_status, camera_tracking_image_status_lost, command_ack, heartbeat,
    message_interval_request, mgmot_track, statustext, target_absolute, timesync_request,
    AckResult, Severity, STREAMS,
};
pub use link::{
    Link, LinkEvent, LinkSender, LinkSettings, LinkStats, PacketTap, Received, SigningSettings,
};
pub use signing::{is_signed, parse_raw, signing_config};

/// Our component id: MAV_COMP_ID_ONBOARD_COMPUTER.
pub const COMPONENT_ID: u8 = 191;
