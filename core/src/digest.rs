//! What the operator gets when the autopilot's telemetry radio is the only way to the ground.
//!
//! An autopilot forwards only the messages its own dialect knows: ArduPilot drops MGMOT_TRACK
//! and TARGET_ABSOLUTE (seen in its SITL, upstream 90700977c5), so over its radio the operator
//! would see no track at all. STATUSTEXT passes, and every ground station shows it. The digest
//! turns the track reports into short texts (at most [`TEXT_LEN`] characters, one STATUSTEXT
//! each):
//! - a new object, once, when it is first seen with a position:
//!   `mgmot new swimmer #12 47.672345,9.268012`;
//! - every period, a count by class (`mgmot 5 tracks: 3 swimmer, 2 boat`) and the latest
//!   position of up to `max_positions` of them, the most recently seen first
//!   (`mgmot #12 swimmer 47.672345,9.268012 4s ago`).
//!
//! An id is announced once in a flight: a re-identified track keeps its announcement (the id
//! it had is dropped and the old id it carries now is not announced again), and an object
//! re-found under its old id after the digest forgot it (a minute unreported) is not announced
//! again either. A position is where the object was last *seen* (a report that matched a
//! detection): the filters' predictions while a track coasts are not listed as positions, so
//! "4s ago" is the time since the object was last in sight.
//!
//! Pure: the caller passes its time, on a clock that never goes back or restarts (not the
//! autopilot's, which restarts at a reboot): every age is measured on it.

use crate::report::TrackReport;
use std::collections::{BTreeMap, BTreeSet};

/// The longest text: STATUSTEXT's 50 characters.
pub const TEXT_LEN: usize = 50;

/// Class names by SeaDronesSee category id (MGMOT_OBJECT_CLASS).
const CLASSES: [&str; 6] = ["object", "swimmer", "boat", "jetski", "lifebuoy", "buoy"];

/// A track is dropped from the digest when it has not been reported for this long (µs).
const FORGET_US: u64 = 60_000_000;

/// The most announced ids remembered (a few hundred kB at most). A flight sees thousands of
/// track ids, far fewer of them geolocated objects; beyond this the lowest ids (the tracker
/// hands ids out in increasing order, so the objects announced first) are forgotten, and only
/// such an object, re-found after that many others, could be announced a second time.
pub const MAX_ANNOUNCED: usize = 1 << 16;

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
    /// Latest position seen (lat, lon in degrees) and when (caller's clock, µs).
    position: Option<(f64, f64, u64)>,
    /// Latest report of any kind (caller's clock, µs).
    last_us: u64,
}

/// The digest's memory of the tracks reported.
#[derive(Debug, Clone)]
pub struct Digest {
    settings: DigestSettings,
    tracks: BTreeMap<u64, Seen>,
    /// Ids whose "new" text was sent (or that continue one that was), for the whole flight
    /// (at most [`MAX_ANNOUNCED`]).
    announced: BTreeSet<u64>,
    last_digest_us: Option<u64>,
}

impl Digest {
    /// Nothing reported yet.
    pub fn new(settings: DigestSettings) -> Self {
        Self {
            settings,
            tracks: BTreeMap::new(),
            announced: BTreeSet::new(),
            last_digest_us: None,
        }
    }

    /// Takes one track report, observed at `now_us` (the caller's clock, which never goes
    /// back); returns the "new object" text when this is the first report of an object seen
    /// with a position. Provisional reports are ignored: the track may still turn out to be
    /// an object already announced.
    pub fn observe(&mut self, r: &TrackReport, now_us: u64) -> Option<String> {
        if r.provisional {
            return None;
        }
        if let Some(old) = r.merged_from_id {
            // The same object under its older id: keep what was said about it. The id it had
            // is never reported again.
            if self.announced.remove(&old) {
                self.remember_announced(r.track_id);
            }
            self.tracks.remove(&old);
        }
        // A coasting report's position is the filters' prediction, not a sighting.
        let position = r
            .geo
            .filter(|_| r.tracked)
            .map(|g| (g.position.lat_deg, g.position.lon_deg, now_us));
        let seen = self.tracks.entry(r.track_id).or_insert(Seen {
            class_id: r.class_id,
            position: None,
            last_us: now_us,
        });
        seen.class_id = r.class_id;
        seen.last_us = now_us;
        if position.is_some() {
            seen.position = position;
        }
        let (lat, lon, _) = position?;
        self.remember_announced(r.track_id).then(|| {
            clip(format!(
                "mgmot new {} #{} {lat:.6},{lon:.6}",
                class_name(r.class_id),
                r.track_id
            ))
        })
    }

