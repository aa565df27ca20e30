//! CLEAR MOT metrics (Bernardin & Stiefelhagen 2008) as TrackEval's
//! `metrics/clear.py` computes them.

use super::assignment::maximise_score;
use super::sequence::PreparedSequence;
use super::EPS;

/// IoU a CLEAR match needs (TrackEval's default `THRESHOLD`).
const THRESHOLD: f64 = 0.5;

/// Bonus that makes the assignment keep last frame's matches first, so that
/// IoU only decides among the rest (TrackEval's `1000 * score_mat`).
const CONTINUATION_BONUS: f64 = 1000.0;

/// CLEAR counts of one sequence (or of several combined).
#[derive(Debug, Clone, PartialEq)]
pub struct ClearCounts {
    /// Matches (`CLR_TP`).
    pub tp: u64,
    /// Unmatched ground truth (`CLR_FN`).
    pub fn_: u64,
    /// Unmatched predictions (`CLR_FP`).
    pub fp: u64,
    /// Identity switches.
    pub idsw: u64,
    /// Mostly tracked ground-truth ids.
    pub mt: u64,
    /// Partially tracked ground-truth ids.
    pub pt: u64,
    /// Mostly lost ground-truth ids.
    pub ml: u64,
    /// Fragmentations.
    pub frag: u64,
    /// Sum of the IoUs of all matches (`MOTP_sum`).
    pub motp_sum: f64,
    /// TrackEval returns early for a sequence with predictions but no ground
    /// truth and leaves its MOTA at 0 instead of `-FP`; this records that case.
    pub mota_reported_as_zero: bool,
}

/// CLEAR ratios.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ClearFinal {
    pub(crate) mota: f64,
    pub(crate) motp: f64,
    pub(crate) recall: f64,
    pub(crate) precision: f64,
}

impl ClearCounts {
    fn zeros() -> Self {
        ClearCounts {
            tp: 0,
            fn_: 0,
            fp: 0,
            idsw: 0,
            mt: 0,
            pt: 0,
            ml: 0,
            frag: 0,
            motp_sum: 0.0,
            mota_reported_as_zero: false,
        }
    }

    /// TrackEval's `CLEAR.combine_sequences`: every count and `MOTP_sum` summed.
    pub fn combine<'a>(parts: impl IntoIterator<Item = &'a ClearCounts>) -> ClearCounts {
        let mut out = ClearCounts::zeros();
        for p in parts {
            out.tp += p.tp;
            out.fn_ += p.fn_;
            out.fp += p.fp;
            out.idsw += p.idsw;
            out.mt += p.mt;
            out.pt += p.pt;
            out.ml += p.ml;
            out.frag += p.frag;
            out.motp_sum += p.motp_sum;
        }
        out
    }

    /// TrackEval's `_compute_final_fields` for the reported ratios.
    pub(crate) fn finalize(&self) -> ClearFinal {
        let (tp, fn_, fp, idsw) = (
            self.tp as f64,
            self.fn_ as f64,
            self.fp as f64,
            self.idsw as f64,
        );
        let mota = if self.mota_reported_as_zero {
            0.0
        } else {
            (tp - fp - idsw) / (tp + fn_).max(1.0)
        };
        ClearFinal {
            mota,
            motp: self.motp_sum / tp.max(1.0),
            recall: tp / (tp + fn_).max(1.0),
            precision: tp / (tp + fp).max(1.0),
        }
    }
}

/// CLEAR metrics of one sequence (TrackEval's `CLEAR.eval_sequence`).
pub(crate) fn evaluate(seq: &PreparedSequence) -> ClearCounts {
    let mut res = ClearCounts::zeros();
    if seq.num_pred_dets == 0 {
        res.fn_ = seq.num_gt_dets as u64;
        res.ml = seq.num_gt_ids as u64;
        return res;
    }
    if seq.num_gt_dets == 0 {
        res.fp = seq.num_pred_dets as u64;
        res.mota_reported_as_zero = true;
        return res;
    }

    let n = seq.num_gt_ids;
    let mut gt_id_count = vec![0u64; n];
    let mut gt_matched_count = vec![0u64; n];
    let mut gt_frag_count = vec![0u64; n];
    // Last prediction matched to each gt id, any number of frames ago (for IDSW).
    let mut prev_pred_id: Vec<Option<usize>> = vec![None; n];
    // Prediction matched to each gt id in the last frame that had both gt and
    // predictions (for the continuation bonus and Frag). TrackEval skips frames
    // with an empty side before resetting it, and so does this.
    let mut prev_frame_pred_id: Vec<Option<usize>> = vec![None; n];
    let mut prev_frame_matched: Vec<usize> = Vec::new();
    let mut score = Vec::new();

    for frame in &seq.frames {
        let (ng, np) = (frame.gt_ids.len(), frame.pred_ids.len());
        if ng == 0 {
            res.fp += np as u64;
            continue;
        }
        if np == 0 {
            res.fn_ += ng as u64;
            for &g in &frame.gt_ids {
                gt_id_count[g] += 1;
            }
            continue;
        }

        score.clear();
        for (gi, &g) in frame.gt_ids.iter().enumerate() {
            for (pi, &p) in frame.pred_ids.iter().enumerate() {
                let s = frame.sim(gi, pi);
                score.push(if s < THRESHOLD - EPS {
                    0.0
                } else if prev_frame_pred_id[g] == Some(p) {
                    CONTINUATION_BONUS + s
                } else {
                    s
                });
            }
        }
        let matched: Vec<(usize, usize)> = maximise_score(ng, np, &score)
            .into_iter()
            .filter(|&(gi, pi)| score[gi * np + pi] > EPS)
            .collect();

        for &(gi, pi) in &matched {
            let (g, p) = (frame.gt_ids[gi], frame.pred_ids[pi]);
            if prev_pred_id[g].is_some_and(|prev| prev != p) {
                res.idsw += 1;
            }
        }
        for &g in &frame.gt_ids {
            gt_id_count[g] += 1;
        }
        // A gt id starts a new tracked stretch if it was not matched in the
        // previous (non-empty) frame.
        let was_tracked: Vec<bool> = matched
            .iter()
            .map(|&(gi, _)| prev_frame_pred_id[frame.gt_ids[gi]].is_some())
            .collect();
        for g in prev_frame_matched.drain(..) {
            prev_frame_pred_id[g] = None;
        }
        let mut frame_motp_sum = 0.0;
        for (&(gi, pi), was) in matched.iter().zip(was_tracked) {
            let (g, p) = (frame.gt_ids[gi], frame.pred_ids[pi]);
            gt_matched_count[g] += 1;
            prev_pred_id[g] = Some(p);
            prev_frame_pred_id[g] = Some(p);
            prev_frame_matched.push(g);
            if !was {
                gt_frag_count[g] += 1;
            }
            frame_motp_sum += frame.sim(gi, pi);
        }
        res.motp_sum += frame_motp_sum;

        let num_matches = matched.len();
        res.tp += num_matches as u64;
        res.fn_ += (ng - num_matches) as u64;
        res.fp += (np - num_matches) as u64;
    }

    for g in 0..n {
        if gt_id_count[g] == 0 {
            continue;
        }
        let ratio = gt_matched_count[g] as f64 / gt_id_count[g] as f64;
        if ratio > 0.8 {
            res.mt += 1;
        } else if ratio >= 0.2 {
            res.pt += 1;
        }
    }
    res.ml = n as u64 - res.mt - res.pt;
    res.frag = gt_frag_count.iter().map(|&c| c.saturating_sub(1)).sum();
    res
}
