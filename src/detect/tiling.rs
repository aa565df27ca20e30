//! Overlapping tiles for large frames with tiny objects.
//!
//! A 4K frame letterboxed into an 800x448 input shrinks a 20 px swimmer to
//! 4 px, at the edge of what a small detector resolves. Tiling runs the model on
//! overlapping windows at (close to) native resolution and merges the
//! detections with NMS; an optional extra pass over the whole frame keeps the
//! large objects that no single tile contains.

use serde::{Deserialize, Serialize};

use super::preprocess::Region;

/// Tiling settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct TilingConfig {
    /// Side of a square tile in frame pixels; `None` uses tiles of the
    /// model's input size (width x height), i.e. native resolution with no
    /// letterbox padding.
    pub tile_px: Option<u32>,
    /// Overlap between neighbouring tiles in frame pixels; at least the size
    /// of the largest object that must not be cut in two.
    pub overlap_px: u32,
    /// Also run the whole frame letterboxed (for objects larger than a tile).
    pub include_full_frame: bool,
}

impl Default for TilingConfig {
    fn default() -> Self {
        Self {
            tile_px: None,
            overlap_px: 64,
            include_full_frame: true,
        }
    }
}

/// Start offsets of tiles of length `tile` covering `0..len` with at least
/// `overlap` between neighbours; the last tile ends exactly at `len`.
fn starts(len: u32, tile: u32, overlap: u32) -> Vec<u32> {
    if len <= tile {
        return vec![0];
    }
    let step = tile.saturating_sub(overlap).max(1);
    let span = len - tile;
    let n = span.div_ceil(step) + 1;
    // Spread the tiles evenly so every overlap is >= `overlap`.
    (0..n)
        .map(|i| ((i as u64 * span as u64) / (n as u64 - 1)) as u32)
        .collect()
}

/// Tiles covering a `width x height` frame. Every tile lies inside the frame,
/// is `tile_w x tile_h` (clipped to the frame where the frame is smaller), and
/// neighbours overlap by at least `overlap` pixels (at most a tile side - 1).
pub fn tile_grid(width: u32, height: u32, tile_w: u32, tile_h: u32, overlap: u32) -> Vec<Region> {
    let (tile_w, tile_h) = (tile_w.max(1), tile_h.max(1));
    let xs = starts(width, tile_w, overlap.min(tile_w - 1));
    let ys = starts(height, tile_h, overlap.min(tile_h - 1));
    let mut out = Vec::with_capacity(xs.len() * ys.len());
    for &y in &ys {
        for &x in &xs {
            out.push(Region {
                x_px: x,
                y_px: y,
                w_px: tile_w.min(width),
                h_px: tile_h.min(height),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn small_frame_is_one_tile() {
        assert_eq!(
            tile_grid(200, 100, 320, 320, 64),
            vec![Region::full(200, 100)]
        );
    }

    #[test]
    fn hd_frame_in_tiles_of_the_shipped_model_input() {
        // 1280: span 480 / step 736 -> 2 columns; 720: span 272 / step 384 -> 2 rows.
        let g = tile_grid(1280, 720, 800, 448, 64);
        let starts: Vec<_> = g.iter().map(|r| (r.x_px, r.y_px)).collect();
        assert_eq!(starts, vec![(0, 0), (480, 0), (0, 272), (480, 272)]);
        assert!(g.iter().all(|r| (r.w_px, r.h_px) == (800, 448)));
    }

    #[test]
    fn uhd_frame_grid() {
        let g = tile_grid(3840, 2160, 640, 640, 64);
        // 3840: span 3200 / step 576 -> 6 steps -> 7 columns; 2160: 1520/576 -> 3 -> 4 rows.
        assert_eq!(g.len(), 7 * 4);
        assert_eq!(
            g.last().map(|r| (r.x_px + r.w_px, r.y_px + r.h_px)),
            Some((3840, 2160))
        );
    }

    proptest! {
        #[test]
        fn tiles_cover_the_frame_and_overlap(w in 1u32..5000, h in 1u32..3000, tile_w in 64u32..1024, tile_h in 64u32..1024, overlap in 0u32..256) {
            let g = tile_grid(w, h, tile_w, tile_h, overlap);
            for r in &g {
                prop_assert!(r.x_px + r.w_px <= w && r.y_px + r.h_px <= h);
                prop_assert!(r.w_px > 0 && r.h_px > 0);
            }
            for (len, tile, mut spans) in [
                (w, tile_w, g.iter().map(|r| (r.x_px, r.w_px)).collect::<Vec<_>>()),
                (h, tile_h, g.iter().map(|r| (r.y_px, r.h_px)).collect()),
            ] {
                let eff_overlap = overlap.min(tile - 1);
                spans.sort();
                spans.dedup();
                prop_assert_eq!(spans[0].0, 0);
                prop_assert_eq!(spans.last().map(|s| s.0 + s.1), Some(len));
                for pair in spans.windows(2) {
                    let (a, b) = (pair[0], pair[1]);
                    prop_assert!(a.0 + a.1 >= b.0 + eff_overlap, "{:?} then {:?}", a, b);
                }
            }
        }
    }
}
