//! MG-MOT metadata-guided re-identification (paper Sec. 3.2, Eq. 5-9), shared by the online
//! tracker and the offline post-processing.
//!
//! A finished track ("exit", `T_i` in the paper, waiting in the memory bank) is linked to a
//! track that started later ("entry", `T_j`) of the same class (but for the offline orphans,
//! below):
//!
//! 1. short-term ReID (Eq. 6): exits lost *inside* the view, cost = world distance between
//!    the exit and the entry position, gated by `tau_match`;
//! 2. long-term ReID: every pair left over, positions extrapolated towards each other with
//!    BiME (Eq. 7-8, [`extrapolate_bidirectional`]) and gated by the MTE threshold (Eq. 9,
//!    [`expanded_match_threshold`]).
//!
//! Under the default probabilistic gate ([`LongTermGate::Mahalanobis`]) the long-term stage
//! carries the ends with the class's sea drift ([`SeaDrift`]) once it is estimated, ranks
//! the pairs inside the gate by likelihood ([`ReidParams::likelihood_cost`]), and prices
//! "this entry is a new object" in the assignment.
//!
//! Each stage is one Hungarian assignment per class (class-wise ReID): these assignments never
//! link tracks of different classes. Only the offline post-processing goes further and offers
//! a tracklet left unlinked (an orphan) as another class: as one with the same thresholds when
//! its own class rests on few detections (`offline.weak_class_max_detections`), or as one
//! whose thresholds are no wider than its own when the colour signatures of both ends agree
//! (`offline.stricter_class_orphans`); see `link_orphans_as_other_classes` in `offline.rs`.
//!
//! **Time units.** The paper counts time in frames; here every time is in seconds (frames
//! can be dropped, the frame rate is not constant): velocities are m/s, `dt` is s, `lambda`
//! is 1/s and `tau_memory` is s. Only the window `w` stays in frames (observations).

use std::collections::BTreeSet;

use nalgebra::{Matrix2, Vector2};

use super::appearance::Appearance;
use super::assign::solve_gated;
use super::drift::{DriftEstimate, SeaDrift};
use super::params::{ClassReidParams, LongTermGate, ReidParams};
use super::world::mahalanobis2;

/// One end of a track as seen by ReID: where and when it was last (exit) or first (entry)
/// observed on the sea, and its velocity over the window `w` there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackEnd {
    /// Class of the track (majority vote).
    pub class_id: u32,
    /// Time of the exit (last observation) or entry (first observation), s.
    pub time_s: f64,
    /// World position at that time, north/east m (the paper's `X^3D_t_exit` /
    /// `X^3D_t_entry`; here the track's world filter estimate).
    pub pos_ne_m: Vector2<f64>,
    /// Velocity at that end, m/s (the paper's Eq. 8 window velocity; here the world filter's
    /// estimate, the same quantity with less noise and with a covariance).
    pub vel_ne_m_s: Vector2<f64>,
    /// Covariance of `pos_ne_m`, m^2 (the world filter's at that end).
    pub pos_cov_m2: Matrix2<f64>,
    /// Covariance of `vel_ne_m_s`, m^2/s^2.
    pub vel_cov_m2_s2: Matrix2<f64>,
    /// For an exit: whether the track's last box touched the image border (it left the view;
    /// only long-term ReID applies). Ignored for entries.
    pub left_view: bool,
    /// Mean colour signature of the track's detections up to this end (the whole track for
    /// an exit), when it has enough of them (`reid.appearance_min_count`).
    pub appearance: Option<Appearance>,
}

/// Where and when an object was observed, for [`with_chain_velocity`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainPoint {
    /// Time, s.
    pub time_s: f64,
    /// World position, north/east m.
    pub pos_ne_m: Vector2<f64>,
}

impl ChainPoint {
    /// The time and position of a track end.
    pub fn of(end: &TrackEnd) -> Self {
        Self {
            time_s: end.time_s,
            pos_ne_m: end.pos_ne_m,
        }
    }
}

/// Chain velocity: `end` with its velocity replaced by the object's average velocity from
/// `from` to `to`, the first and last observations of the chain of tracklets already linked
/// on that side of the end (offline: the chain's first observation to an exit, an entry to
/// its chain's last observation). A swimmer's own swimming direction persists for a
/// minute or more, while the world filter's velocity at an end follows seconds of wobble;
/// over long gaps the chain's average predicts the displacement better than the drift alone
/// (docs/benchmark.md, "Chain velocity").
///
/// Applies only to classes adrift (the drift model carries it), and when the chain spans at
/// least `min_span_s`; otherwise `end` is returned unchanged. The average's uncertainty as
/// a predictor of the coming gap is taken as the class's own speed prior
/// (`own_speed_std_m_s^2 I`), so the drift model shrinks it half-way towards the drift.
pub fn with_chain_velocity(
    end: &TrackEnd,
    from: ChainPoint,
    to: ChainPoint,
    class: &ClassReidParams,
    min_span_s: f64,
) -> TrackEnd {
    let span = to.time_s - from.time_s;
    if !(class.adrift && span >= min_span_s && span > 0.0) {
        return *end;
    }
    let vel = (to.pos_ne_m - from.pos_ne_m) / span;
    if !vel.iter().all(|v| v.is_finite()) {
        return *end;
    }
    TrackEnd {
        vel_ne_m_s: vel,
        vel_cov_m2_s2: Matrix2::identity() * class.own_speed_std_m_s.powi(2),
        ..*end
    }
}

/// Movement extrapolation, Eq. 7: `X + dt * V`, with `|dt|` capped at `tau_memory_s`
/// ("we will not extrapolate further beyond tau_memory"). A negative `dt_s` extrapolates
/// backwards (used for entries).
pub fn extrapolate(
    pos_ne_m: Vector2<f64>,
    vel_ne_m_s: Vector2<f64>,
    dt_s: f64,
    tau_memory_s: f64,
) -> Vector2<f64> {
    let dt = dt_s.clamp(-tau_memory_s, tau_memory_s);
    pos_ne_m + vel_ne_m_s * dt
}

