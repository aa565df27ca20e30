//! All tracker parameters in one struct; the defaults are the paper's values where it gives
//! them, and documented choices where it does not.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::contact::ContactParams;
use super::drift::DriftParams;
use super::error::TrackError;
use crate::geo::AttitudeSmoothing;

/// Every parameter of the tracker (baseline, MG-MOT ReID, offline post-processing).
///
/// Loadable from a config file (`#[serde(default, deny_unknown_fields)]`: missing fields take
/// the defaults, misspelt ones are errors). Call [`TrackerParams::validate`] after loading.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackerParams {
    /// BoT-SORT image-plane association.
    pub baseline: BaselineParams,
    /// MG-MOT metadata-guided re-identification.
    pub reid: ReidParams,
    /// Offline post-processing (interpolation).
    pub offline: OfflineParams,
    /// Identity swaps inside a close group repaired by colour once it parts.
    pub contact: ContactParams,
}

/// BoT-SORT baseline parameters (paper Sec. 5.1 "Tracking").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BaselineParams {
    /// Detections at or above this score enter the first association stage (paper: 0.5).
    pub track_high_thresh: f32,
    /// Detections below this score are ignored; between this and `track_high_thresh` they
    /// enter the second stage (paper: 0.1).
    pub track_low_thresh: f32,
    /// Unmatched high-confidence detections at or above this score start a new track
    /// (paper: 0.2; with the high threshold at 0.5 every unmatched high detection qualifies,
    /// as in the paper's BoT-SORT configuration).
    pub new_track_thresh: f32,
    /// Frames a lost track is kept for IoU re-activation before it is removed (paper: 100).
    pub track_buffer_frames: u64,
    /// First-stage gate on the cost `1 - IoU * score` (BoT-SORT `match_thresh`). 0.9, the
    /// best value of the paper's matching-threshold ablation (Table "thresholds": HOTA 69.9
    /// at 0.9 against 69.6 at 0.6-0.8).
    pub match_thresh: f64,
    /// Second-stage (low-confidence detections) gate on `1 - IoU` (BoT-SORT constant 0.5).
    pub second_match_thresh: f64,
    /// Gate on `1 - IoU * score` for matching tentative tracks (BoT-SORT constant 0.7).
    pub unconfirmed_match_thresh: f64,
    /// Multiply IoU by the detection score in the high-confidence stages (BoT-SORT default
    /// for non-MOT20 data).
    pub fuse_score: bool,
    /// A tracked and a lost track whose boxes overlap with `1 - IoU` below this are
    /// duplicates; the younger one is removed (BoT-SORT constant 0.15).
    pub duplicate_iou_dist: f64,
    /// IoU threshold of the "prefer larger" NMS applied to the detections of every frame
    /// (paper Sec. 5.1 post-processing; 0.5 is the best "IoU threshold" of the paper's
    /// ablation). Off (`None`) by default: measured on the simulator's close groups
    /// (`swimmer_group`, held-out seed 7771), it suppressed the real detections of
    /// overlapping swimmers (online IDF1 0.851 with it, 0.982 without; nothing else in the
    /// benchmark changed). It cannot do what the paper wants it for either: a small false
    /// positive inside an object at least twice its area has an IoU of at most 0.5 with it,
    /// so only boxes of similar size are ever suppressed. Set 0.5 for the paper's setting.
    pub nms_iou_threshold: Option<f64>,
    /// Standard deviation of the white-noise acceleration of the world-state filter, m/s^2.
    /// 0.5: swimmers and drifting objects barely accelerate; boats manoeuvre more but the
    /// world state is re-anchored by every observation (tens per second).
    pub world_accel_std_m_s2: f64,
    /// Metadata-guided association (MG-MOT's addition to BoT-SORT, not in the paper): after
    /// the IoU stages, detections left over (high or low confidence) are matched to the
    /// confirmed and lost tracks left over by the squared Mahalanobis distance between the
    /// detection's sea-surface position and the track's world state predicted to the frame
    /// (innovation covariance = predicted position covariance + the detection's), one
    /// assignment per class, gated at this value. 9.21 is the chi-square 99 % quantile
    /// with 2 degrees of freedom. It keeps small, flickering objects (a swimmer seen from
    /// 60-90 m is a few pixels wide, its box jitters by as much as it overlaps) on one
    /// track where IoU fails. 2.0 (63 %), chosen on the benchmark: 9.21 let the fast
    /// gimbal swings' geolocation errors pair wrong tracks (offline IDF1 on gimbal_swings
    /// seed 7771 0.838 against 0.918 at 4.0), and 4.0 still re-acquired lost tracks on
    /// the wrong swimmer after short gaps in the long missions (`expanding_square` own
    /// seed: 17 id changes after a gap at 4.0, 12 at 2.0; `sector_search` and
    /// `expanding_square`, 4 seeds: online IDF1 over the oracle's +0.02 to +0.03, offline
    /// +0.02 to +0.04 at 2.0; 1.0 cost `gimbal_swings` online 0.04). `None` disables it
    /// (plain BoT-SORT association).
    pub world_gate_chi2: Option<f64>,
    /// Whether the world stage (`world_gate_chi2`) offers the low-confidence detections
    /// left over (between `track_low_thresh` and `track_high_thresh`) to lost tracks too,
    /// not only to the tracks matched in the previous frame (false: as in BoT-SORT's second
    /// stage, a low-confidence box continues a track but does not bring a lost one back).
    /// Which is better depends on what the detector's low scores mean. On by default: the
    /// simulated detector's low-confidence boxes are real, small swimmers, and off cost its
    /// benchmark broadly (12 seeds x 10 scenarios: `mixed_mission_soak` online HOTA -0.02 to
    /// -0.04 on every seed, `gimbal_swings` seeds 14 and 90210 online IDF1 -0.13 and -0.09,
    /// `swimmer_group` seed 12 -0.06). Off for the shipped model (its setting with
    /// `track_high_thresh` 0.4: `systemd/mgmot.example.toml`, the demo, the benchmark): the
    /// low-confidence boxes it leaves over in a group, given to lost tracks, were mostly
    /// false positives. Its `swimmer_group` own seed: FP 694 -> 515 online (FN +62), HOTA /
    /// IDF1 online 0.446 / 0.671 -> 0.461 / 0.646, offline 0.444 / 0.667 -> 0.462 / 0.647
    /// (the tracker before the world stage: 0.456 / 0.644 and 0.462 / 0.648); seed 7771
    /// online 0.464 / 0.679 -> 0.496 / 0.724, offline 0.462 / 0.675 -> 0.494 / 0.722; its
    /// other six runs within 0.003.
    pub world_low_confidence_to_lost: bool,
    /// Frames a lost track is still reported ("coasting") after its last detection: with
    /// its Kalman-predicted box, its world state predicted to the frame, state
    /// [`TrackState::Lost`](super::TrackState::Lost) and no detection, while the whole
    /// predicted box stays inside the image. A small swimmer's detections flicker (a frame
    /// missed here and there in the waves); BoT-SORT reports only matched tracks, so each
    /// flicker is a hole in the track and a blink on the operator's map. 0 is BoT-SORT's
    /// output. 2, measured on the benchmark (96 runs: 10 scenarios, 12 seeds for the long
    /// missions and the short scenarios with sweeps or groups, 4 for the others; online,
    /// provisional tracks withheld): IDF1 over the oracle's +0.013 and HOTA +0.031 on the
    /// mean, no run down by more than 0.01 in either (`lawnmower_search` IDF1 -0.005 on its
    /// mean, the only scenario that loses); 1 gives nearly as much, 5 and 30 a little less
    /// (the predicted boxes drift off the truth). Offline never coasts: interpolation fills
    /// the holes from both ends.
    pub coast_frames: u64,
    /// Camera-motion compensation with the sea-plane homography between consecutive frames'
    /// poses (the caller's [`FrameInput::image_motion`](super::FrameInput::image_motion),
    /// from the drone metadata): every track's predicted box is carried by the camera's
    /// motion before the IoU stages, as BoT-SORT carries it by its image registration.
    /// `false` ignores the homography (the box filter then absorbs the camera's motion as
    /// track velocity). Measured on the benchmark (docs/benchmark.md, "Metadata camera-motion
    /// compensation", 4 seeds, online HOTA with -> without): `gimbal_swings` 0.770 -> 0.687,
    /// `expanding_square` 0.695 -> 0.643, `fast_drone` 0.814 -> 0.790; but the simulated
    /// attitude noise (white, 0.1-0.15 deg a sample) makes it cost `lawnmower_search`
    /// (0.617 -> 0.771 without) and `sector_search` (0.642 -> 0.707).
    pub camera_motion_compensation: bool,
    /// Smoothing of the camera attitude the motion compensation's homography is computed
    /// from (not the geolocation's): an alpha-beta filter that keeps the camera's smooth
    /// motion and drops the attitude's frame-to-frame noise, snapping to the measurement on
    /// a real jump (see [`AttitudeSmoothing`]). Applied by the caller that builds the
    /// tracker's inputs ([`crate::frame::InputBuilder`], `mgmot track`). Measured on the
    /// benchmark: docs/benchmark.md, "Metadata camera-motion compensation".
    pub cmc_smoothing: AttitudeSmoothing,
    /// Added to the cost of a track and a detection of different classes in the IoU stages
    /// (the track's class is its majority vote), so that a track prefers its own class's
    /// detection when it has one and still takes another class's when it has none (a
    /// detector confuses a swimmer and a life-saving appliance now and then). 0 is
    /// BoT-SORT's class-blind association. 0.05, measured (docs/benchmark.md, "Class-aware
    /// association"): on `swimmer_group` seed 90210 a swimmer's track took a life ring's
    /// first detection beside it (IoU 0.18, a cost just under the 0.9 gate) while its own
    /// swimmer's detection, low in score, waited for the second stage.
    pub class_mismatch_cost: f64,
}

