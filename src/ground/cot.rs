//! The fused picture as Cursor-on-Target: one event per fused track (uid
//! `mgmot.ground.<run tag>.<fused id>`, `how="m-f"`: machine, fused), the end of every fused
//! id a merge retired, and optionally the drones with their camera footprints. Pure: times come in, events go out.

use crate::cot::event::{delete_xml, event_xml, Detail, Envelope, Point, UNKNOWN};
use crate::cot::vehicle::{footprint_event, vehicle_event, VehicleFix, VehicleId};
use crate::cot::{CotMessage, TypesByClass};
use mgmot_core::digest::class_name;
use mgmot_core::fuse::{FusedTrack, FusedTrackState, Retired};

use super::geojson::FOOTPRINT_STALE_S;
use super::ingest::Drone;

/// The ground's CoT settings.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundCotSettings {
    /// How long an event stays valid (µs).
    pub stale_us: i64,
    /// Between two events of one track (µs).
    pub every_us: i64,
    /// CoT type by class.
    pub types: TypesByClass,
    /// The ground's callsign.
    pub callsign: String,
    /// A tag of this run, so ids from before a restart are not reused.
    pub run_tag: String,
    /// Also send the drones.
    pub drones: bool,
}

/// Turns pictures into events.
#[derive(Debug)]
pub struct GroundCot {
    settings: GroundCotSettings,
    last_sent_us: Option<i64>,
    /// The class each fused id was last sent as: a uid keeps one CoT type to its end.
    sent_class: std::collections::HashMap<u64, u32>,
}

impl GroundCot {
    /// Nothing sent yet.
    pub fn new(settings: GroundCotSettings) -> Self {
        Self {
            settings,
            last_sent_us: None,
            sent_class: std::collections::HashMap::new(),
        }
    }

    /// The ground's own uid: `mgmot.ground.<run tag>`.
    pub fn ground_uid(&self) -> String {
        format!("mgmot.ground.{}", self.settings.run_tag)
    }

    /// The uid of fused track `id`.
    pub fn track_uid(&self, id: u64) -> String {
        format!("{}.{id}", self.ground_uid())
    }

    /// The ground's identity event (the first of every stream connection; stale at once).
    pub fn identity(&self, now_us: i64) -> CotMessage {
        let uid = self.ground_uid();
        let detail = Detail::new()
            .element(
                "contact",
                &[("callsign", Some(self.settings.callsign.clone()))],
            )
            .element("mgmot", &[("role", Some("ground".to_owned()))])
            .into_xml();
        let xml = event_xml(
            &Envelope {
                uid: &uid,
                cot_type: "a-f-G-U-C",
                how: "m-g",
                time_us: now_us,
                start_us: now_us,
                stale_us: now_us,
                point: Point::unknown(),
            },
            &detail,
        );
        CotMessage {
            uid: uid.into(),
            xml: xml.into(),
        }
    }