/// Result of [`extrapolate_bidirectional`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BidirectionalExtrapolation {
    /// The exit position extrapolated forward, m.
    pub exit_forward_ne_m: Vector2<f64>,
    /// The entry position extrapolated backward, m.
    pub entry_backward_ne_m: Vector2<f64>,
    /// Time from the exit to the meeting time, s (`dt_exit` of Eq. 9).
    pub dt_exit_s: f64,
    /// Time from the meeting time back to the entry, s (`dt_entry` of Eq. 9).
    pub dt_entry_s: f64,
}

impl BidirectionalExtrapolation {
    /// Distance between the two extrapolated positions, m: the long-term ReID cost.
    pub fn distance_m(&self) -> f64 {
        (self.exit_forward_ne_m - self.entry_backward_ne_m).norm()
    }
}

/// Bi-directional movement extrapolation (BiME, Eq. 7-8): the exit is extrapolated forward
/// and the entry backward, each by half the gap, so they meet at the gap's midpoint
/// (`dt_exit = dt_entry = (t_entry - t_exit) / 2`); each extrapolation is capped at
/// `tau_memory_s`. The paper leaves the meeting time open; the midpoint shares the
/// extrapolation error evenly between the two velocity estimates.
pub fn extrapolate_bidirectional(
    exit: &TrackEnd,
    entry: &TrackEnd,
    tau_memory_s: f64,
) -> BidirectionalExtrapolation {
    let half_gap = ((entry.time_s - exit.time_s) / 2.0).max(0.0);
    BidirectionalExtrapolation {
        exit_forward_ne_m: extrapolate(exit.pos_ne_m, exit.vel_ne_m_s, half_gap, tau_memory_s),
        entry_backward_ne_m: extrapolate(entry.pos_ne_m, entry.vel_ne_m_s, -half_gap, tau_memory_s),
        dt_exit_s: half_gap,
        dt_entry_s: half_gap,
    }
}

/// Matching threshold expansion (MTE, Eq. 9): `tau' = lambda * (dt_exit + dt_entry) * tau_match`.
///
/// Units: `dt_exit_s`, `dt_entry_s` in seconds (the full, uncapped times, since the object's
/// possible displacement keeps growing after extrapolation stops), `lambda_per_s` in 1/s, so
/// `lambda * (dt_exit + dt_entry)` is a dimensionless factor and the result is in metres.
///
/// Combination with tau_match: Eq. 9 alone shrinks to zero for a short gap, which would make
/// a link after a brief occlusion impossible, so the gate never goes below the short-term
/// gate `tau_match`; it is also capped at `max_gate_m`:
/// `clamp(lambda * (dt_exit + dt_entry) * tau_match, tau_match, max_gate)`.
pub fn expanded_match_threshold(
    tau_match_m: f64,
    lambda_per_s: f64,
    dt_exit_s: f64,
    dt_entry_s: f64,
    max_gate_m: f64,
) -> f64 {
    let expanded = lambda_per_s * (dt_exit_s + dt_entry_s) * tau_match_m;
    let expanded = if expanded.is_finite() {
        expanded
    } else {
        max_gate_m
    };
    expanded.max(tau_match_m).min(max_gate_m.max(tau_match_m))
}

/// Long-term cost under the Mahalanobis gate (see [`LongTermGate::Mahalanobis`]).
///
/// Without a drift estimate for the class, the exit is carried forward and the entry
/// backward by their own velocities, each for half the gap capped at `tau_memory_s`
/// (`te`, `tn`; the paper's BiME):
/// `d = p_exit + te v_exit + tn v_entry - p_entry`, with covariance
/// `S = P_exit + P_entry + te^2 V_exit + tn^2 V_entry + (diffusion * gap + bias^2) I`.
///
/// With a sea drift estimate `D` (covariance `C`, see [`SeaDrift`]) both ends move with the
/// drift over the whole gap, and by their own velocities relative to it only as far as
/// those are known: each is shrunk towards zero by its reliability against the class's own
/// speed (`u = K (v - D)`, `K = Q (Q + V)^-1`, `Q = own_speed_std^2 I`, remaining covariance
/// `Q - K Q`) and extrapolated for `t = min(gap / 2, own_motion_s)`. A young entry's
/// velocity (a third of a second of noisy positions) is thus all but ignored, and a long
/// exit track's is used: `d = p_exit + t u_exit + gap D + t u_entry - p_entry`,
/// `S = P_exit + P_entry + t^2 (U_exit + U_entry) + gap^2 C + (diffusion * gap + bias^2) I`.
///
/// The cost is `d^T S^-1 d`; `None` when it exceeds `gate_chi2` or `|d| > max_gate_m`.
pub fn mahalanobis_long_term_cost(
    exit: &TrackEnd,
    entry: &TrackEnd,
    class: &ClassReidParams,
    drift: Option<&DriftEstimate>,
    gate_chi2: f64,
) -> Option<f64> {
    long_term_fit(exit, entry, class, drift, gate_chi2).map(|f| f.d2)
}

/// The squared Mahalanobis gate of a pair: `long_gap_gate_chi2` when the gap is at least
/// `long_gap_s`, else `gate_chi2`.
fn pair_gate(exit: &TrackEnd, entry: &TrackEnd, params: &ReidParams) -> f64 {
    if entry.time_s - exit.time_s >= params.long_gap_s {
        params.long_gap_gate_chi2
    } else {
        params.gate_chi2
    }
}

/// How well a pair fits under the Mahalanobis gate: the squared distance and the log
/// determinant of its covariance (see [`mahalanobis_long_term_cost`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct LongTermFit {
    /// `d^T S^-1 d`.
    d2: f64,
    /// `ln det(S)`, with `S` in m^2.
    log_det: f64,
    /// Appearance evidence in the cost's units ([`appearance_cost`]; negative where the
    /// colours agree).
    appearance: f64,
}

impl LongTermFit {
    /// The assignment cost: `d2 + log_det` when ranking by likelihood, else `d2`.
    fn cost(&self, likelihood: bool) -> f64 {
        if likelihood {
            self.d2 + self.appearance + self.log_det
        } else {
            self.d2 + self.appearance
        }
    }
}