impl Default for BaselineParams {
    fn default() -> Self {
        Self {
            track_high_thresh: 0.5,
            track_low_thresh: 0.1,
            new_track_thresh: 0.2,
            track_buffer_frames: 100,
            match_thresh: 0.9,
            second_match_thresh: 0.5,
            unconfirmed_match_thresh: 0.7,
            fuse_score: true,
            duplicate_iou_dist: 0.15,
            nms_iou_threshold: None,
            world_accel_std_m_s2: 0.5,
            world_gate_chi2: Some(2.0),
            world_low_confidence_to_lost: true,
            coast_frames: 2,
            camera_motion_compensation: true,
            cmc_smoothing: AttitudeSmoothing::default(),
            class_mismatch_cost: 0.05,
        }
    }
}

/// Thresholds of the class-wise ReID for one class (paper Sec. 3.2 "Class-wise Re-ID").
///
/// Time is in seconds throughout (the paper counts frames; real time is used here because
/// frames can be dropped and the frame rate varies), so `lambda_per_s` is per second.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClassReidParams {
    /// tau_match, m: largest world distance between an exit and an entry that may be linked
    /// (short-term gate, and the base of the long-term gate).
    pub tau_match_m: f64,
    /// tau_memory, s: longest time a track is extrapolated (BiME, Eq. 7); beyond it the
    /// extrapolated position stays put.
    pub tau_memory_s: f64,
    /// lambda, 1/s: matching threshold expansion rate (MTE, Eq. 9):
    /// `tau' = lambda * (dt_exit + dt_entry) * tau_match`, see
    /// [`expanded_match_threshold`](super::reid::expanded_match_threshold).
    pub lambda_per_s: f64,
    /// Upper bound on the expanded gate, m: without it MTE grows without limit and a long
    /// enough gap would link any two tracks of the class. The Mahalanobis gate keeps it as
    /// a hard bound on the distance too.
    pub max_gate_m: f64,
    /// Mahalanobis gate only: how fast the unobserved object's position spreads over a gap,
    /// m^2/s, added as `diffusion * gap` to both axes' variance (a random walk of the
    /// object's own motion that the end velocities do not predict: a swimmer changing
    /// direction, a boat changing course).
    pub diffusion_m2_s: f64,
    /// Mahalanobis gate only: standard deviation, m, of the systematic geolocation error
    /// between two sightings from different viewpoints (attitude and altitude biases that
    /// the per-detection covariance treats as white), added to both axes.
    pub view_bias_m: f64,
    /// Whether objects of the class drift with the sea (current plus wind leeway): their
    /// tracks feed the class's drift estimate ([`DriftParams`]) and long-term ReID carries
    /// them with it over a whole gap. True for swimmers, life-saving appliances and buoys
    /// (a moored buoy's estimate is simply zero); false for boats and jetskis, whose own
    /// motion dominates.
    pub adrift: bool,
    /// Drift only: standard deviation of an object's own velocity through the water per
    /// axis, m/s, the prior its estimated velocity relative to the drift is shrunk against
    /// (see [`mahalanobis_long_term_cost`](super::reid::mahalanobis_long_term_cost)).
    pub own_speed_std_m_s: f64,
    /// Drift only: longest time, s, an end is extrapolated by its own (shrunk) velocity on
    /// top of the drift.
    pub own_motion_s: f64,
    /// Appearance gate: an exit and an entry of this class whose mean colour signatures
    /// ([`super::appearance::Appearance`], from the pixels of their detections) are further
    /// apart than this Hellinger distance are never linked. Only pairs where both ends have
    /// a signature (`reid.appearance_min_count` detections with one) are judged; the others
    /// are linked on position alone. 1 (the largest distance) turns the gate off.
    pub appearance_gate: f64,
    /// Weight of the colours' evidence in the long-term link cost (Mahalanobis gate), in
    /// squared-distance units: a pair whose signatures are identical costs
    /// `appearance_weight_chi2 / 2` less (and may lie that much beyond the position gate),
    /// one at the appearance gate that much more (see `reid::appearance_cost`). 0 (default):
    /// the colours only gate. Needs `appearance_gate` below 1. Measured at 4 against the gate
    /// alone, 12 seeds (IDF1 over the oracle's): the long missions online 0.935 -> 0.949,
    /// offline 0.997 -> 1.007, but `gimbal_swings` seed 11 online -0.089 and
    /// `leave_and_return`'s own seed online -0.030, so it is not on by default (docs/benchmark.md,
    /// "Appearance gate").
    pub appearance_weight_chi2: f64,
}

