//! Multi-object tracking metrics computed exactly as TrackEval computes them.
//!
//! This module is the pure core of `mgmot eval`: it takes annotations that are
//! already in memory (see `mgmot::formats::mot` for the MOTChallenge text
//! reader) and returns HOTA, CLEAR and Identity metrics. It does no IO.
//!
//! # What "exactly as TrackEval" means here
//!
//! The reference is `JonathonLuiten/TrackEval` (`trackeval/metrics/hota.py`,
//! `clear.py`, `identity.py`, `datasets/mot_challenge_2d_box.py`):
//!
//! - Similarity is box IoU on `(x, y, w, h)` boxes, with TrackEval's handling of
//!   degenerate boxes ([`box_iou`]).
//! - Per frame assignments use an exact linear sum assignment solver that is a
//!   port of scipy's `linear_sum_assignment` (the `lsap` crate), fed the same
//!   score matrices in the same row/column order (rows = ground-truth objects
//!   of the frame in file order, columns = predictions in file order), so ties
//!   resolve as they do in TrackEval. This includes CLEAR's `1000 x` bonus for
//!   continuing the previous frame's match and HOTA's global-alignment weighting.
//! - HOTA is evaluated at alpha = 0.05, 0.10, ..., 0.95 (19 values) and every
//!   HOTA sub-metric reported ([`Summary`]) is the mean over those alphas, as in
//!   TrackEval's summary tables.
//! - CLEAR and Identity use the similarity threshold 0.5.
//! - Sequences are combined as TrackEval's `combine_sequences` does: counts are
//!   summed, `AssA`/`AssRe`/`AssPr` are averaged weighted by HOTA true
//!   positives, `LocA` likewise, then ratios are recomputed from the sums
//!   ([`combine_sequences`]). Empty sequences contribute their counts (zero or
//!   only FN / only FP) and otherwise the same early-return values TrackEval
//!   gives them (for example a sequence with predictions but no ground truth has
//!   MOTA 0, not `-FP`).
//! - Classes can be combined as TrackEval's `combine_classes_class_averaged` and
//!   `combine_classes_det_averaged` do ([`combine_classes_class_averaged`],
//!   [`combine_sequences`] gives the detection average).
//!
//! # Class-agnostic evaluation (the default)
//!
//! SeaDronesSee evaluates tracking without regard to class. In TrackEval terms
//! the default here is the `MotChallenge2DBox` dataset with preprocessing
//! disabled (`DO_PREPROC = False`, which is what the `MOT15` benchmark setting
//! does) and one class that contains every object:
//!
//! - ground-truth rows are kept if and only if their `conf` ("considered") flag
//!   is non-zero, whatever their class;
//! - all prediction rows are kept, whatever their confidence or class;
//! - no distractor matching or removal happens (MOT17's distractor classes are
//!   pedestrian-specific and meaningless for SeaDronesSee).
//!
//! With [`ClassSelection::Only`] (per class evaluation) a ground-truth row is
//! kept if it is considered and of that class, and a prediction row if it is of
//! that class. This is TrackEval's per-class evaluation of a multi-class dataset
//! without distractor preprocessing.
//!
//! # Differences that do not change any number
//!
//! - The Identity metric is solved as a maximum-weight bipartite matching
//!   between ground-truth and predicted ids on the gt x pred block only, instead
//!   of TrackEval's padded `(G + T) x (G + T)` cost matrix. Both minimise
//!   `IDFN + IDFP = |gt| + |pred| - 2 * matched`, so IDTP/IDFN/IDFP are the same
//!   integers.
//! - Global counters are kept sparse (only id pairs that ever overlap), which
//!   changes only the order of floating point sums (differences ~1e-16).

mod assignment;
mod clear;
mod hota;
mod identity;
pub mod oracle;
mod pair_table;
mod sequence;
mod similarity;

pub use clear::ClearCounts;
pub use hota::{HotaCounts, ALPHAS};
pub use identity::IdentityCounts;
pub use sequence::{ClassSelection, PreparedSequence};
pub use similarity::box_iou;

use serde::Serialize;

/// `np.finfo(float).eps`, which TrackEval adds to or subtracts from every threshold.
pub(crate) const EPS: f64 = f64::EPSILON;

