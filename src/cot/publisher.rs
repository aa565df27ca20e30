//! Which Cursor-on-Target events one frame's tracks make: one event per geolocated track at
//! the configured rate, the end of a uid the tracker retired (an online ReID merge), and the
//! vehicle itself. Pure: the clocks come in as numbers, events go out as [`CotMessage`]s.

use super::event::{delete_xml, event_xml, Detail, Envelope, Point, UNKNOWN};
use super::vehicle::{footprint_event, vehicle_event, VehicleFix, VehicleId};
use crate::digest::class_name;
use crate::report::TrackReport;
use crate::track::MergeEvent;
use std::collections::HashMap;
use std::sync::Arc;

/// The CoT types by SeaDronesSee class id (index 0: an unknown class).
pub type TypesByClass = [String; 6];

/// The default CoT type of each class (index = SeaDronesSee class id, 0 unknown): a person in
/// the water as a neutral ground point (TAK draws it as a plain marker labelled with the
/// callsign, which names the class), craft as neutral non-military surface vessels, life
/// rings and buoys as unknown surface objects. `[outputs.cot.types]` overrides them.
pub fn default_types() -> TypesByClass {
    [
        "a-u-G".into(),   // object (unknown class)
        "a-n-G".into(),   // swimmer
        "a-n-S-X".into(), // boat
        "a-n-S-X".into(), // jetski
        "a-u-S".into(),   // life-saving appliance
        "a-u-S".into(),   // buoy
    ]
}

/// The CoT type of the drone itself: friendly, air, military, rotary wing, drone (UAV).
pub const VEHICLE_TYPE: &str = "a-f-A-M-H-Q";

/// What the publisher needs to know besides the tracks.
#[derive(Debug, Clone, PartialEq)]
pub struct PublisherSettings {
    /// Between two events of one track (µs).
    pub every_us: u64,
    /// How long an event stays valid (µs).
    pub stale_us: i64,
    /// CoT type per class.
    pub types: TypesByClass,
    /// The vehicle's MAVLink system id (part of every uid).
    pub system_id: u8,
    /// The vehicle's callsign on the map.
    pub callsign: String,
    /// A tag of this run (its start time), so ids from before a restart are not reused.
    pub run_tag: String,
}

/// One event ready to send: the uid it updates (a transport that has to wait keeps only the
/// latest event per uid) and its XML.
#[derive(Debug, Clone, PartialEq)]
pub struct CotMessage {
    /// The uid the event is about.
    pub uid: Arc<str>,
    /// The whole event.
    pub xml: Arc<str>,
}

/// The clocks of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CotClock {
    /// The tracker's clock (µs): what the rate is measured on.
    pub tracker_us: u64,
    /// When the frame was exposed, UTC (µs since the epoch).
    pub observed_unix_us: i64,
    /// Now, UTC (µs since the epoch).
    pub now_unix_us: i64,
}

#[derive(Debug, Clone)]
struct Published {
    last_sent_us: u64,
    last_seen_unix_us: i64,
    last_event: Option<(Point, u32)>,
}

/// The per-track state of the CoT output.
#[derive(Debug)]
pub struct CotPublisher {
    settings: PublisherSettings,
    tracks: HashMap<u64, Published>,
    vehicle_last_sent_us: Option<u64>,
}

impl CotPublisher {
    /// A publisher with nothing published yet.
    pub fn new(settings: PublisherSettings) -> Self {
        Self {
            settings,
            tracks: HashMap::new(),
            vehicle_last_sent_us: None,
        }
    }

    /// The uid of track `id`: `mgmot.<system id>.<run tag>.<track id>`.
    pub fn track_uid(&self, id: u64) -> String {
        format!("{}.{id}", self.vehicle_uid())
    }

    /// The vehicle's uid: `mgmot.<system id>.<run tag>`.
    pub fn vehicle_uid(&self) -> String {
        format!(
            "mgmot.{}.{}",
            self.settings.system_id, self.settings.run_tag
        )
    }