/// Swimmer diffusion, m^2/s (see [`ClassReidParams::SWIMMER`]).
const DEFAULT_SWIMMER_DIFFUSION: f64 = 1.0;
/// Boat diffusion, m^2/s (see [`ClassReidParams::BOAT`]).
const DEFAULT_BOAT_DIFFUSION: f64 = 20.0;

/// How long-term ReID decides whether an exit and an entry may be the same object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LongTermGate {
    /// The paper's matching threshold expansion (Eq. 9): a metre gate growing linearly with
    /// the gap, cost = BiME distance.
    Mte,
    /// A probabilistic gate: the BiME residual's squared Mahalanobis distance under the
    /// covariance of both ends' positions, their velocities times the extrapolation time,
    /// `diffusion_m2_s * gap` and `view_bias_m`, gated at `gate_chi2`; cost = twice the
    /// negative log-likelihood `d^2 + ln det(S)` (with [`ReidParams::likelihood_cost`]), so
    /// a sighting that fits as well but after a shorter gap wins, or `d^2` alone.
    Mahalanobis,
}

impl ClassReidParams {
    /// Swimmer-like objects (swimmers, life-saving appliances, buoys): slow, drifting.
    ///
    /// - tau_match 5 m: drone GPS (2-3 m) plus attitude error (about 1 m at 30 m altitude per
    ///   degree) dominates; swimmers in a group are a few metres apart, so the gate stays
    ///   below a group's spread.
    /// - tau_memory 2 s: a drifting swimmer's velocity is mostly geolocation noise
    ///   differentiated over w frames; extrapolating it for long moves the point away from
    ///   the truth. Under the Mahalanobis gate it only applies until the class has a sea
    ///   drift estimate ([`DriftParams`]); then the drift alone carries the ends.
    /// - lambda 0.1 /s: the gate grows by `lambda * tau_match` = 0.5 m per second of gap, a
    ///   swimmer's sustained speed; it starts to exceed tau_match after a 10 s gap.
    /// - max gate 80 m: a hard bound on the distance under either gate (a swimmer at
    ///   0.5 m/s covers 60 m in two minutes, the time between two lawnmower legs).
    /// - diffusion 1 m^2/s: after a minute the spread adds 7.7 m (1 sigma) per axis.
    /// - view bias 2 m.
    /// - adrift; own speed 0.15 m/s per axis, extrapolated for at most 10 s on top of the
    ///   drift (measured on 4 long missions and 4 short scenarios x 4 seeds: with the drift
    ///   alone, leave_and_return lost a swimmer pair's ids on one seed (online IDF1 0.939 ->
    ///   0.772) and the shipped model's run of it offline 0.922 -> 0.852; shrunk own
    ///   velocities for 10 s keep both and cost the long missions 0.005 on average).
    pub const SWIMMER: Self = Self {
        tau_match_m: 5.0,
        tau_memory_s: 2.0,
        lambda_per_s: 0.1,
        max_gate_m: 80.0,
        diffusion_m2_s: DEFAULT_SWIMMER_DIFFUSION,
        view_bias_m: 2.0,
        adrift: true,
        own_speed_std_m_s: 0.15,
        own_motion_s: 10.0,
        appearance_gate: 0.6,
        appearance_weight_chi2: 0.0,
    };

    /// Boat-like objects (boats, jetskis): fast, purposeful motion.
    ///
    /// - tau_match 10 m: the paper sets a larger tau_match for boats; the box centre of a
    ///   boat wanders along its several-metre hull.
    /// - tau_memory 10 s: boat velocity is large against geolocation noise and boats hold
    ///   their course, so extrapolation stays useful longer.
    /// - lambda 0.2 /s: the gate grows by 2 m per second of gap (an unobserved change of
    ///   speed or course); equals tau_match after a 5 s gap.
    /// - max gate 200 m.
    /// - diffusion 20 m^2/s: a boat's course changes spread it 35 m (1 sigma) in a minute.
    /// - view bias 3 m (longer hulls: the box centre wanders).
    /// - not adrift: under way a boat holds its course over ground (the drift fields are
    ///   unused).
    /// - appearance gate 0.95: a hull's colours change with the viewing angle and the wake,
    ///   so only colours that share almost nothing keep two ends apart. Found on the shipped
    ///   model's `gimbal_swings` run: two buoys half out of the image, each boxed as a boat,
    ///   were linked to each other at a colour distance of 0.99 (offline 0.683 / 0.928 ->
    ///   0.696 / 0.953 with `offline.stricter_class_orphans`); on the simulated detector's
    ///   benchmark (10 scenarios x 12 seeds, online and offline) nothing changed against the
    ///   gate off.
    pub const BOAT: Self = Self {
        tau_match_m: 10.0,
        tau_memory_s: 10.0,
        lambda_per_s: 0.2,
        max_gate_m: 200.0,
        diffusion_m2_s: DEFAULT_BOAT_DIFFUSION,
        view_bias_m: 3.0,
        adrift: false,
        own_speed_std_m_s: 5.0,
        own_motion_s: 10.0,
        appearance_gate: 0.95,
        appearance_weight_chi2: 0.0,
    };
}

impl Default for ClassReidParams {
    fn default() -> Self {
        Self::SWIMMER
    }
}

impl ClassReidParams {
    /// Whether a link judged under these thresholds is judged at least as strictly as under
    /// `other`'s: every gate, spread and extrapolation no wider (whether the class drifts
    /// with the sea is a model, not a width, and is not compared). The swimmer's are no
    /// wider than the boat's.
    pub fn no_wider_than(&self, other: &Self) -> bool {
        self.tau_match_m <= other.tau_match_m
            && self.tau_memory_s <= other.tau_memory_s
            && self.lambda_per_s <= other.lambda_per_s
            && self.max_gate_m <= other.max_gate_m
            && self.diffusion_m2_s <= other.diffusion_m2_s
            && self.view_bias_m <= other.view_bias_m
            && self.own_speed_std_m_s <= other.own_speed_std_m_s
            && self.own_motion_s <= other.own_motion_s
            && self.appearance_gate <= other.appearance_gate
    }
}

