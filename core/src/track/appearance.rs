//! Appearance signature of a detection: the colours an object shows against the sea, from
//! the pixels of its box. Cheap (a few microseconds per box, sampled on at most a 32 x 32
//! grid) and meant for long-gap ReID, where position alone cannot tell apart neighbours
//! that come back after a minute: a swimmer in an orange life jacket is not the one in the
//! green jacket beside it.
//!
//! The box's background is the median colour of a ring of pixels around it (the sea); the
//! pixels inside the box that differ from it by more than [`FOREGROUND_L1`] are the
//! object's. Each of those votes into a hue histogram ([`HUE_BINS`] bins, soft-assigned
//! between neighbouring bins) when it is saturated and bright enough, otherwise into one of
//! two achromatic bins (dark: hair, wet suits, shadowed hulls; light: white hulls, foam).
//! Signatures are compared with the Hellinger distance (0 same, 1 disjoint).

use serde::{Deserialize, Serialize};

use super::bbox::BBox;

/// Hue bins of the chromatic part.
pub const HUE_BINS: usize = 16;
/// Bins of a signature: hues, then dark, then light.
pub const BINS: usize = HUE_BINS + 2;
/// A pixel belongs to the object when its colour differs from the background's by more than
/// this (sum of the absolute channel differences, 0-765).
pub const FOREGROUND_L1: i32 = 60;
/// Pixels darker than this value (HSV V, 0-1) are "dark".
const DARK_V: f32 = 0.25;
/// Pixels less saturated than this (HSV S, 0-1) are "light" (or dark, if dark).
const GREY_S: f32 = 0.3;
/// Largest sampling grid per axis; bigger boxes are subsampled.
const MAX_SAMPLES: usize = 32;
/// Fewest object pixels for a signature.
const MIN_PIXELS: f32 = 2.0;

/// A normalised colour histogram of an object's pixels (the bins sum to 1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Appearance {
    /// [`HUE_BINS`] hue bins (0 deg red upwards), then dark, then light.
    pub bins: [f32; BINS],
}

/// An RGB24 image (or a window of one) to take signatures from.
#[derive(Debug, Clone, Copy)]
pub struct RgbImage<'a> {
    /// Pixels, row-major, 3 bytes each.
    pub rgb: &'a [u8],
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
}

impl RgbImage<'_> {
    fn pixel(&self, x: usize, y: usize) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y * self.width + x) * 3;
        let p = self.rgb.get(i..i + 3)?;
        Some([p[0], p[1], p[2]])
    }
}

impl Appearance {
    /// The signature of the object in `bbox` (pixels of `image`), or `None` when the box is
    /// outside the image, has no background ring, or fewer than two of its pixels differ
    /// from the background (an object too small or too close to the sea's colour to say).
    pub fn from_box(image: &RgbImage<'_>, bbox: &BBox) -> Option<Self> {
        if image.rgb.len() < image.width * image.height * 3 || !bbox_is_usable(bbox) {
            return None;
        }
        let (w_img, h_img) = (image.width as f64, image.height as f64);
        let x0 = bbox.x.max(0.0).floor();
        let y0 = bbox.y.max(0.0).floor();
        let x1 = (bbox.x + bbox.w).min(w_img).ceil();
        let y1 = (bbox.y + bbox.h).min(h_img).ceil();
        if x1 - x0 < 1.0 || y1 - y0 < 1.0 {
            return None;
        }
        let (x0, y0, x1, y1) = (x0 as usize, y0 as usize, x1 as usize, y1 as usize);
        let background = background(image, x0, y0, x1, y1)?;
        let step_x = (x1 - x0).div_ceil(MAX_SAMPLES).max(1);
        let step_y = (y1 - y0).div_ceil(MAX_SAMPLES).max(1);
        let mut bins = [0f32; BINS];
        let mut total = 0f32;
        for y in (y0..y1).step_by(step_y) {
            for x in (x0..x1).step_by(step_x) {
                let Some(p) = image.pixel(x, y) else { continue };
                let diff: i32 = p
                    .iter()
                    .zip(background)
                    .map(|(&a, b)| (i32::from(a) - i32::from(b)).abs())
                    .sum();
                if diff <= FOREGROUND_L1 {
                    continue;
                }
                vote(&mut bins, p);
                total += 1.0;
            }
        }
        if total < MIN_PIXELS {
            return None;
        }
        for b in &mut bins {
            *b /= total;
        }
        Some(Self { bins })
    }

