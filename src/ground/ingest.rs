//! MAVLink in: each message a drone's system sends becomes fuser input or drone state.
//!
//! - MGMOT_TRACK (from any component of a vehicle): a [`Report`] on the common clock.
//! - SYSTEM_TIME (from the autopilot component): the vehicle's boot clock against UTC.
//! - GLOBAL_POSITION_INT (from the autopilot component): where the drone is.
//! - STATUSTEXT: mgmot's radio digest, used only for a vehicle from which no MGMOT_TRACK has
//!   arrived (its autopilot's radio drops mgmot's own message).
//! - CAMERA_FOV_STATUS (from any component of a vehicle: `mgmot run`, or a camera): the
//!   camera's footprint on the sea, for the map.
//! - HEARTBEAT: the vehicle exists.

use super::config::InputConfig;
use crate::mavlink::dialect::{MavMessage, MgmotTrackFlags, MgmotTrackState};
use mavlink_core::MavHeader;
use mgmot_core::digest::parse_text;
use mgmot_core::fuse::{ClockAlign, Fuser, Report};
use mgmot_core::geo::{CameraView, Geodetic};
use nalgebra::{Quaternion, UnitQuaternion, Vector2};
use serde::Serialize;
use std::collections::BTreeMap;

/// What the ground knows of one drone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Drone {
    /// Its MAVLink system id.
    pub system_id: u8,
    /// Latest position (degrees; `None` before GLOBAL_POSITION_INT).
    pub position: Option<(f64, f64)>,
    /// Altitude above mean sea level (m).
    pub alt_m: f64,
    /// Heading (degrees from north), when the autopilot gives one.
    pub heading_deg: Option<f64>,
    /// When anything last came from it (s, the ground's UTC clock).
    pub last_heard_s: f64,
    /// MGMOT_TRACK messages received from it.
    pub track_messages: u64,
    /// Digest positions used from it.
    pub digest_positions: u64,
    /// Its camera's footprint on the sea, a ring of (lat, lon) in degrees (empty before the
    /// first CAMERA_FOV_STATUS, or while the camera sees no water).
    pub footprint: Vec<(f64, f64)>,
    /// When the footprint came (s, the ground's UTC clock).
    pub footprint_s: Option<f64>,
    /// The sea surface's altitude (m AMSL) as the drone last told it (`alt_image`).
    #[serde(skip)]
    water_amsl_m: Option<f64>,
}

/// Counters of what arrived.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct IngestStats {
    /// MAVLink messages decoded.
    pub messages: u64,
    /// MGMOT_TRACK messages.
    pub track_messages: u64,
    /// Of those, used by the fuser.
    pub track_reports_used: u64,
    /// Of those, without a geolocation (no pose onboard): nothing to place.
    pub not_geolocated: u64,
    /// Of those, provisional (the drone's ReID decision pending): ignored.
    pub provisional: u64,
    /// Digest positions used.
    pub digest_positions: u64,
    /// Messages from vehicles not in `input.vehicles`.
    pub other_vehicles: u64,
    /// Camera footprints made from CAMERA_FOV_STATUS.
    pub footprints: u64,
    /// CAMERA_FOV_STATUS messages that gave no footprint (unknown position or field of view).
    pub bad_footprints: u64,
}

/// Turns messages into fuser input.
#[derive(Debug)]
pub struct Ingest {
    settings: InputConfig,
    clock: ClockAlign,
    drones: BTreeMap<u8, Drone>,
    stats: IngestStats,
}

impl Ingest {
    /// Nothing heard yet.
    pub fn new(settings: InputConfig) -> Self {
        Self {
            settings,
            clock: ClockAlign::new(),
            drones: BTreeMap::new(),
            stats: IngestStats::default(),
        }
    }

    /// The fuser's time at ground time `ground_s` (UTC, s).
    pub fn now(&self, ground_s: f64) -> f64 {
        self.clock.now(ground_s)
    }

    /// The drones heard so far, by system id.
    pub fn drones(&self) -> impl Iterator<Item = &Drone> {
        self.drones.values()
    }

    /// The counters.
    pub fn stats(&self) -> &IngestStats {
        &self.stats
    }