/// MG-MOT re-identification parameters (paper Sec. 3.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReidParams {
    /// Run the metadata-guided ReID at all (false: plain BoT-SORT ids).
    pub enabled: bool,
    /// Short-term ReID (tracks lost inside the view, Eq. 6): a first assignment stage for them,
    /// gated by the fixed `tau_match_m`. Off by default: under the Mahalanobis long-term gate
    /// an exit lost inside the view is judged by the same probabilistic gate (a short gap
    /// gives a tight one), and the fixed stage taking precedence cost IDF1 on
    /// `gimbal_swings` (four seeds, offline 0.957 without it against 0.932, online withheld
    /// 0.759 against 0.746) and changed nothing elsewhere in the benchmark. On for the
    /// paper's setting (with `long_term_gate = "mte"`).
    pub short_term: bool,
    /// Long-term ReID (BiME + MTE, Eq. 7-9).
    pub long_term: bool,
    /// w, frames: how long a new track is observed before its ReID decision (the paper's
    /// velocity window, Eq. 8). Online, a new track is decided once
    /// `frame_index - start_frame >= w` (frame numbers, so dropped frames count), with its
    /// world filter's state then as the entry (position, velocity and their covariances);
    /// (offline uses `offline.entry_window_frames`). The tracks still undecided compete in
    /// the same assignment (so an older entry does not take the exit a younger one fits
    /// better) but are only linked once due. 10 frames (a third of a second at 30 fps):
    /// with the sea drift the decision needs the entry's position, not its velocity, and
    /// the shorter a new track is provisional, the less an operator waits for it (measured
    /// with gate_chi2 16, `scripts/bench_tracking.sh`, 4 long missions x 4 seeds, online
    /// IDF1 with provisional tracks withheld against the oracle: w 30 0.804, 15 0.818,
    /// 10 0.823 on average; gimbal_swings, 4 seeds, +0.09).
    pub window_frames: u32,
    /// Online, a due track whose best link is contested waits: when another exit of the
    /// memory bank that no other track claims costs at most this much more (in the link
    /// cost's units: squared Mahalanobis distance, plus `ln det(S)` with
    /// `likelihood_cost`) than the chosen one, the decision is put off (the track stays
    /// provisional) so that the rival exit's own entry, if it comes back meanwhile, is
    /// decided jointly with it. 0 never defers. Only long-term links under the Mahalanobis
    /// gate are deferred. Measured with `defer_max_frames` 30 (online IDF1 over the
    /// oracle's, provisional tracks withheld, 12 seeds): `leave_and_return` +0.036,
    /// `sector_search` +0.017, `expanding_square` -0.010, the other long missions within
    /// 0.01; margins 2 and 4 gained less.
    pub defer_margin_chi2: f64,
    /// Online, the longest a contested decision waits beyond `window_frames`, frames; then it
    /// is taken with what is known (15 gained less than 30; 60 was no better and kept
    /// tracks provisional longer).
    pub defer_max_frames: u32,
    /// Online, a glimpse is forgotten (`true`, default): a new track lost before its ReID
    /// decision was due (seen for fewer than `window_frames` frames) while it carried a
    /// provisional old id (`provisional_old_id`: it lay within the gate of an exit in the
    /// memory bank) does not join the memory bank itself. Kept there (`false`), such a
    /// glimpse is the freshest exit near its object, so the object's next track links to it
    /// and carries the glimpse's new id instead of the object's own, whose exit stays
    /// unclaimed. A glimpse with no provisional old id (a new object's first sighting)
    /// joins the memory bank as before, so that the object's next track still takes its id.
    /// Measured against `false` (`scripts/bench_tracking.sh`, 12 seeds, IDF1 over the
    /// oracle's): long missions online 0.935 -> 0.946, provisional tracks withheld 0.919 ->
    /// 0.930, predicted ids per true object (withheld) 1.26 -> 1.21; `gimbal_swings` online
    /// 0.958 -> 1.012; no run of the 10 scenarios lower by more than 0.01.
    pub forget_glimpses: bool,
    /// Online, an undecided new track is reported under the old id it would be linked to
    /// now (`true`, default): every frame while any track is undecided, after the frame's
    /// decisions, the undecided tracks are assigned to the memory bank as at a decision (a
    /// track not yet `window_frames` old by its position alone: its filter's velocity has
    /// not settled), and a track linked to an old track's exit carries that track's id, still
    /// flagged provisional, until its decision (which may confirm it, move it to another exit
    /// or give it its own id). The old track's coasting report gives way to it; lost before
    /// its decision, the track coasts under the old id and waits in the memory bank under
    /// its own (unless it was a glimpse, see `forget_glimpses`). `false`: an undecided track
    /// carries its own new id until its decision.
    /// Measured on 10 scenarios (7 at 12 seeds, 3 at 4), online IDF1 over the oracle's with
    /// every confirmed track reported: 0.900 -> 0.923 on average, the long missions +0.024
    /// to +0.048, `gimbal_swings` +0.034, `leave_and_return` +0.034, no run lower by more
    /// than 0.01; predicted ids per true object near those of the output with provisional
    /// tracks withheld (`expanding_square` 4.96 -> 1.39, withheld 1.30). The output with
    /// provisional tracks withheld is unchanged.
    pub provisional_old_id: bool,
    /// Per-class thresholds keyed by detector class id. Default: SeaDronesSee classes,
    /// 1 swimmer, 4 life-saving appliance, 5 buoy swimmer-like; 2 boat, 3 jetski boat-like.
    pub classes: BTreeMap<u32, ClassReidParams>,
    /// Thresholds for classes not in `classes`.
    pub default_class: ClassReidParams,
    /// A track whose last box comes within this fraction of the image size of the border has
    /// left the view (long-term ReID only); otherwise it was lost inside the view and is a
    /// short-term candidate. 2 %: 77 px on a 3840 px frame, about one swimmer.
    pub exit_border_fraction: f64,
    /// Long-term gate: `mahalanobis` (default) or the paper's `mte`.
    pub long_term_gate: LongTermGate,
    /// Squared Mahalanobis gate of the online long-term ReID (`long_term_gate =
    /// "mahalanobis"`), and the price of "this is a new object" in its assignment; offline
    /// uses `offline.gate_chi2`. 9 (3 sigma): online a link is decided a third of a second
    /// after the track appears, cannot be undone, and one wrong link takes the exit another
    /// entry needed, so "new object" pays off sooner than offline, where every tracklet is
    /// whole and all are assigned at once. Measured with `likelihood_cost` on 7 scenarios x
    /// 12 seeds (IDF1 over the oracle's, provisional tracks withheld) against 16: the long
    /// missions +0.005 (`sector_search` +0.011, `expanding_square` +0.008),
    /// `gimbal_swings` +0.015, no scenario lower on average; 6: +0.003, 10: +0.005,
    /// 12: +0.004. (Before the likelihood ranking, at w 30, 16 was best online: 12 0.801,
    /// 16 0.804, 25 0.788.)
    pub gate_chi2: f64,
    /// Gaps of at least this many seconds are gated at `long_gap_gate_chi2` instead of
    /// `gate_chi2` (online; offline has one gate, `offline.gate_chi2`).
    pub long_gap_s: f64,
    /// The online Mahalanobis gate for gaps of at least `long_gap_s`; the price of "this is
    /// a new object" is the larger of the two gates. Over gaps of seconds the geolocation
    /// error and the class's own motion are what the covariance models, and 9 holds; over
    /// the minutes between two legs of a search pattern the current and the leeway also
    /// change, which the drift estimate does not follow, and right pairs fall beyond 9.
    /// 12 from 30 s, measured on 2026-12-04 against 9 for every gap (10 scenarios x 12
    /// seeds, docs/benchmark.md "A wider gate after long gaps"): the long missions online IDF1 over
    /// the oracle's 0.946 -> 0.949 (`expanding_square` 0.925 -> 0.932), ids per object
    /// online withheld lower (`sector_search` largest run 1.48 -> 1.39), the short
    /// scenarios unchanged. 12 for every gap cost `gimbal_swings` seed 11 online IDF1
    /// 0.089 (a newly seen buoy linked to a neighbouring buoy's exit 12 s old); 16 from
    /// 30 s lost more on `sector_search`.
    pub long_gap_gate_chi2: f64,
    /// Rank long-term links by their likelihood (`true`, default): the cost of a pair is
    /// `d^T S^-1 d + ln |S|` (twice the Gaussian negative log-likelihood, up to a constant)
    /// instead of the squared Mahalanobis distance alone, so an exit whose position has
    /// grown uncertain over a long gap no longer looks as close as a recent one at the same
    /// number of sigmas. The gate stays on the squared distance (`gate_chi2`), and "this is a
    /// new object" costs `gate_chi2` plus the smallest `ln |S|` among the entry's candidates
    /// inside the gate, so whether an entry links at all is decided as before. Measured on
    /// 7 scenarios x 12 seeds (online IDF1 over the oracle's, provisional tracks withheld):
    /// `sector_search` +0.031, `expanding_square` +0.011, the long missions +0.010; offline
    /// `sector_search` +0.018, the long missions +0.006.
    pub likelihood_cost: bool,
    /// How long an ended track stays in the memory bank, s. The paper keeps every track of a
    /// sequence (SeaDronesSee clips last a few minutes); online the bank must be bounded:
    /// 600 s covers a clip.
    pub memory_max_s: f64,
    /// Fewest detections with a colour signature before a track end's mean signature is
    /// used by the class's `appearance_gate`.
    pub appearance_min_count: u32,
    /// Sea drift estimated from the tracks of the classes that are `adrift`, used by the
    /// Mahalanobis long-term gate.
    pub drift: DriftParams,
}

