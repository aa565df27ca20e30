//! The simulator's truth (`mgmot-sim run --truth-out DIR`) against a flight's reports: per
//! true object, the error of the position reported for it over time.
//!
//! `camera.csv` maps the autopilot-clock stamp of each simulated frame (`frame_stamp_us`,
//! what mgmot records as `autopilot_time_us`) to scenario time. An autopilot reboot
//! (`faults.reboots_s`) starts its clock again, so the stamps are split into boot epochs where
//! they go back, and a stamp found in several epochs (or none, or missing) is told apart by
//! the companion's clock, which survives the reboot: the frame's UTC time plus the offset to
//! scenario time of the nearest frame whose stamp is unambiguous. `world.csv` holds every
//! visible object's true lat/lon per frame. Objects are interpolated in time between the
//! frames where they were visible. A report is matched to the nearest true object within
//! [`MATCH_RADIUS_M`] at its frame's time, horizontally, as the simulator's track check does.

use super::{class_name, Merges, ReviewError};
use crate::geo::{Geodetic, LocalTangentFrame};
use crate::record::format::FrameRecord;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Reports farther than this from every true object (m) are unmatched.
pub const MATCH_RADIUS_M: f64 = 10.0;
/// A true object is interpolated at most this far beyond its first and last visible frame (s).
const EXTEND_S: f64 = 0.25;
/// The autopilot clock going back by more than this between frames is a reboot (µs).
const REBOOT_STEP_US: u64 = 1_000_000;

/// One true object's positions over time.
#[derive(Debug, Clone)]
struct Object {
    class: String,
    /// (scenario time s, lat, lon), ascending in time.
    samples: Vec<(f64, f64, f64)>,
}

/// The simulator's truth of a run.
#[derive(Debug, Clone)]
pub struct Truth {
    /// Per boot epoch of the autopilot, in time order: (autopilot stamp µs, scenario time s),
    /// ascending.
    epochs: Vec<Vec<(u64, f64)>>,
    /// The first and last frame's scenario time (s).
    span: (f64, f64),
    objects: BTreeMap<u32, Object>,
}

/// One matched report.
#[derive(Debug, Clone, Serialize)]
pub struct ErrorSample {
    /// Time (s since the first frame).
    pub t: f64,
    /// Horizontal error (m).
    pub error_m: f64,
    /// The reporting track's final id.
    pub track_id: u64,
}

/// Median, 95th percentile and maximum of errors (m).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct ErrorStats {
    /// Samples.
    pub n: usize,
    /// Median (m).
    pub median_m: f64,
    /// 95th percentile (m).
    pub p95_m: f64,
    /// Maximum (m).
    pub max_m: f64,
}

