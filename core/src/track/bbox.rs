//! Axis-aligned image boxes and their overlap.

use serde::{Deserialize, Serialize};

/// An axis-aligned box in image pixels, top-left origin: `(x, y)` is the top-left corner,
/// so the centre is `(x + w/2, y + h/2)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BBox {
    /// Left edge, px.
    pub x: f64,
    /// Top edge, px.
    pub y: f64,
    /// Width, px (non-negative for a meaningful box).
    pub w: f64,
    /// Height, px (non-negative for a meaningful box).
    pub h: f64,
}

impl BBox {
    /// A box from its top-left corner and size.
    pub const fn new(x: f64, y: f64, w: f64, h: f64) -> Self {
        Self { x, y, w, h }
    }

    /// A box from its centre and size.
    pub fn from_center(cx: f64, cy: f64, w: f64, h: f64) -> Self {
        Self {
            x: cx - w / 2.0,
            y: cy - h / 2.0,
            w,
            h,
        }
    }

    /// Centre of the box, px.
    pub fn center(&self) -> (f64, f64) {
        (self.x + self.w / 2.0, self.y + self.h / 2.0)
    }

    /// Area in px^2 (0 for degenerate or negative sizes).
    pub fn area(&self) -> f64 {
        self.w.max(0.0) * self.h.max(0.0)
    }

    /// Whether all four numbers are finite and the size is positive: boxes that fail this are
    /// dropped by the tracker instead of poisoning the Kalman filter.
    pub fn is_valid(&self) -> bool {
        self.x.is_finite()
            && self.y.is_finite()
            && self.w.is_finite()
            && self.h.is_finite()
            && self.w > 0.0
            && self.h > 0.0
    }

    /// Intersection over union in [0, 1]; 0 when either box is empty.
    pub fn iou(&self, other: &BBox) -> f64 {
        let ix = (self.x + self.w).min(other.x + other.w) - self.x.max(other.x);
        let iy = (self.y + self.h).min(other.y + other.h) - self.y.max(other.y);
        if ix <= 0.0 || iy <= 0.0 {
            return 0.0;
        }
        let inter = ix * iy;
        let union = self.area() + other.area() - inter;
        if union <= 0.0 {
            0.0
        } else {
            inter / union
        }
    }

    /// Linear interpolation between two boxes, `s` = 0 gives `self`, 1 gives `other`.
    pub fn lerp(&self, other: &BBox, s: f64) -> BBox {
        BBox {
            x: self.x + (other.x - self.x) * s,
            y: self.y + (other.y - self.y) * s,
            w: self.w + (other.w - self.w) * s,
            h: self.h + (other.h - self.h) * s,
        }
    }

    /// Whether the box reaches within `margin_fraction` of the image width (left/right) or
    /// height (top/bottom) of the border, or beyond it: a track whose last box does this is
    /// taken to have left the view (long-term ReID) rather than to have been lost inside it
    /// (short-term ReID).
    pub fn touches_border(&self, image_size_px: (u32, u32), margin_fraction: f64) -> bool {
        let (iw, ih) = (f64::from(image_size_px.0), f64::from(image_size_px.1));
        let (mx, my) = (iw * margin_fraction, ih * margin_fraction);
        self.x <= mx || self.y <= my || self.x + self.w >= iw - mx || self.y + self.h >= ih - my
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn iou_of_identical_boxes_is_one() {
        let a = BBox::new(10.0, 20.0, 30.0, 40.0);
        assert_relative_eq!(a.iou(&a), 1.0);
    }

    #[test]
    fn iou_of_half_overlap() {
        let a = BBox::new(0.0, 0.0, 10.0, 10.0);
        let b = BBox::new(5.0, 0.0, 10.0, 10.0);
        // intersection 50, union 150
        assert_relative_eq!(a.iou(&b), 1.0 / 3.0);
        assert_relative_eq!(b.iou(&a), 1.0 / 3.0);
    }

    #[test]
    fn disjoint_and_degenerate_boxes_have_zero_iou() {
        let a = BBox::new(0.0, 0.0, 10.0, 10.0);
        assert_eq!(a.iou(&BBox::new(20.0, 0.0, 5.0, 5.0)), 0.0);
        assert_eq!(a.iou(&BBox::new(2.0, 2.0, 0.0, 0.0)), 0.0);
        assert!(!BBox::new(2.0, 2.0, 0.0, 1.0).is_valid());
        assert!(!BBox::new(f64::NAN, 2.0, 1.0, 1.0).is_valid());
    }

    #[test]
    fn border_test_uses_margin() {
        let img = (100, 50);
        // margins: 2 px left/right, 1 px top/bottom
        assert!(BBox::new(1.0, 10.0, 5.0, 5.0).touches_border(img, 0.02));
        assert!(!BBox::new(3.0, 10.0, 5.0, 5.0).touches_border(img, 0.02));
        assert!(BBox::new(90.0, 10.0, 9.0, 5.0).touches_border(img, 0.02));
        assert!(BBox::new(40.0, 44.0, 5.0, 5.0).touches_border(img, 0.02));
        assert!(!BBox::new(40.0, 43.0, 5.0, 5.0).touches_border(img, 0.02));
    }
}