/// The colours' evidence for a long-term pair, in the units of the link cost (squared
/// Mahalanobis distance): `appearance_weight_chi2 * (distance / appearance_gate - 0.5)`, from
/// `-weight / 2` for identical signatures to `+weight / 2` at the gate (beyond it the pair is
/// not admissible at all), 0 where either end has no signature or the class has no gate. It
/// is added to the squared distance both in the gate and in the cost, so a pair whose colours
/// agree may lie a little further apart than one whose colours merely pass.
fn appearance_cost(exit: &TrackEnd, entry: &TrackEnd, class: &ClassReidParams) -> f64 {
    match (&exit.appearance, &entry.appearance) {
        (Some(a), Some(b)) if class.appearance_weight_chi2 > 0.0 && class.appearance_gate < 1.0 => {
            class.appearance_weight_chi2 * (a.distance(b) / class.appearance_gate - 0.5)
        }
        _ => 0.0,
    }
}

/// How well a pair fits under the Mahalanobis gate (see [`mahalanobis_long_term_cost`]):
/// `None` outside the gate or the `max_gate_m` bound.
fn long_term_fit(
    exit: &TrackEnd,
    entry: &TrackEnd,
    class: &ClassReidParams,
    drift: Option<&DriftEstimate>,
    gate_chi2: f64,
) -> Option<LongTermFit> {
    let gap = (entry.time_s - exit.time_s).max(0.0);
    let spread = class.diffusion_m2_s * gap + class.view_bias_m * class.view_bias_m;
    let mut s = exit.pos_cov_m2 + entry.pos_cov_m2 + Matrix2::identity() * spread;
    let d = match drift {
        Some(drift) => {
            // Own velocities relative to the drift, shrunk towards zero by their reliability
            // (prior: own speed std per axis), for at most `own_motion_s` each.
            let prior = Matrix2::identity() * class.own_speed_std_m_s.powi(2);
            let shrink = |v: Vector2<f64>, cov: &Matrix2<f64>| {
                let gain = prior * (prior + cov).try_inverse().unwrap_or_else(Matrix2::zeros);
                (gain * (v - drift.vel_ne_m_s), prior - gain * prior)
            };
            let t = (gap / 2.0).min(class.own_motion_s);
            let (v_exit, cov_exit) = shrink(exit.vel_ne_m_s, &exit.vel_cov_m2_s2);
            let (v_entry, cov_entry) = shrink(entry.vel_ne_m_s, &entry.vel_cov_m2_s2);
            s += (cov_exit + cov_entry) * (t * t) + drift.cov_m2_s2 * (gap * gap);
            exit.pos_ne_m + (v_exit + v_entry) * t + drift.vel_ne_m_s * gap - entry.pos_ne_m
        }
        None => {
            let bime = extrapolate_bidirectional(exit, entry, class.tau_memory_s);
            let (te, tn) = (
                bime.dt_exit_s.min(class.tau_memory_s),
                bime.dt_entry_s.min(class.tau_memory_s),
            );
            s += exit.vel_cov_m2_s2 * (te * te) + entry.vel_cov_m2_s2 * (tn * tn);
            bime.exit_forward_ne_m - bime.entry_backward_ne_m
        }
    };
    if d.norm() > class.max_gate_m {
        return None;
    }
    let appearance = appearance_cost(exit, entry, class);
    let d2 = mahalanobis2(d, s).filter(|&d2| d2 + appearance <= gate_chi2)?;
    // S is positive definite here (mahalanobis2 inverted it and d2 >= 0).
    let log_det = s.determinant().ln();
    log_det.is_finite().then_some(LongTermFit {
        d2,
        log_det,
        appearance,
    })
}

/// Short-term ReID cost, Eq. 6: `|| X_t_exit_i - X_t_entry_j ||`, m.
pub fn short_term_cost(exit: &TrackEnd, entry: &TrackEnd) -> f64 {
    (exit.pos_ne_m - entry.pos_ne_m).norm()
}

/// Whether the pair passes the short-term stage's gate: the stage is on, the exit was lost
/// inside the view, and the entry is within `tau_match_m` of it.
fn within_short_term_gate(
    exit: &TrackEnd,
    entry: &TrackEnd,
    params: &ReidParams,
    cp: &ClassReidParams,
) -> bool {
    params.short_term && !exit.left_view && short_term_cost(exit, entry) <= cp.tau_match_m
}

/// Whether an exit may be linked to an entry at all: same class, the entry strictly after
/// the exit (the two tracks never coexisted), and the gap within the memory.
fn may_link(exit: &TrackEnd, entry: &TrackEnd, params: &ReidParams) -> bool {
    let gap = entry.time_s - exit.time_s;
    exit.class_id == entry.class_id
        && gap > 0.0
        && gap <= params.memory_max_s
        && appearance_compatible(exit, entry, params)
}

/// Whether the two ends' signatures are within `reid.appearance_gate` of each other (or one
/// of them has none).
fn appearance_compatible(exit: &TrackEnd, entry: &TrackEnd, params: &ReidParams) -> bool {
    match (&exit.appearance, &entry.appearance) {
        (Some(a), Some(b)) => {
            let gate = params.class(exit.class_id).appearance_gate;
            gate >= 1.0 || a.distance(b) <= gate
        }
        _ => true,
    }
}

/// Whether ReID could link this exit to this entry at all: the pair passes the short-term
/// gate (exits lost inside the view) or the long-term one.
pub fn within_gate(
    exit: &TrackEnd,
    entry: &TrackEnd,
    params: &ReidParams,
    drift: &SeaDrift,
) -> bool {
    if !params.enabled || !may_link(exit, entry, params) {
        return false;
    }
    let cp = params.class(exit.class_id);
    if within_short_term_gate(exit, entry, params, cp) {
        return true;
    }
    params.long_term
        && long_term_cost(
            exit,
            entry,
            cp,
            params,
            drift.estimate(exit.class_id).as_ref(),
        )
        .is_finite()
}

