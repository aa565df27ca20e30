//! The fuser: drones' track reports in, one fused track per object out.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{Matrix2, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use crate::geo::{circular_error_m, Geodetic, LocalTangentFrame};
use crate::track::assign::solve_gated;
use crate::track::{DriftParams, SeaDrift};

/// The later of two optional times.
fn later(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.max(b)),
        (a, b) => a.or(b),
    }
}

/// A report this much (s) older than the latest of its track is not late but on a clock
/// that was re-mapped.
const CLOCK_JUMP_S: f64 = 30.0;

/// Squared Mahalanobis distance between two positions with their covariances (summed), or
/// `None` when the sum is singular.
fn mahalanobis2(a: (Vector2<f64>, Matrix2<f64>), b: (Vector2<f64>, Matrix2<f64>)) -> Option<f64> {
    let d = a.0 - b.0;
    let s = (a.1 + b.1).try_inverse()?;
    Some((d.transpose() * s * d)[(0, 0)])
}

/// A drone's track: (system id, track id).
pub type MemberKey = (u8, u64);

/// The smallest per-axis standard deviation a report is given (m): a report claiming better
/// is not trusted to be that good.
const MIN_STD_M: f64 = 0.5;

/// Fusion parameters (`[fusion]` of `mgmot ground`'s configuration).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FuseParams {
    /// Gate on the squared Mahalanobis distance between a drone's track and a fused track
    /// (chi-square, 2 degrees of freedom: 9.21 holds 99 % of true pairs).
    pub gate_chi2: f64,
    /// A pair further apart than this (m) is never the same object, whatever the covariances.
    pub max_distance_m: f64,
    /// A drone's track not reported for this long (s) no longer counts as seen by that drone.
    pub live_s: f64,
    /// Two fused tracks of different drones inside the gate for this long (s) are merged.
    pub merge_after_s: f64,
    /// A fused track nobody has reported for this long (s) is dropped.
    pub keep_s: f64,
    /// Variance (m^2, per axis) a position gains per second of prediction for the object's
    /// own motion (a swimmer's strokes, a boat's turns).
    pub own_motion_m2_s: f64,
    /// Own motion is counted for at most this long (s); beyond it only the drift's
    /// uncertainty grows.
    pub own_motion_max_s: f64,
    /// A drone's track is carried forward to now with its velocity only when its speed is
    /// at least this (m/s); slower, its velocity is mostly the drone filter's noise.
    pub min_extrapolation_speed_m_s: f64,
    /// Sea drift estimation, as the onboard tracker's `[reid.drift]`.
    pub drift: DriftParams,
    /// A track's velocity is a drift sample once the track has been reported this long (s).
    pub drift_min_age_s: f64,
    /// A drone track that comes back after a gap far outside its fused track's gate is held
    /// this long (s) before the fused track follows it: while held it moves nothing, and it
    /// leaves as soon as another live track of the fused track, or another fused track, says
    /// the drone's ReID took it for the wrong object. 0: followed at once.
    pub reacquire_hold_s: f64,
    /// A drone's new track may take the place of another track of the same drone in a fused
    /// track that track joined at most this long ago (s), when the new one fits the fused
    /// track's other drones better; the one it displaces is associated anew. Undoes a first
    /// pairing of two neighbours' tracks the wrong way round. 0: never.
    pub rematch_within_s: f64,
    /// The sea drift carries a fused track nobody sees only while the drift's own uncertainty
    /// (the larger per-axis standard deviation of its mean velocity) is at most this (m/s): a
    /// drift estimated from a few noisy track velocities is worse than keeping still (seen:
    /// 1.7 m/s, which put a swimmer's lost fused track out of every gate).
    pub max_drift_std_m_s: f64,
}

impl Default for FuseParams {
    fn default() -> Self {
        Self {
            gate_chi2: 9.21,
            max_distance_m: 30.0,
            live_s: 3.0,
            merge_after_s: 2.0,
            keep_s: 900.0,
            own_motion_m2_s: 0.5,
            own_motion_max_s: 60.0,
            min_extrapolation_speed_m_s: 1.0,
            drift: DriftParams::default(),
            drift_min_age_s: 5.0,
            reacquire_hold_s: 5.0,
            rematch_within_s: 10.0,
            max_drift_std_m_s: 0.3,
        }
    }
}

impl FuseParams {
    /// Every parameter in its range; the first one that is not, with why.
    pub fn validate(&self) -> Result<(), String> {
        let positive = [
            ("gate_chi2", self.gate_chi2),
            ("max_distance_m", self.max_distance_m),
            ("live_s", self.live_s),
            ("keep_s", self.keep_s),
            ("own_motion_max_s", self.own_motion_max_s),
            ("drift.time_constant_s", self.drift.time_constant_s),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be a positive number, not {v}"));
            }
        }
        let non_negative = [
            ("merge_after_s", self.merge_after_s),
            ("own_motion_m2_s", self.own_motion_m2_s),
            (
                "min_extrapolation_speed_m_s",
                self.min_extrapolation_speed_m_s,
            ),
            ("drift_min_age_s", self.drift_min_age_s),
            ("max_drift_std_m_s", self.max_drift_std_m_s),
            ("reacquire_hold_s", self.reacquire_hold_s),
            ("rematch_within_s", self.rematch_within_s),
            ("drift.min_sample_s", self.drift.min_sample_s),
            ("drift.max_vel_std_m_s", self.drift.max_vel_std_m_s),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} must be 0 or more, not {v}"));
            }
        }
        if self.keep_s < self.live_s {
            return Err(format!(
                "keep_s ({}) must be at least live_s ({})",
                self.keep_s, self.live_s
            ));
        }
        Ok(())
    }
}

/// One drone's report of one of its tracks, on the fuser's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Report {
    /// The reporting drone's MAVLink system id.
    pub system_id: u8,
    /// The drone's track id.
    pub track_id: u64,
    /// The drone's ReID merged this older track into `track_id` (MGMOT_TRACK_FLAGS_MERGED).
    pub merged_from_id: Option<u64>,
    /// Class id (SeaDronesSee numbering).
    pub class_id: u32,
    /// Time of the state (s, the fuser's clock: [`ClockAlign`](super::ClockAlign)).
    pub time_s: f64,
    /// Position on the sea (degrees).
    pub lat_deg: f64,
    /// Position on the sea (degrees).
    pub lon_deg: f64,
    /// Velocity north, east (m/s), when the report has one (the digest has none).
    pub vel_ne_m_s: Option<Vector2<f64>>,
    /// Horizontal uncertainty: DRMS (m), the root of the sum of the two axes' variances.
    pub h_std_m: f64,
    /// The drone's detector saw the object at `time_s` (false: the drone's prediction).
    pub tracked: bool,
    /// The drone's ReID decision is still pending (MGMOT_TRACK_FLAGS_PROVISIONAL): such a
    /// report is ignored, its id may still change.
    pub provisional: bool,
}

/// The picture's verdict on a drone track that came back after a gap.
enum Reacquired {
    /// Where its fused track is: the same object.
    Inside,
    /// The picture says it is another object: it leaves its fused track.
    Wrong,
    /// Far from its fused track, and nothing says otherwise yet.
    Unconfirmed,
}

/// A fused id retired by a merge, and the id it lives on as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Retired {
    /// The id no longer used.
    pub id: u64,
    /// The id that continues the object.
    pub into: u64,
}

/// Whether anyone sees a fused track's object now.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FusedTrackState {
    /// A drone's detector saw it in its latest report.
    Tracked,
    /// Only predicted: by the drones' filters, or by the fuser with the sea drift once no
    /// drone reports it.
    Lost,
}

/// One drone's track inside a fused track.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FusedMember {
    /// The drone's system id.
    pub system_id: u8,
    /// The drone's track id.
    pub track_id: u64,
    /// Reported within `live_s`.
    pub live: bool,
    /// Its latest report was a detection (not a prediction).
    pub tracked: bool,
}

/// One object of the fused picture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FusedTrack {
    /// Fused id: unique over the fuser's life, never reused.
    pub id: u64,
    /// Class id (SeaDronesSee numbering).
    pub class_id: u32,
    /// Seen now, or only predicted.
    pub state: FusedTrackState,
    /// Position (degrees).
    pub lat_deg: f64,
    /// Position (degrees).
    pub lon_deg: f64,
    /// Position covariance, north/east (m^2).
    pub cov_m2: Matrix2<f64>,
    /// Radius (m) holding the position with 95 % probability.
    pub ce95_m: f64,
    /// Velocity north, east (m/s).
    pub vel_ne_m_s: Vector2<f64>,
    /// When a drone's detector last saw it (s, the fuser's clock); `None` if only ever
    /// predicted.
    pub last_seen_s: Option<f64>,
    /// The drones' tracks that are this object, by system id then track id.
    pub members: Vec<FusedMember>,
    /// Fused ids merged into this one.
    pub merged_from: Vec<u64>,
}

/// What the fuser knows of one drone's track.
#[derive(Debug, Clone)]
struct Member {
    class_id: u32,
    pos: Vector2<f64>,
    vel: Option<Vector2<f64>>,
    /// Per-axis position variance (m^2).
    var: f64,
    /// Time of the latest state (s).
    time_s: f64,
    /// First report (s).
    first_s: f64,
    /// Latest report that was a detection (s).
    last_seen_s: Option<f64>,
    tracked: bool,
    fused: Option<u64>,
    /// Came back after a gap far from its fused track and held there until this time (s):
    /// it neither moves its fused track nor keeps another track of its drone out of one.
    held_until_s: Option<f64>,
    /// When it last joined a fused track (s).
    joined_s: f64,
}

