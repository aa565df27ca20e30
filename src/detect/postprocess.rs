//! From raw model output to the final detections: decoding the YOLOv8 rows,
//! class-aware NMS, and the MG-MOT paper's larger-box-priority suppression.

use super::model::OutputLayout;
use super::preprocess::Letterbox;
use super::{Detection, PixelBox};
use crate::track::{nms_prefer_larger, BBox};

/// Decodes one output tensor (`data` in row-major order of the layout's shape)
/// into frame-pixel detections scoring at least `score_threshold`.
///
/// As Ultralytics does for single-label detection, each candidate keeps only
/// its best class. Boxes are clipped to the `frame_w x frame_h` frame; boxes
/// that end up empty are dropped.
#[allow(clippy::too_many_arguments)]
pub fn decode(
    data: &[f32],
    layout: OutputLayout,
    num_classes: usize,
    num_candidates: usize,
    letterbox: &Letterbox,
    frame_w: f32,
    frame_h: f32,
    score_threshold: f32,
    out: &mut Vec<Detection>,
) {
    let rows = 4 + num_classes;
    if data.len() < rows * num_candidates {
        return;
    }
    let at = |row: usize, i: usize| match layout {
        OutputLayout::ChannelsFirst => data[row * num_candidates + i],
        OutputLayout::ChannelsLast => data[i * rows + row],
    };
    for i in 0..num_candidates {
        let mut best = 0usize;
        let mut best_score = f32::NEG_INFINITY;
        for c in 0..num_classes {
            let s = at(4 + c, i);
            if s > best_score {
                best_score = s;
                best = c;
            }
        }
        if best_score.is_nan() || best_score < score_threshold {
            continue;
        }
        let (cx, cy, w, h) = (at(0, i), at(1, i), at(2, i), at(3, i));
        let (x1, y1) = letterbox.to_frame(cx - w / 2.0, cy - h / 2.0);
        let (x2, y2) = letterbox.to_frame(cx + w / 2.0, cy + h / 2.0);
        let (x1, y1) = (x1.clamp(0.0, frame_w), y1.clamp(0.0, frame_h));
        let (x2, y2) = (x2.clamp(0.0, frame_w), y2.clamp(0.0, frame_h));
        if !(x2 > x1 && y2 > y1) {
            continue;
        }
        out.push(Detection {
            class_id: best,
            score: best_score,
            bbox: PixelBox::from_corners(x1, y1, x2, y2),
        });
    }
}

/// Greedy non-maximum suppression within each class: highest score first, a
/// box is dropped when it overlaps a kept box of its class with IoU above
/// `iou_threshold`. Keeps at most `max_detections`, sorted by score.
pub fn class_aware_nms(
    mut dets: Vec<Detection>,
    iou_threshold: f32,
    max_detections: usize,
) -> Vec<Detection> {
    dets.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut kept: Vec<Detection> = Vec::with_capacity(dets.len().min(max_detections));
    for d in dets {
        if kept.len() >= max_detections {
            break;
        }
        let suppressed = kept
            .iter()
            .any(|k| k.class_id == d.class_id && k.bbox.iou(&d.bbox) > iou_threshold);
        if !suppressed {
            kept.push(d);
        }
    }
    kept
}

