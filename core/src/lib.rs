//! mgmot-core: the pure core of mgmot, metadata-guided multi-object tracking for maritime
//! search and rescue drones (the MG-MOT paper).
//!
//! Pure and synchronous by construction: this crate depends on no IO crate (no tokio, MAVLink,
//! ONNX Runtime, V4L2), does no file or socket access and reads no clock (`clippy.toml` beside
//! `Cargo.toml` forbids the std calls; CI runs clippy with `-D warnings`). Times, poses,
//! detections and configuration come in as values; the `mgmot` crate's edges do the IO.
//!
//! - [`geo`]: camera model, WGS84 <-> local NED, ray / sea-plane intersection and
//!   geolocation uncertainty (paper Sec. 3.1, Eq. 1-4).
//! - [`track`]: the BoT-SORT-style tracker and the MG-MOT metadata-guided ReID
//!   (paper Sec. 3.2), online and offline, and the larger-box-priority NMS.
//! - [`eval`]: HOTA, CLEAR and Identity metrics computed as TrackEval does.
//! - [`telemetry`]: autopilot clock mapping and pose interpolation at frame time.
//! - [`frame`]: one frame's detections and camera pose -> the tracker's input, and a track's
//!   world state -> its geodetic fix (shared by the onboard runtime and `mgmot track`).
//! - [`report`]: what the outputs say about a track and about the operator-selected one.
//! - [`operator`]: which track an operator's click or rectangle selects, kept by id.
//! - [`digest`]: the tracks as short texts (STATUSTEXT) for a ground station that only hears
//!   the autopilot's telemetry radio.
//! - [`health`]: loss and return of telemetry, camera and detector, reported on change only.
#![warn(missing_docs)]

pub mod digest;
pub mod eval;
pub mod frame;
pub mod fuse;
pub mod geo;
pub mod health;
pub mod operator;
pub mod report;
pub mod telemetry;
pub mod track;
