//! Turning raw annotations of one sequence into what the metrics need
//! (TrackEval's `get_preprocessed_seq_data` for the configuration described in
//! the module docs of [`crate::eval`]).

use super::{box_iou, Annotation, EvalError};

/// Which objects take part in an evaluation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ClassSelection {
    /// Class-agnostic: every considered ground-truth row and every prediction.
    #[default]
    All,
    /// Only rows of this class (ground truth must also be considered).
    Only(i64),
}

impl ClassSelection {
    fn keeps(self, class: i64) -> bool {
        match self {
            ClassSelection::All => true,
            ClassSelection::Only(c) => c == class,
        }
    }
}

/// One frame after filtering: contiguous ids (0-based, in order of the
/// original ids) and the gt x pred IoU matrix, row-major. Rows and columns are
/// in input order, which decides how assignment ties break.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PreparedFrame {
    pub(crate) gt_ids: Vec<usize>,
    pub(crate) pred_ids: Vec<usize>,
    pub(crate) similarity: Vec<f64>,
}

impl PreparedFrame {
    /// IoU between the `g`-th gt and the `p`-th prediction of this frame.
    pub(crate) fn sim(&self, g: usize, p: usize) -> f64 {
        self.similarity[g * self.pred_ids.len() + p]
    }
}

/// A sequence ready to be evaluated: frames in time order with IoUs computed.
#[derive(Debug, Clone, PartialEq)]
pub struct PreparedSequence {
    pub(crate) frames: Vec<PreparedFrame>,
    pub(crate) num_gt_ids: usize,
    pub(crate) num_pred_ids: usize,
    pub(crate) num_gt_dets: usize,
    pub(crate) num_pred_dets: usize,
}

impl PreparedSequence {
    /// Filters, groups by frame (keeping input order within a frame), relabels
    /// ids and computes IoUs.
    ///
    /// Errors if an id occurs twice in one frame on one side (checked on all
    /// rows, before filtering, as TrackEval does) or if a kept box is not finite.
    pub fn new(
        gt: &[Annotation],
        pred: &[Annotation],
        classes: ClassSelection,
    ) -> Result<Self, EvalError> {
        check_unique(gt, "ground truth")?;
        check_unique(pred, "prediction")?;
        let mut gt: Vec<&Annotation> = gt
            .iter()
            .filter(|a| a.considered && classes.keeps(a.class))
            .collect();
        let mut pred: Vec<&Annotation> = pred.iter().filter(|a| classes.keeps(a.class)).collect();
        // Stable: rows of one frame stay in input order.
        gt.sort_by_key(|a| a.frame);
        pred.sort_by_key(|a| a.frame);
        check_finite(&gt, "ground truth")?;
        check_finite(&pred, "prediction")?;

        let gt_ids = IdMap::new(&gt);
        let pred_ids = IdMap::new(&pred);
        let gt_by_frame = group_by_frame(&gt);
        let pred_by_frame = group_by_frame(&pred);

        // Walk both frame lists (sorted by frame number) together.
        let mut frames = Vec::with_capacity(gt_by_frame.len().max(pred_by_frame.len()));
        let mut gt_frames = gt_by_frame.iter().peekable();
        let mut pred_frames = pred_by_frame.iter().peekable();
        let empty: &[&Annotation] = &[];
        loop {
            let frame = match (gt_frames.peek(), pred_frames.peek()) {
                (None, None) => break,
                (Some(g), Some(p)) => g.0.min(p.0),
                (Some(g), None) => g.0,
                (None, Some(p)) => p.0,
            };
            let g = gt_frames
                .next_if(|(f, _)| *f == frame)
                .map_or(empty, |(_, rows)| *rows);
            let p = pred_frames
                .next_if(|(f, _)| *f == frame)
                .map_or(empty, |(_, rows)| *rows);
            let mut similarity = Vec::with_capacity(g.len() * p.len());
            for a in g {
                for b in p {
                    similarity.push(box_iou(&a.bbox, &b.bbox));
                }
            }
            frames.push(PreparedFrame {
                gt_ids: g.iter().map(|a| gt_ids.index(a.id)).collect(),
                pred_ids: p.iter().map(|a| pred_ids.index(a.id)).collect(),
                similarity,
            });
        }

        Ok(PreparedSequence {
            frames,
            num_gt_ids: gt_ids.len(),
            num_pred_ids: pred_ids.len(),
            num_gt_dets: gt.len(),
            num_pred_dets: pred.len(),
        })
    }

    /// Number of ground-truth boxes taking part.
    pub fn num_gt_dets(&self) -> usize {
        self.num_gt_dets
    }

    /// Number of predicted boxes taking part.
    pub fn num_pred_dets(&self) -> usize {
        self.num_pred_dets
    }

    /// Number of distinct ground-truth ids taking part.
    pub fn num_gt_ids(&self) -> usize {
        self.num_gt_ids
    }

    /// Number of distinct predicted ids taking part.
    pub fn num_pred_ids(&self) -> usize {
        self.num_pred_ids
    }
}

fn check_unique(rows: &[Annotation], side: &'static str) -> Result<(), EvalError> {
    let mut keys: Vec<(u64, i64)> = rows.iter().map(|a| (a.frame, a.id)).collect();
    keys.sort_unstable();
    match keys.windows(2).find(|w| w[0] == w[1]) {
        Some(w) => Err(EvalError::DuplicateId {
            side,
            frame: w[0].0,
            id: w[0].1,
        }),
        None => Ok(()),
    }
}

fn check_finite(rows: &[&Annotation], side: &'static str) -> Result<(), EvalError> {
    match rows.iter().find(|a| {
        let b = a.bbox;
        !(b.x.is_finite() && b.y.is_finite() && b.w.is_finite() && b.h.is_finite())
    }) {
        Some(a) => Err(EvalError::NonFiniteBox {
            side,
            frame: a.frame,
            id: a.id,
        }),
        None => Ok(()),
    }
}

/// Maps original ids to 0..n in increasing order of the original id (TrackEval
/// uses `np.unique`, which sorts).
struct IdMap {
    sorted_ids: Vec<i64>,
}

impl IdMap {
    fn new(rows: &[&Annotation]) -> Self {
        let mut sorted_ids: Vec<i64> = rows.iter().map(|a| a.id).collect();
        sorted_ids.sort_unstable();
        sorted_ids.dedup();
        IdMap { sorted_ids }
    }

    /// The contiguous index of an id taken from the rows this map was built from.
    fn index(&self, id: i64) -> usize {
        // Every id of those rows is in the list, so the search always succeeds.
        self.sorted_ids.binary_search(&id).unwrap_or_else(|i| i)
    }

    fn len(&self) -> usize {
        self.sorted_ids.len()
    }
}

/// Rows grouped by frame, frames in increasing order, rows of a frame in input
/// order (TrackEval keeps file order within a timestep).
fn group_by_frame<'r, 'a>(rows: &'r [&'a Annotation]) -> Vec<(u64, &'r [&'a Annotation])> {
    let mut groups = Vec::new();
    let mut start = 0;
    for i in 1..=rows.len() {
        if i == rows.len() || rows[i].frame != rows[start].frame {
            if start < i {
                groups.push((rows[start].frame, &rows[start..i]));
            }
            start = i;
        }
    }
    groups
}
