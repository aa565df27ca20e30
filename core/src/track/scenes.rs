//! Scenes shared by the online and offline tests.

use super::appearance::{Appearance, BINS};
use super::bbox::BBox;
use super::types::{Detection, FrameInput};

/// A colour signature wholly in hue bin `bin`.
pub(crate) fn colour(bin: usize) -> Appearance {
    let mut bins = [0.0; BINS];
    bins[bin] = 1.0;
    Appearance { bins }
}

/// Two swimmers (20 px boxes, 640 x 480 px frames at 30 fps) whose colour signatures peak in
/// hue bins `colours` swim towards each other at 3 px a frame, meet at frame 30 (their boxes
/// coincide) and turn back the way they came, over frames 1-70. Returns the frames and, per
/// frame, the centres' x of the first swimmer (detection 0, starting at x 40) and the second
/// (detection 1, starting at x 220). The box filter carries each track on through the
/// meeting, so each id ends on the other swimmer.
pub(crate) fn meet_and_turn_back(colours: (usize, usize)) -> Vec<(FrameInput, (f64, f64))> {
    let (first, second) = (colour(colours.0), colour(colours.1));
    (1..=70u64)
        .map(|i| {
            let d = 3.0 * (30.0 - (i as f64 - 30.0).abs());
            let xs = (40.0 + d, 220.0 - d);
            let det = |x: f64, appearance: Appearance| Detection {
                bbox: BBox::from_center(x, 100.0, 20.0, 20.0),
                score: 0.9,
                class_id: 1,
                world: None,
                appearance: Some(appearance),
            };
            let frame = FrameInput {
                frame_index: i,
                time_s: i as f64 / 30.0,
                image_size_px: (640, 480),
                detections: vec![det(xs.0, first), det(xs.1, second)],
                image_motion: None,
            };
            (frame, xs)
        })
        .collect()
}

/// The id of the box whose centre's x is nearest `x`, if any.
pub(crate) fn nearest_id(boxes: impl Iterator<Item = (u64, BBox)>, x: f64) -> Option<u64> {
    boxes
        .map(|(id, b)| (id, (b.center().0 - x).abs()))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(id, _)| id)
}