    /// Hellinger distance to `other`, in [0, 1].
    pub fn distance(&self, other: &Self) -> f64 {
        let (mut bc, mut sa, mut sb) = (0.0, 0.0, 0.0);
        for (&a, &b) in self.bins.iter().zip(&other.bins) {
            let (a, b) = (f64::from(a.max(0.0)), f64::from(b.max(0.0)));
            bc += (a * b).sqrt();
            sa += a;
            sb += b;
        }
        if sa <= 0.0 || sb <= 0.0 {
            return 1.0;
        }
        // Normalised so that rounding in the bins cannot make a signature far from itself.
        (1.0 - bc / (sa * sb).sqrt()).max(0.0).sqrt()
    }

    /// The signature as hex, one byte per bin (the bin times 255, rounded): the extra column
    /// of `mgmot-sim detections --appearance` and `mgmot detect` MOT files.
    pub fn to_hex(&self) -> String {
        let mut s = String::with_capacity(2 * BINS);
        for b in self.bins {
            let q = (b.clamp(0.0, 1.0) * 255.0).round() as u8;
            s.push_str(&format!("{q:02x}"));
        }
        s
    }

    /// Parses [`Appearance::to_hex`]'s text (renormalised); `None` unless it is exactly
    /// `2 * BINS` hex digits with a non-zero sum.
    pub fn from_hex(s: &str) -> Option<Self> {
        let s = s.trim();
        if s.len() != 2 * BINS || !s.is_ascii() {
            return None;
        }
        let mut bins = [0f32; BINS];
        for (i, b) in bins.iter_mut().enumerate() {
            *b = f32::from(u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok()?);
        }
        let sum: f32 = bins.iter().sum();
        if sum <= 0.0 {
            return None;
        }
        for b in &mut bins {
            *b /= sum;
        }
        Some(Self { bins })
    }
}

/// Running mean of the signatures of a track's detections.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AppearanceMean {
    sum: [f64; BINS],
    count: u32,
}

impl AppearanceMean {
    /// Adds one detection's signature.
    pub fn add(&mut self, a: &Appearance) {
        for (s, &b) in self.sum.iter_mut().zip(&a.bins) {
            *s += f64::from(b);
        }
        self.count = self.count.saturating_add(1);
    }

    /// How many signatures were added.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// The mean signature, once at least `min_count` (and one) were added.
    pub fn mean(&self, min_count: u32) -> Option<Appearance> {
        if self.count == 0 || self.count < min_count {
            return None;
        }
        let n = f64::from(self.count);
        let mut bins = [0f32; BINS];
        for (b, &s) in bins.iter_mut().zip(&self.sum) {
            *b = (s / n) as f32;
        }
        Some(Appearance { bins })
    }
}

fn bbox_is_usable(b: &BBox) -> bool {
    [b.x, b.y, b.w, b.h].iter().all(|v| v.is_finite()) && b.w > 0.0 && b.h > 0.0
}