impl Default for ReidParams {
    fn default() -> Self {
        let mut classes = BTreeMap::new();
        classes.insert(1, ClassReidParams::SWIMMER);
        classes.insert(2, ClassReidParams::BOAT);
        classes.insert(3, ClassReidParams::BOAT);
        classes.insert(4, ClassReidParams::SWIMMER);
        classes.insert(5, ClassReidParams::SWIMMER);
        Self {
            enabled: true,
            short_term: false,
            long_term: true,
            window_frames: 10,
            defer_margin_chi2: 1.0,
            defer_max_frames: 30,
            forget_glimpses: true,
            provisional_old_id: true,
            classes,
            default_class: ClassReidParams::SWIMMER,
            exit_border_fraction: 0.02,
            long_term_gate: LongTermGate::Mahalanobis,
            gate_chi2: 9.0,
            long_gap_s: 30.0,
            long_gap_gate_chi2: 12.0,
            likelihood_cost: true,
            memory_max_s: 600.0,
            appearance_min_count: 3,
            drift: DriftParams::default(),
        }
    }
}

impl ReidParams {
    /// Thresholds of one class.
    pub fn class(&self, class_id: u32) -> &ClassReidParams {
        self.classes.get(&class_id).unwrap_or(&self.default_class)
    }
}

/// Offline post-processing parameters (paper Sec. 5.1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OfflineParams {
    /// Longest gap, frames, filled by linear interpolation (both passes). The paper gives no
    /// number; 20 is ByteTrack's interpolation default, under a second at 30 fps.
    pub interp_max_gap_frames: u64,
    /// Offline, the entry of a tracklet for ReID is its world filter's state at this
    /// observation (or its last, if shorter). Offline has no latency to keep, so it can
    /// wait longer than the online `reid.window_frames` for the state to settle: 30 (1 s at
    /// 30 fps) was measured against 10, 60 and 120 on the long missions.
    pub entry_window_frames: u32,
    /// Offline, the baseline run keeps a lost track this many frames for IoU re-activation
    /// (instead of `baseline.track_buffer_frames`, which stays the online value). Offline the
    /// metadata-guided ReID joins the tracklets afterwards with both ends known, and does it
    /// better than IoU re-activation of a coasting box: 50 against 100 raised `sector_search`
    /// offline IDF1 over the oracle's from 0.907 to 0.952 (4 seeds, every seed gained;
    /// 30: 0.946, 70: 0.912); one run of 40 lost more than 0.01 (`fast_drone` seed 90210,
    /// 0.985 -> 0.963). Online the same change cost 0.02 (the lost tracks' re-activation is
    /// what brings a swimmer back under its id before the ReID window has passed).
    pub track_buffer_frames: u64,
    /// Offline, the squared Mahalanobis gate of the long-term ReID and the price of "this is
    /// a new object" (see `reid.gate_chi2`, the online one). 16 (4 sigma), wider than a
    /// chi-square quantile because the per-detection covariances leave out correlated
    /// errors. Measured with `likelihood_cost` on the 4 long missions x 12 seeds (offline
    /// IDF1 over the oracle's) against 16: 9 -0.008, 12 -0.001. Before the likelihood
    /// ranking (4 seeds, with the drift): 12 0.923, 16 0.928, 25 0.924.
    pub gate_chi2: f64,
    /// Chain velocity ([`super::reid::with_chain_velocity`]): after the first ReID pass, a
    /// second one where an exit whose chain of linked tracklets began at least
    /// `chain_velocity_min_s` before it moves with the chain's average velocity, and an
    /// entry likewise with the average over the chain it starts. Measured on the long
    /// missions x 12 seeds (offline IDF1 over the oracle's): expanding_square 0.924 ->
    /// 0.935, mixed_mission_soak 0.933 -> 0.943, sector_search 0.941 -> 0.947,
    /// lawnmower_search 0.964 -> 0.964 (docs/benchmark.md, "Chain velocity"). Online it was tried on
    /// the exits (the id's history) and gained nothing, so online does not use it.
    pub chain_velocity: bool,
    /// Shortest chain span for the chain velocity, s. 30: the swimmers' wobble (a few
    /// seconds) averages out.
    pub chain_velocity_min_s: f64,
    /// A tracklet linked to nothing after the assignments whose class rests on at most this
    /// many detections may be of another class with the same ReID thresholds (a swimmer's
    /// lone detection classed as a life-saving appliance: detectors confuse the two); it is
    /// then offered, as that class, to the free ends of the chains (under the same gate).
    /// 0 turns it off. Measured on 2026-12-04 at 2 (10 scenarios x 12 seeds, the bench's
    /// detections re-tracked): two runs of 120 changed, `sector_search` seed 90210 offline
    /// ids per true object 1.13 -> 1.10 and `lawnmower_search` seed 90210 1.00 -> 0.97 (each
    /// one id fewer, the link right), IDF1 and HOTA unchanged; 5 changed the same two.
    pub weak_class_max_detections: u32,
    /// A tracklet linked to nothing after the assignments may also be offered as any class
    /// whose ReID thresholds are no wider than its own
    /// ([`ClassReidParams::no_wider_than`]: a boat's tracklet as a swimmer, never the
    /// reverse), into the gap of a link of that class or to a chain's free end, judged by
    /// that class's gates, and only where both ends have a colour signature and that class
    /// has a colour gate (a change of class needs the colours to agree). Found on the
    /// shipped model's `gimbal_swings` run: a buoy half out of the image at the left edge is
    /// boxed as a swimmer for a few frames and as a boat for forty, so its tracklet's
    /// majority class is boat and class-wise ReID kept it out of the buoy's swimmer-class
    /// chain: offline 0.683 / 0.928 -> 0.696 / 0.953 (with the boats' colour gate). The
    /// simulated detector's benchmark (10 scenarios x 12 seeds) did not change.
    pub stricter_class_orphans: bool,
    /// Offline, a tracklet with fewer than `reid.appearance_min_count` detections with a
    /// colour signature has a *scant* one (the mean of those it has), too noisy for the
    /// classes' `appearance_gate`. A link where either end is scant is still refused when the
    /// two signatures are further apart than this Hellinger distance (or the class's own
    /// `appearance_gate`, if that is larger): colours that share almost nothing (only for
    /// classes whose `appearance_gate` is on). 1 turns it off.
    /// Found on `fast_drone` seed 90210: a swimmer seen for four frames in the image's
    /// corner (one detection with a signature) was linked to another swimmer entering 110 px
    /// away 0.4 s later (scant distance 0.78). Measured on 10 scenarios x 12 seeds (offline,
    /// the bench's detections re-tracked), against no such gate: at 0.7 that run 0.963 ->
    /// 0.987 IDF1 (HOTA 0.813 -> 0.837), `sector_search` seeds 13, 17, 7771 +0.006, seed 18
    /// -0.003, nothing else moved by more than 0.0002 (mean IDF1 over the oracle's 1.0067 ->
    /// 1.0070); at 0.6 it cost `sector_search` seeds 12 and 16 0.008 (scant signatures of
    /// one swimmer lie up to 0.6 apart).
    pub scant_appearance_gate: f64,
}

