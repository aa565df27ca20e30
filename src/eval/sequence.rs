//! Turning raw annotations of one sequence into what the metrics need
//! (TrackEval's `get_preprocessed_seq_data` for the configuration described in
//! the module docs of [`crate::eval`]).

use std::collections::{HashMap, HashSet};

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
        let gt: Vec<&Annotation> = gt
            .iter()
            .filter(|a| a.considered && classes.keeps(a.class))
            .collect();
        let pred: Vec<&Annotation> = pred.iter().filter(|a| classes.keeps(a.class)).collect();
        check_finite(&gt, "ground truth")?;
        check_finite(&pred, "prediction")?;

        let gt_map = relabel(&gt);
        let pred_map = relabel(&pred);
        let gt_by_frame = group_by_frame(&gt);
        let pred_by_frame = group_by_frame(&pred);

        let mut frame_numbers: Vec<u64> = gt_by_frame
            .keys()
            .chain(pred_by_frame.keys())
            .copied()
            .collect();
        frame_numbers.sort_unstable();
        frame_numbers.dedup();

        let empty: Vec<&Annotation> = Vec::new();
        let frames = frame_numbers
            .iter()
            .map(|f| {
                let g = gt_by_frame.get(f).unwrap_or(&empty);
                let p = pred_by_frame.get(f).unwrap_or(&empty);
                let mut similarity = Vec::with_capacity(g.len() * p.len());
                for a in g {
                    for b in p {
                        similarity.push(box_iou(&a.bbox, &b.bbox));
                    }
                }
                PreparedFrame {
                    gt_ids: g.iter().map(|a| gt_map[&a.id]).collect(),
                    pred_ids: p.iter().map(|a| pred_map[&a.id]).collect(),
                    similarity,
                }
            })
            .collect();

        Ok(PreparedSequence {
            frames,
            num_gt_ids: gt_map.len(),
            num_pred_ids: pred_map.len(),
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
    let mut seen = HashSet::with_capacity(rows.len());
    for a in rows {
        if !seen.insert((a.frame, a.id)) {
            return Err(EvalError::DuplicateId {
                side,
                frame: a.frame,
                id: a.id,
            });
        }
    }
    Ok(())
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
fn relabel(rows: &[&Annotation]) -> HashMap<i64, usize> {
    let mut ids: Vec<i64> = rows.iter().map(|a| a.id).collect();
    ids.sort_unstable();
    ids.dedup();
    ids.into_iter().enumerate().map(|(i, id)| (id, i)).collect()
}

fn group_by_frame<'a>(rows: &[&'a Annotation]) -> HashMap<u64, Vec<&'a Annotation>> {
    let mut by_frame: HashMap<u64, Vec<&'a Annotation>> = HashMap::new();
    for a in rows {
        by_frame.entry(a.frame).or_default().push(a);
    }
    by_frame
}