/// Errors from preparing or evaluating a sequence.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EvalError {
    /// The same id appears twice in one frame on one side (TrackEval rejects this too).
    #[error("{side} id {id} appears more than once in frame {frame}")]
    DuplicateId {
        /// `"ground truth"` or `"prediction"`.
        side: &'static str,
        /// The frame number as given in the input.
        frame: u64,
        /// The repeated id.
        id: i64,
    },
    /// A box coordinate is NaN or infinite.
    #[error("{side} id {id} in frame {frame} has a non-finite box")]
    NonFiniteBox {
        /// `"ground truth"` or `"prediction"`.
        side: &'static str,
        /// The frame number as given in the input.
        frame: u64,
        /// The id of the offending object.
        id: i64,
    },
}

/// An axis-aligned box: top-left corner and size, in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BoxXywh {
    /// Left edge.
    pub x: f64,
    /// Top edge.
    pub y: f64,
    /// Width.
    pub w: f64,
    /// Height.
    pub h: f64,
}

/// One object in one frame, on either the ground-truth or the prediction side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Annotation {
    /// Frame number (MOTChallenge frames start at 1; only the order matters here).
    pub frame: u64,
    /// Track id; ids only need to be unique within a frame and side.
    pub id: i64,
    /// The box.
    pub bbox: BoxXywh,
    /// Class id (MOTChallenge column 8); only used by [`ClassSelection::Only`].
    pub class: i64,
    /// Ground truth: the MOTChallenge `conf` column is non-zero ("consider this
    /// object"). Rows that are not considered are dropped. Predictions: always true.
    pub considered: bool,
}

/// Everything TrackEval keeps per sequence for one class, enough to combine
/// sequences or classes later without losing precision.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceResult {
    /// HOTA counts and per-alpha association scores.
    pub hota: HotaCounts,
    /// CLEAR counts.
    pub clear: ClearCounts,
    /// Identity counts.
    pub identity: IdentityCounts,
}

/// Evaluates one prepared sequence (HOTA, CLEAR and Identity).
pub fn evaluate_sequence(seq: &PreparedSequence) -> SequenceResult {
    SequenceResult {
        hota: hota::evaluate(seq),
        clear: clear::evaluate(seq),
        identity: identity::evaluate(seq),
    }
}

/// Combines per-sequence results as TrackEval's `combine_sequences` does (also
/// used for TrackEval's `combine_classes_det_averaged`, which is the same rule).
pub fn combine_sequences<'a>(
    results: impl IntoIterator<Item = &'a SequenceResult>,
) -> SequenceResult {
    let results: Vec<&SequenceResult> = results.into_iter().collect();
    SequenceResult {
        hota: HotaCounts::combine(results.iter().map(|r| &r.hota)),
        clear: ClearCounts::combine(results.iter().map(|r| &r.clear)),
        identity: IdentityCounts::combine(results.iter().map(|r| &r.identity)),
    }
}

impl SequenceResult {
    /// The reported metrics (HOTA family averaged over alpha).
    pub fn summary(&self) -> Summary {
        let h = self.hota.finalize();
        let c = self.clear.finalize();
        let i = self.identity.finalize();
        Summary {
            hota: h.hota,
            det_a: h.det_a,
            ass_a: h.ass_a,
            det_re: h.det_re,
            det_pr: h.det_pr,
            ass_re: h.ass_re,
            ass_pr: h.ass_pr,
            loc_a: h.loc_a,
            mota: c.mota,
            motp: c.motp,
            idf1: i.idf1,
            idr: i.idr,
            idp: i.idp,
            idsw: self.clear.idsw,
            frag: self.clear.frag,
            mt: self.clear.mt,
            pt: self.clear.pt,
            ml: self.clear.ml,
            fp: self.clear.fp,
            fn_: self.clear.fn_,
            recall: c.recall,
            precision: c.precision,
        }
    }
}

