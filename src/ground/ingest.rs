//! MAVLink in: each message a drone's system sends becomes fuser input or drone state.
//!
//! - MGMOT_TRACK (from any component of a vehicle): a [`Report`] on the common clock.
//! - SYSTEM_TIME (from the autopilot component): the vehicle's boot clock against UTC.
//! - GLOBAL_POSITION_INT (from the autopilot component): where the drone is.
//! - STATUSTEXT: mgmot's radio digest, used only for a vehicle from which no MGMOT_TRACK has
//!   arrived (its autopilot's radio drops mgmot's own message).
//! - HEARTBEAT: the vehicle exists.

use super::config::InputConfig;
use crate::mavlink::dialect::{MavMessage, MgmotTrackFlags, MgmotTrackState};
use mavlink_core::MavHeader;
use mgmot_core::digest::parse_text;
use mgmot_core::fuse::{ClockAlign, Fuser, Report};
use nalgebra::Vector2;
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
