//! Box IoU exactly as TrackEval's `_calculate_box_ious(..., box_format='xywh')`.

use super::{BoxXywh, EPS};

/// Intersection over union of two `(x, y, w, h)` boxes.
///
/// Follows TrackEval's arithmetic step by step (corners are `x + w`, areas are
/// `(x1 - x0) * (y1 - y0)`) so that IoUs land on the same side of the 0.5 and
/// alpha thresholds. A box with area `<= eps`, or a pair whose union is
/// `<= eps`, has IoU 0.
pub fn box_iou(a: &BoxXywh, b: &BoxXywh) -> f64 {
    let (a0, a1, a2, a3) = (a.x, a.y, a.x + a.w, a.y + a.h);
    let (b0, b1, b2, b3) = (b.x, b.y, b.x + b.w, b.y + b.h);
    let iw = (a2.min(b2) - a0.max(b0)).max(0.0);
    let ih = (a3.min(b3) - a1.max(b1)).max(0.0);
    let mut intersection = iw * ih;
    let area_a = (a2 - a0) * (a3 - a1);
    let area_b = (b2 - b0) * (b3 - b1);
    let mut union = area_a + area_b - intersection;
    if area_a <= EPS || area_b <= EPS || union <= EPS {
        intersection = 0.0;
    }
    if union <= EPS {
        union = 1.0;
    }
    intersection / union
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bx(x: f64, y: f64, w: f64, h: f64) -> BoxXywh {
        BoxXywh { x, y, w, h }
    }

    #[test]
    fn identical_boxes_have_iou_one() {
        assert_eq!(
            box_iou(&bx(1.0, 2.0, 3.0, 4.0), &bx(1.0, 2.0, 3.0, 4.0)),
            1.0
        );
    }

    #[test]
    fn half_overlap() {
        // Two 2x1 boxes sharing a 1x1 square: 1 / 3.
        let iou = box_iou(&bx(0.0, 0.0, 2.0, 1.0), &bx(1.0, 0.0, 2.0, 1.0));
        assert!((iou - 1.0 / 3.0).abs() < 1e-15);
    }

    #[test]
    fn disjoint_and_degenerate_boxes_have_iou_zero() {
        assert_eq!(
            box_iou(&bx(0.0, 0.0, 1.0, 1.0), &bx(5.0, 5.0, 1.0, 1.0)),
            0.0
        );
        assert_eq!(
            box_iou(&bx(0.0, 0.0, 0.0, 1.0), &bx(0.0, 0.0, 0.0, 1.0)),
            0.0
        );
        assert_eq!(
            box_iou(&bx(0.0, 0.0, -1.0, 1.0), &bx(0.0, 0.0, 1.0, 1.0)),
            0.0
        );
    }
}