/// The MG-MOT paper's suppression (Sec. "Post-Processing") on the detector's output: among
/// overlapping detections the one with the **larger box area** wins, because at low altitude
/// the smaller of two overlapping boxes is most often a false positive (a part of a swimmer or
/// boat). The one implementation is the core's [`nms_prefer_larger`] (which the tracker's
/// baseline also applies, with its own threshold); this only orders the detections by score
/// first, so that ties in area go to the higher score, and returns them sorted by score.
///
/// Class-agnostic; a box is dropped when its IoU with a larger kept box exceeds
/// `iou_threshold`.
pub fn larger_box_priority_suppression(
    mut dets: Vec<Detection>,
    iou_threshold: f32,
) -> Vec<Detection> {
    dets.sort_by(|a, b| b.score.total_cmp(&a.score));
    let boxes: Vec<BBox> = dets.iter().map(|d| d.bbox.to_bbox()).collect();
    // Ascending indices: still sorted by score.
    let kept = nms_prefer_larger(&boxes, f64::from(iou_threshold));
    let mut keep = kept.into_iter().peekable();
    dets.into_iter()
        .enumerate()
        .filter_map(|(i, d)| keep.next_if_eq(&i).map(|_| d))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn det(class_id: usize, score: f32, x: f32, y: f32, w: f32, h: f32) -> Detection {
        Detection {
            class_id,
            score,
            bbox: PixelBox {
                x_px: x,
                y_px: y,
                w_px: w,
                h_px: h,
            },
        }
    }

    const IDENTITY: Letterbox = Letterbox {
        scale: 1.0,
        pad_x_px: 0.0,
        pad_y_px: 0.0,
        origin_x_px: 0.0,
        origin_y_px: 0.0,
    };

    #[test]
    fn decodes_both_layouts_and_maps_through_the_letterbox() {
        // Two candidates, two classes: rows cx, cy, w, h, s0, s1.
        let cf = [
            10.0, 50.0, // cx
            20.0, 50.0, // cy
            4.0, 10.0, // w
            6.0, 10.0, // h
            0.9, 0.1, // class 0
            0.2, 0.05, // class 1
        ];
        let mut cl = [0.0; 12];
        for r in 0..6 {
            for i in 0..2 {
                cl[i * 6 + r] = cf[r * 2 + i];
            }
        }
        let lb = Letterbox {
            scale: 0.5,
            pad_x_px: 2.0,
            pad_y_px: 0.0,
            origin_x_px: 100.0,
            origin_y_px: 0.0,
        };
        for (data, layout) in [
            (&cf[..], OutputLayout::ChannelsFirst),
            (&cl[..], OutputLayout::ChannelsLast),
        ] {
            let mut out = Vec::new();
            decode(data, layout, 2, 2, &lb, 1000.0, 1000.0, 0.25, &mut out);
            assert_eq!(out.len(), 1, "{layout:?}");
            let d = out[0];
            assert_eq!(d.class_id, 0);
            assert_eq!(d.score, 0.9);
            // x1 = (10 - 2 - 2) / 0.5 + 100 = 112; y1 = (20 - 3) / 0.5 = 34
            assert_eq!(d.bbox, PixelBox::from_corners(112.0, 34.0, 120.0, 46.0));
        }
    }

    #[test]
    fn decode_clips_to_the_frame() {
        let data = [1.0, 1.0, 10.0, 10.0, 0.8];
        let mut out = Vec::new();
        decode(
            &data,
            OutputLayout::ChannelsFirst,
            1,
            1,
            &IDENTITY,
            5.0,
            5.0,
            0.5,
            &mut out,
        );
        assert_eq!(out[0].bbox, PixelBox::from_corners(0.0, 0.0, 5.0, 5.0));
    }

    #[test]
    fn nms_is_class_aware() {
        let dets = vec![
            det(0, 0.9, 0.0, 0.0, 10.0, 10.0),
            det(0, 0.8, 1.0, 1.0, 10.0, 10.0), // same class, overlaps: dropped
            det(1, 0.7, 1.0, 1.0, 10.0, 10.0), // other class: kept
            det(0, 0.6, 50.0, 50.0, 10.0, 10.0),
        ];
        let kept = class_aware_nms(dets, 0.5, 100);
        let scores: Vec<f32> = kept.iter().map(|d| d.score).collect();
        assert_eq!(scores, vec![0.9, 0.7, 0.6]);
        assert_eq!(class_aware_nms(kept, 0.5, 2).len(), 2);
    }

    #[test]
    fn larger_box_wins_even_with_a_lower_score() {
        let big = det(0, 0.5, 0.0, 0.0, 10.0, 10.0);
        let small = det(0, 0.9, 0.5, 0.5, 9.0, 9.0); // IoU 0.81
        let far = det(1, 0.3, 40.0, 40.0, 5.0, 5.0);
        let kept = larger_box_priority_suppression(vec![small, big, far], 0.7);
        assert_eq!(kept, vec![big, far]);
    }

    fn arb_det() -> impl Strategy<Value = Detection> {
        (
            0usize..3,
            0.0f32..1.0,
            0.0f32..100.0,
            0.0f32..100.0,
            1.0f32..30.0,
            1.0f32..30.0,
        )
            .prop_map(|(c, s, x, y, w, h)| det(c, s, x, y, w, h))
    }

    proptest! {
        #[test]
        fn nms_output_has_no_same_class_overlaps(dets in prop::collection::vec(arb_det(), 0..40), thr in 0.1f32..0.9) {
            let kept = class_aware_nms(dets.clone(), thr, 1000);
            prop_assert!(kept.len() <= dets.len());
            for (i, a) in kept.iter().enumerate() {
                for b in &kept[i + 1..] {
                    prop_assert!(a.class_id != b.class_id || a.bbox.iou(&b.bbox) <= thr);
                }
                prop_assert!(dets.contains(a));
            }
            // The best detection always survives.
            if let Some(best) = dets.iter().max_by(|a, b| a.score.total_cmp(&b.score)) {
                prop_assert_eq!(kept[0].score, best.score);
            }
        }

        #[test]
        fn larger_box_suppression_keeps_the_largest(dets in prop::collection::vec(arb_det(), 1..40), thr in 0.1f32..0.9) {
            let kept = larger_box_priority_suppression(dets.clone(), thr);
            for (i, a) in kept.iter().enumerate() {
                for b in &kept[i + 1..] {
                    prop_assert!(a.bbox.to_bbox().iou(&b.bbox.to_bbox()) <= f64::from(thr));
                }
            }
            let max_area = dets.iter().map(|d| d.bbox.area()).fold(0.0f32, f32::max);
            prop_assert!(kept.iter().any(|d| d.bbox.area() == max_area));
        }
    }
}