/// Median colour of the one-pixel ring just outside `[x0, x1) x [y0, y1)` (the pixels inside
/// the image), or of the box's own outermost ring when the box fills the image.
fn background(image: &RgbImage<'_>, x0: usize, y0: usize, x1: usize, y1: usize) -> Option<[u8; 3]> {
    let mut ring: Vec<[u8; 3]> = Vec::with_capacity(2 * (x1 - x0 + y1 - y0) + 4);
    let (rx0, ry0) = (x0.checked_sub(1), y0.checked_sub(1));
    let (rx1, ry1) = (x1, y1);
    let xs = rx0.unwrap_or(x0)..=rx1.min(image.width.saturating_sub(1));
    for x in xs.clone() {
        if let Some(y) = ry0 {
            ring.extend(image.pixel(x, y));
        }
        ring.extend(image.pixel(x, ry1));
    }
    for y in y0..y1 {
        if let Some(x) = rx0 {
            ring.extend(image.pixel(x, y));
        }
        ring.extend(image.pixel(rx1, y));
    }
    if ring.len() < 4 {
        // No ring outside: the box's own border.
        ring.clear();
        for x in x0..x1 {
            ring.extend(image.pixel(x, y0));
            ring.extend(image.pixel(x, y1.saturating_sub(1)));
        }
        for y in y0..y1 {
            ring.extend(image.pixel(x0, y));
            ring.extend(image.pixel(x1.saturating_sub(1), y));
        }
    }
    if ring.is_empty() {
        return None;
    }
    let mut out = [0u8; 3];
    let mid = ring.len() / 2;
    for (c, o) in out.iter_mut().enumerate() {
        let mut ch: Vec<u8> = ring.iter().map(|p| p[c]).collect();
        let (_, m, _) = ch.select_nth_unstable(mid);
        *o = *m;
    }
    Some(out)
}