    /// The events due at `now_us` (UTC µs): ends of retired ids at once (as the type they
    /// were last sent as; an id never sent needs no end), and every track and drone once per
    /// `every_us`.
    pub fn events<'a>(
        &mut self,
        tracks: &[FusedTrack],
        retired: &[Retired],
        drones: impl Iterator<Item = &'a Drone>,
        now_us: i64,
    ) -> Vec<CotMessage> {
        let mut out = Vec::new();
        for r in retired {
            let uid = self.track_uid(r.id);
            let Some(class_id) = self.sent_class.remove(&r.id) else {
                continue; // never sent: nothing to end on the map
            };
            let types = &self.settings.types;
            let cot_type = types.get(class_id as usize).unwrap_or(&types[0]);
            let into = self.track_uid(r.into);
            let detail = Detail::new()
                .element(
                    "mgmot",
                    &[
                        ("state", Some("retired".to_owned())),
                        ("merged_into", Some(into)),
                    ],
                )
                .into_xml();
            let xml = event_xml(
                &Envelope {
                    uid: &uid,
                    cot_type,
                    how: "m-f",
                    time_us: now_us,
                    start_us: now_us,
                    stale_us: now_us,
                    point: Point::unknown(),
                },
                &detail,
            );
            out.push(CotMessage {
                uid: uid.clone().into(),
                xml: xml.into(),
            });
            out.push(CotMessage {
                uid: uid.clone().into(),
                xml: delete_xml(&uid, &self.ground_uid(), now_us).into(),
            });
        }
        let due = self
            .last_sent_us
            .is_none_or(|t| now_us - t >= self.settings.every_us);
        if !due && retired.is_empty() {
            return out;
        }
        if due {
            self.last_sent_us = Some(now_us);
            for t in tracks {
                self.sent_class.insert(t.id, t.class_id);
                out.push(self.track(t, now_us));
            }
            if self.settings.drones {
                out.extend(drones.flat_map(|d| self.drone(d, now_us)));
            }
        }
        out
    }

    fn track(&self, t: &FusedTrack, now_us: i64) -> CotMessage {
        let uid = self.track_uid(t.id);
        let class = class_name(t.class_id);
        let members = t
            .members
            .iter()
            .map(|m| format!("{}:{}", m.system_id, m.track_id))
            .collect::<Vec<_>>()
            .join(" ");
        let last_seen_us = t.last_seen_s.map(|s| (s * 1e6) as i64);
        let speed = t.vel_ne_m_s.norm();
        let course = t
            .vel_ne_m_s
            .y
            .atan2(t.vel_ne_m_s.x)
            .to_degrees()
            .rem_euclid(360.0);
        let detail = Detail::new()
            .element(
                "contact",
                &[("callsign", Some(format!("{class} #{}", t.id)))],
            )
            .element(
                "mgmot",
                &[
                    ("class", Some(class.to_owned())),
                    ("class_id", Some(t.class_id.to_string())),
                    (
                        "state",
                        Some(match t.state {
                            FusedTrackState::Tracked => "tracked".to_owned(),
                            FusedTrackState::Lost => "lost".to_owned(),
                        }),
                    ),
                    ("fused_id", Some(t.id.to_string())),
                    ("members", Some(members)),
                    (
                        "last_seen",
                        last_seen_us.map(crate::cot::event::format_time),
                    ),
                ],
            )
            .element(
                "track",
                &[
                    ("course", Some(format!("{course:.1}"))),
                    ("speed", Some(format!("{speed:.2}"))),
                ],
            )
            .into_xml();
        let types = &self.settings.types;
        let cot_type = types.get(t.class_id as usize).unwrap_or(&types[0]);
        let xml = event_xml(
            &Envelope {
                uid: &uid,
                cot_type,
                how: "m-f",
                time_us: now_us,
                start_us: last_seen_us.unwrap_or(now_us).min(now_us),
                stale_us: now_us + self.settings.stale_us,
                point: Point {
                    lat_deg: t.lat_deg,
                    lon_deg: t.lon_deg,
                    hae_m: UNKNOWN,
                    ce_m: t.ce95_m,
                    le_m: UNKNOWN,
                },
            },
            &detail,
        );
        CotMessage {
            uid: uid.into(),
            xml: xml.into(),
        }
    }

    /// A drone's event, and its camera footprint while fresh.
    fn drone(&self, d: &Drone, now_us: i64) -> Vec<CotMessage> {
        let Some((lat, lon)) = d.position else {
            return Vec::new();
        };
        let uid = format!("{}.drone.{}", self.ground_uid(), d.system_id);
        let callsign = format!("drone {}", d.system_id);
        let id = VehicleId {
            uid: &uid,
            callsign: &callsign,
            system_id: d.system_id,
        };
        let fix = VehicleFix {
            lat_deg: lat,
            lon_deg: lon,
            alt_amsl_m: d.alt_m,
            heading_deg: d.heading_deg,
        };
        let mut out = vec![vehicle_event(
            id,
            Some(&fix),
            now_us,
            self.settings.stale_us,
        )];
        if let Some(at_s) = d.footprint_s.filter(|_| d.footprint.len() >= 3) {
            let at_us = (at_s * 1e6) as i64;
            if (now_us - at_us) as f64 <= FOOTPRINT_STALE_S * 1e6 {
                out.push(footprint_event(
                    id,
                    &d.footprint,
                    at_us,
                    now_us,
                    self.settings.stale_us,
                ));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mgmot_core::fuse::FusedMember;
    use nalgebra::{Matrix2, Vector2};

    fn track(id: u64, class_id: u32) -> FusedTrack {
        FusedTrack {
            id,
            class_id,
            state: FusedTrackState::Tracked,
            lat_deg: 54.18,
            lon_deg: 7.89,
            cov_m2: Matrix2::identity(),
            ce95_m: 2.4,
            vel_ne_m_s: Vector2::zeros(),
            last_seen_s: Some(1.0),
            members: vec![FusedMember {
                system_id: 1,
                track_id: 12,
                live: true,
                tracked: true,
            }],
            merged_from: Vec::new(),
        }
    }

    #[test]
    fn a_retired_id_ends_as_the_type_it_was_sent_as() {
        let mut c = GroundCot::new(GroundCotSettings {
            stale_us: 60_000_000,
            every_us: 1_000_000,
            types: crate::cot::default_types(),
            callsign: "ground".into(),
            run_tag: "T".into(),
            drones: false,
        });
        let sent = c.events(&[track(3, 2), track(4, 2)], &[], std::iter::empty(), 0);
        assert_eq!(sent.len(), 2);
        assert!(
            sent[0].xml.contains("uid=\"mgmot.ground.T.3\"") && sent[0].xml.contains("how=\"m-f\"")
        );
        assert!(sent[0].xml.contains("members=\"1:12\""));
        // 4 merged into 3 (sent), 9 into 3 (never sent: nothing to end).
        let retired = [Retired { id: 4, into: 3 }, Retired { id: 9, into: 3 }];
        let out = c.events(&[track(3, 2)], &retired, std::iter::empty(), 500_000);
        assert_eq!(out.len(), 2, "{out:?}");
        assert!(out[0].xml.contains("type=\"a-n-S-X\"") && out[0].xml.contains("merged_into"));
        assert!(out[1].xml.contains("t-x-d-d"));
    }
}
