//! Non-maximum suppression that keeps the larger box (paper Sec. 5.1, post-processing).
//!
//! The paper observes that at low altitude overlapping detections are mostly a small false
//! positive inside a real object, so unlike standard NMS (which keeps the higher score) the
//! larger box of an overlapping pair wins.

use super::bbox::BBox;

/// Indices of the boxes kept by "prefer larger" NMS, in ascending index order.
///
/// Boxes are visited from the largest area to the smallest (ties broken by the lower index,
/// so the result is deterministic); a box is kept unless its IoU with an already kept box is
/// strictly greater than `iou_threshold`. Invalid boxes (non-finite or empty) are dropped.
/// The result is a subset of `0..boxes.len()` with no kept pair above the threshold.
pub fn nms_prefer_larger(boxes: &[BBox], iou_threshold: f64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..boxes.len()).filter(|&i| boxes[i].is_valid()).collect();
    let mut kept = Vec::with_capacity(order.len());
    nms_prefer_larger_into(boxes, iou_threshold, &mut order, &mut kept);
    kept
}

/// Allocation-free core of [`nms_prefer_larger`]: `order` must hold the candidate indices
/// (it is sorted in place), `kept` receives the kept indices in ascending order.
pub(crate) fn nms_prefer_larger_into(
    boxes: &[BBox],
    iou_threshold: f64,
    order: &mut [usize],
    kept: &mut Vec<usize>,
) {
    kept.clear();
    order.sort_by(|&a, &b| {
        boxes[b]
            .area()
            .total_cmp(&boxes[a].area())
            .then_with(|| a.cmp(&b))
    });
    for &i in order.iter() {
        if kept
            .iter()
            .all(|&k| boxes[k].iou(&boxes[i]) <= iou_threshold)
        {
            kept.push(i);
        }
    }
    kept.sort_unstable();
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn keeps_larger_of_overlapping_pair() {
        let big = BBox::new(0.0, 0.0, 10.0, 10.0);
        let small = BBox::new(0.0, 0.0, 9.0, 9.0); // IoU 0.81
        let far = BBox::new(100.0, 100.0, 2.0, 2.0);
        assert_eq!(nms_prefer_larger(&[small, big, far], 0.5), vec![1, 2]);
        // below the threshold both survive
        assert_eq!(nms_prefer_larger(&[small, big], 0.9), vec![0, 1]);
    }

    #[test]
    fn drops_invalid_boxes() {
        let boxes = [
            BBox::new(0.0, 0.0, 0.0, 10.0),
            BBox::new(5.0, 5.0, 1.0, 1.0),
        ];
        assert_eq!(nms_prefer_larger(&boxes, 0.5), vec![1]);
    }

    fn arb_box() -> impl Strategy<Value = BBox> {
        (0.0..100.0f64, 0.0..100.0f64, 1.0..40.0f64, 1.0..40.0f64)
            .prop_map(|(x, y, w, h)| BBox::new(x, y, w, h))
    }

    proptest! {
        #[test]
        fn output_is_subset_without_overlapping_pair(
            boxes in prop::collection::vec(arb_box(), 0..40),
            thr in 0.05..0.95f64,
        ) {
            let kept = nms_prefer_larger(&boxes, thr);
            for w in kept.windows(2) {
                prop_assert!(w[0] < w[1]);
            }
            for &k in &kept {
                prop_assert!(k < boxes.len());
            }
            for (a, &i) in kept.iter().enumerate() {
                for &j in &kept[a + 1..] {
                    prop_assert!(boxes[i].iou(&boxes[j]) <= thr);
                }
            }
            // every dropped box overlaps a kept box that is at least as large
            for i in 0..boxes.len() {
                if !kept.contains(&i) {
                    prop_assert!(kept.iter().any(|&k| boxes[k].iou(&boxes[i]) > thr
                        && boxes[k].area() >= boxes[i].area()));
                }
            }
        }
    }
}