/// The long-term cost of a pair under `params.long_term_gate`, infinite outside the gate.
fn long_term_cost(
    exit: &TrackEnd,
    entry: &TrackEnd,
    cp: &ClassReidParams,
    params: &ReidParams,
    drift: Option<&DriftEstimate>,
) -> f64 {
    match params.long_term_gate {
        LongTermGate::Mahalanobis => {
            long_term_fit(exit, entry, cp, drift, pair_gate(exit, entry, params))
                .map_or(f64::INFINITY, |f| f.cost(params.likelihood_cost))
        }
        LongTermGate::Mte => {
            let bime = extrapolate_bidirectional(exit, entry, cp.tau_memory_s);
            let gate = expanded_match_threshold(
                cp.tau_match_m,
                cp.lambda_per_s,
                bime.dt_exit_s,
                bime.dt_entry_s,
                cp.max_gate_m,
            );
            let d = bime.distance_m();
            if d <= gate {
                d
            } else {
                f64::INFINITY
            }
        }
    }
}

/// Links exits to entries: short-term then long-term ReID, one Hungarian assignment per
/// class and stage, with `drift` the sea drift estimate (under the Mahalanobis gate).
/// Returns `(exit index, entry index)` pairs; every exit and every entry appears at most
/// once. Deterministic: classes are processed in ascending id order and the solver is
/// deterministic.
pub fn associate_exits_to_entries(
    exits: &[TrackEnd],
    entries: &[TrackEnd],
    params: &ReidParams,
    drift: &SeaDrift,
) -> Vec<(usize, usize)> {
    associate_exits_to_entries_where(exits, entries, params, drift, |_, _| true)
}

/// [`associate_exits_to_entries`] with an extra admissibility test `allowed(exit index,
/// entry index)` (the callers use it to forbid tracks whose frame spans overlap even where
/// their world observations do not).
pub fn associate_exits_to_entries_where(
    exits: &[TrackEnd],
    entries: &[TrackEnd],
    params: &ReidParams,
    drift: &SeaDrift,
    allowed: impl Fn(usize, usize) -> bool,
) -> Vec<(usize, usize)> {
    let mut links = Vec::new();
    if !params.enabled || exits.is_empty() || entries.is_empty() {
        return links;
    }
    let mut exit_used = vec![false; exits.len()];
    let mut entry_used = vec![false; entries.len()];
    let classes: BTreeSet<u32> = exits.iter().map(|e| e.class_id).collect();
    let mut cost = Vec::new();
    let mut pairs = Vec::new();
    for class_id in classes {
        let cp = params.class(class_id);
        let class_drift = drift.estimate(class_id);
        for long_term in [false, true] {
            if (long_term && !params.long_term) || (!long_term && !params.short_term) {
                continue;
            }
            let rows: Vec<usize> = (0..exits.len())
                .filter(|&i| !exit_used[i] && exits[i].class_id == class_id)
                .filter(|&i| long_term || !exits[i].left_view)
                .collect();
            let cols: Vec<usize> = (0..entries.len())
                .filter(|&j| !entry_used[j] && entries[j].class_id == class_id)
                .collect();
            if rows.is_empty() || cols.is_empty() {
                continue;
            }
            let probabilistic = long_term && params.long_term_gate == LongTermGate::Mahalanobis;
            cost.clear();
            // Per entry, the smallest ln det(S) among its candidates inside the gate.
            let mut min_log_det = vec![f64::INFINITY; cols.len()];
            for &i in &rows {
                for (k, &j) in cols.iter().enumerate() {
                    let (x, y) = (&exits[i], &entries[j]);
                    let c = if !may_link(x, y, params) || !allowed(i, j) {
                        f64::INFINITY
                    } else if probabilistic {
                        match long_term_fit(x, y, cp, class_drift.as_ref(), pair_gate(x, y, params))
                        {
                            Some(fit) => {
                                min_log_det[k] = min_log_det[k].min(fit.log_det);
                                fit.cost(params.likelihood_cost)
                            }
                            None => f64::INFINITY,
                        }
                    } else if long_term {
                        long_term_cost(x, y, cp, params, class_drift.as_ref())
                    } else {
                        let d = short_term_cost(x, y);
                        if d <= cp.tau_match_m {
                            d
                        } else {
                            f64::INFINITY
                        }
                    };
                    cost.push(c);
                }
            }
            // Under the probabilistic gate "this entry is a new object" is a hypothesis too,
            // priced at the gate: one extra row per entry, usable by that entry only, so the
            // solver never links a pair just to match more pairs. Ranked by likelihood, the
            // price adds the entry's smallest ln det(S), so that whether it links at all is
            // still decided by its best-determined candidate's squared distance.
            let mut n_rows = rows.len();
            if probabilistic {
                let gate = params.gate_chi2.max(params.long_gap_gate_chi2);
                for (k, &log_det) in min_log_det.iter().enumerate() {
                    let price = if params.likelihood_cost && log_det.is_finite() {
                        gate + log_det
                    } else {
                        gate
                    };
                    cost.extend(
                        (0..cols.len()).map(|j| if j == k { price } else { f64::INFINITY }),
                    );
                }
                n_rows += cols.len();
            }
            solve_gated(n_rows, cols.len(), &mut cost, &mut pairs);
            for &(r, c) in pairs.iter().filter(|&&(r, _)| r < rows.len()) {
                let (i, j) = (rows[r], cols[c]);
                exit_used[i] = true;
                entry_used[j] = true;
                links.push((i, j));
            }
        }
    }
    links.sort_unstable();
    links
}