    /// Marks `id` announced; `false` if it was already. Keeps at most [`MAX_ANNOUNCED`] ids.
    fn remember_announced(&mut self, id: u64) -> bool {
        let fresh = self.announced.insert(id);
        while self.announced.len() > MAX_ANNOUNCED {
            self.announced.pop_first();
        }
        fresh
    }

    /// The periodic texts due at `now_us` (the caller's clock, which never goes back; none
    /// before a period has passed since the last, or while nothing is tracked).
    pub fn due(&mut self, now_us: u64) -> Vec<String> {
        if self
            .last_digest_us
            .is_some_and(|t| now_us.saturating_sub(t) < self.settings.every_us)
        {
            return Vec::new();
        }
        self.tracks
            .retain(|_, s| now_us.saturating_sub(s.last_us) < FORGET_US);
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

/// The short name of a SeaDronesSee class id ("object" for an id outside 1..=5), as the
/// digest and the Cursor-on-Target callsigns write it.
pub fn class_name(id: u32) -> &'static str {
    CLASSES.get(id as usize).copied().unwrap_or(CLASSES[0])
}

/// A position read back from a digest text (what a ground station that only gets STATUSTEXT
/// can use): the `new` announcement or a periodic position line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DigestPosition {
    /// Track id.
    pub track_id: u64,
    /// Class id (SeaDronesSee numbering; 0 for a name this digest does not write).
    pub class_id: u32,
    /// Latitude (degrees).
    pub lat_deg: f64,
    /// Longitude (degrees).
    pub lon_deg: f64,
    /// How long before the text was sent the object was seen there (s; 0 for `new`).
    pub age_s: f64,
}

