//! mgmot: metadata-guided multi-object tracking for maritime search and rescue drones.
//!
//! The crate is split into a pure core and IO edges (see `ARCHITECTURE.md`):
//!
//! - [`geo`]: camera model, WGS84 <-> local NED, ray / sea-plane intersection and
//!   geolocation uncertainty (paper Sec. 3.1, Eq. 1-4).
//! - [`track`]: the BoT-SORT-style tracker and the MG-MOT metadata-guided ReID
//!   (paper Sec. 3.2), online and offline.
//! - [`eval`]: HOTA, CLEAR and Identity metrics computed as TrackEval does.
//! - [`formats`]: readers and writers for MOTChallenge txt, SeaDronesSee / COCO JSON.
//! - [`detect`]: ONNX detector through `ort` (tract or ONNX Runtime), letterbox, NMS.
//! - [`telemetry`]: autopilot clock mapping and pose interpolation at frame time (pure).
//! - [`mavlink`], [`camera`], [`config`], [`pipeline`]: the onboard runtime's edges and wiring.
#![warn(missing_docs)]

pub mod camera;
pub mod config;
pub mod detect;
pub mod eval;
pub mod formats;
pub mod geo;
pub mod logging;
pub mod mavlink;
pub mod pipeline;
pub mod telemetry;
pub mod track;