impl Member {
    /// Position and per-axis variance at `now_s`.
    fn predict(&self, now_s: f64, p: &FuseParams) -> (Vector2<f64>, f64) {
        let dt = (now_s - self.time_s).max(0.0);
        // A drone's velocity of a swimmer is mostly its filter's noise: extrapolating with
        // it adds error. Only a clearly moving object (a boat under way) is carried forward.
        // So is that of a track seen for only a few seconds (see `Fuser::predict`).
        let measured = self
            .last_seen_s
            .is_some_and(|seen| seen - self.first_s >= p.drift_min_age_s);
        let vel = self
            .vel
            .filter(|v| measured && v.norm() >= p.min_extrapolation_speed_m_s)
            .unwrap_or_else(Vector2::zeros);
        let pos = self.pos + vel * dt;
        (pos, self.var + p.own_motion_m2_s * dt)
    }
}

#[derive(Debug, Clone)]
struct Fused {
    class_id: u32,
    members: BTreeSet<MemberKey>,
    /// Latest estimate and its time: updated every step while a member is live.
    pos: Vector2<f64>,
    cov: Matrix2<f64>,
    vel: Vector2<f64>,
    est_time_s: f64,
    /// When a drone first and last saw it (s): how long its own velocity was measured.
    first_seen_s: Option<f64>,
    last_seen_s: Option<f64>,
    merged_from: Vec<u64>,
    /// Every drone that ever had a track in it.
    seen_by: BTreeSet<u8>,
}

/// A fused track's position now, and who sees it.
struct Prediction {
    pos: Vector2<f64>,
    cov: Matrix2<f64>,
    vel: Vector2<f64>,
    live: usize,
    tracked: bool,
}

/// The ground picture. Feed it reports ([`Fuser::observe`]), step it ([`Fuser::step`]),
/// read it ([`Fuser::picture`]).
#[derive(Debug, Clone)]
pub struct Fuser {
    params: FuseParams,
    frame: Option<LocalTangentFrame>,
    members: BTreeMap<MemberKey, Member>,
    fused: BTreeMap<u64, Fused>,
    next_id: u64,
    drift: SeaDrift,
    retired: Vec<Retired>,
    /// Pairs of fused ids inside the gate, since when (s).
    close: BTreeMap<(u64, u64), f64>,
    /// Fused tracks a re-acquired drone track left (see [`Fuser::observe`]), with that track.
    left: Vec<(u64, MemberKey)>,
    last_step_s: Option<f64>,
}

impl Fuser {
    /// An empty picture with these parameters (checked with [`FuseParams::validate`] by the
    /// caller).
    pub fn new(params: FuseParams) -> Self {
        let drift = SeaDrift::new(params.drift.clone());
        Self {
            params,
            frame: None,
            members: BTreeMap::new(),
            fused: BTreeMap::new(),
            next_id: 1,
            drift,
            retired: Vec::new(),
            close: BTreeMap::new(),
            left: Vec::new(),
            last_step_s: None,
        }
    }

    /// Takes one report. Returns `false` when it is not used: provisional, not finite, or
    /// older than what the fuser already has of that track.
    pub fn observe(&mut self, r: &Report) -> bool {
        if r.provisional
            || !(r.time_s.is_finite() && r.lat_deg.is_finite() && r.lon_deg.is_finite())
            || !(-90.0..=90.0).contains(&r.lat_deg)
        {
            return false;
        }
        let frame = self.frame.get_or_insert_with(|| {
            LocalTangentFrame::new(Geodetic {
                lat_deg: r.lat_deg,
                lon_deg: r.lon_deg,
                alt_m: 0.0,
            })
        });
        let ned = frame.to_ned(&Geodetic {
            lat_deg: r.lat_deg,
            lon_deg: r.lon_deg,
            alt_m: 0.0,
        });
        let pos = Vector2::new(ned.x, ned.y);
        let key = (r.system_id, r.track_id);
        if let Some(old) = r.merged_from_id.filter(|old| *old != r.track_id) {
            self.drone_merged((r.system_id, old), key);
        }
        let h_std = if r.h_std_m.is_finite() {
            r.h_std_m
        } else {
            0.0
        };
        let var = (h_std * h_std / 2.0).max(MIN_STD_M * MIN_STD_M);
        let vel = r.vel_ne_m_s.filter(|v| v.iter().all(|x| x.is_finite()));
        self.check_reacquired(key, pos, var, r.time_s);
        match self.members.get_mut(&key) {
            // Out of order; but a jump back by more than CLOCK_JUMP_S is the vehicle's clock
            // being mapped anew (its SYSTEM_TIME arrived, or it rebooted): taken.
            Some(m) if r.time_s < m.time_s && m.time_s - r.time_s < CLOCK_JUMP_S => return false,
            Some(m) => {
                m.class_id = r.class_id;
                m.pos = pos;
                m.vel = vel;
                m.var = var;
                m.time_s = r.time_s;
                m.tracked = r.tracked;
                if r.tracked {
                    m.last_seen_s = Some(r.time_s);
                }
            }
            None => {
                self.members.insert(
                    key,
                    Member {
                        class_id: r.class_id,
                        pos,
                        vel,
                        var,
                        time_s: r.time_s,
                        first_s: r.time_s,
                        last_seen_s: r.tracked.then_some(r.time_s),
                        tracked: r.tracked,
                        fused: None,
                        held_until_s: None,
                        joined_s: r.time_s,
                    },
                );
            }
        }
        true
    }

    /// A drone track reported again after a gap (not live) far outside the gate of its fused
    /// track (see [`Fuser::reacquired_verdict`]) leaves it at once, is held, or stays.
    fn check_reacquired(&mut self, key: MemberKey, pos: Vector2<f64>, var: f64, time_s: f64) {
        let Some(m) = self.members.get(&key) else {
            return;
        };
        let Some(fid) = m.fused.filter(|_| !self.is_live(m, time_s)) else {
            return;
        };
        match self.reacquired_verdict(key, fid, pos, var, m.class_id, time_s) {
            Reacquired::Inside => {}
            Reacquired::Wrong => self.leave(key, fid, time_s),
            Reacquired::Unconfirmed => {
                if let Some(m) = self.members.get_mut(&key) {
                    let hold = self.params.reacquire_hold_s;
                    m.held_until_s = (hold > 0.0).then_some(time_s + hold);
                }
            }
        }
    }

    /// What the ground's picture says of drone track `key` of fused track `fid`, at `pos`
    /// (variance `var`) at `now_s` after a gap. The fused track's estimate is made from its
    /// other, unheld tracks or, when none is live, carried from before the gap.
    /// - **Wrong** when the picture says it is another object: it is outside the fused
    ///   track's gate while another live, unheld track of the fused track sees its object
    ///   now, or another fused track of its class that could take it fits it better (the
    ///   drone's long-term ReID took it for the wrong object: seen when a drone came back on a
    ///   group of swimmers and shifted its ids by one). "Fits better" counts only where
    ///   another drone saw one of the two fused tracks: where this drone alone saw both, the
    ///   ground knows nothing of them that the drone's own ReID did not weigh (positions
    ///   only, against its appearance and motion), and the drone's word stands (seen on the
    ///   ArduPilot SITL bench: a swimmer that drifted 7 m in 50 s came back nearer its
    ///   neighbour's lost fused track, and two swimmers changed fused ids).
    /// - **Inside** the gate of its fused track, and of no other fused track of its class: the
    ///   same object.
    /// - Otherwise **unconfirmed**: far from its fused track with nothing there to say
    ///   otherwise (the object may have moved more than the drift says, and the drone's ReID
    ///   knows more of that track's past than the drift does), or inside the gates of
    ///   several fused tracks (after a long gap the gates are wide, and a neighbour's may
    ///   fit better once the tracks that keep it from this one have come back).
    fn reacquired_verdict(
        &self,
        key: MemberKey,
        fid: u64,
        pos: Vector2<f64>,
        var: f64,
        class_id: u32,
        now_s: f64,
    ) -> Reacquired {
        let Some(f) = self.fused.get(&fid) else {
            return Reacquired::Inside;
        };
        let me = (pos, Matrix2::identity() * var);
        let p = self.predict(f, now_s);
        let own = self.gated(me, (p.pos, p.cov));
        // Another live, unheld track of the fused track: it says where the object is now, and
        // one of the same drone says (the drone's own tracker) that this is another object.
        let contradicted = f
            .members
            .iter()
            .any(|k| *k != key && (own.is_none() || k.0 == key.0) && self.live_unheld(k, now_s));
        if contradicted {
            return Reacquired::Wrong;
        }
        let single = BTreeSet::from([key]);
        let mut ambiguous = false;
        for (id, g) in &self.fused {
            if *id == fid || g.class_id != class_id {
                continue;
            }
            let q = self.predict(g, now_s);
            let Some(d2) = self.gated(me, (q.pos, q.cov)) else {
                continue;
            };
            if self.compatible(&single, &g.members, true)
                && own.is_none_or(|o| d2 < o)
                && (Self::seen_by_another(f, key.0) || Self::seen_by_another(g, key.0))
            {
                return Reacquired::Wrong;
            }
            ambiguous = true;
        }
        if own.is_some() && !ambiguous {
            Reacquired::Inside
        } else {
            Reacquired::Unconfirmed
        }
    }