impl Default for OfflineParams {
    fn default() -> Self {
        Self {
            interp_max_gap_frames: 20,
            entry_window_frames: 30,
            track_buffer_frames: 50,
            gate_chi2: 16.0,
            chain_velocity: true,
            chain_velocity_min_s: 30.0,
            weak_class_max_detections: 2,
            stricter_class_orphans: true,
            scant_appearance_gate: 0.7,
        }
    }
}

/// Upper bounds of the parameters that have no natural one. Values beyond them have no
/// physical meaning for drone-borne maritime tracking, and the largest `f64`s make the
/// filters overflow (a world acceleration std of 1e308 squared is infinite, and the tracks
/// file filled with NaN).
pub mod limits {
    /// White-noise acceleration std, m/s^2: about 10 g. Swimmers barely accelerate and fast
    /// boats and jetskis manoeuvre at well under 1 g; beyond this the world filter ignores its
    /// motion model, and near 1e154 its process noise (`sigma^2 dt^4 / 4`) overflows.
    pub const WORLD_ACCEL_STD_M_S2: f64 = 100.0;
    /// Match gates (`tau_match_m`, `max_gate_m`), m: geolocation gives up on rays beyond
    /// 10 km (see `geo`), so a wider gate links any two objects the camera can place.
    pub const GATE_M: f64 = 10_000.0;
    /// Extrapolation time `tau_memory_s`, s: an hour, longer than a multicopter flies.
    pub const TAU_MEMORY_S: f64 = 3_600.0;
    /// Gate expansion rate `lambda_per_s`, 1/s: at 10 /s the gate grows by ten `tau_match`
    /// per second of gap and reaches any `max_gate_m` within seconds; faster rates change
    /// nothing but invite overflow of `lambda * dt * tau_match`.
    pub const LAMBDA_PER_S: f64 = 10.0;
    /// Memory bank retention `memory_max_s`, s: a day, longer than any flight.
    pub const MEMORY_MAX_S: f64 = 86_400.0;
    /// Frame counts (`track_buffer_frames`, `interp_max_gap_frames`): a million frames is over
    /// 9 h at 30 fps, longer than any flight. Interpolation creates a box for every frame of a
    /// gap it fills, so the bound also caps what one bad value can allocate.
    pub const FRAMES: u64 = 1_000_000;
    /// Velocity window `window_frames`: 10 000 frames is over 5 min at 30 fps (the paper uses
    /// 30); every track keeps up to this many observations at its head and tail.
    pub const WINDOW_FRAMES: u32 = 10_000;
    /// Squared Mahalanobis gates: 1000 is a 31-sigma gate, which admits anything.
    pub const CHI2: f64 = 1_000.0;
    /// Position diffusion, m^2/s: 10 000 spreads 1 km in 100 s.
    pub const DIFFUSION_M2_S: f64 = 10_000.0;
    /// Speeds and their standard deviations, m/s: faster than any vessel or drone.
    pub const SPEED_M_S: f64 = 1_000.0;
}

fn check(ok: bool, path: &str, requirement: &str) -> Result<(), TrackError> {
    if ok {
        Ok(())
    } else {
        Err(TrackError::InvalidParam {
            path: path.to_owned(),
            requirement: requirement.to_owned(),
        })
    }
}

/// Checks that a float is finite and in `[min, max]`; the requirement names the range and the
/// value found.
fn check_range(v: f64, min: f64, max: f64, path: &str) -> Result<(), TrackError> {
    check(
        v.is_finite() && (min..=max).contains(&v),
        path,
        &format!("a finite number in [{min}, {max}], got {v}"),
    )
}

/// Checks that a float is finite and in `(0, max]`.
fn check_positive(v: f64, max: f64, path: &str) -> Result<(), TrackError> {
    check(
        v.is_finite() && v > 0.0 && v <= max,
        path,
        &format!("a finite number in (0, {max}], got {v}"),
    )
}

fn unit(v: f64) -> bool {
    (0.0..=1.0).contains(&v)
}

impl TrackerParams {
    /// Checks every value: finite, and within its meaningful range (the `limits` module in
    /// `params.rs` holds the bounds that are not natural ones). The error names the field by
    /// its path (`reid.classes.2.tau_match_m`).
    pub fn validate(&self) -> Result<(), TrackError> {
        validate_baseline(&self.baseline)?;
        validate_reid(&self.reid)?;
        validate_offline(&self.offline)?;
        validate_contact(&self.contact)?;
        // `offline.interp_max_gap_frames` comes after the contact section: when several values
        // are wrong, the error names the first one in this order.
        validate_interpolation(&self.offline)
    }
}