/// Adds one object pixel to the histogram.
fn vote(bins: &mut [f32; BINS], p: [u8; 3]) {
    let [r, g, b] = p.map(|c| f32::from(c) / 255.0);
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let s = if max > 0.0 { (max - min) / max } else { 0.0 };
    if max < DARK_V {
        bins[HUE_BINS] += 1.0;
        return;
    }
    if s < GREY_S {
        bins[HUE_BINS + 1] += 1.0;
        return;
    }
    let d = max - min;
    let hue6 = if max == r {
        ((g - b) / d).rem_euclid(6.0)
    } else if max == g {
        (b - r) / d + 2.0
    } else {
        (r - g) / d + 4.0
    };
    // Soft assignment between the two nearest bin centres (bin k centred on k + 0.5).
    let pos = hue6 / 6.0 * HUE_BINS as f32 - 0.5;
    let lo = pos.floor();
    let frac = pos - lo;
    let lo_bin = (lo as i32).rem_euclid(HUE_BINS as i32) as usize;
    let hi_bin = (lo_bin + 1) % HUE_BINS;
    bins[lo_bin] += 1.0 - frac;
    bins[hi_bin] += frac;
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const SEA: [u8; 3] = [20, 60, 80];

    /// A 20 x 20 sea image with a `size` px square of `colour` at (8, 8).
    fn image_with(colour: [u8; 3], size: usize) -> Vec<u8> {
        let mut rgb = Vec::with_capacity(20 * 20 * 3);
        for y in 0..20 {
            for x in 0..20 {
                let inside = (8..8 + size).contains(&x) && (8..8 + size).contains(&y);
                rgb.extend_from_slice(if inside { &colour } else { &SEA });
            }
        }
        rgb
    }

    fn signature(colour: [u8; 3], size: usize) -> Option<Appearance> {
        let rgb = image_with(colour, size);
        let img = RgbImage {
            rgb: &rgb,
            width: 20,
            height: 20,
        };
        Appearance::from_box(
            &img,
            &BBox::new(6.0, 6.0, size as f64 + 4.0, size as f64 + 4.0),
        )
    }

    #[test]
    fn the_same_jacket_is_close_and_different_ones_are_far() {
        let orange = signature([255, 110, 0], 4).unwrap();
        let orange_big = signature([255, 110, 0], 8).unwrap();
        let green = signature([170, 230, 40], 4).unwrap();
        let pink = signature([240, 60, 120], 4).unwrap();
        assert!(orange.distance(&orange_big) < 1e-3);
        assert!(orange.distance(&green) > 0.9, "{}", orange.distance(&green));
        assert!(orange.distance(&pink) > 0.9);
        let sum: f32 = orange.bins.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5);
    }

    #[test]
    fn dark_and_white_objects_go_to_the_achromatic_bins() {
        let dark = signature([30, 25, 20], 4).unwrap();
        assert!((dark.bins[HUE_BINS] - 1.0).abs() < 1e-6);
        let white = signature([240, 240, 235], 4).unwrap();
        assert!((white.bins[HUE_BINS + 1] - 1.0).abs() < 1e-6);
        assert!(dark.distance(&white) > 0.99);
    }

    #[test]
    fn the_sea_alone_has_no_signature() {
        assert_eq!(signature(SEA, 4), None);
        // A single object pixel is too few.
        assert_eq!(signature([255, 110, 0], 1), None);
    }

    #[test]
    fn boxes_outside_the_image_or_degenerate_have_none() {
        let rgb = image_with([255, 110, 0], 4);
        let img = RgbImage {
            rgb: &rgb,
            width: 20,
            height: 20,
        };
        assert_eq!(
            Appearance::from_box(&img, &BBox::new(30.0, 30.0, 4.0, 4.0)),
            None
        );
        assert_eq!(
            Appearance::from_box(&img, &BBox::new(5.0, 5.0, 0.0, 4.0)),
            None
        );
        assert_eq!(
            Appearance::from_box(&img, &BBox::new(f64::NAN, 5.0, 4.0, 4.0)),
            None
        );
        let short = RgbImage {
            rgb: &rgb[..30],
            width: 20,
            height: 20,
        };
        assert_eq!(
            Appearance::from_box(&short, &BBox::new(6.0, 6.0, 8.0, 8.0)),
            None
        );
        // A box covering the whole image takes its own border as the background.
        assert!(Appearance::from_box(&img, &BBox::new(0.0, 0.0, 20.0, 20.0)).is_some());
    }

    #[test]
    fn the_mean_needs_its_minimum_count() {
        let a = signature([255, 110, 0], 4).unwrap();
        let b = signature([170, 230, 40], 4).unwrap();
        let mut m = AppearanceMean::default();
        assert_eq!(m.mean(1), None);
        m.add(&a);
        assert_eq!(m.mean(2), None);
        m.add(&b);
        let mean = m.mean(2).unwrap();
        assert_eq!(m.count(), 2);
        let sum: f32 = mean.bins.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5);
        assert!(mean.distance(&a) < a.distance(&b));
    }

    #[test]
    fn hex_round_trip_and_rejects() {
        let a = signature([255, 110, 0], 4).unwrap();
        let back = Appearance::from_hex(&a.to_hex()).unwrap();
        assert!(a.distance(&back) < 0.02);
        assert_eq!(Appearance::from_hex(""), None);
        assert_eq!(Appearance::from_hex(&"0".repeat(2 * BINS)), None);
        assert_eq!(Appearance::from_hex(&"zz".repeat(BINS)), None);
        assert_eq!(Appearance::from_hex(&"é".repeat(BINS)), None);
    }

    proptest! {
        #[test]
        fn distance_is_a_bounded_symmetric_measure(
            c1 in proptest::array::uniform3(0u8..=255),
            c2 in proptest::array::uniform3(0u8..=255),
            size in 2usize..10,
        ) {
            if let (Some(a), Some(b)) = (signature(c1, size), signature(c2, size)) {
                let d = a.distance(&b);
                prop_assert!((0.0..=1.0).contains(&d));
                prop_assert!((d - b.distance(&a)).abs() < 1e-9);
                prop_assert!(a.distance(&a) < 1e-3);
            }
        }

        #[test]
        fn any_box_on_any_image_is_safe(
            rgb in proptest::collection::vec(0u8..=255, 0..300),
            w in 0usize..12, h in 0usize..12,
            x in -5.0f64..15.0, y in -5.0f64..15.0, bw in -1.0f64..15.0, bh in -1.0f64..15.0,
        ) {
            let img = RgbImage { rgb: &rgb, width: w, height: h };
            if let Some(a) = Appearance::from_box(&img, &BBox::new(x, y, bw, bh)) {
                let sum: f32 = a.bins.iter().sum();
                prop_assert!((sum - 1.0).abs() < 1e-4);
            }
        }
    }
}