    /// The events of one frame: `reports` are the tracker's reported tracks (confirmed and
    /// coasting), `merges` the ReID decisions of the frame. A merged-away id's uid is ended
    /// (an event that is stale at once, then a delete); the id it became is sent at once.
    pub fn frame(
        &mut self,
        reports: &[TrackReport],
        merges: &[MergeEvent],
        clock: CotClock,
    ) -> Vec<CotMessage> {
        let mut out = Vec::new();
        for m in merges {
            if let Some(p) = self.tracks.remove(&m.new_id) {
                out.extend(self.retire(m.new_id, m.merged_into_id, &p, clock));
            }
            // The id it now carries is due at once.
            if let Some(p) = self.tracks.get_mut(&m.merged_into_id) {
                p.last_sent_us = 0;
            }
        }
        for r in reports {
            let Some(geo) = r.geo else { continue };
            let entry = self.tracks.entry(r.track_id).or_insert(Published {
                last_sent_us: 0,
                last_seen_unix_us: clock.observed_unix_us,
                last_event: None,
            });
            if r.tracked {
                entry.last_seen_unix_us = clock.observed_unix_us;
            }
            let due = entry.last_event.is_none()
                || clock.tracker_us.saturating_sub(entry.last_sent_us) >= self.settings.every_us
                || r.merged_from_id.is_some();
            if !due {
                continue;
            }
            entry.last_sent_us = clock.tracker_us;
            let point = Point {
                lat_deg: geo.position.lat_deg,
                lon_deg: geo.position.lon_deg,
                hae_m: UNKNOWN,
                ce_m: geo.ce95_m,
                le_m: UNKNOWN,
            };
            entry.last_event = Some((point, r.class_id));
            let last_seen = entry.last_seen_unix_us;
            let state = if !r.tracked {
                "coasting"
            } else if r.provisional {
                "provisional"
            } else {
                "tracked"
            };
            let speed = geo.vel_n_mps.hypot(geo.vel_e_mps);
            let course = geo
                .vel_e_mps
                .atan2(geo.vel_n_mps)
                .to_degrees()
                .rem_euclid(360.0);
            let extra = [
                ("score", Some(format!("{:.2}", r.confidence))),
                ("merged_from", r.merged_from_id.map(|id| self.track_uid(id))),
            ];
            let detail = self
                .track_detail(r.track_id, r.class_id, state, last_seen, &extra)
                .element(
                    "track",
                    &[
                        ("course", Some(format!("{course:.1}"))),
                        ("speed", Some(format!("{speed:.2}"))),
                    ],
                )
                .into_xml();
            out.push(self.message(r.track_id, &point, r.class_id, detail, clock, false));
        }
        // Forget what has been stale for a while (a flight sees thousands of ids).
        let forget_before = clock.observed_unix_us - 2 * self.settings.stale_us;
        self.tracks
            .retain(|_, p| p.last_seen_unix_us >= forget_before);
        out
    }

    /// The vehicle's own event when due (at the track rate), and its camera footprint when
    /// `footprint` has at least three points (lat, lon in degrees, a ring as
    /// `geo::FrameGeometry::footprint` gives it).
    pub fn vehicle(
        &mut self,
        fix: &VehicleFix,
        footprint: &[(f64, f64)],
        clock: CotClock,
    ) -> Vec<CotMessage> {
        let due = self
            .vehicle_last_sent_us
            .is_none_or(|at| clock.tracker_us.saturating_sub(at) >= self.settings.every_us);
        if !due {
            return Vec::new();
        }
        self.vehicle_last_sent_us = Some(clock.tracker_us);
        let mut out = vec![self.vehicle_message(Some(fix), clock.now_unix_us)];
        if footprint.len() >= 3 {
            out.push(self.footprint_message(footprint, clock));
        }
        out
    }

    fn vehicle_id<'a>(&'a self, uid: &'a str) -> VehicleId<'a> {
        VehicleId {
            uid,
            callsign: &self.settings.callsign,
            system_id: self.settings.system_id,
        }
    }

    /// The camera footprint (see [`footprint_event`]).
    fn footprint_message(&self, ring: &[(f64, f64)], clock: CotClock) -> CotMessage {
        let uid = self.vehicle_uid();
        footprint_event(
            self.vehicle_id(&uid),
            ring,
            clock.observed_unix_us,
            clock.now_unix_us,
            self.settings.stale_us,
        )
    }

    /// The vehicle's event at `now_unix_us`; without a fix it is an identity only (at 0, 0
    /// with unknown errors, stale at once), which a TAK server takes as the connection's
    /// identity.
    pub fn vehicle_message(&self, fix: Option<&VehicleFix>, now_unix_us: i64) -> CotMessage {
        let uid = self.vehicle_uid();
        vehicle_event(
            self.vehicle_id(&uid),
            fix,
            now_unix_us,
            self.settings.stale_us,
        )
    }

