//! Identity metrics (Ristani et al. 2016) as TrackEval's `metrics/identity.py`
//! computes them.

use std::collections::HashMap;

use super::assignment::maximise_score;
use super::pair_table::PairTable;
use super::sequence::PreparedSequence;

/// IoU a frame-level identity match needs (TrackEval's default; compared with
/// `>=` and no epsilon, as TrackEval does).
const THRESHOLD: f64 = 0.5;

/// Identity counts of one sequence (or of several combined).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IdentityCounts {
    /// Identity true positives.
    pub idtp: u64,
    /// Identity false negatives.
    pub idfn: u64,
    /// Identity false positives.
    pub idfp: u64,
}

/// Identity ratios.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct IdentityFinal {
    pub(crate) idf1: f64,
    pub(crate) idr: f64,
    pub(crate) idp: f64,
}

impl IdentityCounts {
    /// TrackEval's `Identity.combine_sequences`: counts summed.
    pub fn combine<'a>(parts: impl IntoIterator<Item = &'a IdentityCounts>) -> IdentityCounts {
        parts
            .into_iter()
            .fold(IdentityCounts::default(), |acc, p| IdentityCounts {
                idtp: acc.idtp + p.idtp,
                idfn: acc.idfn + p.idfn,
                idfp: acc.idfp + p.idfp,
            })
    }

    pub(crate) fn finalize(&self) -> IdentityFinal {
        let (tp, fn_, fp) = (self.idtp as f64, self.idfn as f64, self.idfp as f64);
        IdentityFinal {
            idr: tp / (tp + fn_).max(1.0),
            idp: tp / (tp + fp).max(1.0),
            idf1: tp / (tp + 0.5 * fp + 0.5 * fn_).max(1.0),
        }
    }
}

/// Identity metrics of one sequence (TrackEval's `Identity.eval_sequence`).
///
/// TrackEval solves a `(G + T) x (G + T)` assignment whose cost is
/// `IDFN + IDFP`; that is `|gt| + |pred| - 2 * IDTP`, so its optimum is the
/// maximum-weight matching between gt ids and predicted ids with weights = the
/// number of frames in which the pair overlaps with IoU >= 0.5. That matching
/// is solved here per connected component of the overlap graph, which gives the
/// same integers with far smaller matrices.
pub(crate) fn evaluate(seq: &PreparedSequence) -> IdentityCounts {
    if seq.num_pred_dets == 0 || seq.num_gt_dets == 0 {
        // One of the two is zero: IDFN = gt or IDFP = pred.
        return IdentityCounts {
            idtp: 0,
            idfn: seq.num_gt_dets as u64,
            idfp: seq.num_pred_dets as u64,
        };
    }
    let (ng, np) = (seq.num_gt_ids, seq.num_pred_ids);
    let mut potential_matches: PairTable<u64> = PairTable::new(ng, np);
    for frame in &seq.frames {
        let fp = frame.pred_ids.len();
        for (gi, &g) in frame.gt_ids.iter().enumerate() {
            for (pi, &p) in frame.pred_ids.iter().enumerate() {
                if frame.similarity[gi * fp + pi] >= THRESHOLD {
                    *potential_matches.get_mut(g, p) += 1;
                }
            }
        }
    }
    let pairs = potential_matches.into_sorted_entries();

    // Connected components over nodes 0..ng (gt ids) and ng..ng+np (pred ids).
    let mut components = DisjointSets::new(ng + np);
    for &((g, p), _) in &pairs {
        components.union(g, ng + p);
    }
    let mut by_component: HashMap<usize, Vec<Edge>> = HashMap::new();
    for &pair in &pairs {
        let root = components.find(pair.0 .0);
        by_component.entry(root).or_default().push(pair);
    }

    let mut idtp = 0u64;
    for edges in by_component.values() {
        let mut gts: Vec<usize> = edges.iter().map(|((g, _), _)| *g).collect();
        let mut preds: Vec<usize> = edges.iter().map(|((_, p), _)| *p).collect();
        gts.sort_unstable();
        gts.dedup();
        preds.sort_unstable();
        preds.dedup();
        let (rows, cols) = (gts.len(), preds.len());
        let mut weight = vec![0.0; rows * cols];
        for &((g, p), w) in edges {
            // Both searches succeed: the lists were built from these edges.
            if let (Ok(r), Ok(c)) = (gts.binary_search(&g), preds.binary_search(&p)) {
                weight[r * cols + c] = w as f64;
            }
        }
        idtp += maximise_score(rows, cols, &weight)
            .into_iter()
            .map(|(r, c)| weight[r * cols + c] as u64)
            .sum::<u64>();
    }

    let num_gt_dets = seq.num_gt_dets as u64;
    let num_pred_dets = seq.num_pred_dets as u64;
    IdentityCounts {
        idtp,
        idfn: num_gt_dets - idtp,
        idfp: num_pred_dets - idtp,
    }
}

/// A (gt id, predicted id) pair and the number of frames it overlaps in.
type Edge = ((usize, usize), u64);

/// Union-find with path halving, for splitting the id overlap graph.
struct DisjointSets {
    parent: Vec<usize>,
}

impl DisjointSets {
    fn new(n: usize) -> Self {
        DisjointSets {
            parent: (0..n).collect(),
        }
    }

    fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra] = rb;
        }
    }
}