/// The `baseline` section.
fn validate_baseline(b: &BaselineParams) -> Result<(), TrackError> {
    check(
        unit(f64::from(b.track_low_thresh)),
        "baseline.track_low_thresh",
        "in [0, 1]",
    )?;
    check(
        unit(f64::from(b.track_high_thresh)) && b.track_high_thresh >= b.track_low_thresh,
        "baseline.track_high_thresh",
        "in [track_low_thresh, 1]",
    )?;
    check(
        unit(f64::from(b.new_track_thresh)),
        "baseline.new_track_thresh",
        "in [0, 1]",
    )?;
    check(
        (1..=limits::FRAMES).contains(&b.track_buffer_frames),
        "baseline.track_buffer_frames",
        &format!("in [1, {}]", limits::FRAMES),
    )?;
    check(
        b.coast_frames <= limits::FRAMES,
        "baseline.coast_frames",
        &format!("in [0, {}]", limits::FRAMES),
    )?;
    check(unit(b.match_thresh), "baseline.match_thresh", "in [0, 1]")?;
    check(
        unit(b.second_match_thresh),
        "baseline.second_match_thresh",
        "in [0, 1]",
    )?;
    check(
        unit(b.unconfirmed_match_thresh),
        "baseline.unconfirmed_match_thresh",
        "in [0, 1]",
    )?;
    check(
        unit(b.duplicate_iou_dist),
        "baseline.duplicate_iou_dist",
        "in [0, 1]",
    )?;
    if let Some(t) = b.nms_iou_threshold {
        check(unit(t), "baseline.nms_iou_threshold", "in [0, 1]")?;
    }
    if let Some(g) = b.world_gate_chi2 {
        check_positive(g, limits::CHI2, "baseline.world_gate_chi2")?;
    }
    check_range(
        b.world_accel_std_m_s2,
        0.0,
        limits::WORLD_ACCEL_STD_M_S2,
        "baseline.world_accel_std_m_s2",
    )?;
    check(
        unit(b.class_mismatch_cost),
        "baseline.class_mismatch_cost",
        "in [0, 1]",
    )?;
    if let Some((name, requirement)) = b.cmc_smoothing.invalid() {
        check(
            false,
            &format!("baseline.cmc_smoothing.{name}"),
            requirement,
        )?;
    }
    Ok(())
}

/// The `reid` section: its own values, then the drift estimate's (`reid.drift`), then every
/// class's (`reid.classes.<id>` in id order, then `reid.default_class`).
fn validate_reid(r: &ReidParams) -> Result<(), TrackError> {
    check(
        (1..=limits::WINDOW_FRAMES).contains(&r.window_frames),
        "reid.window_frames",
        &format!("in [1, {}]", limits::WINDOW_FRAMES),
    )?;
    check(
        r.exit_border_fraction.is_finite() && (0.0..0.5).contains(&r.exit_border_fraction),
        "reid.exit_border_fraction",
        "in [0, 0.5)",
    )?;
    check_positive(r.memory_max_s, limits::MEMORY_MAX_S, "reid.memory_max_s")?;
    check_positive(r.gate_chi2, limits::CHI2, "reid.gate_chi2")?;
    check_range(r.long_gap_s, 0.0, limits::MEMORY_MAX_S, "reid.long_gap_s")?;
    check_positive(
        r.long_gap_gate_chi2,
        limits::CHI2,
        "reid.long_gap_gate_chi2",
    )?;
    check(
        (1..=limits::WINDOW_FRAMES).contains(&r.appearance_min_count),
        "reid.appearance_min_count",
        &format!("in [1, {}]", limits::WINDOW_FRAMES),
    )?;
    check_range(
        r.defer_margin_chi2,
        0.0,
        limits::CHI2,
        "reid.defer_margin_chi2",
    )?;
    check(
        r.defer_max_frames <= limits::WINDOW_FRAMES,
        "reid.defer_max_frames",
        &format!("in [0, {}]", limits::WINDOW_FRAMES),
    )?;
    validate_drift(&r.drift)?;
    let classes = r
        .classes
        .iter()
        .map(|(id, c)| (format!("reid.classes.{id}"), c))
        .chain(std::iter::once((
            "reid.default_class".to_owned(),
            &r.default_class,
        )));
    for (path, c) in classes {
        validate_class(&path, c)?;
    }
    Ok(())
}

/// The `reid.drift` section.
fn validate_drift(d: &DriftParams) -> Result<(), TrackError> {
    check_positive(
        d.time_constant_s,
        limits::MEMORY_MAX_S,
        "reid.drift.time_constant_s",
    )?;
    check_range(
        d.min_sample_s,
        0.0,
        limits::MEMORY_MAX_S,
        "reid.drift.min_sample_s",
    )?;
    check_positive(
        d.max_vel_std_m_s,
        limits::SPEED_M_S,
        "reid.drift.max_vel_std_m_s",
    )?;
    Ok(())
}

/// One class's ReID thresholds, `path` naming the class (`reid.classes.2`).
fn validate_class(path: &str, c: &ClassReidParams) -> Result<(), TrackError> {
    check_positive(
        c.tau_match_m,
        limits::GATE_M,
        &format!("{path}.tau_match_m"),
    )?;
    check_range(
        c.tau_memory_s,
        0.0,
        limits::TAU_MEMORY_S,
        &format!("{path}.tau_memory_s"),
    )?;
    check_range(
        c.lambda_per_s,
        0.0,
        limits::LAMBDA_PER_S,
        &format!("{path}.lambda_per_s"),
    )?;
    check_range(
        c.max_gate_m,
        c.tau_match_m,
        limits::GATE_M,
        &format!("{path}.max_gate_m"),
    )?;
    check_range(
        c.diffusion_m2_s,
        0.0,
        limits::DIFFUSION_M2_S,
        &format!("{path}.diffusion_m2_s"),
    )?;
    check_range(
        c.view_bias_m,
        0.0,
        limits::GATE_M,
        &format!("{path}.view_bias_m"),
    )?;
    check_range(
        c.appearance_gate,
        0.0,
        1.0,
        &format!("{path}.appearance_gate"),
    )?;
    check_range(
        c.appearance_weight_chi2,
        0.0,
        limits::CHI2,
        &format!("{path}.appearance_weight_chi2"),
    )?;
    check_range(
        c.own_speed_std_m_s,
        0.0,
        limits::SPEED_M_S,
        &format!("{path}.own_speed_std_m_s"),
    )?;
    check_range(
        c.own_motion_s,
        0.0,
        limits::TAU_MEMORY_S,
        &format!("{path}.own_motion_s"),
    )?;
    Ok(())
}

/// The `offline` section except `offline.interp_max_gap_frames` (see
/// [`validate_interpolation`]).
fn validate_offline(o: &OfflineParams) -> Result<(), TrackError> {
    check(
        (1..=limits::WINDOW_FRAMES).contains(&o.entry_window_frames),
        "offline.entry_window_frames",
        &format!("in [1, {}]", limits::WINDOW_FRAMES),
    )?;
    check(
        (1..=limits::FRAMES).contains(&o.track_buffer_frames),
        "offline.track_buffer_frames",
        &format!("in [1, {}]", limits::FRAMES),
    )?;
    check_positive(o.gate_chi2, limits::CHI2, "offline.gate_chi2")?;
    check_positive(
        o.chain_velocity_min_s,
        limits::MEMORY_MAX_S,
        "offline.chain_velocity_min_s",
    )?;
    check(
        o.weak_class_max_detections <= limits::WINDOW_FRAMES,
        "offline.weak_class_max_detections",
        &format!("in [0, {}]", limits::WINDOW_FRAMES),
    )?;
    check(
        (0.0..=1.0).contains(&o.scant_appearance_gate),
        "offline.scant_appearance_gate",
        "in [0, 1]",
    )?;
    Ok(())
}