/// Whether the long-term link of `entry` to `exits[linked]` is contested: another exit of
/// the same class, not `claimed` by another link and `allowed`, costs at most
/// `params.defer_margin_chi2` more for this entry, so the two hypotheses are nearly as
/// likely and the exit's own entry may still come. Only long-term links under the
/// Mahalanobis gate can be contested (a margin of 0 contests nothing).
pub fn link_is_contested(
    exits: &[TrackEnd],
    entry: &TrackEnd,
    linked: usize,
    claimed: &[bool],
    params: &ReidParams,
    drift: &SeaDrift,
    allowed: impl Fn(usize) -> bool,
) -> bool {
    let Some(x) = exits.get(linked) else {
        return false;
    };
    if params.defer_margin_chi2 <= 0.0 || params.long_term_gate != LongTermGate::Mahalanobis {
        return false;
    }
    let cp = params.class(x.class_id);
    if within_short_term_gate(x, entry, params, cp) {
        return false;
    }
    let class_drift = drift.estimate(x.class_id);
    let best = long_term_cost(x, entry, cp, params, class_drift.as_ref());
    if !best.is_finite() {
        return false;
    }
    exits.iter().enumerate().any(|(i, other)| {
        i != linked
            && !claimed.get(i).copied().unwrap_or(true)
            && other.class_id == x.class_id
            && may_link(other, entry, params)
            && allowed(i)
            && long_term_cost(other, entry, cp, params, class_drift.as_ref())
                <= best + params.defer_margin_chi2
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn end(class_id: u32, t: f64, n: f64, e: f64, vn: f64, ve: f64, left: bool) -> TrackEnd {
        TrackEnd {
            class_id,
            time_s: t,
            pos_ne_m: Vector2::new(n, e),
            vel_ne_m_s: Vector2::new(vn, ve),
            pos_cov_m2: Matrix2::identity(),
            vel_cov_m2_s2: Matrix2::identity() * 0.01,
            left_view: left,
            appearance: None,
        }
    }

    #[test]
    fn extrapolation_is_capped_by_tau_memory() {
        let p = extrapolate(Vector2::zeros(), Vector2::new(1.0, 0.0), 10.0, 3.0);
        assert_relative_eq!(p, Vector2::new(3.0, 0.0));
        let p = extrapolate(Vector2::zeros(), Vector2::new(1.0, 0.0), -10.0, 3.0);
        assert_relative_eq!(p, Vector2::new(-3.0, 0.0));
    }

    #[test]
    fn bime_meets_in_the_middle_for_constant_velocity() {
        // object moving 2 m/s north: exit at t=0 at n=0, entry at t=10 at n=20
        let x = end(2, 0.0, 0.0, 0.0, 2.0, 0.0, true);
        let y = end(2, 10.0, 20.0, 0.0, 2.0, 0.0, false);
        let b = extrapolate_bidirectional(&x, &y, 100.0);
        assert_relative_eq!(b.distance_m(), 0.0, epsilon = 1e-12);
        assert_relative_eq!(b.dt_exit_s, 5.0);
        assert_relative_eq!(b.dt_entry_s, 5.0);
        // with tau_memory 2 s each side moves only 4 m: 12 m remain
        let b = extrapolate_bidirectional(&x, &y, 2.0);
        assert_relative_eq!(b.distance_m(), 12.0, epsilon = 1e-12);
    }

    #[test]
    fn mte_never_below_tau_match_and_capped() {
        assert_relative_eq!(expanded_match_threshold(5.0, 0.1, 0.0, 0.0, 50.0), 5.0);
        assert_relative_eq!(expanded_match_threshold(5.0, 0.1, 0.5, 0.5, 50.0), 5.0);
        // 30 s gap: 0.1 * 30 * 5 = 15 m
        assert_relative_eq!(expanded_match_threshold(5.0, 0.1, 15.0, 15.0, 50.0), 15.0);
        assert_relative_eq!(expanded_match_threshold(5.0, 0.1, 500.0, 500.0, 50.0), 50.0);
        assert_relative_eq!(
            expanded_match_threshold(5.0, 0.1, f64::INFINITY, 1.0, 50.0),
            50.0
        );
    }

    #[test]
    fn short_term_links_nearest_within_gate() {
        let p = ReidParams {
            short_term: true,
            long_term: false,
            ..ReidParams::default()
        };
        let exits = [
            end(1, 0.0, 0.0, 0.0, 0.0, 0.0, false),
            end(1, 0.0, 10.0, 0.0, 0.0, 0.0, false),
        ];
        let entries = [
            end(1, 1.0, 10.5, 0.0, 0.0, 0.0, false),
            end(1, 1.0, 0.5, 0.0, 0.0, 0.0, false),
            end(1, 1.0, 40.0, 0.0, 0.0, 0.0, false),
        ];
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &SeaDrift::default()),
            vec![(0, 1), (1, 0)]
        );
    }

    #[test]
    fn classes_are_never_linked_and_order_in_time_is_required() {
        let p = ReidParams::default();
        let exits = [end(1, 5.0, 0.0, 0.0, 0.0, 0.0, false)];
        let other_class = [end(2, 6.0, 0.0, 0.0, 0.0, 0.0, false)];
        assert!(
            associate_exits_to_entries(&exits, &other_class, &p, &SeaDrift::default()).is_empty()
        );
        let earlier = [end(1, 4.0, 0.0, 0.0, 0.0, 0.0, false)];
        assert!(associate_exits_to_entries(&exits, &earlier, &p, &SeaDrift::default()).is_empty());
    }

    /// A signature with all its weight in one bin.
    fn colour(bin: usize) -> Option<Appearance> {
        Some(crate::track::scenes::colour(bin))
    }

    /// Two swimmers come back swapped in position: the appearance gate keeps each with its
    /// own jacket; without signatures on either side, or with the gate off, position decides.
    #[test]
    fn the_appearance_gate_keeps_jackets_apart() {
        let mut p = ReidParams::default();
        p.classes.get_mut(&1).unwrap().appearance_gate = 0.6;
        let exits = [
            TrackEnd {
                appearance: colour(1),
                ..end(1, 0.0, 0.0, 0.0, 0.0, 0.0, true)
            },
            TrackEnd {
                appearance: colour(6),
                ..end(1, 0.0, 0.0, 3.0, 0.0, 0.0, true)
            },
        ];
        // The green jacket (bin 6) returns where the orange one (bin 1) left, and vice versa.
        let entries = [
            TrackEnd {
                appearance: colour(6),
                ..end(1, 60.0, 0.0, 0.0, 0.0, 0.0, false)
            },
            TrackEnd {
                appearance: colour(1),
                ..end(1, 60.0, 0.0, 3.0, 0.0, 0.0, false)
            },
        ];
        let drift = SeaDrift::default();
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &drift),
            vec![(0, 1), (1, 0)]
        );
        assert!(within_gate(&exits[0], &entries[1], &p, &drift));
        assert!(!within_gate(&exits[0], &entries[0], &p, &drift));
        // Off: position alone.
        p.classes.get_mut(&1).unwrap().appearance_gate = 1.0;
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &drift),
            vec![(0, 0), (1, 1)]
        );
        // Ends without a signature are judged on position alone.
        p.classes.get_mut(&1).unwrap().appearance_gate = 0.6;
        let unseen = entries.map(|e| TrackEnd {
            appearance: None,
            ..e
        });
        assert!(within_gate(&exits[0], &unseen[0], &p, &drift));
        assert_eq!(
            associate_exits_to_entries(&exits, &unseen, &p, &drift),
            vec![(0, 0), (1, 1)]
        );
    }

    /// With the appearance weight, of two exits at the same distance the one whose colour
    /// agrees wins, and an agreeing pair is admitted a little beyond the position gate.
    #[test]
    fn agreeing_colours_lower_the_link_cost() {
        let mut p = ReidParams::default();
        let swimmer = p.classes.get_mut(&1).unwrap();
        swimmer.appearance_gate = 0.6;
        swimmer.appearance_weight_chi2 = 4.0;
        let mut near_colour = colour(1).unwrap();
        near_colour.bins[2] = 0.3;
        let exits = [
            TrackEnd {
                appearance: Some(near_colour),
                ..end(1, 0.0, 0.0, -1.0, 0.0, 0.0, true)
            },
            TrackEnd {
                appearance: colour(1),
                ..end(1, 0.0, 0.0, 1.0, 0.0, 0.0, true)
            },
        ];
        let entry = [TrackEnd {
            appearance: colour(1),
            ..end(1, 60.0, 0.0, 0.0, 0.0, 0.0, false)
        }];
        let drift = SeaDrift::default();
        let cp = p.class(1);
        let near = appearance_cost(&exits[0], &entry[0], cp);
        let same = appearance_cost(&exits[1], &entry[0], cp);
        assert!(same < near, "{same} {near}");
        assert_relative_eq!(same, -2.0, epsilon = 1e-6);
        assert_eq!(
            associate_exits_to_entries(&exits, &entry, &p, &drift),
            vec![(1, 0)]
        );
        // Without the weight the two are equally far: either may win, but the cost no
        // longer prefers the matching colour.
        let mut off = p.clone();
        off.classes.get_mut(&1).unwrap().appearance_weight_chi2 = 0.0;
        assert_eq!(appearance_cost(&exits[0], &entry[0], off.class(1)), 0.0);
        // Beyond the position gate by less than the bonus: admitted only with agreeing colours.
        let far_exit = TrackEnd {
            pos_ne_m: Vector2::new(0.0, 0.0),
            ..exits[1]
        };
        let gap_s = 60.0;
        let spread = cp.diffusion_m2_s * gap_s + cp.view_bias_m * cp.view_bias_m + 2.0;
        let e = (pair_gate(&exits[1], &entry[0], &p) + 1.0).sqrt() * spread.sqrt();
        let far_entry = TrackEnd {
            pos_ne_m: Vector2::new(0.0, e),
            ..entry[0]
        };
        assert!(within_gate(&far_exit, &far_entry, &p, &drift));
        assert!(!within_gate(&far_exit, &far_entry, &off, &drift));
    }

    #[test]
    fn left_view_needs_long_term_and_gate_expands_with_gap() {
        let mut p = ReidParams {
            long_term_gate: LongTermGate::Mte,
            ..ReidParams::default()
        };
        // swimmer leaves the view, comes back 60 s later 12 m away (no usable velocity)
        let exits = [end(1, 0.0, 0.0, 0.0, 0.0, 0.0, true)];
        let entries = [end(1, 60.0, 12.0, 0.0, 0.0, 0.0, false)];
        // gate = 0.1 * 60 * 5 = 30 m
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &SeaDrift::default()),
            vec![(0, 0)]
        );
        p.long_term = false;
        assert!(associate_exits_to_entries(&exits, &entries, &p, &SeaDrift::default()).is_empty());
        // the same displacement after 2 s is beyond the gate
        p.long_term = true;
        let entries = [end(1, 2.0, 12.0, 0.0, 0.0, 0.0, false)];
        assert!(associate_exits_to_entries(&exits, &entries, &p, &SeaDrift::default()).is_empty());
    }

    #[test]
    fn mahalanobis_gate_grows_with_the_gap_and_prices_a_new_object() {
        let p = ReidParams::default();
        let cp = *p.class(1);
        // A swimmer seen again 20 m away: after 2 s that is far outside the spread, after
        // 60 s (diffusion 1 m^2/s: 60 m^2 per axis) it is well inside.
        let x = end(1, 0.0, 0.0, 0.0, 0.0, 0.0, true);
        let soon = end(1, 2.0, 20.0, 0.0, 0.0, 0.0, false);
        let late = end(1, 60.0, 20.0, 0.0, 0.0, 0.0, false);
        assert!(mahalanobis_long_term_cost(&x, &soon, &cp, None, p.gate_chi2).is_none());
        let d2 = mahalanobis_long_term_cost(&x, &late, &cp, None, p.gate_chi2).unwrap();
        // S = 2 I (positions) + 0.01 * 2 * (2 s)^2 I (velocities) + (60 + 4) I
        let var = 2.0 + 0.01 * 4.0 * 2.0 + 60.0 + cp.view_bias_m * cp.view_bias_m;
        assert_relative_eq!(d2, 400.0 / var, epsilon = 1e-9);
        assert!(
            within_gate(&x, &late, &p, &SeaDrift::default())
                && !within_gate(&x, &soon, &p, &SeaDrift::default())
        );
        // beyond max_gate_m nothing links, however long the gap
        let far = end(1, 500.0, cp.max_gate_m + 1.0, 0.0, 0.0, 0.0, false);
        assert!(mahalanobis_long_term_cost(&x, &far, &cp, None, 1e9).is_none());
    }

    #[test]
    fn a_long_gap_is_gated_wider() {
        let mut p = ReidParams::default();
        let cp = *p.class(1);
        let drift = SeaDrift::default();
        let x = end(1, 0.0, 0.0, 0.0, 0.0, 0.0, true);
        let entry_after = |gap: f64| end(1, gap, 16.0, 0.0, 0.0, 0.0, false);
        // The same pair 40 s apart, its squared distance between the two gates.
        let d2 = mahalanobis_long_term_cost(&x, &entry_after(40.0), &cp, None, 1e9).unwrap();
        p.gate_chi2 = d2 * 0.9;
        p.long_gap_gate_chi2 = d2 * 1.1;
        p.long_gap_s = 30.0;
        assert!(within_gate(&x, &entry_after(40.0), &p, &drift));
        // A gap under long_gap_s keeps the narrow gate.
        p.long_gap_s = 50.0;
        assert!(!within_gate(&x, &entry_after(40.0), &p, &drift));
        // And the assignment follows the gate: linked only as a long gap.
        let exits = [x];
        let entries = [entry_after(40.0)];
        assert!(associate_exits_to_entries(&exits, &entries, &p, &drift).is_empty());
        p.long_gap_s = 30.0;
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &drift),
            vec![(0, 0)]
        );
    }

    #[test]
    fn a_recent_exit_beats_an_old_uncertain_one_that_fits_as_many_sigmas() {
        // Entry at t = 330 s at the origin. Exit `old` ended 330 s before, 18 m east (its
        // covariance has grown to about 336 m^2 per axis: d^2 about 0.96); exit `recent`
        // ended 30 s before, 8 m north (about 36 m^2: d^2 about 1.8). By the squared
        // distance alone the old exit wins; by likelihood the recent one does, because the
        // old one "fits" only as well as a 336 m^2 spread fits anything.
        let p = ReidParams::default();
        assert!(p.likelihood_cost);
        let old = end(1, 0.0, 0.0, 18.0, 0.0, 0.0, true);
        let recent = end(1, 300.0, 8.0, 0.0, 0.0, 0.0, true);
        let entry = end(1, 330.0, 0.0, 0.0, 0.0, 0.0, false);
        let cp = p.class(1);
        let d2_old = mahalanobis_long_term_cost(&old, &entry, cp, None, p.gate_chi2).unwrap();
        let d2_recent = mahalanobis_long_term_cost(&recent, &entry, cp, None, p.gate_chi2).unwrap();
        assert!(d2_old < d2_recent, "{d2_old} {d2_recent}");
        let drift = SeaDrift::default();
        let both = [old, recent];
        assert_eq!(
            associate_exits_to_entries(&both, &[entry], &p, &drift),
            vec![(1, 0)]
        );
        let by_distance = ReidParams {
            likelihood_cost: false,
            ..p.clone()
        };
        assert_eq!(
            associate_exits_to_entries(&both, &[entry], &by_distance, &drift),
            vec![(0, 0)]
        );
        // Alone, the old exit is still linked: "new object" is priced from the entry's own
        // candidates, so the larger ln det(S) does not push a fitting pair out of the gate.
        assert_eq!(
            associate_exits_to_entries(&[old], &[entry], &p, &drift),
            vec![(0, 0)]
        );
    }

    #[test]
    fn the_new_object_hypothesis_stops_forced_links() {
        // 30 s gap, variance 36.08 m^2 per axis. Entry 0 fits exit 0 (d^2 0.03) and, barely,
        // exit 1 (19.9); entry 1 fits exit 0 only (10.0). Linking both (29.9) costs more
        // than entry 0 -> exit 0 plus "entry 1 is a new object" (0.03 + gate_chi2 16): a
        // count-maximising assignment would link both and get entry 0 wrong. (Gate 16, the
        // offline one: at the online default 9 both pairs would be outside the gate.)
        let p = ReidParams {
            gate_chi2: 16.0,
            ..ReidParams::default()
        };
        let exits = [
            end(1, 0.0, 0.0, 0.0, 0.0, 0.0, true),
            end(1, 0.0, 27.8, 0.0, 0.0, 0.0, true),
        ];
        let entries = [
            end(1, 30.0, 1.0, 0.0, 0.0, 0.0, false),
            end(1, 30.0, -19.0, 0.0, 0.0, 0.0, false),
        ];
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &SeaDrift::default()),
            vec![(0, 0)]
        );
    }

    /// 30 s gap, variance 36.08 m^2 per axis: an entry between two exits is contested by
    /// the one that costs at most `defer_margin_chi2` more, unless another link claims it,
    /// it is of another class, or the margin is 0.
    #[test]
    fn a_link_is_contested_by_a_free_exit_nearly_as_good() {
        let p = ReidParams {
            defer_margin_chi2: 1.0,
            ..ReidParams::default()
        };
        let drift = SeaDrift::default();
        let exits = [
            end(1, 0.0, 0.0, 0.0, 0.0, 0.0, true),
            end(1, 0.0, 6.0, 0.0, 0.0, 0.0, true),
            end(1, 0.0, 12.0, 0.0, 0.0, 0.0, true),
        ];
        // d^2 to exit 0: 2.8^2 / 36.08 = 0.22; exit 1: 0.29; exit 2: 2.4.
        let entry = end(1, 30.0, 2.8, 0.0, 0.0, 0.0, false);
        let free = [false; 3];
        let any = |_: usize| true;
        assert!(link_is_contested(&exits, &entry, 0, &free, &p, &drift, any));
        // exit 1 claimed by another entry: exit 2 is too far to contest
        let claimed = [false, true, false];
        assert!(!link_is_contested(
            &exits, &entry, 0, &claimed, &p, &drift, any
        ));
        // exit 1 not admissible for this entry (the tracks overlap in time)
        assert!(!link_is_contested(
            &exits,
            &entry,
            0,
            &free,
            &p,
            &drift,
            |i| i != 1
        ));
        // another class never contests
        let mut boats = exits;
        boats[1].class_id = 2;
        assert!(!link_is_contested(
            &boats, &entry, 0, &free, &p, &drift, any
        ));
        // margin 0: never
        let off = ReidParams {
            defer_margin_chi2: 0.0,
            ..p.clone()
        };
        assert!(!link_is_contested(
            &exits, &entry, 0, &free, &off, &drift, any
        ));
    }

    /// The swimmers' drift estimated from a minute of two swimmers paddling north and south
    /// across a drift of `east_m_s` east.
    fn paddling_drift(p: &ReidParams, east_m_s: f64) -> SeaDrift {
        let mut drift = SeaDrift::new(p.drift.clone());
        for k in 0..1800 {
            let samples = [
                (1, 1, Vector2::new(0.1, east_m_s)),
                (1, 2, Vector2::new(-0.1, east_m_s)),
            ];
            drift.observe(f64::from(k) / 30.0, &samples);
        }
        drift
    }

    /// Two swimmers 12 m apart along the drift, the first comes back a minute later carried
    /// 12 m downwind: by position alone its entry is where the second one left and the link
    /// is wrong; with the drift estimated from the tracks it is right.
    #[test]
    fn sea_drift_carries_a_group_across_a_long_gap() {
        let p = ReidParams::default();
        let exits = [
            end(1, 0.0, 0.0, 0.0, 0.0, 0.2, true),
            end(1, 0.0, 0.0, 12.0, 0.0, 0.2, true),
        ];
        // The first one to come back (online, entries are decided as they become due).
        let entries = [end(1, 60.0, 0.0, 12.5, 0.0, 0.2, false)];
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &SeaDrift::default()),
            vec![(1, 0)]
        );
        let drift = paddling_drift(&p, 0.2);
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &drift),
            vec![(0, 0)]
        );
        // The drift of one class says nothing about another.
        let boats: Vec<TrackEnd> = exits
            .iter()
            .map(|e| TrackEnd { class_id: 2, ..*e })
            .collect();
        let boat_entries: Vec<TrackEnd> = entries
            .iter()
            .map(|e| TrackEnd { class_id: 2, ..*e })
            .collect();
        assert_eq!(
            associate_exits_to_entries(&boats, &boat_entries, &p, &drift),
            associate_exits_to_entries(&boats, &boat_entries, &p, &SeaDrift::default())
        );
    }

    fn point(t: f64, n: f64, e: f64) -> ChainPoint {
        ChainPoint {
            time_s: t,
            pos_ne_m: Vector2::new(n, e),
        }
    }

    #[test]
    fn chain_velocity_averages_long_chains_of_classes_adrift_only() {
        let swimmer = ClassReidParams::SWIMMER;
        let e = end(1, 60.0, 0.0, 30.0, 0.4, -0.2, true);
        let c = with_chain_velocity(
            &e,
            point(0.0, 0.0, 0.0),
            point(60.0, 0.0, 30.0),
            &swimmer,
            30.0,
        );
        assert_relative_eq!(c.vel_ne_m_s, Vector2::new(0.0, 0.5));
        assert_relative_eq!(c.vel_cov_m2_s2, Matrix2::identity() * 0.15 * 0.15);
        // Everything else is the end's own.
        assert_eq!(
            (c.time_s, c.pos_ne_m, c.left_view),
            (e.time_s, e.pos_ne_m, e.left_view)
        );
        // Too short a chain, no span at all, or a class that does not drift: unchanged.
        let unchanged = [
            (40.0, &swimmer, 30.0),
            (60.0, &swimmer, 0.0),
            (0.0, &ClassReidParams::BOAT, 30.0),
        ];
        for (from_s, class, min_span_s) in unchanged {
            let from = point(from_s, 0.0, 0.0);
            let to = point(60.0, 0.0, 30.0);
            assert_eq!(with_chain_velocity(&e, from, to, class, min_span_s), e);
        }
    }

    /// Two swimmers 10 m apart: the first has been swimming east at 0.3 m/s for two minutes,
    /// the second has stayed put; both filters end on a wobble of zero velocity. A new track
    /// appears 100 s later 8.5 m east of the first: by the filters' velocities it is the
    /// second one, by the chains' it is the first, which swam on.
    #[test]
    fn chain_velocity_carries_a_swimmer_that_keeps_swimming() {
        let p = ReidParams::default();
        let drift = paddling_drift(&p, 0.0);
        let exits = [
            end(1, 0.0, 0.0, 0.0, 0.0, 0.0, true),
            end(1, 0.0, 0.0, 10.0, 0.0, 0.0, true),
        ];
        let mut entry = end(1, 100.0, 0.0, 8.5, 0.0, 0.0, false);
        entry.vel_cov_m2_s2 = Matrix2::identity();
        let entries = [entry];
        assert_eq!(
            associate_exits_to_entries(&exits, &entries, &p, &drift),
            vec![(1, 0)]
        );
        let swimmer = p.class(1);
        let chained = [
            with_chain_velocity(
                &exits[0],
                point(-120.0, 0.0, -36.0),
                ChainPoint::of(&exits[0]),
                swimmer,
                30.0,
            ),
            with_chain_velocity(
                &exits[1],
                point(-120.0, 0.0, 10.0),
                ChainPoint::of(&exits[1]),
                swimmer,
                30.0,
            ),
        ];
        let mut unbounded = p.clone();
        for c in std::iter::once(&mut unbounded.default_class).chain(unbounded.classes.values_mut())
        {
            c.own_motion_s = f64::INFINITY;
        }
        assert_eq!(
            associate_exits_to_entries(&chained, &entries, &unbounded, &drift),
            vec![(0, 0)]
        );
    }

    proptest! {
        #[test]
        fn links_are_one_to_one_same_class_and_forward_in_time(
            xs in prop::collection::vec((1u32..3, 0.0..100.0f64, -50.0..50.0f64, -50.0..50.0f64, any::<bool>()), 0..12),
            ys in prop::collection::vec((1u32..3, 0.0..100.0f64, -50.0..50.0f64, -50.0..50.0f64), 0..12),
        ) {
            let exits: Vec<_> = xs.iter().map(|&(c, t, n, e, l)| end(c, t, n, e, 0.3, -0.2, l)).collect();
            let entries: Vec<_> = ys.iter().map(|&(c, t, n, e)| end(c, t, n, e, 0.1, 0.0, false)).collect();
            let links = associate_exits_to_entries(&exits, &entries, &ReidParams::default(), &SeaDrift::default());
            let mut si = std::collections::HashSet::new();
            let mut sj = std::collections::HashSet::new();
            for &(i, j) in &links {
                prop_assert!(si.insert(i) && sj.insert(j));
                prop_assert_eq!(exits[i].class_id, entries[j].class_id);
                prop_assert!(entries[j].time_s > exits[i].time_s);
            }
            // deterministic
            prop_assert_eq!(links, associate_exits_to_entries(&exits, &entries, &ReidParams::default(), &SeaDrift::default()));
        }
    }
}