    /// The common detail of a track's events; `extra` are more attributes of `<mgmot>`.
    fn track_detail(
        &self,
        id: u64,
        class_id: u32,
        state: &str,
        last_seen_us: i64,
        extra: &[(&str, Option<String>)],
    ) -> Detail {
        let class = class_name(class_id);
        let mut attributes = vec![
            ("class", Some(class.to_owned())),
            ("class_id", Some(class_id.to_string())),
            ("state", Some(state.to_owned())),
            ("last_seen", Some(super::event::format_time(last_seen_us))),
            ("vehicle", Some(self.settings.callsign.clone())),
            ("system_id", Some(self.settings.system_id.to_string())),
            ("track_id", Some(id.to_string())),
        ];
        attributes.extend(extra.iter().cloned());
        Detail::new()
            .element(
                "contact",
                &[(
                    "callsign",
                    Some(format!("{class} {id} ({})", self.settings.callsign)),
                )],
            )
            .element(
                "link",
                &[
                    ("uid", Some(self.vehicle_uid())),
                    ("type", Some(VEHICLE_TYPE.to_owned())),
                    ("relation", Some("p-p".to_owned())),
                ],
            )
            .element("mgmot", &attributes)
    }

    /// A track event; `ended`: stale at once (the uid is retired).
    fn message(
        &self,
        id: u64,
        point: &Point,
        class_id: u32,
        detail: String,
        clock: CotClock,
        ended: bool,
    ) -> CotMessage {
        let uid = self.track_uid(id);
        let stale_us = if ended {
            clock.now_unix_us
        } else {
            clock.now_unix_us + self.settings.stale_us
        };
        let cot_type = &self.settings.types[(class_id as usize).min(5)];
        let xml = event_xml(
            &Envelope {
                uid: &uid,
                cot_type,
                how: "m-i",
                time_us: clock.now_unix_us,
                start_us: clock.observed_unix_us.min(clock.now_unix_us),
                stale_us,
                point: *point,
            },
            &detail,
        );
        CotMessage {
            uid: uid.into(),
            xml: xml.into(),
        }
    }