    /// Takes one message that arrived at `arrival_s` (the ground's UTC clock, s).
    pub fn message(
        &mut self,
        header: &MavHeader,
        msg: &MavMessage,
        arrival_s: f64,
        fuser: &mut Fuser,
    ) {
        self.stats.messages += 1;
        let Ok(sys) = u8::try_from(header.system_id) else {
            return;
        };
        if sys == self.settings.system_id && header.component_id == self.settings.component_id {
            return; // our own heartbeat, echoed by a router
        }
        let is_vehicle_message = matches!(
            msg,
            MavMessage::MGMOT_TRACK(_)
                | MavMessage::SYSTEM_TIME(_)
                | MavMessage::GLOBAL_POSITION_INT(_)
                | MavMessage::STATUSTEXT(_)
                | MavMessage::CAMERA_FOV_STATUS(_)
                | MavMessage::HEARTBEAT(_)
        );
        if !is_vehicle_message {
            return;
        }
        if let MavMessage::HEARTBEAT(h) = msg {
            // Other ground stations are not drones.
            if h.mavtype == crate::mavlink::dialect::MavType::MAV_TYPE_GCS {
                return;
            }
        }
        if !self.settings.vehicles.is_empty() && !self.settings.vehicles.contains(&sys) {
            self.stats.other_vehicles += 1;
            return;
        }
        let autopilot = header.component_id == self.settings.autopilot_component_id;
        let drone = self.drones.entry(sys).or_insert(Drone {
            system_id: sys,
            position: None,
            alt_m: f64::NAN,
            heading_deg: None,
            last_heard_s: arrival_s,
            track_messages: 0,
            digest_positions: 0,
            footprint: Vec::new(),
            footprint_s: None,
            water_amsl_m: None,
        });
        drone.last_heard_s = arrival_s;
        match msg {
            MavMessage::SYSTEM_TIME(t) if autopilot => {
                self.clock.system_time(
                    sys,
                    t.time_unix_usec as f64 / 1e6,
                    f64::from(t.time_boot_ms) / 1e3,
                );
            }
            MavMessage::GLOBAL_POSITION_INT(p) if autopilot && (p.lat != 0 || p.lon != 0) => {
                drone.position = Some((f64::from(p.lat) / 1e7, f64::from(p.lon) / 1e7));
                drone.alt_m = f64::from(p.alt) / 1e3;
                drone.heading_deg = (p.hdg != u16::MAX).then(|| f64::from(p.hdg) / 100.0);
            }
            MavMessage::CAMERA_FOV_STATUS(f) => {
                if let Some(water) = known_mm(f.alt_image) {
                    drone.water_amsl_m = Some(water);
                }
                match footprint(f, drone.water_amsl_m.unwrap_or(0.0)) {
                    Ok(ring) => {
                        drone.footprint = ring;
                        drone.footprint_s = Some(arrival_s);
                        self.stats.footprints += 1;
                    }
                    Err(why) => {
                        self.stats.bad_footprints += 1;
                        tracing::debug!(system_id = sys, %why, "CAMERA_FOV_STATUS not used");
                    }
                }
            }
            MavMessage::MGMOT_TRACK(t) => {
                drone.track_messages += 1;
                self.stats.track_messages += 1;
                if t.flags
                    .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_PROVISIONAL)
                {
                    self.stats.provisional += 1;
                    return;
                }
                if !t
                    .flags
                    .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID)
                {
                    self.stats.not_geolocated += 1;
                    return;
                }
                let time_s = self.clock.align(sys, t.time_usec as f64 / 1e6, arrival_s);
                let vel = Vector2::new(f64::from(t.vel_n), f64::from(t.vel_e));
                let report = Report {
                    system_id: sys,
                    track_id: u64::from(t.track_id),
                    merged_from_id: t
                        .flags
                        .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_MERGED)
                        .then_some(u64::from(t.merged_from_id)),
                    class_id: t.object_class as u32,
                    time_s,
                    lat_deg: f64::from(t.lat) / 1e7,
                    lon_deg: f64::from(t.lon) / 1e7,
                    vel_ne_m_s: vel.iter().all(|v| v.is_finite()).then_some(vel),
                    h_std_m: f64::from(t.h_std),
                    tracked: t.state == MgmotTrackState::MGMOT_TRACK_STATE_TRACKED,
                    provisional: false,
                };
                if fuser.observe(&report) {
                    self.stats.track_reports_used += 1;
                }
            }
            MavMessage::STATUSTEXT(s) if self.settings.digest && drone.track_messages == 0 => {
                let Ok(text) = s.text.to_str() else { return };
                let Some(d) = parse_text(text) else { return };
                let report = Report {
                    system_id: sys,
                    track_id: d.track_id,
                    merged_from_id: None,
                    class_id: d.class_id,
                    // The digest says how long ago; its clock is the sender's now.
                    time_s: self.clock.now(arrival_s) - d.age_s,
                    lat_deg: d.lat_deg,
                    lon_deg: d.lon_deg,
                    vel_ne_m_s: None,
                    h_std_m: self.settings.digest_h_std_m,
                    tracked: true,
                    provisional: false,
                };
                if fuser.observe(&report) {
                    drone.digest_positions += 1;
                    self.stats.digest_positions += 1;
                }
            }
            _ => {}
        }
    }
}

