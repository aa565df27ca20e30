//! The bench's view of mgmot's output: every MGMOT_TRACK that mgmot sends to the simulated
//! autopilot is checked against the ground truth of the instant it describes, so a bench user
//! sees geolocated tracks arrive and how far off they are. Pure: no IO, no clock.
//!
//! A message is associated with the nearest true object, of any class, that exists at the
//! message's capture time, within [`ASSOCIATION_GATE_M`]; its geolocation error is the
//! horizontal distance to that object's reference point on the sea surface. Whether the class
//! agrees is counted apart: the shipped detector knows swimmers and boats only, so a buoy
//! reported as a swimmer is a class error at a correct position, not a geolocation error of
//! the swimmer nearest to it.

use crate::scenario::ObjectClass;
use crate::world::World;
use mgmot_core::geo::{GeoError, Geodetic, LocalTangentFrame};
use mgmot_wire::dialect::{MgmotObjectClass, MgmotTrackFlags, MgmotTrackState, MGMOT_TRACK_DATA};
use nalgebra::Vector3;
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};

/// A report further than this from every true object is counted as a false
/// track rather than as a large error (m). Boats are up to ~15 m long and their box centre is
/// not their reference point, hence the generous gate.
pub const ASSOCIATION_GATE_M: f64 = 20.0;

/// What one MGMOT_TRACK was checked to be.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TrackCheck {
    /// The message carries no geolocation (no usable pose for its frame).
    NoGeolocation,
    /// Its capture time is outside the scenario.
    OutOfScenario,
    /// No true object within the gate.
    FalseTrack {
        /// Distance to the nearest true object, if there is one (m).
        nearest_m: Option<f64>,
    },
    /// Associated with a true object.
    Matched {
        /// The object's id in the ground truth.
        object_id: u32,
        /// Horizontal geolocation error (m).
        error_m: f64,
        /// The message's class is the object's (or the message says unknown).
        same_class: bool,
        /// The object's class.
        class: ObjectClass,
    },
}

/// Aggregates the checks of a run.
#[derive(Debug, Clone)]
pub struct TrackMonitor {
    frame: LocalTangentFrame,
    boot_time_s: f64,
    camera_offset_s: f64,
    messages: u64,
    without_geolocation: u64,
    out_of_scenario: u64,
    false_tracks: u64,
    wrong_class: u64,
    errors_m: Vec<f64>,
    /// Per true object: every mgmot track id associated with it, and the latest one.
    ids: BTreeMap<u32, (BTreeSet<u32>, u32)>,
    /// Per true object: the largest error of a message at it, and of one in state TRACKED.
    worst_m: BTreeMap<u32, (f64, f64)>,
    /// Per true object: its class, and how many of its messages carried each class (by the
    /// message's SeaDronesSee category id, 0 for unknown).
    classes: BTreeMap<u32, (ObjectClass, BTreeMap<u32, u64>)>,
    track_ids: BTreeSet<u32>,
    /// Re-identification merges mgmot announced: new id -> the old id it now carries.
    merged_into: BTreeMap<u32, u32>,
}

/// The summary printed (and written as JSON) at the end of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MonitorSummary {
    /// MGMOT_TRACK messages received.
    pub messages: u64,
    /// Of those, without a geolocation.
    pub without_geolocation: u64,
    /// Of those, with a capture time outside the scenario.
    pub out_of_scenario: u64,
    /// Of those, geolocated but far from every true object of their class.
    pub false_tracks: u64,
    /// Of those, associated with a true object.
    pub matched: u64,
    /// Of the matched, with another class than the object's.
    pub wrong_class: u64,
    /// Distinct mgmot track ids seen.
    pub track_ids: usize,
    /// Median horizontal geolocation error of the matched messages (m).
    pub error_median_m: Option<f64>,
    /// 95th percentile of the error (m).
    pub error_p95_m: Option<f64>,
    /// Largest error (m).
    pub error_max_m: Option<f64>,
    /// Per true object: the mgmot track ids associated with it (one id = the identity
    /// survived everything the scenario did), and the latest one.
    pub objects: Vec<ObjectIds>,
}