    /// The end of a retired uid: its last position, stale at once, then a delete.
    fn retire(&self, id: u64, into: u64, p: &Published, clock: CotClock) -> Vec<CotMessage> {
        let Some((point, class_id)) = p.last_event else {
            return Vec::new();
        };
        let extra = [("merged_into", Some(self.track_uid(into)))];
        let detail = self
            .track_detail(id, class_id, "retired", p.last_seen_unix_us, &extra)
            .into_xml();
        let ended = self.message(id, &point, class_id, detail, clock, true);
        let uid = self.track_uid(id);
        let delete = CotMessage {
            uid: uid.clone().into(),
            xml: delete_xml(&uid, &self.vehicle_uid(), clock.now_unix_us).into(),
        };
        vec![ended, delete]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::GeoFix;
    use crate::geo::Geodetic;
    use crate::telemetry::AutopilotTimeUs;

    fn settings() -> PublisherSettings {
        PublisherSettings {
            every_us: 1_000_000,
            stale_us: 60_000_000,
            types: default_types(),
            system_id: 7,
            callsign: "mgmot-7".into(),
            run_tag: "20261206T153000".into(),
        }
    }

    fn report(id: u64, class_id: u32, tracked: bool) -> TrackReport {
        TrackReport {
            time: AutopilotTimeUs(0),
            track_id: id,
            merged_from_id: None,
            class_id,
            confidence: 0.9,
            bbox_norm: [0.1, 0.1, 0.05, 0.05],
            tracked,
            geo: Some(GeoFix {
                position: Geodetic::new(47.5, 9.25, 0.0).unwrap(),
                vel_n_mps: 0.0,
                vel_e_mps: 1.0,
                h_std_m: 1.0,
                ce95_m: 1.73,
            }),
            provisional: false,
        }
    }

    fn clock(t_s: f64) -> CotClock {
        let us = (t_s * 1e6) as i64;
        CotClock {
            tracker_us: us as u64,
            observed_unix_us: 1_796_571_000_000_000 + us - 100_000,
            now_unix_us: 1_796_571_000_000_000 + us,
        }
    }

    #[test]
    fn one_event_per_track_at_the_rate_with_a_stable_uid() {
        let mut p = CotPublisher::new(settings());
        let mut uids = Vec::new();
        for i in 0..30 {
            for m in p.frame(&[report(3, 1, true)], &[], clock(f64::from(i) / 10.0)) {
                uids.push(m.uid.to_string());
                assert!(m.xml.contains("type=\"a-n-G\""));
                assert!(m.xml.contains("ce=\"1.7\""));
                assert!(m.xml.contains("state=\"tracked\""));
                assert!(m.xml.contains("course=\"90.0\""), "{}", m.xml);
            }
        }
        // 3 s at 1 Hz: t = 0, 1, 2.
        assert_eq!(uids, vec!["mgmot.7.20261206T153000.3"; 3]);
    }

    #[test]
    fn a_track_without_a_position_makes_no_event() {
        let mut p = CotPublisher::new(settings());
        let mut r = report(3, 2, true);
        r.geo = None;
        assert!(p.frame(&[r], &[], clock(0.0)).is_empty());
    }

    #[test]
    fn a_merged_away_uid_is_ended_and_the_survivor_is_sent_at_once() {
        let mut p = CotPublisher::new(settings());
        p.frame(&[report(1, 1, true), report(9, 1, true)], &[], clock(0.0));
        let mut survivor = report(1, 1, true);
        survivor.merged_from_id = Some(9);
        let merge = MergeEvent {
            new_id: 9,
            merged_into_id: 1,
            frame_index: 5,
        };
        let out = p.frame(&[survivor], &[merge], clock(0.2));
        let kinds: Vec<(&str, bool)> = out
            .iter()
            .map(|m| (&*m.uid, m.xml.contains("t-x-d-d")))
            .collect();
        assert_eq!(
            kinds,
            vec![
                ("mgmot.7.20261206T153000.9", false),
                ("mgmot.7.20261206T153000.9", true),
                ("mgmot.7.20261206T153000.1", false),
            ]
        );
        let ended = &out[0].xml;
        assert!(ended.contains("state=\"retired\""));
        assert!(ended.contains("merged_into=\"mgmot.7.20261206T153000.1\""));
        // Stale at once: stale == time.
        let time = attr(ended, "time");
        assert_eq!(time, attr(ended, "stale"));
        assert!(out[2]
            .xml
            .contains("merged_from=\"mgmot.7.20261206T153000.9\""));
    }

    #[test]
    fn a_coasting_track_keeps_its_last_seen_time() {
        let mut p = CotPublisher::new(settings());
        p.frame(&[report(4, 5, true)], &[], clock(0.0));
        let out = p.frame(&[report(4, 5, false)], &[], clock(1.5));
        assert_eq!(out.len(), 1);
        assert!(out[0].xml.contains("state=\"coasting\""));
        assert!(
            out[0]
                .xml
                .contains("last_seen=\"2026-12-06T15:29:59.900Z\""),
            "{}",
            out[0].xml
        );
        assert!(out[0].xml.contains("type=\"a-u-S\""));
    }

    #[test]
    fn the_vehicle_is_sent_at_the_rate_and_an_identity_without_a_fix_is_stale() {
        let mut p = CotPublisher::new(settings());
        let fix = VehicleFix {
            lat_deg: 47.5,
            lon_deg: 9.25,
            alt_amsl_m: 60.0,
            heading_deg: Some(-90.0),
        };
        let ring = [(47.5, 9.25), (47.5, 9.26), (47.49, 9.26), (47.49, 9.25)];
        assert_eq!(p.vehicle(&fix, &ring, clock(0.0)).len(), 2);
        assert!(p.vehicle(&fix, &ring, clock(0.5)).is_empty());
        let out = p.vehicle(&fix, &[], clock(1.0));
        assert_eq!(out.len(), 1, "no footprint without a ring");
        let m = &out[0];
        assert!(m.xml.contains("type=\"a-f-A-M-H-Q\""));
        assert!(m.xml.contains("course=\"270.0\""));
        let f = &p.vehicle(&fix, &ring, clock(2.0))[1];
        assert_eq!(&*f.uid, "mgmot.7.20261206T153000.footprint");
        assert!(f.xml.contains("type=\"u-d-f\""));
        // Closed: five points, the first repeated.
        assert_eq!(f.xml.matches("<link point=").count(), 5);
        assert!(
            f.xml
                .contains("<point lat=\"47.4950000\" lon=\"9.2550000\""),
            "{}",
            f.xml
        );
        let id = p.vehicle_message(None, 5);
        assert_eq!(attr(&id.xml, "time"), attr(&id.xml, "stale"));
    }

    fn attr(xml: &str, name: &str) -> String {
        let key = format!(" {name}=\"");
        let start = xml.find(&key).unwrap() + key.len();
        xml[start..start + xml[start..].find('"').unwrap()].to_owned()
    }
}
