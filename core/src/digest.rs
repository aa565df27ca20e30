//! What the operator gets when the autopilot's telemetry radio is the only way to the ground.
//!
//! An autopilot forwards only the messages its own dialect knows: ArduPilot drops MGMOT_TRACK
//! and TARGET_ABSOLUTE (seen in its SITL, upstream 90700977c5), so over its radio the operator
//! would see no track at all. STATUSTEXT passes, and every ground station shows it. The digest
//! turns the track reports into short texts (at most [`TEXT_LEN`] characters, one STATUSTEXT
//! each):
//! - a new object, once, when it is first geolocated: `mgmot new swimmer #12 47.672345,9.268012`;
//! - every period, a count by class (`mgmot 5 tracks: 3 swimmer, 2 boat`) and the latest
//!   position of up to `max_positions` of them, the most recently seen first
//!   (`mgmot #12 swimmer 47.672345,9.268012 4s ago`).
//!
//! A re-identified track keeps its announcement: the id it had is forgotten and the new one is
//! not announced again. Pure: times (the frames' autopilot times) are passed in.

use crate::report::TrackReport;
use std::collections::BTreeMap;

/// The longest text: STATUSTEXT's 50 characters.
pub const TEXT_LEN: usize = 50;

/// Class names by SeaDronesSee category id (MGMOT_OBJECT_CLASS).
const CLASSES: [&str; 6] = ["object", "swimmer", "boat", "jetski", "lifebuoy", "buoy"];

/// A track is dropped from the digest when it has not been reported for this long (µs).
const FORGET_US: u64 = 60_000_000;

/// How often and how much.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DigestSettings {
    /// Between two periodic digests (µs).
    pub every_us: u64,
    /// Positions listed per digest.
    pub max_positions: usize,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Seen {
    class_id: u32,
    /// Latest geolocated position (lat, lon in degrees) and when.
    position: Option<(f64, f64, u64)>,
    /// Latest report of any kind.
    last_us: u64,
}

/// The digest's memory of the tracks reported.
#[derive(Debug, Clone)]
pub struct Digest {
    settings: DigestSettings,
    tracks: BTreeMap<u64, Seen>,
    /// Ids whose "new" text was sent (or that continue one that was).
    announced: std::collections::BTreeSet<u64>,
    last_digest_us: Option<u64>,
}

impl Digest {
    /// Nothing reported yet.
    pub fn new(settings: DigestSettings) -> Self {
        Self {
            settings,
            tracks: BTreeMap::new(),
            announced: Default::default(),
            last_digest_us: None,
        }
    }

    /// Takes one track report; returns the "new object" text when this is the first
    /// geolocated report of an object. Provisional reports are ignored: the track may still
    /// turn out to be an object already announced.
    pub fn observe(&mut self, r: &TrackReport) -> Option<String> {
        if r.provisional {
            return None;
        }
        let now = r.time.0;
        if let Some(old) = r.merged_from_id {
            // The same object under its older id: keep what was said about it.
            if self.announced.remove(&old) {
                self.announced.insert(r.track_id);
            }
            self.tracks.remove(&old);
        }
        let position = r.geo.map(|g| (g.position.lat_deg, g.position.lon_deg, now));
        let seen = self.tracks.entry(r.track_id).or_insert(Seen {
            class_id: r.class_id,
            position: None,
            last_us: now,
        });
        seen.class_id = r.class_id;
        seen.last_us = now;
        if position.is_some() {
            seen.position = position;
        }
        let (lat, lon, _) = position?;
        self.announced.insert(r.track_id).then(|| {
            clip(format!(
                "mgmot new {} #{} {lat:.6},{lon:.6}",
                class_name(r.class_id),
                r.track_id
            ))
        })
    }

    /// The periodic texts due at autopilot time `now_us` (none before a period has passed
    /// since the last, or while nothing is tracked).
    pub fn due(&mut self, now_us: u64) -> Vec<String> {
        if self.last_digest_us.is_some_and(|t| now_us < t) {
            // The autopilot's clock went back (a reboot): restart the ages from now.
            for s in self.tracks.values_mut() {
                s.last_us = now_us;
                if let Some(p) = s.position.as_mut() {
                    p.2 = now_us;
                }
            }
            self.last_digest_us = None;
        }
        if self
            .last_digest_us
            .is_some_and(|t| now_us.saturating_sub(t) < self.settings.every_us)
        {
            return Vec::new();
        }
        self.tracks
            .retain(|_, s| now_us.saturating_sub(s.last_us) < FORGET_US);
        let announced = &mut self.announced;
        let tracks = &self.tracks;
        announced.retain(|id| tracks.contains_key(id));
        if self.tracks.is_empty() {
            return Vec::new();
        }
        self.last_digest_us = Some(now_us);
        let mut by_class: BTreeMap<u32, usize> = BTreeMap::new();
        for s in self.tracks.values() {
            *by_class.entry(s.class_id).or_default() += 1;
        }
        let counts: Vec<String> = by_class
            .iter()
            .map(|(c, n)| format!("{n} {}", class_name(*c)))
            .collect();
        let mut texts = vec![clip(format!(
            "mgmot {} tracks: {}",
            self.tracks.len(),
            counts.join(", ")
        ))];
        let mut latest: Vec<(u64, &Seen, (f64, f64, u64))> = self
            .tracks
            .iter()
            .filter_map(|(id, s)| Some((*id, s, s.position?)))
            .collect();
        latest.sort_by(|a, b| b.2 .2.cmp(&a.2 .2).then(a.0.cmp(&b.0)));
        texts.extend(latest.into_iter().take(self.settings.max_positions).map(
            |(id, s, (lat, lon, at))| {
                clip(format!(
                    "mgmot #{id} {} {lat:.6},{lon:.6} {}s ago",
                    class_name(s.class_id),
                    now_us.saturating_sub(at) / 1_000_000
                ))
            },
        ));
        texts
    }
}