    /// Whether a drone other than `system_id` ever saw fused track `f`.
    fn seen_by_another(f: &Fused, system_id: u8) -> bool {
        f.seen_by.iter().any(|s| *s != system_id)
    }

    /// Drone track `key` leaves fused track `fid` at `now_s` and is associated anew, as a
    /// track that starts now: its past belongs to the object it followed before.
    fn leave(&mut self, key: MemberKey, fid: u64, now_s: f64) {
        if let Some(m) = self.members.get_mut(&key) {
            m.fused = None;
            m.held_until_s = None;
            m.first_s = now_s;
        }
        if let Some(f) = self.fused.get_mut(&fid) {
            f.members.remove(&key);
        }
        self.left.push((fid, key));
    }

    /// Decides on the held drone tracks at `now_s`: one now inside its fused track's gate is
    /// released, one the picture now contradicts leaves, one held for `reacquire_hold_s` is
    /// released and its fused track follows it.
    fn decide_held(&mut self, now_s: f64) {
        let held: Vec<(MemberKey, u64, f64)> = self
            .members
            .iter()
            .filter_map(|(k, m)| Some((*k, m.fused?, m.held_until_s?)))
            .collect();
        for (key, fid, until) in held {
            let Some(m) = self.members.get(&key) else {
                continue;
            };
            let (pos, var) = m.predict(now_s, &self.params);
            let verdict = self.reacquired_verdict(key, fid, pos, var, m.class_id, now_s);
            match verdict {
                Reacquired::Wrong => self.leave(key, fid, now_s),
                Reacquired::Unconfirmed if now_s < until && self.is_live(m, now_s) => {}
                Reacquired::Inside | Reacquired::Unconfirmed => {
                    if let Some(m) = self.members.get_mut(&key) {
                        m.held_until_s = None;
                    }
                }
            }
        }
    }

    /// A fused track that a re-acquired drone track left with no member is retired into the
    /// fused track that drone track joined, when that drone alone ever saw it (nobody else
    /// says its object was not the one the drone's ReID took it for). One that several drones
    /// saw stays, carried with the drift: the ground's picture says its object is still there
    /// (seen when both drones' ReID moved their tracks of one swimmer onto a neighbour, and
    /// the swimmer's next sightings rejoined its fused id).
    fn retire_left(&mut self) {
        for (fid, key) in std::mem::take(&mut self.left) {
            let into = self.members.get(&key).and_then(|m| m.fused);
            let empty = self
                .fused
                .get(&fid)
                .is_some_and(|f| f.members.is_empty() && f.seen_by.len() <= 1);
            if let (true, Some(into)) = (empty, into) {
                if into != fid {
                    self.fused.remove(&fid);
                    self.close.retain(|(x, y), _| *x != fid && *y != fid);
                    self.retired.push(Retired { id: fid, into });
                }
            }
        }
    }

    /// A drone said `old` is `new` (its ReID): the two are one object on the ground too.
    fn drone_merged(&mut self, old: MemberKey, new: MemberKey) {
        let Some(gone) = self.members.remove(&old) else {
            return;
        };
        let Some(f_old) = gone.fused else {
            return;
        };
        if let Some(f) = self.fused.get_mut(&f_old) {
            f.members.remove(&old);
        }
        match self.members.get_mut(&new) {
            Some(m) => match m.fused {
                Some(f_new) if f_new != f_old => self.merge_fused(f_old, f_new),
                Some(_) => {}
                None => {
                    m.fused = Some(f_old);
                    if let Some(f) = self.fused.get_mut(&f_old) {
                        f.members.insert(new);
                        f.seen_by.insert(new.0);
                    }
                }
            },
            // The new id's first report: it continues the old id's fused track.
            None => {
                self.members.insert(
                    new,
                    Member {
                        fused: None,
                        ..gone
                    },
                );
                if let Some(m) = self.members.get_mut(&new) {
                    m.fused = Some(f_old);
                }
                if let Some(f) = self.fused.get_mut(&f_old) {
                    f.members.insert(new);
                    f.seen_by.insert(new.0);
                }
            }
        }
    }

    /// Merges fused tracks `a` and `b`: the lower id survives.
    fn merge_fused(&mut self, a: u64, b: u64) {
        let (keep, gone) = (a.min(b), a.max(b));
        let Some(g) = self.fused.remove(&gone) else {
            return;
        };
        for k in &g.members {
            if let Some(m) = self.members.get_mut(k) {
                m.fused = Some(keep);
            }
        }
        if let Some(f) = self.fused.get_mut(&keep) {
            f.members.extend(g.members.iter().copied());
            f.seen_by.extend(g.seen_by.iter().copied());
            // The more recent estimate stands for the merged track until the next step.
            if g.est_time_s > f.est_time_s {
                f.pos = g.pos;
                f.cov = g.cov;
                f.vel = g.vel;
                f.est_time_s = g.est_time_s;
            }
            f.merged_from.push(gone);
            f.merged_from.extend(g.merged_from.iter().copied());
            f.last_seen_s = later(f.last_seen_s, g.last_seen_s);
            f.first_seen_s = match (f.first_seen_s, g.first_seen_s) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
        }
        self.close.retain(|(x, y), _| *x != gone && *y != gone);
        self.retired.push(Retired {
            id: gone,
            into: keep,
        });
    }

    /// Whether two tracks of one drone can be one object: the drone saw them at different
    /// times (one ended, or only coasted, before the other was first reported). Tracks the
    /// drone saw at the same time are two objects: its own tracker kept them apart.
    fn sequential(a: &Member, b: &Member) -> bool {
        let a_last = a.last_seen_s.unwrap_or(a.first_s);
        let b_last = b.last_seen_s.unwrap_or(b.first_s);
        a_last < b.first_s || b_last < a.first_s
    }

    /// Whether the tracks of `a` and `b` can be one object: every pair of tracks of one
    /// drone is [`Fuser::sequential`]. With `skip_held`, a held track (see
    /// [`Fuser::reacquired_verdict`]) keeps no track out: for one track joining a fused track,
    /// not for merging two fused tracks.
    fn compatible(
        &self,
        a: &BTreeSet<MemberKey>,
        b: &BTreeSet<MemberKey>,
        skip_held: bool,
    ) -> bool {
        a.iter().all(|ka| {
            b.iter().filter(|kb| kb.0 == ka.0).all(|kb| {
                match (self.members.get(ka), self.members.get(kb)) {
                    (Some(ma), Some(mb))
                        if !skip_held
                            || (ma.held_until_s.is_none() && mb.held_until_s.is_none()) =>
                    {
                        Self::sequential(ma, mb)
                    }
                    _ => true,
                }
            })
        })
    }

    fn is_live(&self, m: &Member, now_s: f64) -> bool {
        now_s - m.time_s <= self.params.live_s
    }

    /// Where fused track `f` is at `now_s`, and who sees it.
    fn predict(&self, f: &Fused, now_s: f64) -> Prediction {
        self.predict_without(f, now_s, None)
    }

    /// [`Fuser::predict`] leaving out drone track `skip`.
    fn predict_without(&self, f: &Fused, now_s: f64, skip: Option<MemberKey>) -> Prediction {
        let p = &self.params;
        let mut info = Matrix2::zeros();
        let mut info_pos = Vector2::zeros();
        let (mut vel_sum, mut vel_n) = (Vector2::zeros(), 0.0);
        let (mut live, mut tracked) = (0, false);
        // A drone's sighting beats any drone's prediction: while one live member is tracked,
        // the coasting ones are left out.
        let any_tracked = f
            .members
            .iter()
            .filter(|k| Some(**k) != skip)
            .filter_map(|k| self.members.get(k))
            .any(|m| m.tracked && m.held_until_s.is_none() && self.is_live(m, now_s));
        for m in f
            .members
            .iter()
            .filter(|k| Some(**k) != skip)
            .filter_map(|k| self.members.get(k))
        {
            if !self.is_live(m, now_s) || m.held_until_s.is_some() || (any_tracked && !m.tracked) {
                continue;
            }
            let (pos, var) = m.predict(now_s, p);
            info += Matrix2::identity() / var;
            info_pos += pos / var;
            if let Some(v) = m.vel {
                vel_sum += v;
                vel_n += 1.0;
            }
            live += 1;
            tracked |= m.tracked;
        }
        if live > 0 {
            if let Some(cov) = info.try_inverse() {
                let vel = if vel_n > 0.0 {
                    vel_sum / vel_n
                } else {
                    Vector2::zeros()
                };
                return Prediction {
                    pos: cov * info_pos,
                    cov,
                    vel,
                    live,
                    tracked,
                };
            }
        }
        // Nobody sees it: carry it with the drift of its class; before there is one, with its
        // own velocity for at most own_motion_max_s, if that was measured long enough to mean
        // something (a drone's velocity of a track seen for a few seconds is mostly its own
        // geolocation error changing as it flies: seen carrying a still boat 60 m off).
        let dt = (now_s - f.est_time_s).max(0.0);
        let measured = f
            .first_seen_s
            .zip(f.last_seen_s)
            .is_some_and(|(a, b)| b - a >= p.drift_min_age_s);
        let own_dt = dt.min(p.own_motion_max_s);
        let own_vel = if measured && f.vel.norm() >= p.min_extrapolation_speed_m_s {
            f.vel
        } else {
            Vector2::zeros()
        };
        let drift = self
            .drift
            .estimate(f.class_id)
            .filter(|d| d.cov_m2_s2.symmetric_eigenvalues().max().sqrt() <= p.max_drift_std_m_s);
        let (pos, cov, vel) = match drift {
            Some(d) => (
                f.pos + d.vel_ne_m_s * dt,
                f.cov + d.cov_m2_s2 * dt * dt + Matrix2::identity() * p.own_motion_m2_s * own_dt,
                d.vel_ne_m_s,
            ),
            None => (
                f.pos + own_vel * own_dt,
                f.cov + Matrix2::identity() * p.own_motion_m2_s * own_dt,
                own_vel,
            ),
        };
        Prediction {
            pos,
            cov,
            vel,
            live: 0,
            tracked: false,
        }
    }