impl ErrorStats {
    /// Of a set of errors (zeros when empty).
    pub fn of(errors: &[f64]) -> Self {
        let mut v: Vec<f64> = errors.iter().copied().filter(|e| e.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        let q = |p: f64| {
            if v.is_empty() {
                0.0
            } else {
                let i = ((v.len() - 1) as f64 * p).round() as usize;
                v[i.min(v.len() - 1)]
            }
        };
        Self {
            n: v.len(),
            median_m: q(0.5),
            p95_m: q(0.95),
            max_m: v.last().copied().unwrap_or(0.0),
        }
    }
}

/// One true object's errors.
#[derive(Debug, Clone, Serialize)]
pub struct ObjectErrors {
    /// The object's id in the truth.
    pub object_id: u32,
    /// Its class.
    pub class: String,
    /// Final track ids matched to it.
    pub track_ids: Vec<u64>,
    /// Matched reports over time.
    pub samples: Vec<ErrorSample>,
    /// Their statistics.
    pub stats: ErrorStats,
    /// Its true path (north, east in m of the review's local frame), thinned.
    pub path: Vec<[f64; 2]>,
}

/// The truth's side of the review.
#[derive(Debug, Clone, Serialize)]
pub struct TruthReview {
    /// Per true object seen by the camera.
    pub objects: Vec<ObjectErrors>,
    /// Over every matched report.
    pub overall: ErrorStats,
    /// Geolocated reports matched to a true object.
    pub matched: usize,
    /// Geolocated reports with no true object within [`MATCH_RADIUS_M`].
    pub unmatched: usize,
    /// Geolocated reports whose frame has no time in the truth (by neither clock).
    pub untimed: usize,
    /// Geolocated reports timed by the companion's clock: their frame's autopilot time was
    /// missing, or ambiguous over an autopilot reboot.
    pub retimed: usize,
    /// The match radius (m).
    pub radius_m: f64,
}

fn bad(path: &Path, message: impl Into<String>) -> ReviewError {
    ReviewError::Truth {
        path: path.to_owned(),
        message: message.into(),
    }
}

/// The rows of a CSV with a header: each row as the named columns' text.
fn read_csv(path: &Path, columns: &[&str]) -> Result<Vec<Vec<String>>, ReviewError> {
    let mut reader = csv::Reader::from_path(path).map_err(|e| bad(path, e.to_string()))?;
    let header = reader
        .headers()
        .map_err(|e| bad(path, e.to_string()))?
        .clone();
    let idx: Vec<usize> = columns
        .iter()
        .map(|c| {
            header
                .iter()
                .position(|h| h == *c)
                .ok_or_else(|| bad(path, format!("no column {c:?}")))
        })
        .collect::<Result<_, _>>()?;
    let mut rows = Vec::new();
    for (n, rec) in reader.records().enumerate() {
        let rec = rec.map_err(|e| bad(path, format!("row {}: {e}", n + 2)))?;
        rows.push(
            idx.iter()
                .map(|&i| rec.get(i).unwrap_or_default().to_owned())
                .collect(),
        );
    }
    Ok(rows)
}

fn num<T: std::str::FromStr>(path: &Path, row: usize, s: &str) -> Result<T, ReviewError> {
    s.trim()
        .parse()
        .map_err(|_| bad(path, format!("row {}: {s:?} is not a number", row + 2)))
}

impl Truth {
    /// Reads `camera.csv` and `world.csv` of a truth folder.
    pub fn load(dir: &Path) -> Result<Self, ReviewError> {
        let camera = dir.join("camera.csv");
        let mut stamps = Vec::new();
        for (n, r) in read_csv(&camera, &["time_s", "frame_stamp_us"])?
            .iter()
            .enumerate()
        {
            stamps.push((
                num::<u64>(&camera, n, &r[1])?,
                num::<f64>(&camera, n, &r[0])?,
            ));
        }
        // In time order; a reboot starts a new epoch.
        stamps.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (Some(first), Some(last)) = (stamps.first(), stamps.last()) else {
            return Err(bad(&camera, "no frames"));
        };
        let span = (first.1, last.1);
        let mut epochs: Vec<Vec<(u64, f64)>> = Vec::new();
        let mut prev: Option<u64> = None;
        for s in stamps {
            if prev.is_none_or(|p| s.0.saturating_add(REBOOT_STEP_US) < p) {
                epochs.push(Vec::new());
            }
            prev = Some(s.0);
            if let Some(e) = epochs.last_mut() {
                e.push(s);
            }
        }
        for e in &mut epochs {
            e.sort_by_key(|s| s.0);
        }
        let world = dir.join("world.csv");
        let mut objects: BTreeMap<u32, Object> = BTreeMap::new();
        for (n, r) in read_csv(&world, &["time_s", "id", "class", "lat_deg", "lon_deg"])?
            .iter()
            .enumerate()
        {
            let o = objects.entry(num(&world, n, &r[1])?).or_insert(Object {
                class: r[2].clone(),
                samples: Vec::new(),
            });
            o.samples.push((
                num(&world, n, &r[0])?,
                num(&world, n, &r[3])?,
                num(&world, n, &r[4])?,
            ));
        }
        for o in objects.values_mut() {
            o.samples.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        Ok(Self {
            epochs,
            span,
            objects,
        })
    }

    /// The scenario times an autopilot stamp has: one per boot epoch it falls in.
    fn scenario_times(&self, stamp_us: u64) -> Vec<f64> {
        self.epochs
            .iter()
            .filter_map(|e| Self::epoch_time(e, stamp_us))
            .collect()
    }

    /// Scenario time of an autopilot stamp in one boot epoch (linear between its frames, up to
    /// a second beyond them).
    fn epoch_time(stamps: &[(u64, f64)], stamp_us: u64) -> Option<f64> {
        let i = stamps.partition_point(|s| s.0 < stamp_us);
        let (a, b) = match (i.checked_sub(1).and_then(|j| stamps.get(j)), stamps.get(i)) {
            (Some(a), Some(b)) => (*a, *b),
            (Some(a), None) => (*a, *a),
            (None, Some(b)) => (*b, *b),
            (None, None) => return None,
        };
        let t = if b.0 > a.0 {
            a.1 + (b.1 - a.1) * (stamp_us - a.0) as f64 / (b.0 - a.0) as f64
        } else {
            a.1 + (stamp_us as f64 - a.0 as f64) / 1e6
        };
        let (lo, hi) = stamps
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
                (lo.min(s.1), hi.max(s.1))
            });
        (t >= lo - 1.0 && t <= hi + 1.0).then_some(t)
    }