/// The `contact` section.
fn validate_contact(c: &ContactParams) -> Result<(), TrackError> {
    for (v, name) in [
        (c.contact_iou, "contact.contact_iou"),
        (c.clean_iou, "contact.clean_iou"),
    ] {
        check(v > 0.0 && v <= 1.0, name, "in (0, 1]")?;
    }
    check(unit(c.margin), "contact.margin", "in [0, 1]")?;
    for (v, name) in [
        (c.anchor_min_count, "contact.anchor_min_count"),
        (c.post_count, "contact.post_count"),
        (c.partner_min_count, "contact.partner_min_count"),
    ] {
        check(
            (1..=limits::WINDOW_FRAMES).contains(&v),
            name,
            &format!("in [1, {}]", limits::WINDOW_FRAMES),
        )?;
    }
    Ok(())
}

/// `offline.interp_max_gap_frames`.
fn validate_interpolation(o: &OfflineParams) -> Result<(), TrackError> {
    check(
        o.interp_max_gap_frames <= limits::FRAMES,
        "offline.interp_max_gap_frames",
        &format!("in [0, {}]", limits::FRAMES),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_match_the_paper() {
        let p = TrackerParams::default();
        p.validate().unwrap();
        assert_eq!(p.baseline.track_high_thresh, 0.5);
        assert_eq!(p.baseline.track_low_thresh, 0.1);
        assert_eq!(p.baseline.new_track_thresh, 0.2);
        assert_eq!(p.baseline.track_buffer_frames, 100);
        assert!(p.reid.class(2).tau_match_m > p.reid.class(1).tau_match_m);
        assert_eq!(p.reid.class(99), &p.reid.default_class);
    }

    #[test]
    fn partial_config_fills_defaults_and_unknown_field_is_rejected() {
        let p: TrackerParams = serde_json::from_str(r#"{"reid": {"window_frames": 10}}"#).unwrap();
        assert_eq!(p.reid.window_frames, 10);
        assert_eq!(p.baseline, BaselineParams::default());
        let err = serde_json::from_str::<TrackerParams>(r#"{"reid": {"windw": 10}}"#)
            .unwrap_err()
            .to_string();
        assert!(err.contains("windw"), "{err}");
    }

    #[test]
    fn round_trips_through_json() {
        let p = TrackerParams::default();
        let s = serde_json::to_string(&p).unwrap();
        let q: TrackerParams = serde_json::from_str(&s).unwrap();
        assert_eq!(p, q);
    }

    /// A change that makes parameters invalid, and the key the error must name.
    type Breaks = (&'static str, fn(&mut TrackerParams));

    #[test]
    fn validate_refuses_non_finite_and_overflowing_values() {
        let cases: [Breaks; 27] = [
            ("baseline.class_mismatch_cost", |p| {
                p.baseline.class_mismatch_cost = f64::NAN
            }),
            ("contact.contact_iou", |p| p.contact.contact_iou = 2.0),
            ("contact.margin", |p| p.contact.margin = f64::NAN),
            ("contact.post_count", |p| p.contact.post_count = 0),
            ("baseline.cmc_smoothing.alpha", |p| {
                p.baseline.cmc_smoothing.alpha = f64::NAN
            }),
            ("baseline.coast_frames", |p| {
                p.baseline.coast_frames = u64::MAX
            }),
            ("offline.track_buffer_frames", |p| {
                p.offline.track_buffer_frames = 0
            }),
            ("offline.track_buffer_frames", |p| {
                p.offline.track_buffer_frames = u64::MAX
            }),
            ("baseline.world_accel_std_m_s2", |p| {
                p.baseline.world_accel_std_m_s2 = 1e308
            }),
            ("baseline.world_accel_std_m_s2", |p| {
                p.baseline.world_accel_std_m_s2 = f64::NAN
            }),
            ("baseline.track_buffer_frames", |p| {
                p.baseline.track_buffer_frames = u64::MAX
            }),
            ("reid.window_frames", |p| p.reid.window_frames = u32::MAX),
            ("reid.memory_max_s", |p| p.reid.memory_max_s = f64::INFINITY),
            ("reid.memory_max_s", |p| p.reid.memory_max_s = 1e300),
            ("reid.default_class.tau_match_m", |p| {
                p.reid.default_class.tau_match_m = 1e300
            }),
            ("reid.default_class.lambda_per_s", |p| {
                p.reid.default_class.lambda_per_s = 1e300
            }),
            ("reid.classes.2.max_gate_m", |p| {
                p.reid.classes.get_mut(&2).unwrap().max_gate_m = f64::INFINITY
            }),
            ("offline.interp_max_gap_frames", |p| {
                p.offline.interp_max_gap_frames = u64::MAX
            }),
            ("reid.long_gap_s", |p| p.reid.long_gap_s = -1.0),
            ("reid.long_gap_gate_chi2", |p| {
                p.reid.long_gap_gate_chi2 = f64::NAN
            }),
            ("reid.long_gap_gate_chi2", |p| {
                p.reid.long_gap_gate_chi2 = 0.0
            }),
            ("offline.gate_chi2", |p| p.offline.gate_chi2 = f64::NAN),
            ("offline.gate_chi2", |p| p.offline.gate_chi2 = 0.0),
            ("offline.chain_velocity_min_s", |p| {
                p.offline.chain_velocity_min_s = 0.0
            }),
            ("offline.chain_velocity_min_s", |p| {
                p.offline.chain_velocity_min_s = f64::INFINITY
            }),
            ("offline.weak_class_max_detections", |p| {
                p.offline.weak_class_max_detections = u32::MAX
            }),
            ("offline.scant_appearance_gate", |p| {
                p.offline.scant_appearance_gate = f64::NAN
            }),
        ];
        for (field, set) in cases {
            let mut p = TrackerParams::default();
            set(&mut p);
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{field}: {e}");
        }
        // The bounds themselves are accepted.
        let mut p = TrackerParams::default();
        p.baseline.world_accel_std_m_s2 = limits::WORLD_ACCEL_STD_M_S2;
        p.reid.default_class.tau_memory_s = limits::TAU_MEMORY_S;
        p.reid.default_class.lambda_per_s = limits::LAMBDA_PER_S;
        p.reid.default_class.max_gate_m = limits::GATE_M;
        p.reid.memory_max_s = limits::MEMORY_MAX_S;
        p.reid.window_frames = limits::WINDOW_FRAMES;
        p.baseline.track_buffer_frames = limits::FRAMES;
        p.offline.interp_max_gap_frames = limits::FRAMES;
        p.validate().unwrap();
    }

    #[test]
    fn validate_names_the_field() {
        let mut p = TrackerParams::default();
        p.reid.classes.get_mut(&2).unwrap().tau_match_m = -1.0;
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("reid.classes.2.tau_match_m"), "{e}");
    }
}