fn class_name(id: u32) -> &'static str {
    CLASSES.get(id as usize).copied().unwrap_or(CLASSES[0])
}

/// At most [`TEXT_LEN`] characters (the texts are ASCII; a cut never splits a character).
fn clip(mut s: String) -> String {
    if s.len() > TEXT_LEN {
        let mut end = TEXT_LEN;
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        s.truncate(end);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::GeoFix;
    use crate::geo::Geodetic;
    use crate::telemetry::AutopilotTimeUs;

    fn report(id: u64, class_id: u32, t_s: f64, at: Option<(f64, f64)>) -> TrackReport {
        TrackReport {
            time: AutopilotTimeUs((t_s * 1e6) as u64),
            track_id: id,
            merged_from_id: None,
            class_id,
            confidence: 0.9,
            bbox_norm: [0.1, 0.1, 0.05, 0.05],
            tracked: true,
            geo: at.map(|(lat, lon)| GeoFix {
                position: Geodetic::new(lat, lon, 0.0).unwrap(),
                vel_n_mps: 0.0,
                vel_e_mps: 0.0,
                h_std_m: 1.0,
            }),
            provisional: false,
        }
    }

    const SETTINGS: DigestSettings = DigestSettings {
        every_us: 10_000_000,
        max_positions: 2,
    };

    #[test]
    fn a_new_object_is_announced_once_when_first_geolocated() {
        let mut d = Digest::new(SETTINGS);
        assert_eq!(d.observe(&report(3, 1, 1.0, None)), None, "no position yet");
        assert_eq!(
            d.observe(&report(3, 1, 1.5, Some((-35.3632611, 149.1652299)))),
            Some("mgmot new swimmer #3 -35.363261,149.165230".to_owned())
        );
        assert_eq!(d.observe(&report(3, 1, 2.0, Some((-35.36, 149.16)))), None);
    }

    #[test]
    fn a_reidentified_track_is_not_announced_again() {
        let mut d = Digest::new(SETTINGS);
        assert!(d.observe(&report(3, 1, 1.0, Some((47.0, 9.0)))).is_some());
        let mut merged = report(7, 1, 20.0, Some((47.0, 9.0)));
        merged.merged_from_id = Some(3);
        assert_eq!(d.observe(&merged), None);
        let texts = d.due(20_000_000);
        assert_eq!(texts[0], "mgmot 1 tracks: 1 swimmer", "{texts:?}");
    }

    #[test]
    fn the_digest_counts_by_class_and_lists_the_latest_positions() {
        let mut d = Digest::new(SETTINGS);
        assert!(d.due(0).is_empty(), "nothing tracked: nothing said");
        d.observe(&report(1, 1, 1.0, Some((47.1, 9.1))));
        d.observe(&report(2, 2, 2.0, Some((47.2, 9.2))));
        d.observe(&report(4, 1, 3.0, Some((47.4, 9.4))));
        d.observe(&report(5, 1, 3.5, None));
        let texts = d.due(5_000_000);
        assert_eq!(
            texts,
            vec![
                "mgmot 4 tracks: 3 swimmer, 1 boat".to_owned(),
                "mgmot #4 swimmer 47.400000,9.400000 2s ago".to_owned(),
                "mgmot #2 boat 47.200000,9.200000 3s ago".to_owned(),
            ]
        );
        assert!(d.due(14_000_000).is_empty(), "within the period");
        assert_eq!(d.due(15_000_000).len(), 3);
        // A minute without reports: forgotten.
        assert!(d.due(70_000_000).is_empty());
    }

    #[test]
    fn a_clock_that_goes_back_does_not_stop_the_digest() {
        let mut d = Digest::new(SETTINGS);
        d.observe(&report(1, 1, 100.0, Some((47.1, 9.1))));
        assert_eq!(d.due(100_000_000).len(), 2);
        // The autopilot rebooted: its clock restarts near 0.
        assert_eq!(d.due(5_000_000).len(), 2, "due at once after the jump back");
        assert!(d.due(6_000_000).is_empty());
        assert_eq!(d.due(15_000_000).len(), 2);
    }

    #[test]
    fn every_text_fits_a_statustext() {
        let mut d = Digest::new(DigestSettings {
            every_us: 1,
            max_positions: 10,
        });
        let big = u64::MAX / 3;
        let text = d
            .observe(&report(big, 99, 1.0, Some((-89.999999, -179.999999))))
            .unwrap();
        assert!(text.len() <= TEXT_LEN, "{text}");
        for t in d.due(2_000_000) {
            assert!(t.len() <= TEXT_LEN, "{t}");
        }
    }
}
