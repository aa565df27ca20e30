//! HOTA (Luiten et al., IJCV 2021) as TrackEval's `metrics/hota.py` computes it.

use super::assignment::maximise_score;
use super::pair_table::PairTable;
use super::sequence::PreparedSequence;
use super::EPS;

/// Number of localisation thresholds alpha.
const NUM_ALPHAS: usize = 19;

/// The localisation thresholds alpha = 0.05, 0.10, ..., 0.95, bit for bit the
/// values of TrackEval's `np.arange(0.05, 0.99, 0.05)`.
pub const ALPHAS: [f64; NUM_ALPHAS] = {
    let mut a = [0.0; NUM_ALPHAS];
    let mut i = 0;
    while i < NUM_ALPHAS {
        a[i] = 0.05 + (i as f64) * 0.05;
        i += 1;
    }
    a
};

/// Per-alpha HOTA state of one sequence (or of several combined): detection
/// counts plus the association and localisation scores that are combined
/// weighted by true positives.
#[derive(Debug, Clone, PartialEq)]
pub struct HotaCounts {
    /// True positives per alpha (`HOTA_TP`).
    pub tp: [f64; NUM_ALPHAS],
    /// False negatives per alpha (`HOTA_FN`).
    pub fn_: [f64; NUM_ALPHAS],
    /// False positives per alpha (`HOTA_FP`).
    pub fp: [f64; NUM_ALPHAS],
    /// Association accuracy per alpha.
    pub ass_a: [f64; NUM_ALPHAS],
    /// Association recall per alpha.
    pub ass_re: [f64; NUM_ALPHAS],
    /// Association precision per alpha.
    pub ass_pr: [f64; NUM_ALPHAS],
    /// Localisation accuracy per alpha.
    pub loc_a: [f64; NUM_ALPHAS],
}

/// HOTA sub-metrics averaged over alpha.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct HotaFinal {
    pub(crate) hota: f64,
    pub(crate) det_a: f64,
    pub(crate) ass_a: f64,
    pub(crate) det_re: f64,
    pub(crate) det_pr: f64,
    pub(crate) ass_re: f64,
    pub(crate) ass_pr: f64,
    pub(crate) loc_a: f64,
}

impl HotaCounts {
    fn zeros() -> Self {
        HotaCounts {
            tp: [0.0; NUM_ALPHAS],
            fn_: [0.0; NUM_ALPHAS],
            fp: [0.0; NUM_ALPHAS],
            ass_a: [0.0; NUM_ALPHAS],
            ass_re: [0.0; NUM_ALPHAS],
            ass_pr: [0.0; NUM_ALPHAS],
            loc_a: [0.0; NUM_ALPHAS],
        }
    }

    /// TrackEval's `HOTA.combine_sequences`: sums of counts, TP-weighted means
    /// of the association and localisation scores.
    pub fn combine<'a>(parts: impl IntoIterator<Item = &'a HotaCounts>) -> HotaCounts {
        let parts: Vec<&HotaCounts> = parts.into_iter().collect();
        let mut out = HotaCounts::zeros();
        for a in 0..NUM_ALPHAS {
            out.tp[a] = parts.iter().map(|p| p.tp[a]).sum();
            out.fn_[a] = parts.iter().map(|p| p.fn_[a]).sum();
            out.fp[a] = parts.iter().map(|p| p.fp[a]).sum();
            let weighted = |f: fn(&HotaCounts) -> &[f64; NUM_ALPHAS]| -> f64 {
                parts.iter().map(|p| f(p)[a] * p.tp[a]).sum()
            };
            let tp = out.tp[a];
            out.ass_a[a] = weighted(|p| &p.ass_a) / tp.max(1.0);
            out.ass_re[a] = weighted(|p| &p.ass_re) / tp.max(1.0);
            out.ass_pr[a] = weighted(|p| &p.ass_pr) / tp.max(1.0);
            out.loc_a[a] = weighted(|p| &p.loc_a).max(1e-10) / tp.max(1e-10);
        }
        out
    }

    /// TrackEval's `_compute_final_fields`, then the mean over alpha.
    pub(crate) fn finalize(&self) -> HotaFinal {
        let mut f = HotaFinal {
            hota: 0.0,
            det_a: 0.0,
            ass_a: 0.0,
            det_re: 0.0,
            det_pr: 0.0,
            ass_re: 0.0,
            ass_pr: 0.0,
            loc_a: 0.0,
        };
        for a in 0..NUM_ALPHAS {
            let (tp, fn_, fp) = (self.tp[a], self.fn_[a], self.fp[a]);
            let det_re = tp / (tp + fn_).max(1.0);
            let det_pr = tp / (tp + fp).max(1.0);
            let det_a = tp / (tp + fn_ + fp).max(1.0);
            f.hota += (det_a * self.ass_a[a]).sqrt();
            f.det_a += det_a;
            f.det_re += det_re;
            f.det_pr += det_pr;
            f.ass_a += self.ass_a[a];
            f.ass_re += self.ass_re[a];
            f.ass_pr += self.ass_pr[a];
            f.loc_a += self.loc_a[a];
        }
        let n = NUM_ALPHAS as f64;
        HotaFinal {
            hota: f.hota / n,
            det_a: f.det_a / n,
            ass_a: f.ass_a / n,
            det_re: f.det_re / n,
            det_pr: f.det_pr / n,
            ass_re: f.ass_re / n,
            ass_pr: f.ass_pr / n,
            loc_a: f.loc_a / n,
        }
    }
}