/// Points per image edge of a footprint (16 in all, as `mgmot run`'s CoT footprint).
const FOOTPRINT_POINTS_PER_EDGE: usize = 4;
/// A footprint reaches at most this far from the camera (m): beyond it a flat sea and a
/// degree of attitude error say little (the review's footprints use the same limit).
const FOOTPRINT_MAX_RANGE_M: f64 = 1500.0;

/// A CAMERA_FOV_STATUS altitude (mm) in m, `None` when unknown (INT32_MAX) or at infinity
/// (INT32_MIN).
fn known_mm(v: i32) -> Option<f64> {
    (v != i32::MAX && v != i32::MIN).then(|| f64::from(v) / 1e3)
}

/// The camera footprint a CAMERA_FOV_STATUS describes, as (lat, lon) degrees; the sea at
/// `water_amsl_m`.
pub fn footprint(
    f: &crate::mavlink::dialect::CAMERA_FOV_STATUS_DATA,
    water_amsl_m: f64,
) -> Result<Vec<(f64, f64)>, String> {
    let (Some(alt_m), true) = (
        known_mm(f.alt_camera),
        f.lat_camera != i32::MAX && f.lon_camera != i32::MAX,
    ) else {
        return Err("camera position unknown".into());
    };
    let camera = Geodetic::new(
        f64::from(f.lat_camera) / 1e7,
        f64::from(f.lon_camera) / 1e7,
        alt_m,
    )
    .map_err(|e| e.to_string())?;
    let q = Quaternion::new(
        f64::from(f.q[0]),
        f64::from(f.q[1]),
        f64::from(f.q[2]),
        f64::from(f.q[3]),
    );
    if !(q.norm() > 0.5 && q.norm() < 1.5) {
        return Err(format!("quaternion norm {}", q.norm()));
    }
    let view = CameraView {
        camera,
        height_above_sea_m: alt_m - water_amsl_m,
        attitude_frd: UnitQuaternion::from_quaternion(q),
        hfov_deg: f64::from(f.hfov),
        vfov_deg: f64::from(f.vfov),
    };
    let ring = view
        .footprint(FOOTPRINT_MAX_RANGE_M, FOOTPRINT_POINTS_PER_EDGE)
        .map_err(|e| e.to_string())?;
    Ok(ring.iter().map(|g| (g.lat_deg, g.lon_deg)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::attitude::camera_from_heading_pitch_deg;
    use crate::geo::{FrameMetadata, LocalTangentFrame};
    use crate::ground::geojson::footprint_feature;
    use crate::mavlink::encode::camera_fov_status;
    use crate::telemetry::AutopilotTimeUs;
    use mgmot_core::fuse::FuseParams;

    fn header(system_id: u8, component_id: u8) -> MavHeader {
        MavHeader {
            system_id: system_id.into(),
            component_id,
            sequence: 0,
        }
    }

    /// What `mgmot run` sends for a camera 60 m above a sea at 2 m AMSL, looking `heading_deg`
    /// and `pitch_deg` below the horizon, with a 16:9 image and a 70 deg field of view.
    fn fov_message(heading_deg: f64, pitch_deg: f64, centre: bool) -> MavMessage {
        let meta = FrameMetadata {
            position: Geodetic::new(54.18, 7.89, 62.0).unwrap(),
            height_above_sea_m: 60.0,
            camera_attitude: camera_from_heading_pitch_deg(heading_deg, pitch_deg, 0.0),
            horizontal_accuracy_m: None,
        };
        let vfov = 2.0 * (35f64.to_radians().tan() * 9.0 / 16.0).atan().to_degrees();
        let view = CameraView::of_frame(&meta, 70.0, vfov);
        let c = Geodetic::new(54.18, 7.89, 2.0).unwrap();
        camera_fov_status(AutopilotTimeUs(5_000_000), &view, centre.then_some(&c))
    }

    /// Drone 3's `mgmot run` (component 191) sends `msg`, arriving at `at` (s).
    fn from_drone_3(ingest: &mut Ingest, fuser: &mut Fuser, msg: &MavMessage, at: f64) {
        ingest.message(&header(3, 191), msg, at, fuser);
    }

    /// East (m) of each footprint point from the camera's nadir.
    fn east_of(drone: &Drone) -> Vec<f64> {
        let frame = LocalTangentFrame::new(Geodetic::new(54.18, 7.89, 0.0).unwrap());
        drone
            .footprint
            .iter()
            .map(|&(lat, lon)| frame.to_ned(&Geodetic::new(lat, lon, 0.0).unwrap()).y)
            .collect()
    }

    #[test]
    fn a_camera_fov_status_from_mgmot_run_becomes_the_drones_footprint_on_the_map() {
        let mut ingest = Ingest::new(InputConfig::default());
        let mut fuser = Fuser::new(FuseParams::default());
        from_drone_3(
            &mut ingest,
            &mut fuser,
            &fov_message(0.0, 90.0, true),
            100.0,
        );
        let drone = ingest.drones().next().unwrap();
        assert_eq!(drone.system_id, 3);
        assert_eq!(drone.footprint.len(), 16);
        assert_eq!(ingest.stats().footprints, 1);
        // Nadir from 60 m above the sea (alt_image gave the sea at 2 m): 2 * 60 * tan(35 deg)
        // = 84.0 m across, east-west, as the camera's heading is north.
        let east = east_of(drone);
        let width = east.iter().copied().fold(f64::MIN, f64::max)
            - east.iter().copied().fold(f64::MAX, f64::min);
        assert!((width - 84.02).abs() < 0.1, "{width}");

        // As GeoJSON: a closed, counterclockwise ring, while fresh.
        let f = footprint_feature(drone, 5.0, 101.0).unwrap();
        let ring = f["geometry"]["coordinates"][0].as_array().unwrap();
        assert_eq!(ring.len(), 17);
        assert_eq!(ring[0], ring[16]);
        let pts: Vec<(f64, f64)> = ring
            .iter()
            .map(|p| (p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
            .collect();
        let area2: f64 = pts
            .windows(2)
            .map(|w| w[0].0 * w[1].1 - w[1].0 * w[0].1)
            .sum();
        assert!(area2 > 0.0, "clockwise ring");
        assert_eq!(
            f["properties"]["time_unix_ms"], 4000,
            "on the picture's clock"
        );
        assert!(footprint_feature(drone, 64.0, 160.0).is_none(), "stale");
    }

    #[test]
    fn an_oblique_camera_looking_east_sees_water_to_the_east_and_bad_messages_are_counted() {
        let mut ingest = Ingest::new(InputConfig::default());
        let mut fuser = Fuser::new(FuseParams::default());
        // The sea level was told once; a later message whose centre is above the horizon
        // (alt_image unknown) keeps it.
        from_drone_3(
            &mut ingest,
            &mut fuser,
            &fov_message(0.0, 90.0, true),
            100.0,
        );
        from_drone_3(
            &mut ingest,
            &mut fuser,
            &fov_message(90.0, 20.0, false),
            101.0,
        );
        let drone = ingest.drones().next().unwrap();
        let east_min = east_of(drone).into_iter().fold(f64::MAX, f64::min);
        // 20 deg down with a 43 deg vertical field: the near edge 60 / tan(41.5 deg) = 67.9 m
        // east of the camera.
        assert!((east_min - 67.9).abs() < 1.0, "{east_min}");

        let MavMessage::CAMERA_FOV_STATUS(mut bad) = fov_message(0.0, 90.0, true) else {
            unreachable!()
        };
        bad.hfov = f32::NAN;
        from_drone_3(
            &mut ingest,
            &mut fuser,
            &MavMessage::CAMERA_FOV_STATUS(bad.clone()),
            102.0,
        );
        bad.hfov = 70.0;
        bad.lat_camera = i32::MAX;
        from_drone_3(
            &mut ingest,
            &mut fuser,
            &MavMessage::CAMERA_FOV_STATUS(bad),
            103.0,
        );
        assert_eq!(ingest.stats().bad_footprints, 2);
        assert_eq!(ingest.stats().footprints, 2);
    }
}