    /// Squared Mahalanobis distance and distance (m) between two positions, or `None`
    /// outside the gate.
    fn gated(
        &self,
        a: (Vector2<f64>, Matrix2<f64>),
        b: (Vector2<f64>, Matrix2<f64>),
    ) -> Option<f64> {
        if (a.0 - b.0).norm() > self.params.max_distance_m {
            return None;
        }
        let d2 = mahalanobis2(a, b)?;
        (d2.is_finite() && d2 <= self.params.gate_chi2).then_some(d2)
    }

    /// A drone track that is live at `now_s` and not held.
    fn live_unheld(&self, k: &MemberKey, now_s: f64) -> bool {
        self.members
            .get(k)
            .is_some_and(|m| m.held_until_s.is_none() && self.is_live(m, now_s))
    }

    /// Advances the picture to `now_s` (the fuser's clock): new drone tracks are associated,
    /// estimates updated, agreeing fused tracks merged, forgotten ones dropped.
    pub fn step(&mut self, now_s: f64) {
        if !now_s.is_finite() {
            return;
        }
        self.last_step_s = Some(now_s);
        self.observe_drift(now_s);
        self.decide_held(now_s);
        // Each fused track is predicted once per step: association's predictions stand for
        // the tracks it left unchanged, and the updated estimates are what merging compares.
        let predicted = self.associate(now_s);
        self.retire_left();
        let seen = self.update_estimates(now_s, predicted);
        self.merge_agreeing(now_s, &seen);
        self.prune(now_s);
    }

    fn observe_drift(&mut self, now_s: f64) {
        let samples: Vec<(u32, u64, Vector2<f64>)> = self
            .members
            .iter()
            .filter(|(_, m)| {
                self.is_live(m, now_s)
                    && m.tracked
                    && m.time_s - m.first_s >= self.params.drift_min_age_s
            })
            .filter_map(|((sys, id), m)| Some((m.class_id, (u64::from(*sys) << 56) ^ id, m.vel?)))
            .collect();
        self.drift.observe(now_s, &samples);
    }

    /// Live drone tracks not yet in a fused track join one (or start their own), one drone
    /// at a time so that two drones' new tracks of one object meet in one step. Returns the
    /// predictions at `now_s` of the fused tracks whose members it did not change.
    fn associate(&mut self, now_s: f64) -> BTreeMap<u64, Prediction> {
        let mut new: BTreeMap<u8, Vec<MemberKey>> = BTreeMap::new();
        for (k, m) in &self.members {
            if m.fused.is_none() && self.is_live(m, now_s) {
                new.entry(k.0).or_default().push(*k);
            }
        }
        // Predicted once; a fused track a drone's tracks joined (or that one started) is
        // predicted again for the next drone.
        let mut predicted: BTreeMap<u64, Prediction> = BTreeMap::new();
        let (mut cost, mut pairs) = (Vec::new(), Vec::new());
        for rows in new.into_values() {
            // A second round for the tracks the first displaced, which displace nothing.
            let (mut rows, mut may_displace) = (rows, self.params.rematch_within_s > 0.0);
            while !rows.is_empty() {
                for (id, f) in &self.fused {
                    predicted
                        .entry(*id)
                        .or_insert_with(|| self.predict(f, now_s));
                }
                let cols: Vec<(u64, &Prediction)> =
                    predicted.iter().map(|(id, p)| (*id, p)).collect();
                cost.clear();
                let mut displaces = BTreeMap::new();
                for (r, k) in rows.iter().enumerate() {
                    let m = &self.members[k];
                    let (pos, var) = m.predict(now_s, &self.params);
                    let me = (pos, Matrix2::identity() * var);
                    let single = BTreeSet::from([*k]);
                    for (c, (id, pred)) in cols.iter().enumerate() {
                        let f = &self.fused[id];
                        let mut d2 = None;
                        if f.class_id == m.class_id {
                            if self.compatible(&single, &f.members, true) {
                                d2 = self.gated(me, (pred.pos, pred.cov));
                            } else if may_displace {
                                if let Some((j, d)) = self.displaceable(*k, me, f, now_s) {
                                    d2 = Some(d);
                                    displaces.insert((r, c), j);
                                }
                            }
                        }
                        cost.push(d2.unwrap_or(f64::INFINITY));
                    }
                }
                // A track that would start a fused track of its own joins one whose only live
                // tracks are held where it is: another drone sees the object where the held
                // track's drone put it.
                for (r, k) in rows.iter().enumerate() {
                    let row = &mut cost[r * cols.len()..(r + 1) * cols.len()];
                    if row.iter().any(|c| c.is_finite()) {
                        continue;
                    }
                    for (c, (id, pred)) in cols.iter().enumerate() {
                        if pred.live == 0 {
                            if let Some(d2) = self.near_held(*k, &self.fused[id], now_s) {
                                row[c] = d2;
                            }
                        }
                    }
                }
                solve_gated(rows.len(), cols.len(), &mut cost, &mut pairs);
                let mut matched = vec![None; rows.len()];
                let mut displaced = Vec::new();
                for (r, c) in &pairs {
                    matched[*r] = Some(cols[*c].0);
                    if let Some(j) = displaces.get(&(*r, *c)) {
                        displaced.push((*j, cols[*c].0));
                    }
                }
                for (j, id) in &displaced {
                    if let Some(m) = self.members.get_mut(j) {
                        m.fused = None;
                    }
                    if let Some(f) = self.fused.get_mut(id) {
                        f.members.remove(j);
                    }
                }
                for (k, to) in rows.iter().zip(matched) {
                    let id = match to {
                        Some(id) => id,
                        None => self.start_fused(*k, now_s),
                    };
                    predicted.remove(&id);
                    if let Some(m) = self.members.get_mut(k) {
                        m.fused = Some(id);
                        m.joined_s = now_s;
                    }
                    if let Some(f) = self.fused.get_mut(&id) {
                        f.members.insert(*k);
                        f.seen_by.insert(k.0);
                    }
                }
                rows = displaced.into_iter().map(|(j, _)| j).collect();
                may_displace = false;
            }
        }
        predicted
    }

    /// The squared Mahalanobis distance from drone track `k` to the nearest live held track of
    /// fused track `f` inside the gate, when `k` may join `f` (its class, compatible).
    fn near_held(&self, k: MemberKey, f: &Fused, now_s: f64) -> Option<f64> {
        let m = self.members.get(&k)?;
        if f.class_id != m.class_id || !self.compatible(&BTreeSet::from([k]), &f.members, true) {
            return None;
        }
        let (pos, var) = m.predict(now_s, &self.params);
        f.members
            .iter()
            .filter_map(|h| self.members.get(h))
            .filter(|h| h.held_until_s.is_some() && self.is_live(h, now_s))
            .filter_map(|h| {
                let (hp, hv) = h.predict(now_s, &self.params);
                self.gated(
                    (pos, Matrix2::identity() * var),
                    (hp, Matrix2::identity() * hv),
                )
            })
            .min_by(f64::total_cmp)
    }

    /// Whether drone track `k` (at `me`) may take the place of another track `j` of its drone
    /// in fused track `f`: `j` is the only track of `f` that keeps `k` out, it is live and
    /// joined `f` within `rematch_within_s`, `f` has a live track of another drone, and `k`
    /// fits the estimate of `f` without `j` better than `j` does. Returns `j` and `k`'s squared
    /// Mahalanobis distance to that estimate.
    fn displaceable(
        &self,
        k: MemberKey,
        me: (Vector2<f64>, Matrix2<f64>),
        f: &Fused,
        now_s: f64,
    ) -> Option<(MemberKey, f64)> {
        let mk = self.members.get(&k)?;
        let mut blocking = f.members.iter().filter(|j| {
            j.0 == k.0
                && self
                    .members
                    .get(j)
                    .is_some_and(|mj| mj.held_until_s.is_none() && !Self::sequential(mk, mj))
        });
        let j = *blocking.next()?;
        if blocking.next().is_some() {
            return None;
        }
        let mj = self.members.get(&j)?;
        if !self.is_live(mj, now_s) || now_s - mj.joined_s > self.params.rematch_within_s {
            return None;
        }
        let others = self.predict_without(f, now_s, Some(j));
        let other_drone_live = f
            .members
            .iter()
            .any(|o| o.0 != k.0 && self.live_unheld(o, now_s));
        if !other_drone_live || others.live == 0 {
            return None;
        }
        let d2k = self.gated(me, (others.pos, others.cov))?;
        let (pos_j, var_j) = mj.predict(now_s, &self.params);
        let d2j = mahalanobis2(
            (pos_j, Matrix2::identity() * var_j),
            (others.pos, others.cov),
        )?;
        (d2k < d2j).then_some((j, d2k))
    }