    /// Each frame's scenario time, and whether it came from the companion's clock rather
    /// than the autopilot's stamp. A stamp found in exactly one boot epoch is taken as is;
    /// those frames anchor the offset from the companion's clock (UTC) to scenario time.
    /// A stamp found in several epochs takes the one nearest the nearest anchor's offset; a
    /// frame without a stamp, or whose stamp is in no epoch, takes that offset itself (when
    /// it lands within the truth's run).
    fn frame_times(&self, frames: &[FrameRecord]) -> Vec<Option<(f64, bool)>> {
        let utc_s = |f: &FrameRecord| super::frame_unix_us(f) as f64 / 1e6;
        let candidates: Vec<Vec<f64>> = frames
            .iter()
            .map(|f| {
                f.autopilot_time_us
                    .map(|us| self.scenario_times(us))
                    .unwrap_or_default()
            })
            .collect();
        // (UTC s, scenario minus UTC s), by UTC.
        let mut anchors: Vec<(f64, f64)> = frames
            .iter()
            .zip(&candidates)
            .filter(|(_, c)| c.len() == 1)
            .map(|(f, c)| (utc_s(f), c[0] - utc_s(f)))
            .collect();
        anchors.sort_by(|a, b| a.0.total_cmp(&b.0));
        let offset_at = |u: f64| -> Option<f64> {
            let i = anchors.partition_point(|a| a.0 < u);
            [i.checked_sub(1), Some(i)]
                .into_iter()
                .flatten()
                .filter_map(|j| anchors.get(j))
                .min_by(|a, b| (a.0 - u).abs().total_cmp(&(b.0 - u).abs()))
                .map(|a| a.1)
        };
        let (lo, hi) = self.span;
        frames
            .iter()
            .zip(candidates)
            .map(|(f, c)| {
                let predicted = offset_at(utc_s(f)).map(|o| utc_s(f) + o);
                match (c.as_slice(), predicted) {
                    ([t], _) => Some((*t, false)),
                    ([], Some(p)) => (p >= lo - 1.0 && p <= hi + 1.0).then_some((p, true)),
                    ([], None) => None,
                    (many, Some(p)) => many
                        .iter()
                        .copied()
                        .min_by(|a, b| (a - p).abs().total_cmp(&(b - p).abs()))
                        .map(|t| (t, true)),
                    (_, None) => None,
                }
            })
            .collect()
    }