/// Combines per-class results (each already combined over sequences) as
/// TrackEval's `combine_classes_class_averaged` does with its default
/// `ignore_empty_classes = False`: counts are summed and every ratio is the
/// plain mean over classes. Returns `None` for an empty list.
pub fn combine_classes_class_averaged<'a>(
    per_class: impl IntoIterator<Item = &'a SequenceResult>,
) -> Option<Summary> {
    let summaries: Vec<Summary> = per_class.into_iter().map(SequenceResult::summary).collect();
    let n = summaries.len();
    if n == 0 {
        return None;
    }
    let mean = |f: fn(&Summary) -> f64| summaries.iter().map(f).sum::<f64>() / n as f64;
    let sum = |f: fn(&Summary) -> u64| summaries.iter().map(f).sum::<u64>();
    Some(Summary {
        hota: mean(|s| s.hota),
        det_a: mean(|s| s.det_a),
        ass_a: mean(|s| s.ass_a),
        det_re: mean(|s| s.det_re),
        det_pr: mean(|s| s.det_pr),
        ass_re: mean(|s| s.ass_re),
        ass_pr: mean(|s| s.ass_pr),
        loc_a: mean(|s| s.loc_a),
        mota: mean(|s| s.mota),
        motp: mean(|s| s.motp),
        idf1: mean(|s| s.idf1),
        idr: mean(|s| s.idr),
        idp: mean(|s| s.idp),
        idsw: sum(|s| s.idsw),
        frag: sum(|s| s.frag),
        mt: sum(|s| s.mt),
        pt: sum(|s| s.pt),
        ml: sum(|s| s.ml),
        fp: sum(|s| s.fp),
        fn_: sum(|s| s.fn_),
        recall: mean(|s| s.recall),
        precision: mean(|s| s.precision),
    })
}

/// The reported metrics. Ratios are fractions in 0..1 (MOTA can be negative),
/// counts are integers. Serialises with TrackEval's names as keys.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    /// Higher Order Tracking Accuracy, mean over alpha.
    #[serde(rename = "HOTA")]
    pub hota: f64,
    /// Detection accuracy, mean over alpha.
    #[serde(rename = "DetA")]
    pub det_a: f64,
    /// Association accuracy, mean over alpha.
    #[serde(rename = "AssA")]
    pub ass_a: f64,
    /// Detection recall, mean over alpha.
    #[serde(rename = "DetRe")]
    pub det_re: f64,
    /// Detection precision, mean over alpha.
    #[serde(rename = "DetPr")]
    pub det_pr: f64,
    /// Association recall, mean over alpha.
    #[serde(rename = "AssRe")]
    pub ass_re: f64,
    /// Association precision, mean over alpha.
    #[serde(rename = "AssPr")]
    pub ass_pr: f64,
    /// Localisation accuracy (mean IoU of matches), mean over alpha.
    #[serde(rename = "LocA")]
    pub loc_a: f64,
    /// Multiple Object Tracking Accuracy.
    #[serde(rename = "MOTA")]
    pub mota: f64,
    /// Multiple Object Tracking Precision (mean IoU of CLEAR matches).
    #[serde(rename = "MOTP")]
    pub motp: f64,
    /// Identity F1.
    #[serde(rename = "IDF1")]
    pub idf1: f64,
    /// Identity recall.
    #[serde(rename = "IDR")]
    pub idr: f64,
    /// Identity precision.
    #[serde(rename = "IDP")]
    pub idp: f64,
    /// Identity switches.
    #[serde(rename = "IDSW")]
    pub idsw: u64,
    /// Fragmentations.
    #[serde(rename = "Frag")]
    pub frag: u64,
    /// Mostly tracked ground-truth tracks (> 80% matched).
    #[serde(rename = "MT")]
    pub mt: u64,
    /// Partially tracked ground-truth tracks.
    #[serde(rename = "PT")]
    pub pt: u64,
    /// Mostly lost ground-truth tracks (< 20% matched).
    #[serde(rename = "ML")]
    pub ml: u64,
    /// CLEAR false positives.
    #[serde(rename = "FP")]
    pub fp: u64,
    /// CLEAR false negatives.
    #[serde(rename = "FN")]
    pub fn_: u64,
    /// CLEAR detection recall.
    #[serde(rename = "Recall")]
    pub recall: f64,
    /// CLEAR detection precision.
    #[serde(rename = "Precision")]
    pub precision: f64,
}

#[cfg(test)]
mod tests;
