//! The identity oracle: the best identities a tracker could give a set of detections.
//!
//! Every detection that matches a considered ground-truth box (IoU >= the threshold, one
//! optimal assignment per frame that maximises the summed IoU) takes that object's true id;
//! every other detection is dropped. Scored against the same ground truth, the result is
//! the ceiling that association alone can reach with these detections: it never switches,
//! never fragments, never keeps a false positive, but it also fills no frame the detector
//! missed. Tracking benchmarks report identity metrics relative to it, so that a detector
//! that misses small objects does not hide how well the tracker links what it sees.

use std::collections::BTreeMap;

use super::assignment::maximise_score;
use super::similarity::box_iou;
use super::{Annotation, EPS};

/// Labels detections with true ids (see the module doc). `dets` are predictions (their ids
/// are ignored); `gt` rows that are not considered are ignored. Returns `(index into dets,
/// true id)` for the matched detections only, in frame order and, within a frame, in the
/// detections' input order.
pub fn label_detections(gt: &[Annotation], dets: &[Annotation], min_iou: f64) -> Vec<(usize, i64)> {
    let mut gt_by_frame: BTreeMap<u64, Vec<&Annotation>> = BTreeMap::new();
    for g in gt.iter().filter(|g| g.considered) {
        gt_by_frame.entry(g.frame).or_default().push(g);
    }
    let mut det_by_frame: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (k, d) in dets.iter().enumerate() {
        det_by_frame.entry(d.frame).or_default().push(k);
    }
    let mut out = Vec::new();
    let mut score = Vec::new();
    for (frame, ds) in &det_by_frame {
        let Some(gs) = gt_by_frame.get(frame) else {
            continue;
        };
        score.clear();
        for g in gs {
            for &k in ds {
                let iou = box_iou(&g.bbox, &dets[k].bbox);
                score.push(if iou >= min_iou - EPS { iou } else { 0.0 });
            }
        }
        let mut labelled: Vec<(usize, i64)> = maximise_score(gs.len(), ds.len(), &score)
            .into_iter()
            .filter(|&(r, c)| score[r * ds.len() + c] > 0.0)
            .map(|(r, c)| (ds[c], gs[r].id))
            .collect();
        labelled.sort_unstable();
        out.extend(labelled);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::BoxXywh;

    fn ann(frame: u64, id: i64, x: f64, considered: bool) -> Annotation {
        Annotation {
            frame,
            id,
            bbox: BoxXywh {
                x,
                y: 0.0,
                w: 10.0,
                h: 10.0,
            },
            class: 1,
            considered,
        }
    }

    #[test]
    fn matched_detections_take_the_true_id_and_the_rest_are_dropped() {
        let gt = [
            ann(1, 7, 0.0, true),
            ann(1, 8, 20.0, true),
            ann(2, 7, 1.0, true),
            ann(2, 9, 50.0, false),
        ];
        let dets = [
            ann(1, -1, 21.0, true), // -> 8
            ann(1, -1, 1.0, true),  // -> 7
            ann(1, -1, 40.0, true), // false positive
            ann(2, -1, 6.0, true),  // IoU 5/15 < 0.5 with 7: dropped
            ann(2, -1, 50.0, true), // on a box that is not considered: dropped
            ann(3, -1, 0.0, true),  // frame without ground truth
        ];
        assert_eq!(label_detections(&gt, &dets, 0.5), vec![(0, 8), (1, 7)]);
    }

    #[test]
    fn one_detection_per_object_the_best_total_overlap() {
        // two detections on one object: the better one is kept
        let gt = [ann(1, 3, 0.0, true)];
        let dets = [ann(1, -1, 2.0, true), ann(1, -1, 1.0, true)];
        assert_eq!(label_detections(&gt, &dets, 0.5), vec![(1, 3)]);
    }
}