/// Reads a digest text back: `mgmot new swimmer #12 47.672345,9.268012` or
/// `mgmot #12 swimmer 47.672345,9.268012 4s ago`; `None` for anything else (the count line,
/// other STATUSTEXTs, a text cut short).
pub fn parse_text(text: &str) -> Option<DigestPosition> {
    let words: Vec<&str> = text.split_whitespace().collect();
    let (id, class, position, age_s) = match words.as_slice() {
        ["mgmot", "new", class, id, position] => (*id, *class, *position, 0.0),
        ["mgmot", id, class, position, age, "ago"] => {
            let age_s: f64 = age.strip_suffix('s')?.parse().ok()?;
            (*id, *class, *position, age_s)
        }
        _ => return None,
    };
    let track_id = id.strip_prefix('#')?.parse().ok()?;
    let (lat, lon) = position.split_once(',')?;
    let (lat_deg, lon_deg): (f64, f64) = (lat.parse().ok()?, lon.parse().ok()?);
    let valid = lat_deg.is_finite()
        && lon_deg.is_finite()
        && (-90.0..=90.0).contains(&lat_deg)
        && (-180.0..=180.0).contains(&lon_deg)
        && age_s >= 0.0;
    valid.then(|| DigestPosition {
        track_id,
        class_id: CLASSES
            .iter()
            .position(|c| *c == class)
            .map_or(0, |i| i as u32),
        lat_deg,
        lon_deg,
        age_s,
    })
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
                ce95_m: 1.73,
            }),
            provisional: false,
        }
    }

    const SETTINGS: DigestSettings = DigestSettings {
        every_us: 10_000_000,
        max_positions: 2,
    };

    /// Observes `r` at its own time (for the tests where the caller's clock and the
    /// autopilot's agree).
    fn observe(d: &mut Digest, r: &TrackReport) -> Option<String> {
        d.observe(r, r.time.0)
    }

    #[test]
    fn a_new_object_is_announced_once_when_first_geolocated() {
        let mut d = Digest::new(SETTINGS);
        assert_eq!(
            observe(&mut d, &report(3, 1, 1.0, None)),
            None,
            "no position yet"
        );
        assert_eq!(
            observe(&mut d, &report(3, 1, 1.5, Some((-35.3632611, 149.1652299)))),
            Some("mgmot new swimmer #3 -35.363261,149.165230".to_owned())
        );
        assert_eq!(
            observe(&mut d, &report(3, 1, 2.0, Some((-35.36, 149.16)))),
            None
        );
    }

    #[test]
    fn a_reidentified_track_is_not_announced_again() {
        let mut d = Digest::new(SETTINGS);
        assert!(observe(&mut d, &report(3, 1, 1.0, Some((47.0, 9.0)))).is_some());
        let mut merged = report(7, 1, 20.0, Some((47.0, 9.0)));
        merged.merged_from_id = Some(3);
        assert_eq!(observe(&mut d, &merged), None);
        let texts = d.due(20_000_000);
        assert_eq!(texts[0], "mgmot 1 tracks: 1 swimmer", "{texts:?}");
    }

    #[test]
    fn an_object_refound_after_a_minute_is_not_announced_again() {
        let mut d = Digest::new(SETTINGS);
        assert!(observe(&mut d, &report(12, 1, 1.0, Some((47.0, 9.0)))).is_some());
        assert_eq!(d.due(1_000_000).len(), 2);
        // Out of sight for 90 s: the digest forgets it...
        assert!(d.due(91_000_000).is_empty());
        // ...and ReID brings it back under its old id.
        let mut back = report(12, 1, 92.0, Some((47.001, 9.001)));
        back.merged_from_id = Some(40);
        assert_eq!(observe(&mut d, &back), None, "#12 was announced at 1 s");
        assert_eq!(d.due(92_000_000)[0], "mgmot 1 tracks: 1 swimmer");
        // Its new id, once announced, hands the announcement over too.
        assert!(observe(&mut d, &report(41, 2, 93.0, Some((47.1, 9.1)))).is_some());
        assert!(d.due(200_000_000).is_empty());
        let mut boat = report(5, 2, 201.0, Some((47.1, 9.1)));
        boat.merged_from_id = Some(41);
        assert_eq!(observe(&mut d, &boat), None, "#41 was announced at 93 s");
    }

    #[test]
    fn the_announced_ids_are_bounded() {
        let mut d = Digest::new(SETTINGS);
        let n = MAX_ANNOUNCED as u64 + 10;
        for id in 1..=n {
            assert!(observe(&mut d, &report(id, 1, id as f64, Some((47.0, 9.0)))).is_some());
        }
        assert_eq!(d.announced.len(), MAX_ANNOUNCED);
        // The latest ids are still known; the first ones gave way.
        assert_eq!(
            observe(&mut d, &report(n, 1, n as f64, Some((47.0, 9.0)))),
            None
        );
        assert!(observe(&mut d, &report(1, 1, n as f64, Some((47.0, 9.0)))).is_some());
    }

    #[test]
    fn the_digest_counts_by_class_and_lists_the_latest_positions() {
        let mut d = Digest::new(SETTINGS);
        assert!(d.due(0).is_empty(), "nothing tracked: nothing said");
        observe(&mut d, &report(1, 1, 1.0, Some((47.1, 9.1))));
        observe(&mut d, &report(2, 2, 2.0, Some((47.2, 9.2))));
        observe(&mut d, &report(4, 1, 3.0, Some((47.4, 9.4))));
        observe(&mut d, &report(5, 1, 3.5, None));
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
    fn ages_go_on_across_an_autopilot_reboot() {
        let mut d = Digest::new(SETTINGS);
        // Seen at autopilot time 100 s, 100 s into the caller's clock.
        d.observe(&report(1, 1, 100.0, Some((47.1, 9.1))), 100_000_000);
        assert_eq!(d.due(100_000_000).len(), 2);
        // The autopilot reboots; 20 s later its clock reads 20 s, the caller's 120 s, and
        // nothing has been seen since.
        assert_eq!(
            d.due(120_000_000),
            vec![
                "mgmot 1 tracks: 1 swimmer".to_owned(),
                "mgmot #1 swimmer 47.100000,9.100000 20s ago".to_owned(),
            ]
        );
        // A report stamped on the restarted autopilot clock is aged on the caller's.
        d.observe(&report(2, 2, 25.0, Some((47.2, 9.2))), 125_000_000);
        assert_eq!(
            d.due(130_000_000)[1..],
            [
                "mgmot #2 boat 47.200000,9.200000 5s ago".to_owned(),
                "mgmot #1 swimmer 47.100000,9.100000 30s ago".to_owned(),
            ]
        );
    }

    #[test]
    fn a_coasting_track_keeps_the_position_it_was_last_seen_at() {
        let mut d = Digest::new(SETTINGS);
        observe(&mut d, &report(1, 1, 1.0, Some((47.1, 9.1))));
        // Not detected: the report's position is the filters' prediction.
        let mut coasting = report(1, 1, 4.0, Some((47.2, 9.2)));
        coasting.tracked = false;
        observe(&mut d, &coasting);
        assert_eq!(
            d.due(5_000_000),
            vec![
                "mgmot 1 tracks: 1 swimmer".to_owned(),
                "mgmot #1 swimmer 47.100000,9.100000 4s ago".to_owned(),
            ]
        );
        // A track first reported while coasting is not announced from a prediction.
        let mut new_coasting = report(2, 1, 6.0, Some((47.3, 9.3)));
        new_coasting.tracked = false;
        assert_eq!(observe(&mut d, &new_coasting), None);
        assert!(observe(&mut d, &report(2, 1, 7.0, Some((47.3, 9.3)))).is_some());
    }

    #[test]
    fn every_text_fits_a_statustext() {
        let mut d = Digest::new(DigestSettings {
            every_us: 1,
            max_positions: 10,
        });
        let big = u64::MAX / 3;
        let text = observe(
            &mut d,
            &report(big, 99, 1.0, Some((-89.999999, -179.999999))),
        )
        .unwrap();
        assert!(text.len() <= TEXT_LEN, "{text}");
        for t in d.due(2_000_000) {
            assert!(t.len() <= TEXT_LEN, "{t}");
        }
    }

    #[test]
    fn texts_read_back_to_the_positions_they_carry() {
        let mut d = Digest::new(DigestSettings {
            every_us: 1_000_000,
            max_positions: 3,
        });
        let r = report(12, 5, 0.0, Some((47.672345, -9.268012)));
        let new = d.observe(&r, 0).unwrap();
        let p = parse_text(&new).unwrap();
        assert_eq!((p.track_id, p.class_id, p.age_s), (12, 5, 0.0));
        assert_eq!((p.lat_deg, p.lon_deg), (47.672345, -9.268012));
        let texts = d.due(4_000_000);
        assert!(parse_text(&texts[0]).is_none(), "{}", texts[0]);
        let p = parse_text(&texts[1]).unwrap();
        assert_eq!((p.track_id, p.class_id, p.age_s), (12, 5, 4.0));
        for bad in [
            "mgmot #12 swimmer 47.6,9.2 4s",
            "mgmot new swimmer 12 47.6,9.2",
            "mgmot new swimmer #12 95.0,9.2",
            "PreArm: GPS",
            "mgmot #x swimmer 1,2 3s ago",
        ] {
            assert!(parse_text(bad).is_none(), "{bad}");
        }
    }
}