impl MonitorSummary {
    /// One log line about the MGMOT_TRACK messages checked so far (`run` and `follow`).
    pub fn log(&self, what: &str) {
        let m = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |x| format!("{x:.2}"));
        tracing::info!(
            messages = self.messages,
            track_ids = self.track_ids,
            matched = self.matched,
            false_tracks = self.false_tracks,
            wrong_class = self.wrong_class,
            without_geolocation = self.without_geolocation,
            out_of_scenario = self.out_of_scenario,
            error_median_m = %m(self.error_median_m),
            error_p95_m = %m(self.error_p95_m),
            error_max_m = %m(self.error_max_m),
            "{what}"
        );
    }
}

/// The mgmot track ids one true object was reported under.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObjectIds {
    /// The object's id in the ground truth.
    pub object_id: u32,
    /// Every track id associated with it, ascending.
    pub track_ids: Vec<u32>,
    /// The id of its latest message.
    pub latest_track_id: u32,
    /// `track_ids` after mgmot's re-identification merges (a new track linked to an old one
    /// is first reported under its own id, then under the old one with `merged_from_id`):
    /// one id here means the object kept one identity in the end.
    pub final_track_ids: Vec<u32>,
    /// The largest geolocation error of its messages (m).
    pub error_max_m: f64,
    /// The largest of those in state TRACKED, matched to a detection in that frame (m); the
    /// others are the tracker's predictions while the object is not detected.
    pub error_max_tracked_m: Option<f64>,
    /// The object's class (SeaDronesSee name).
    pub class: &'static str,
    /// How many of its messages carried each class, by SeaDronesSee name (`unknown` for a
    /// message without one).
    pub classes_reported: BTreeMap<&'static str, u64>,
}

/// The SeaDronesSee name of MGMOT_TRACK's class (its category id; 0 and others: `unknown`).
fn category_name(id: u32) -> &'static str {
    ObjectClass::from_category_id(id).map_or("unknown", ObjectClass::name)
}

impl TrackMonitor {
    /// A monitor for `world`; errors when the scenario's origin is not a valid position.
    pub fn new(world: &World) -> Result<Self, GeoError> {
        let o = &world.scenario.origin;
        let origin = Geodetic::new(o.lat_deg, o.lon_deg, o.alt_amsl_m)?;
        Ok(Self {
            frame: LocalTangentFrame::new(origin),
            boot_time_s: world.scenario.telemetry.boot_time_s,
            camera_offset_s: world.scenario.faults.camera_time_offset_ms / 1000.0,
            messages: 0,
            without_geolocation: 0,
            out_of_scenario: 0,
            false_tracks: 0,
            wrong_class: 0,
            errors_m: Vec::new(),
            ids: BTreeMap::new(),
            worst_m: BTreeMap::new(),
            classes: BTreeMap::new(),
            track_ids: BTreeSet::new(),
            merged_into: BTreeMap::new(),
        })
    }

    /// Checks one message against the truth of the instant it describes.
    pub fn observe(&mut self, world: &World, m: &MGMOT_TRACK_DATA) -> TrackCheck {
        // time_usec is the frame's stamp on the autopilot clock, which includes the camera's
        // clock offset fault; the truth is at the true capture time.
        let t_s = m.time_usec as f64 / 1e6 - self.boot_time_s - self.camera_offset_s;
        self.observe_at(world, m, t_s)
    }