/// HOTA of one sequence (TrackEval's `HOTA.eval_sequence`).
pub(crate) fn evaluate(seq: &PreparedSequence) -> HotaCounts {
    let mut res = HotaCounts::zeros();
    // TrackEval returns early for empty sides, with LocA = 1.
    if seq.num_pred_dets == 0 || seq.num_gt_dets == 0 {
        // One of the two is zero, so this is HOTA_FN = gt or HOTA_FP = pred.
        res.fn_ = [seq.num_gt_dets as f64; NUM_ALPHAS];
        res.fp = [seq.num_pred_dets as f64; NUM_ALPHAS];
        res.loc_a = [1.0; NUM_ALPHAS];
        return res;
    }

    // First pass: id counts and IoU-normalised potential matches per id pair.
    let mut potential_matches: PairTable<f64> = PairTable::new(seq.num_gt_ids, seq.num_pred_ids);
    let mut gt_id_count = vec![0.0_f64; seq.num_gt_ids];
    let mut pred_id_count = vec![0.0_f64; seq.num_pred_ids];
    let mut row_sum = Vec::new();
    let mut col_sum = Vec::new();
    for frame in &seq.frames {
        let (ng, np) = (frame.gt_ids.len(), frame.pred_ids.len());
        if ng > 0 && np > 0 {
            let rows = frame.similarity.chunks_exact(np);
            row_sum.clear();
            row_sum.extend(rows.clone().map(|row| row.iter().sum::<f64>()));
            col_sum.clear();
            col_sum.resize(np, 0.0);
            for row in rows.clone() {
                for (c, s) in col_sum.iter_mut().zip(row) {
                    *c += s;
                }
            }
            for ((row, &g), &rs) in rows.zip(&frame.gt_ids).zip(&row_sum) {
                for ((&s, &p), &cs) in row.iter().zip(&frame.pred_ids).zip(&col_sum) {
                    if s == 0.0 {
                        continue;
                    }
                    let denom = cs + rs - s;
                    if denom > EPS {
                        *potential_matches.get_mut(g, p) += s / denom;
                    }
                }
            }
        }
        for &g in &frame.gt_ids {
            gt_id_count[g] += 1.0;
        }
        for &p in &frame.pred_ids {
            pred_id_count[p] += 1.0;
        }
    }
    let global_alignment = |g: usize, p: usize| -> f64 {
        let m = potential_matches.get(g, p);
        if m == 0.0 {
            0.0
        } else {
            m / (gt_id_count[g] + pred_id_count[p] - m)
        }
    };

    // Second pass: one assignment per frame, thresholded at every alpha.
    let mut matches_count: PairTable<[u32; NUM_ALPHAS]> =
        PairTable::new(seq.num_gt_ids, seq.num_pred_ids);
    let mut score = Vec::new();
    for frame in &seq.frames {
        let (ng, np) = (frame.gt_ids.len(), frame.pred_ids.len());
        if ng == 0 || np == 0 {
            for a in 0..NUM_ALPHAS {
                res.fp[a] += np as f64;
                res.fn_[a] += ng as f64;
            }
            continue;
        }
        score.clear();
        for g in 0..ng {
            for p in 0..np {
                let s = frame.sim(g, p);
                score.push(if s == 0.0 {
                    0.0
                } else {
                    global_alignment(frame.gt_ids[g], frame.pred_ids[p]) * s
                });
            }
        }
        let pairs = maximise_score(ng, np, &score);
        for (a, alpha) in ALPHAS.iter().enumerate() {
            let mut num_matches = 0usize;
            let mut loc = 0.0;
            for &(g, p) in &pairs {
                let s = frame.sim(g, p);
                if s >= alpha - EPS {
                    num_matches += 1;
                    loc += s;
                    matches_count.get_mut(frame.gt_ids[g], frame.pred_ids[p])[a] += 1;
                }
            }
            res.tp[a] += num_matches as f64;
            res.fn_[a] += (ng - num_matches) as f64;
            res.fp[a] += (np - num_matches) as f64;
            res.loc_a[a] += loc;
        }
    }

    // Association scores: per id pair, weighted by its number of matches.
    for ((g, p), counts) in matches_count.into_sorted_entries() {
        for (a, &count) in counts.iter().enumerate() {
            let m = f64::from(count);
            if m == 0.0 {
                continue;
            }
            res.ass_a[a] += m * (m / (gt_id_count[g] + pred_id_count[p] - m).max(1.0));
            res.ass_re[a] += m * (m / gt_id_count[g].max(1.0));
            res.ass_pr[a] += m * (m / pred_id_count[p].max(1.0));
        }
    }
    for a in 0..NUM_ALPHAS {
        let tp = res.tp[a];
        res.ass_a[a] /= tp.max(1.0);
        res.ass_re[a] /= tp.max(1.0);
        res.ass_pr[a] /= tp.max(1.0);
        res.loc_a[a] = res.loc_a[a].max(1e-10) / tp.max(1e-10);
    }
    res
}