    /// An object's position (lat, lon) at scenario time `t`.
    fn at(o: &Object, t: f64) -> Option<(f64, f64)> {
        let first = o.samples.first()?;
        let last = o.samples.last()?;
        if t < first.0 - EXTEND_S || t > last.0 + EXTEND_S {
            return None;
        }
        let i = o.samples.partition_point(|s| s.0 < t);
        match (
            i.checked_sub(1).and_then(|j| o.samples.get(j)),
            o.samples.get(i),
        ) {
            (Some(a), Some(b)) if b.0 > a.0 => {
                let s = (t - a.0) / (b.0 - a.0);
                Some((a.1 + (b.1 - a.1) * s, a.2 + (b.2 - a.2) * s))
            }
            (Some(a), _) => Some((a.1, a.2)),
            (None, Some(b)) => Some((b.1, b.2)),
            (None, None) => None,
        }
    }

    /// The errors of a flight's reports.
    pub fn review(
        &self,
        frames: &[FrameRecord],
        merges: &Merges,
        local: &LocalTangentFrame,
        t_of: &dyn Fn(&FrameRecord) -> f64,
    ) -> TruthReview {
        let ne = |lat: f64, lon: f64, alt: f64| {
            Geodetic::new(lat, lon, alt).ok().map(|g| {
                let v = local.to_ned(&g);
                [v.x, v.y]
            })
        };
        let alt0 = local.origin().alt_m;
        let mut per: BTreeMap<u32, (Vec<ErrorSample>, Vec<u64>)> = BTreeMap::new();
        let (mut matched, mut unmatched, mut untimed, mut retimed) = (0, 0, 0, 0);
        for (f, time) in frames.iter().zip(self.frame_times(frames)) {
            let geo: Vec<_> = f
                .tracks
                .iter()
                .filter_map(|r| Some((r.track.id, r.geo?)))
                .collect();
            if geo.is_empty() {
                continue;
            }
            let Some((ts, by_companion)) = time else {
                untimed += geo.len();
                continue;
            };
            if by_companion {
                retimed += geo.len();
            }
            let truth: Vec<(u32, [f64; 2])> = self
                .objects
                .iter()
                .filter_map(|(&id, o)| {
                    let (la, lo) = Self::at(o, ts)?;
                    Some((id, ne(la, lo, alt0)?))
                })
                .collect();
            for (track_id, g) in geo {
                let Some(p) = ne(g.lat_deg, g.lon_deg, alt0) else {
                    unmatched += 1;
                    continue;
                };
                let nearest = truth
                    .iter()
                    .map(|(id, q)| (*id, (p[0] - q[0]).hypot(p[1] - q[1])))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                match nearest {
                    Some((id, d)) if d <= MATCH_RADIUS_M => {
                        matched += 1;
                        let final_id = merges.final_id(track_id);
                        let e = per.entry(id).or_default();
                        e.0.push(ErrorSample {
                            t: t_of(f),
                            error_m: d,
                            track_id: final_id,
                        });
                        if !e.1.contains(&final_id) {
                            e.1.push(final_id);
                        }
                    }
                    _ => unmatched += 1,
                }
            }
        }
        let mut all = Vec::new();
        let objects = self
            .objects
            .iter()
            .map(|(&id, o)| {
                let (samples, mut track_ids) = per.remove(&id).unwrap_or_default();
                track_ids.sort_unstable();
                let errors: Vec<f64> = samples.iter().map(|s| s.error_m).collect();
                all.extend_from_slice(&errors);
                let step = (o.samples.len() / 300).max(1);
                ObjectErrors {
                    object_id: id,
                    class: if o.class.is_empty() {
                        class_name(0).to_owned()
                    } else {
                        o.class.clone()
                    },
                    track_ids,
                    stats: ErrorStats::of(&errors),
                    samples,
                    path: o
                        .samples
                        .iter()
                        .step_by(step)
                        .filter_map(|s| ne(s.1, s.2, alt0))
                        .collect(),
                }
            })
            .collect();
        TruthReview {
            objects,
            overall: ErrorStats::of(&all),
            matched,
            unmatched,
            untimed,
            retimed,
            radius_m: MATCH_RADIUS_M,
        }
    }
}