    fn start_fused(&mut self, k: MemberKey, now_s: f64) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        let m = &self.members[&k];
        let (pos, var) = m.predict(now_s, &self.params);
        self.fused.insert(
            id,
            Fused {
                class_id: m.class_id,
                members: BTreeSet::new(),
                seen_by: BTreeSet::new(),
                pos,
                cov: Matrix2::identity() * var,
                vel: m.vel.unwrap_or_else(Vector2::zeros),
                est_time_s: now_s,
                first_seen_s: m.last_seen_s,
                last_seen_s: m.last_seen_s,
                merged_from: Vec::new(),
            },
        );
        id
    }

    /// Moves every fused track a live drone track sees to its estimate at `now_s`
    /// (`predicted`: predictions already made at `now_s` of tracks unchanged since). Returns
    /// the ids of those tracks.
    fn update_estimates(
        &mut self,
        now_s: f64,
        mut predicted: BTreeMap<u64, Prediction>,
    ) -> Vec<u64> {
        let updates: Vec<(u64, Prediction, Option<f64>)> = self
            .fused
            .iter()
            .map(|(id, f)| {
                let seen = f
                    .members
                    .iter()
                    .filter_map(|k| self.members.get(k)?.last_seen_s)
                    .fold(f.last_seen_s, |a, b| later(a, Some(b)));
                let p = predicted
                    .remove(id)
                    .unwrap_or_else(|| self.predict(f, now_s));
                (*id, p, seen)
            })
            .filter(|(_, p, _)| p.live > 0)
            .collect();
        let ids = updates.iter().map(|(id, _, _)| *id).collect();
        for (id, p, seen) in updates {
            if let Some(f) = self.fused.get_mut(&id) {
                f.pos = p.pos;
                f.cov = p.cov;
                f.vel = p.vel;
                f.est_time_s = now_s;
                f.last_seen_s = seen;
                if f.first_seen_s.is_none() {
                    f.first_seen_s = seen;
                }
            }
        }
        ids
    }

    /// Merges two seen fused tracks of one class that have stayed inside the gate for
    /// `merge_after_s`, unless one drone saw both at the same time. `seen`: the ids of the
    /// fused tracks a live drone track sees, their estimates updated to `now_s`.
    fn merge_agreeing(&mut self, now_s: f64, seen: &[u64]) {
        let seen: Vec<(u64, &Fused)> = seen
            .iter()
            .filter_map(|id| Some((*id, self.fused.get(id)?)))
            .collect();
        let mut close_now = BTreeSet::new();
        for (i, a) in seen.iter().enumerate() {
            for b in &seen[i + 1..] {
                if a.1.class_id != b.1.class_id
                    || !self.compatible(&a.1.members, &b.1.members, false)
                {
                    continue;
                }
                if self.gated((a.1.pos, a.1.cov), (b.1.pos, b.1.cov)).is_some() {
                    close_now.insert((a.0, b.0));
                }
            }
        }
        self.close.retain(|pair, _| close_now.contains(pair));
        let mut due = Vec::new();
        for pair in close_now {
            let since = *self.close.entry(pair).or_insert(now_s);
            if now_s - since >= self.params.merge_after_s {
                due.push(pair);
            }
        }
        for (a, b) in due {
            // An earlier merge in this step may have retired one of the two.
            if self.fused.contains_key(&a) && self.fused.contains_key(&b) {
                self.merge_fused(a, b);
            }
        }
    }

    fn prune(&mut self, now_s: f64) {
        let keep_s = self.params.keep_s;
        let gone: Vec<u64> = self
            .fused
            .iter()
            .filter(|(_, f)| now_s - f.est_time_s > keep_s)
            .map(|(id, _)| *id)
            .collect();
        for id in gone {
            if let Some(f) = self.fused.remove(&id) {
                for k in f.members {
                    self.members.remove(&k);
                }
            }
            self.close.retain(|(x, y), _| *x != id && *y != id);
        }
        self.members
            .retain(|_, m| m.fused.is_some() || now_s - m.time_s <= keep_s);
    }

    /// The fused ids retired by merges since the last call.
    pub fn take_retired(&mut self) -> Vec<Retired> {
        std::mem::take(&mut self.retired)
    }

    /// The fused id a drone's track belongs to, if it has one.
    pub fn fused_id_of(&self, system_id: u8, track_id: u64) -> Option<u64> {
        self.members.get(&(system_id, track_id))?.fused
    }

    /// The picture at `now_s`: every fused track, predicted to then, by id.
    pub fn picture(&self, now_s: f64) -> Vec<FusedTrack> {
        let Some(frame) = &self.frame else {
            return Vec::new();
        };
        self.fused
            .iter()
            .map(|(id, f)| {
                let p = self.predict(f, now_s);
                let g = frame.to_geodetic(&Vector3::new(p.pos.x, p.pos.y, 0.0));
                let members = f
                    .members
                    .iter()
                    .filter_map(|k| {
                        let m = self.members.get(k)?;
                        Some(FusedMember {
                            system_id: k.0,
                            track_id: k.1,
                            live: self.is_live(m, now_s),
                            tracked: m.tracked,
                        })
                    })
                    .collect();
                FusedTrack {
                    id: *id,
                    class_id: f.class_id,
                    state: if p.tracked {
                        FusedTrackState::Tracked
                    } else {
                        FusedTrackState::Lost
                    },
                    lat_deg: g.lat_deg,
                    lon_deg: g.lon_deg,
                    cov_m2: p.cov,
                    ce95_m: circular_error_m(&p.cov, 0.95).unwrap_or(f64::NAN),
                    vel_ne_m_s: p.vel,
                    last_seen_s: f.last_seen_s,
                    members,
                    merged_from: f.merged_from.clone(),
                }
            })
            .collect()
    }

    /// How many fused ids were ever given.
    pub fn ids_given(&self) -> u64 {
        self.next_id - 1
    }

    /// The time of the latest step (s), if any.
    pub fn last_step_s(&self) -> Option<f64> {
        self.last_step_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LAT0: f64 = 47.67;
    const LON0: f64 = 9.27;
    const M_PER_DEG_LAT: f64 = 111_200.0;

    fn at(n: f64, e: f64) -> (f64, f64) {
        (
            LAT0 + n / M_PER_DEG_LAT,
            LON0 + e / (M_PER_DEG_LAT * LAT0.to_radians().cos()),
        )
    }

    fn report(sys: u8, id: u64, class_id: u32, t: f64, n: f64, e: f64, h_std: f64) -> Report {
        let (lat, lon) = at(n, e);
        Report {
            system_id: sys,
            track_id: id,
            merged_from_id: None,
            class_id,
            time_s: t,
            lat_deg: lat,
            lon_deg: lon,
            vel_ne_m_s: Some(Vector2::zeros()),
            h_std_m: h_std,
            tracked: true,
            provisional: false,
        }
    }

    fn ids(f: &Fuser, t: f64) -> Vec<u64> {
        f.picture(t).iter().map(|t| t.id).collect()
    }

    #[test]
    fn two_drones_seeing_one_swimmer_give_one_fused_id() {
        let mut f = Fuser::new(FuseParams::default());
        for k in 0..10 {
            let t = f64::from(k);
            f.observe(&report(1, 12, 1, t, 0.0, 0.0, 3.0));
            f.observe(&report(2, 7, 1, t, 1.5, -1.0, 3.0));
            f.step(t);
        }
        let p = f.picture(9.0);
        assert_eq!(p.len(), 1, "{p:?}");
        assert_eq!(p[0].members.len(), 2);
        assert_eq!(p[0].state, FusedTrackState::Tracked);
        assert_eq!(f.fused_id_of(1, 12), f.fused_id_of(2, 7));
        // The fused covariance is half of either's (equal weights): smaller ce.
        let single = circular_error_m(&(Matrix2::identity() * 4.5), 0.95).unwrap();
        assert!(p[0].ce95_m < single, "{} vs {single}", p[0].ce95_m);
    }

    #[test]
    fn the_estimate_weighs_the_better_drone_more() {
        let mut f = Fuser::new(FuseParams::default());
        // Truth at (0, 0). Drone 1 is 1 m off with h_std 1 m, drone 2 4 m off with 6 m.
        f.observe(&report(1, 1, 1, 0.0, 1.0, 0.0, 1.0));
        f.observe(&report(2, 1, 1, 0.0, -4.0, 0.0, 6.0));
        f.step(0.0);
        let p = &f.picture(0.0)[0];
        let frame = LocalTangentFrame::new(Geodetic {
            lat_deg: p.lat_deg,
            lon_deg: p.lon_deg,
            alt_m: 0.0,
        });
        let (lat, lon) = at(0.0, 0.0);
        let err = frame
            .to_ned(&Geodetic {
                lat_deg: lat,
                lon_deg: lon,
                alt_m: 0.0,
            })
            .xy()
            .norm();
        assert!(err < 1.0, "fused error {err} m");
    }

    #[test]
    fn neighbours_of_different_classes_or_far_apart_stay_apart() {
        let mut f = Fuser::new(FuseParams::default());
        for k in 0..5 {
            let t = f64::from(k);
            f.observe(&report(1, 1, 1, t, 0.0, 0.0, 2.0));
            f.observe(&report(2, 1, 5, t, 0.5, 0.0, 2.0)); // a buoy beside the swimmer
            f.observe(&report(2, 2, 1, t, 40.0, 0.0, 2.0)); // another swimmer, 40 m away
            f.step(t);
        }
        assert_eq!(ids(&f, 4.0).len(), 3);
    }

    #[test]
    fn one_drone_two_tracks_are_two_objects_even_when_close() {
        let mut f = Fuser::new(FuseParams::default());
        for k in 0..5 {
            let t = f64::from(k);
            f.observe(&report(1, 1, 1, t, 0.0, 0.0, 3.0));
            f.observe(&report(1, 2, 1, t, 1.0, 0.0, 3.0));
            f.step(t);
        }
        assert_eq!(ids(&f, 4.0).len(), 2);
        // A second drone's track near both joins exactly one of them.
        f.observe(&report(2, 9, 1, 5.0, 0.2, 0.0, 3.0));
        f.observe(&report(1, 1, 1, 5.0, 0.0, 0.0, 3.0));
        f.observe(&report(1, 2, 1, 5.0, 1.0, 0.0, 3.0));
        f.step(5.0);
        let p = f.picture(5.0);
        assert_eq!(p.len(), 2);
        assert_eq!(p.iter().map(|t| t.members.len()).sum::<usize>(), 3);
        assert_eq!(f.fused_id_of(2, 9), f.fused_id_of(1, 1));
    }

    #[test]
    fn a_drones_new_track_after_its_old_one_coasted_rejoins_the_fused_id() {
        let mut f = Fuser::new(FuseParams::default());
        for k in 0..5 {
            f.observe(&report(1, 1, 1, f64::from(k), 0.0, 0.0, 2.0));
            f.step(f64::from(k));
        }
        // Track 1 coasts (the drone still reports its prediction) when the drone's tracker
        // starts track 2 on the same swimmer without linking them.
        for k in 5..9 {
            let t = f64::from(k);
            let mut coasting = report(1, 1, 1, t, 0.0, 0.0, 3.0);
            coasting.tracked = false;
            f.observe(&coasting);
            if k >= 7 {
                f.observe(&report(1, 2, 1, t, 0.8, 0.0, 2.0));
            }
            f.step(t);
        }
        assert_eq!(f.fused_id_of(1, 2), f.fused_id_of(1, 1));
        assert_eq!(ids(&f, 8.0).len(), 1);
    }

    #[test]
    fn a_drone_track_reacquired_far_from_its_fused_track_leaves_it() {
        let mut f = Fuser::new(FuseParams::default());
        // Drone 2's track 12 follows something for 5 s, then is not reported for 10 s.
        for k in 0..5 {
            f.observe(&report(2, 12, 2, f64::from(k), 100.0, 0.0, 2.0));
            f.step(f64::from(k));
        }
        let phantom = f.fused_id_of(2, 12).unwrap();
        // Meanwhile drone 1 tracks a boat 100 m away.
        for k in 10..15 {
            f.observe(&report(1, 22, 2, f64::from(k), 0.0, 0.0, 2.0));
            f.step(f64::from(k));
        }
        let boat = f.fused_id_of(1, 22).unwrap();
        assert_ne!(boat, phantom);
        // Drone 2's ReID puts its track 12 on that boat: it joins the boat's fused id and
        // the phantom's id ends in it.
        f.observe(&report(2, 12, 2, 15.0, 0.5, 0.0, 2.0));
        f.observe(&report(1, 22, 2, 15.0, 0.0, 0.0, 2.0));
        f.step(15.0);
        assert_eq!(f.fused_id_of(2, 12), Some(boat));
        assert_eq!(
            f.take_retired(),
            vec![Retired {
                id: phantom,
                into: boat
            }]
        );
        assert_eq!(ids(&f, 15.0), vec![boat]);
    }

    #[test]
    fn a_drone_track_reacquired_far_away_where_nobody_else_is_keeps_its_fused_id() {
        let mut f = Fuser::new(FuseParams::default());
        // Drone 2 sees a swimmer for 5 s, then loses it for 40 s; its ReID brings track 5
        // back 40 m on (the swimmer moved more than the drift says). No other drone sees it
        // and nothing else is there: the fused id follows the drone's track once it has been
        // held for reacquire_hold_s (5 s) with nothing saying otherwise.
        for k in 0..5 {
            f.observe(&report(2, 5, 1, f64::from(k), 0.0, 0.0, 1.0));
            f.step(f64::from(k));
        }
        let id = f.fused_id_of(2, 5).unwrap();
        for k in 5..45 {
            f.step(f64::from(k));
        }
        let north = |f: &Fuser, t: f64| {
            let p = f.picture(t);
            assert_eq!(p.len(), 1);
            ((p[0].lat_deg - LAT0) * M_PER_DEG_LAT, p[0].state)
        };
        for k in 45..=50 {
            f.observe(&report(2, 5, 1, f64::from(k), 40.0, 0.0, 1.0));
            f.step(f64::from(k));
            assert_eq!(f.fused_id_of(2, 5), Some(id));
            let (n, state) = north(&f, f64::from(k));
            if k < 50 {
                // Held: the fused track stays where it was carried to, lost.
                assert!(n.abs() < 1.0, "{n} m at {k} s");
                assert_eq!(state, FusedTrackState::Lost);
            } else {
                assert!((n - 40.0).abs() < 1.0, "{n} m at {k} s");
                assert_eq!(state, FusedTrackState::Tracked);
            }
        }
        assert!(f.take_retired().is_empty());
        // ... and a later track of drone 1 there joins that id.
        f.observe(&report(1, 9, 1, 51.0, 40.3, 0.2, 1.0));
        f.observe(&report(2, 5, 1, 51.0, 40.0, 0.0, 1.0));
        f.step(51.0);
        assert_eq!(f.fused_id_of(1, 9), Some(id));
        assert_eq!(f.ids_given(), 1);
    }

    /// Seen on the ArduPilot SITL bench (one drone): swimmers A and B 12 m apart, both lost
    /// for 45 s; the drone's ReID brought A's track back where A had drifted, nearer B's lost
    /// fused track than A's. Only this drone ever saw either, so the ground has nothing to
    /// weigh against the drone's ReID: both keep their fused ids, and none is given anew.
    #[test]
    fn one_drones_reid_is_not_overruled_by_nearness_alone() {
        let mut f = Fuser::new(FuseParams::default());
        for k in 0..6 {
            let t = f64::from(k);
            f.observe(&report(1, 3, 1, t, 0.0, 0.0, 1.0));
            f.observe(&report(1, 4, 1, t, 12.0, 0.0, 1.0));
            f.step(t);
        }
        let (a, b) = (f.fused_id_of(1, 3), f.fused_id_of(1, 4));
        assert!(a.is_some() && b.is_some() && a != b);
        for k in 6..51 {
            f.step(f64::from(k));
        }
        // A's track comes back 7.6 m from A's last place and 7.2 m from B's; B's a second
        // later, where B was.
        for k in 51..66 {
            let t = f64::from(k);
            f.observe(&report(1, 3, 1, t, 6.5, 4.0, 1.0));
            if k > 51 {
                f.observe(&report(1, 4, 1, t, 12.3, 0.2, 1.0));
            }
            f.step(t);
            assert_eq!(f.fused_id_of(1, 3), a, "at {t} s");
            if k > 51 {
                assert_eq!(f.fused_id_of(1, 4), b, "at {t} s");
            }
        }
        assert_eq!(f.ids_given(), 2);
        assert!(f.take_retired().is_empty());
        // Followed once the hold is over: A's fused track is where A's track is.
        let p = f.picture(65.0);
        let pa = p
            .iter()
            .find(|x| Some(x.id) == a)
            .map(|x| (x.lat_deg, x.state));
        let (lat, state) = pa.unwrap_or((f64::NAN, FusedTrackState::Lost));
        assert!(((lat - LAT0) * M_PER_DEG_LAT - 6.5).abs() < 1.0, "{lat}");
        assert_eq!(state, FusedTrackState::Tracked);
    }

    /// Seen in CI on `two_drones_abreast` seed 31: drone 2's track came back 55 s later where
    /// the carried estimate was not, and was held; drone 1's new track of the same swimmer
    /// then started a fused id of its own, and the swimmer had two. Now drone 1's track joins
    /// the held track's fused id, and the held track is released.
    #[test]
    fn another_drones_new_track_at_a_held_track_joins_its_fused_id() {
        let mut f = Fuser::new(FuseParams::default());
        for k in 0..5 {
            f.observe(&report(2, 5, 1, f64::from(k), 0.0, 0.0, 1.0));
            f.step(f64::from(k));
        }
        let id = f.fused_id_of(2, 5).unwrap();
        for k in 5..60 {
            f.step(f64::from(k));
        }
        f.observe(&report(2, 5, 1, 60.0, 40.0, 0.0, 1.0));
        f.step(60.0);
        assert_eq!(f.picture(60.0)[0].state, FusedTrackState::Lost, "held");
        f.observe(&report(2, 5, 1, 61.0, 40.0, 0.0, 1.0));
        f.observe(&report(1, 71, 1, 61.0, 40.4, 0.3, 1.0));
        f.step(61.0);
        assert_eq!(f.fused_id_of(1, 71), Some(id));
        f.observe(&report(2, 5, 1, 62.0, 40.0, 0.0, 1.0));
        f.observe(&report(1, 71, 1, 62.0, 40.4, 0.3, 1.0));
        f.step(62.0);
        let p = f.picture(62.0);
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].state, FusedTrackState::Tracked);
        assert_eq!(p[0].members.len(), 2);
        assert_eq!(f.ids_given(), 1);
    }

    #[test]
    fn a_held_track_that_comes_back_inside_the_gate_is_released_at_once() {
        let mut f = Fuser::new(FuseParams::default());
        for k in 0..5 {
            f.observe(&report(2, 5, 1, f64::from(k), 0.0, 0.0, 1.0));
            f.step(f64::from(k));
        }
        for k in 5..45 {
            f.step(f64::from(k));
        }
        // A first fix 40 m off (held), then the drone's track settles where the swimmer was.
        f.observe(&report(2, 5, 1, 45.0, 40.0, 0.0, 1.0));
        f.step(45.0);
        assert_eq!(f.picture(45.0)[0].state, FusedTrackState::Lost);
        f.observe(&report(2, 5, 1, 46.0, 1.0, 0.0, 1.0));
        f.step(46.0);
        assert_eq!(f.picture(46.0)[0].state, FusedTrackState::Tracked);
    }

    /// Seen on `two_drones_abreast` seed 101: after both drones looked away for 25 s, drone 1's
    /// long-term ReID brought each of its swimmer tracks back on the neighbouring swimmer
    /// (a group in a line), while drone 2's came back right. The fused ids stay with the
    /// swimmers, whichever drone's reports arrive first, and no fused id is given twice:
    /// after 25 s away the neighbour is outside a fused track's gate, after 60 s inside it.
    #[test]
    fn a_drones_reid_that_shifted_a_group_moves_no_fused_id() {
        for (drone_1_first, gap_s) in [(true, 25), (false, 25), (true, 60), (false, 60)] {
            let back = 10.0 + f64::from(gap_s);
            let mut f = Fuser::new(FuseParams::default());
            // Swimmers A, B, C at 0, 15 and 30 m north; drone 1 tracks 1, 2, 3, drone 2
            // tracks 11, 12, 13.
            for k in 0..10 {
                let t = f64::from(k);
                for (i, n) in [0.0, 15.0, 30.0].into_iter().enumerate() {
                    f.observe(&report(1, 1 + i as u64, 1, t, n, 0.0, 2.0));
                    f.observe(&report(2, 11 + i as u64, 1, t, n + 0.5, 0.3, 2.0));
                }
                f.step(t);
            }
            let before: Vec<Option<u64>> = (11..14).map(|id| f.fused_id_of(2, id)).collect();
            assert_eq!(ids(&f, 9.0).len(), 3);
            for k in 10..10 + gap_s {
                f.step(f64::from(k));
            }
            // Back at 35 s: drone 1's track 1 on B, 2 on C, and a new track 4 on A; drone 2
            // right. Drone 1 lost its track 3.
            let drone_1 = |t: f64| {
                [
                    report(1, 1, 1, t, 15.2, 0.0, 2.0),
                    report(1, 2, 1, t, 30.2, 0.0, 2.0),
                    report(1, 4, 1, t, 0.2, 0.0, 2.0),
                ]
            };
            let drone_2 = |t: f64| {
                [
                    report(2, 11, 1, t, 0.5, 0.3, 2.0),
                    report(2, 12, 1, t, 15.5, 0.3, 2.0),
                    report(2, 13, 1, t, 30.5, 0.3, 2.0),
                ]
            };
            let mut t = back;
            while t < back + 15.0 {
                let (first, second) = if drone_1_first {
                    (drone_1(t), drone_2(t + 0.5))
                } else {
                    (drone_2(t), drone_1(t + 0.5))
                };
                for r in &first {
                    f.observe(r);
                }
                f.step(t);
                for r in &second {
                    f.observe(r);
                }
                f.step(t + 0.5);
                t += 1.0;
            }
            let after: Vec<Option<u64>> = (11..14).map(|id| f.fused_id_of(2, id)).collect();
            let case = format!("drone 1 first: {drone_1_first}, gap {gap_s} s");
            assert_eq!(after, before, "{case}");
            assert_eq!(f.fused_id_of(1, 4), before[0]);
            assert_eq!(f.fused_id_of(1, 1), before[1]);
            assert_eq!(f.fused_id_of(1, 2), before[2]);
            assert_eq!(f.ids_given(), 3, "{case}");
            assert_eq!(ids(&f, back + 14.5).len(), 3);
        }
    }

    /// Seen on `two_drones_abreast` seed 404: both drones' ReID made the same mistake. After
    /// 25 s away, each drone's track of swimmer A came back on C (never seen before) and its
    /// track of B came back on A; B was then found by new tracks. A and B keep their fused ids
    /// (B's carried with the drift, not retired into A's), C gets a new one, and no fused
    /// track ever holds two tracks one drone had at the same time.
    #[test]
    fn both_drones_reid_wrong_alike_moves_no_fused_id() {
        let mut f = Fuser::new(FuseParams::default());
        for k in 0..10 {
            let t = f64::from(k);
            for (sys, off) in [(1u8, 0.0), (2, 0.4)] {
                let base = u64::from(sys) * 10;
                f.observe(&report(sys, base + 1, 1, t, off, 0.0, 2.0));
                f.observe(&report(sys, base + 2, 1, t, 15.0 + off, 0.0, 2.0));
            }
            f.step(t);
        }
        let (a, b) = (f.fused_id_of(1, 11).unwrap(), f.fused_id_of(1, 12).unwrap());
        assert_eq!(f.fused_id_of(2, 21), Some(a));
        assert_eq!(f.fused_id_of(2, 22), Some(b));
        for k in 10..35 {
            f.step(f64::from(k));
        }
        for k in 0..15 {
            let t = 35.0 + f64::from(k);
            for (sys, off) in [(1u8, 0.0), (2, 0.4)] {
                let base = u64::from(sys) * 10;
                f.observe(&report(sys, base + 1, 1, t, 30.0 + off, 0.0, 2.0)); // A's, on C
                f.observe(&report(sys, base + 2, 1, t, off, 0.0, 2.0)); // B's, on A
                if k >= 8 {
                    f.observe(&report(sys, base + 5, 1, t, 15.0 + off, 0.0, 2.0));
                    // new, on B
                }
            }
            f.step(t);
            for id in f.picture(t).iter().map(|p| p.id) {
                let m: Vec<MemberKey> = f.fused[&id].members.iter().copied().collect();
                for (i, x) in m.iter().enumerate() {
                    for y in &m[i + 1..] {
                        let (mx, my) = (&f.members[x], &f.members[y]);
                        let both_live = f.is_live(mx, t) && f.is_live(my, t);
                        assert!(
                            x.0 != y.0
                                || !both_live
                                || mx.held_until_s.is_some()
                                || my.held_until_s.is_some(),
                            "fused {id} holds {x:?} and {y:?} at {t} s"
                        );
                    }
                }
            }
        }
        assert_eq!(f.fused_id_of(1, 12), Some(a));
        assert_eq!(f.fused_id_of(2, 22), Some(a));
        assert_eq!(f.fused_id_of(1, 15), Some(b));
        assert_eq!(f.fused_id_of(2, 25), Some(b));
        let c = f.fused_id_of(1, 11).unwrap();
        assert!(c != a && c != b);
        assert_eq!(f.fused_id_of(2, 21), Some(c));
        assert_eq!(f.ids_given(), 3);
        assert!(f.take_retired().is_empty());
    }

    /// Seen on `two_drones_abreast` seed 101's rerun: two swimmers 3.6 m apart. Drone 2's
    /// track of A and drone 1's track of B came first and were paired; drone 1's track of A
    /// then takes B's track's place, B's track is associated anew and drone 2's track of B
    /// joins it: two fused ids, each with both drones' tracks of one swimmer.
    #[test]
    fn a_first_pairing_of_two_neighbours_the_wrong_way_round_is_undone() {
        for rematch_within_s in [10.0, 0.0] {
            let mut f = Fuser::new(FuseParams {
                rematch_within_s,
                ..FuseParams::default()
            });
            let (a, b) = (0.0, 3.6);
            for k in 0..8 {
                let t = f64::from(k);
                f.observe(&report(2, 26, 1, t, a, 0.0, 2.0));
                if k >= 1 {
                    f.observe(&report(1, 44, 1, t, b, 0.0, 2.0));
                }
                if k >= 2 {
                    f.observe(&report(1, 46, 1, t, a + 0.2, 0.0, 2.0));
                }
                if k >= 3 {
                    f.observe(&report(2, 29, 1, t, b + 0.2, 0.0, 2.0));
                }
                f.step(t);
            }
            if rematch_within_s > 0.0 {
                assert_eq!(f.fused_id_of(1, 46), f.fused_id_of(2, 26));
                assert_eq!(f.fused_id_of(1, 44), f.fused_id_of(2, 29));
                assert_eq!(f.ids_given(), 2);
            } else {
                // Without it the first pairing stands (the behaviour before 2026-12-07).
                assert_eq!(f.fused_id_of(1, 44), f.fused_id_of(2, 26));
            }
        }
    }

    #[test]
    fn a_lost_track_is_carried_with_its_own_velocity_only_when_it_was_measured_long_enough() {
        // North of each track's start at `t`, in the picture.
        fn north_at(f: &Fuser, id: u64, t: f64) -> f64 {
            let p = f.picture(t).into_iter().find(|p| p.id == id).unwrap();
            let (lat0, _) = at(0.0, 0.0);
            (p.lat_deg - lat0) * 111_320.0
        }
        let mut f = Fuser::new(FuseParams::default());
        // A still boat whose drone track "moved" 2 m/s for 3 s (the drone's geolocation error
        // changing as it flew), and a jetski under way at 3 m/s for 10 s, 200 m apart.
        for k in 0..=10 {
            let t = f64::from(k);
            if k <= 3 {
                let mut r = report(1, 1, 2, t, 2.0 * t, 0.0, 1.0);
                r.vel_ne_m_s = Some(Vector2::new(2.0, 0.0));
                f.observe(&r);
            }
            let mut r = report(1, 2, 3, t, 3.0 * t, 200.0, 1.0);
            r.vel_ne_m_s = Some(Vector2::new(3.0, 0.0));
            f.observe(&r);
            f.step(t);
        }
        let (still, under_way) = (f.fused_id_of(1, 1).unwrap(), f.fused_id_of(1, 2).unwrap());
        for k in 11..=40 {
            f.step(f64::from(k));
        }
        // Lost for 30 s: the still boat stays where last seen; the other is carried on.
        assert!((north_at(&f, still, 40.0) - 6.0).abs() < 1.0);
        assert!((north_at(&f, under_way, 40.0) - 120.0).abs() < 2.0);
    }

    #[test]
    fn a_drone_merge_merges_the_fused_tracks() {
        let mut f = Fuser::new(FuseParams::default());
        // Drone 1 sees a swimmer as track 3 and loses it; its new track 8, 25 m on (too far
        // for the fuser's gate), gets a fused id of its own. Then drone 1's ReID says 8 is 3:
        // MGMOT_TRACK continues id 3 with merged_from_id 8.
        f.observe(&report(1, 3, 1, 0.0, 0.0, 0.0, 2.0));
        f.step(0.0);
        let first = f.fused_id_of(1, 3);
        f.observe(&report(1, 8, 1, 10.0, 25.0, 0.0, 2.0));
        f.step(10.0);
        assert_ne!(f.fused_id_of(1, 8), first);
        let mut r = report(1, 3, 1, 11.0, 25.0, 0.0, 2.0);
        r.merged_from_id = Some(8);
        f.observe(&r);
        f.step(11.0);
        assert_eq!(f.fused_id_of(1, 3), first);
        assert_eq!(f.fused_id_of(1, 8), None);
        let retired = f.take_retired();
        assert_eq!(retired.len(), 1);
        assert_eq!(Some(retired[0].into), first);
        assert_eq!(ids(&f, 11.0), vec![first.unwrap()]);
    }

    #[test]
    fn tracks_appearing_apart_and_converging_are_merged_after_the_wait() {
        let p = FuseParams {
            max_distance_m: 30.0,
            ..FuseParams::default()
        };
        let mut f = Fuser::new(p);
        // First sight 20 m apart (a bad first fix), then converging on the same point.
        f.observe(&report(1, 1, 2, 0.0, 0.0, 0.0, 2.0));
        f.observe(&report(2, 1, 2, 0.0, 20.0, 0.0, 2.0));
        f.step(0.0);
        assert_eq!(ids(&f, 0.0).len(), 2);
        for k in 1..=4 {
            let t = f64::from(k);
            f.observe(&report(1, 1, 2, t, 0.0, 0.0, 2.0));
            f.observe(&report(2, 1, 2, t, 0.5, 0.0, 2.0));
            f.step(t);
        }
        assert_eq!(ids(&f, 4.0), vec![1]);
        assert_eq!(f.take_retired(), vec![Retired { id: 2, into: 1 }]);
    }

    #[test]
    fn a_lost_object_drifts_and_a_later_drone_track_rejoins_it() {
        let mut f = Fuser::new(FuseParams::default());
        // Three swimmers drift east at 0.2 m/s, seen by drone 1 for 60 s.
        let drift = 0.2;
        for k in 0..60 {
            let t = f64::from(k);
            for (id, n) in [(1u64, 0.0), (2, 15.0), (3, -15.0)] {
                let mut r = report(1, id, 1, t, n, drift * t, 2.0);
                r.vel_ne_m_s = Some(Vector2::new(0.0, drift));
                f.observe(&r);
            }
            f.step(t);
        }
        assert_eq!(ids(&f, 59.0), vec![1, 2, 3]);
        // Nobody sees them for two minutes.
        for k in 60..180 {
            f.step(f64::from(k));
        }
        let lost = f.picture(180.0);
        assert!(lost.iter().all(|t| t.state == FusedTrackState::Lost));
        // Drone 2 comes and finds swimmer 1 where the current took it.
        let t = 180.0;
        let mut r = report(2, 40, 1, t, 0.5, drift * t, 2.0);
        r.vel_ne_m_s = Some(Vector2::new(0.0, drift));
        f.observe(&r);
        f.step(t);
        assert_eq!(f.fused_id_of(2, 40), Some(1));
        assert_eq!(ids(&f, t).len(), 3);
    }

    #[test]
    fn provisional_and_stale_reports_are_not_used() {
        let mut f = Fuser::new(FuseParams::default());
        let mut r = report(1, 1, 1, 5.0, 0.0, 0.0, 2.0);
        r.provisional = true;
        assert!(!f.observe(&r));
        r.provisional = false;
        assert!(f.observe(&r));
        assert!(!f.observe(&report(1, 1, 1, 4.0, 3.0, 0.0, 2.0)));
        // A clock mapped anew (minutes back) is not a late report.
        assert!(f.observe(&report(1, 1, 1, -300.0, 0.0, 0.0, 2.0)));
        assert!(f.observe(&report(1, 1, 1, 5.0, 0.0, 0.0, 2.0)));
        let mut bad = report(1, 2, 1, 5.0, 0.0, 0.0, 2.0);
        bad.lat_deg = f64::NAN;
        assert!(!f.observe(&bad));
        f.step(5.0);
        assert_eq!(ids(&f, 5.0).len(), 1);
    }

    #[test]
    fn forgotten_after_keep_s() {
        let p = FuseParams {
            keep_s: 30.0,
            ..FuseParams::default()
        };
        let mut f = Fuser::new(p);
        f.observe(&report(1, 1, 1, 0.0, 0.0, 0.0, 2.0));
        f.step(0.0);
        f.step(20.0);
        assert_eq!(ids(&f, 20.0).len(), 1);
        f.step(40.0);
        assert!(ids(&f, 40.0).is_empty());
        assert_eq!(f.fused_id_of(1, 1), None);
    }

    #[test]
    fn validate_names_the_bad_parameter() {
        let p = FuseParams {
            gate_chi2: -1.0,
            ..FuseParams::default()
        };
        assert!(p.validate().unwrap_err().contains("gate_chi2"));
        assert!(FuseParams::default().validate().is_ok());
    }

    mod properties {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            /// Objects further apart than the distance cap, each seen by two drones with errors
            /// inside their stated uncertainty: exactly one fused id per object, holding both
            /// drones' tracks, and the fused position never further from the truth than the
            /// worse of the two reports (it is a weighted mean of them).
            #[test]
            fn separated_objects_seen_by_two_drones_fuse_one_to_one(
                objects in proptest::collection::vec(
                    ((-1.0f64..1.0, -1.0f64..1.0), (-1.0f64..1.0, -1.0f64..1.0), 1.0f64..4.0),
                    1..8,
                ),
            ) {
                let mut f = Fuser::new(FuseParams::default());
                let spacing = 100.0;
                for (k, (e1, e2, h_std)) in objects.iter().enumerate() {
                    let n = spacing * k as f64;
                    let id = k as u64 + 1;
                    f.observe(&report(1, id, 1, 0.0, n + e1.0, e1.1, *h_std));
                    f.observe(&report(2, 100 + id, 1, 0.0, n + e2.0, e2.1, *h_std));
                }
                f.step(0.0);
                let picture = f.picture(0.0);
                prop_assert_eq!(picture.len(), objects.len());
                let frame = LocalTangentFrame::new(Geodetic { lat_deg: LAT0, lon_deg: LON0, alt_m: 0.0 });
                for (k, (e1, e2, _)) in objects.iter().enumerate() {
                    let id = k as u64 + 1;
                    let fused = f.fused_id_of(1, id);
                    prop_assert!(fused.is_some());
                    prop_assert_eq!(fused, f.fused_id_of(2, 100 + id));
                    let t = picture.iter().find(|t| Some(t.id) == fused).unwrap();
                    prop_assert_eq!(t.members.len(), 2);
                    let (lat, lon) = at(spacing * k as f64, 0.0);
                    let truth = frame.to_ned(&Geodetic { lat_deg: lat, lon_deg: lon, alt_m: 0.0 }).xy();
                    let got = frame.to_ned(&Geodetic { lat_deg: t.lat_deg, lon_deg: t.lon_deg, alt_m: 0.0 }).xy();
                    let worse = e1.0.hypot(e1.1).max(e2.0.hypot(e2.1));
                    prop_assert!((got - truth).norm() <= worse + 0.05, "{} > {}", (got - truth).norm(), worse);
                }
            }
        }
    }
}