    /// Checks one message against the truth at scenario time `t_s`, for callers that map the
    /// message's `time_usec` to scenario time themselves (`mgmot-sim follow`, whose autopilot
    /// clock is a real autopilot's).
    pub fn observe_at(&mut self, world: &World, m: &MGMOT_TRACK_DATA, t_s: f64) -> TrackCheck {
        self.messages += 1;
        self.track_ids.insert(m.track_id);
        if m.flags.contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_MERGED)
            && m.merged_from_id != 0
            && m.merged_from_id != m.track_id
        {
            self.merged_into.insert(m.merged_from_id, m.track_id);
        }
        let check = self.check(world, m, t_s);
        match check {
            TrackCheck::NoGeolocation => self.without_geolocation += 1,
            TrackCheck::OutOfScenario => self.out_of_scenario += 1,
            TrackCheck::FalseTrack { .. } => self.false_tracks += 1,
            TrackCheck::Matched {
                object_id,
                error_m,
                same_class,
                class,
            } => {
                self.errors_m.push(error_m);
                if !same_class {
                    self.wrong_class += 1;
                }
                *self
                    .classes
                    .entry(object_id)
                    .or_insert_with(|| (class, BTreeMap::new()))
                    .1
                    .entry(m.object_class as u32)
                    .or_insert(0) += 1;
                let entry = self
                    .ids
                    .entry(object_id)
                    .or_insert_with(|| (BTreeSet::new(), m.track_id));
                entry.0.insert(m.track_id);
                entry.1 = m.track_id;
                let worst = self.worst_m.entry(object_id).or_insert((0.0, f64::NAN));
                worst.0 = worst.0.max(error_m);
                if m.state == MgmotTrackState::MGMOT_TRACK_STATE_TRACKED {
                    worst.1 = if worst.1.is_nan() {
                        error_m
                    } else {
                        worst.1.max(error_m)
                    };
                }
            }
        }
        check
    }

    fn check(&self, world: &World, m: &MGMOT_TRACK_DATA, t_s: f64) -> TrackCheck {
        if !m
            .flags
            .contains(MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID)
        {
            return TrackCheck::NoGeolocation;
        }
        if !(t_s.is_finite() && t_s >= 0.0 && t_s <= world.scenario.duration_s + 1.0) {
            return TrackCheck::OutOfScenario;
        }
        let Ok(at) = Geodetic::new(
            f64::from(m.lat) * 1e-7,
            f64::from(m.lon) * 1e-7,
            f64::from(m.alt) / 1000.0,
        ) else {
            return TrackCheck::FalseTrack { nearest_m: None };
        };
        let p = self.frame.to_ned(&at);
        let nearest = world
            .objects_at(t_s)
            .into_iter()
            .map(|o| {
                let q = Vector3::from(o.pos_ned_m);
                (o, (p.xy() - q.xy()).norm())
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match nearest {
            Some((o, error_m)) if error_m <= ASSOCIATION_GATE_M => TrackCheck::Matched {
                object_id: o.id,
                error_m,
                same_class: m.object_class == MgmotObjectClass::MGMOT_OBJECT_CLASS_UNKNOWN
                    || o.class.category_id() == m.object_class as u32,
                class: o.class,
            },
            Some((_, d)) => TrackCheck::FalseTrack { nearest_m: Some(d) },
            None => TrackCheck::FalseTrack { nearest_m: None },
        }
    }

    /// The id `id` ended up as, following the merges (a cycle, which mgmot never sends,
    /// stops at the id where it closes).
    fn final_id(&self, id: u32) -> u32 {
        let mut seen = BTreeSet::from([id]);
        let mut f = id;
        while let Some(&next) = self.merged_into.get(&f) {
            if !seen.insert(next) {
                break;
            }
            f = next;
        }
        f
    }

    /// Messages received so far.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// The summary of everything observed so far.
    pub fn summary(&self) -> MonitorSummary {
        let mut e = self.errors_m.clone();
        e.sort_by(f64::total_cmp);
        let pct = |q: f64| -> Option<f64> {
            if e.is_empty() {
                return None;
            }
            let k = ((e.len() - 1) as f64 * q).round() as usize;
            e.get(k).copied()
        };
        MonitorSummary {
            messages: self.messages,
            without_geolocation: self.without_geolocation,
            out_of_scenario: self.out_of_scenario,
            false_tracks: self.false_tracks,
            matched: e.len() as u64,
            wrong_class: self.wrong_class,
            track_ids: self.track_ids.len(),
            error_median_m: pct(0.5),
            error_p95_m: pct(0.95),
            error_max_m: e.last().copied(),
            objects: self
                .ids
                .iter()
                .map(|(&object_id, (ids, latest))| ObjectIds {
                    object_id,
                    track_ids: ids.iter().copied().collect(),
                    latest_track_id: *latest,
                    final_track_ids: ids
                        .iter()
                        .map(|&id| self.final_id(id))
                        .collect::<BTreeSet<u32>>()
                        .into_iter()
                        .collect(),
                    error_max_m: self.worst_m.get(&object_id).map_or(0.0, |w| w.0),
                    error_max_tracked_m: self
                        .worst_m
                        .get(&object_id)
                        .map(|w| w.1)
                        .filter(|e| !e.is_nan()),
                    class: self
                        .classes
                        .get(&object_id)
                        .map_or("unknown", |c| c.0.name()),
                    classes_reported: self
                        .classes
                        .get(&object_id)
                        .map(|c| c.1.iter().map(|(&id, &n)| (category_name(id), n)).collect())
                        .unwrap_or_default(),
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    fn world() -> World {
        let s = Scenario::load("calm_baseline").unwrap();
        World::new(s, 7)
    }

    fn message(world: &World, t_s: f64, ned: [f64; 3], class: u32, id: u32) -> MGMOT_TRACK_DATA {
        let o = &world.scenario.origin;
        let frame =
            LocalTangentFrame::new(Geodetic::new(o.lat_deg, o.lon_deg, o.alt_amsl_m).unwrap());
        let g = frame.to_geodetic(&Vector3::from(ned));
        MGMOT_TRACK_DATA {
            time_usec: world.frame_stamp_us(t_s),
            track_id: id,
            lat: (g.lat_deg * 1e7).round() as i32,
            lon: (g.lon_deg * 1e7).round() as i32,
            alt: (g.alt_m * 1000.0).round() as i32,
            object_class: match class {
                1 => MgmotObjectClass::MGMOT_OBJECT_CLASS_SWIMMER,
                2 => MgmotObjectClass::MGMOT_OBJECT_CLASS_BOAT,
                3 => MgmotObjectClass::MGMOT_OBJECT_CLASS_JETSKI,
                4 => MgmotObjectClass::MGMOT_OBJECT_CLASS_LIFE_SAVING_APPLIANCE,
                5 => MgmotObjectClass::MGMOT_OBJECT_CLASS_BUOY,
                _ => MgmotObjectClass::MGMOT_OBJECT_CLASS_UNKNOWN,
            },
            flags: MgmotTrackFlags::MGMOT_TRACK_FLAGS_GEO_VALID,
            ..Default::default()
        }
    }

    #[test]
    fn a_report_at_a_true_object_matches_it_with_the_offset_as_error() {
        let w = world();
        let t = 3.0;
        let o = w.objects_at(t)[0];
        let class = o.class.category_id();
        let mut mon = TrackMonitor::new(&w).unwrap();
        let at = [o.pos_ned_m[0] + 1.5, o.pos_ned_m[1] - 2.0, 0.0];
        match mon.observe(&w, &message(&w, t, at, class, 9)) {
            TrackCheck::Matched {
                object_id,
                error_m,
                same_class,
                class: c,
            } => {
                assert_eq!(object_id, o.id);
                assert!(same_class);
                assert_eq!(c, o.class);
                assert!((error_m - 2.5).abs() < 0.01, "error {error_m}");
            }
            other => panic!("expected a match, got {other:?}"),
        }
        let s = mon.summary();
        assert_eq!((s.messages, s.matched, s.track_ids), (1, 1, 1));
        assert_eq!(s.objects[0].track_ids, vec![9]);
    }

    #[test]
    fn far_reports_invalid_geolocation_and_wrong_times_are_told_apart() {
        let w = world();
        let mut mon = TrackMonitor::new(&w).unwrap();
        let far = message(&w, 2.0, [5_000.0, 5_000.0, 0.0], 0, 1);
        assert!(matches!(
            mon.observe(&w, &far),
            TrackCheck::FalseTrack { nearest_m: Some(d) } if d > ASSOCIATION_GATE_M
        ));
        let mut no_geo = far.clone();
        no_geo.flags = MgmotTrackFlags::empty();
        assert_eq!(mon.observe(&w, &no_geo), TrackCheck::NoGeolocation);
        let mut late = far.clone();
        late.time_usec = w.frame_stamp_us(w.scenario.duration_s + 60.0);
        assert_eq!(mon.observe(&w, &late), TrackCheck::OutOfScenario);
        let s = mon.summary();
        assert_eq!(
            (
                s.messages,
                s.false_tracks,
                s.without_geolocation,
                s.out_of_scenario
            ),
            (3, 1, 1, 1)
        );
        assert_eq!(s.error_median_m, None);
    }

    #[test]
    fn an_object_reported_under_two_ids_lists_both() {
        let w = world();
        let o = w.objects_at(1.0)[0];
        let class = o.class.category_id();
        let mut mon = TrackMonitor::new(&w).unwrap();
        mon.observe(
            &w,
            &message(&w, 1.0, w.objects_at(1.0)[0].pos_ned_m, class, 4),
        );
        mon.observe(
            &w,
            &message(&w, 2.0, w.objects_at(2.0)[0].pos_ned_m, class, 11),
        );
        let s = mon.summary();
        assert_eq!(s.objects[0].track_ids, vec![4, 11]);
        assert_eq!(s.objects[0].latest_track_id, 11);
        assert_eq!(s.objects[0].final_track_ids, vec![4, 11]);
        assert!(s.error_max_m.unwrap() < 0.01);
    }

    #[test]
    fn each_objects_reported_classes_are_counted() {
        let w = world();
        let o = w.objects_at(1.0)[0];
        let own = o.class.category_id();
        let other = if own == 1 { 2 } else { 1 };
        let mut mon = TrackMonitor::new(&w).unwrap();
        for (t, class) in [(1.0, own), (2.0, own), (3.0, other), (4.0, 0)] {
            let at = w.objects_at(t)[0].pos_ned_m;
            mon.observe(&w, &message(&w, t, at, class, 4));
        }
        let s = mon.summary();
        // The unknown class is not counted as wrong: mgmot said nothing about it.
        assert_eq!((s.matched, s.wrong_class), (4, 1));
        assert_eq!(s.objects[0].class, o.class.name());
        let want = BTreeMap::from([
            (category_name(own), 2),
            (category_name(other), 1),
            ("unknown", 1),
        ]);
        assert_eq!(s.objects[0].classes_reported, want);
        assert_ne!(category_name(own), category_name(other));
    }

    #[test]
    fn merged_ids_resolve_to_the_old_one() {
        let w = world();
        let o = w.objects_at(1.0)[0];
        let class = o.class.category_id();
        let mut mon = TrackMonitor::new(&w).unwrap();
        mon.observe(&w, &message(&w, 1.0, o.pos_ned_m, class, 4));
        // Track 11 appears, then mgmot links it to 4 and chains 15 -> 11 -> 4.
        mon.observe(
            &w,
            &message(&w, 2.0, w.objects_at(2.0)[0].pos_ned_m, class, 11),
        );
        let mut merged = message(&w, 3.0, w.objects_at(3.0)[0].pos_ned_m, class, 4);
        merged.flags |= MgmotTrackFlags::MGMOT_TRACK_FLAGS_MERGED;
        merged.merged_from_id = 11;
        mon.observe(&w, &merged);
        mon.observe(
            &w,
            &message(&w, 4.0, w.objects_at(4.0)[0].pos_ned_m, class, 15),
        );
        let mut chained = message(&w, 5.0, w.objects_at(5.0)[0].pos_ned_m, class, 11);
        chained.flags |= MgmotTrackFlags::MGMOT_TRACK_FLAGS_MERGED;
        chained.merged_from_id = 15;
        mon.observe(&w, &chained);
        let s = mon.summary();
        assert_eq!(s.objects[0].track_ids, vec![4, 11, 15]);
        assert_eq!(s.objects[0].final_track_ids, vec![4]);
    }
}
