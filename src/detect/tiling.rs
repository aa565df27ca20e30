//! Overlapping tiles for large frames with tiny objects.
//!
//! A 4K frame letterboxed into an 800x448 input shrinks a 20 px swimmer to
//! 4 px, at the edge of what a small detector resolves. Tiling runs the model on
//! overlapping windows at (close to) native resolution and merges the
//! detections with NMS; an optional extra pass over the whole frame keeps the
//! large objects that no single tile contains.
//!
//! The tiles and the whole-frame pass split the objects between them by size
//! ([`keep_in_merge`]), so that no object is found twice, once per pass, with two classes
//! or two boxes that NMS does not join:
//! - a tile keeps the small objects it sees whole: none within [`TILE_EDGE_MARGIN_PX`] of one
//!   of its edges inside the frame (an object the tile cut in two, which the neighbouring
//!   tile, through the overlap, or the whole-frame pass sees whole), and none the whole-frame
//!   pass sees at [`WHOLE_FRAME_OBJECT_PX`] or more;
//! - the whole-frame pass keeps the objects it sees at [`WHOLE_FRAME_OBJECT_PX`] or more.
//!
//! Measured with `train/evaluate.py` on the tuning seeds (shipped fp32 model, whole 1280x720
//! frames; whole frames alone mAP50 0.731): every box of every pass kept 0.808, the tile edge
//! rule 0.814, the tiles' size rule 0.847; with the whole-frame pass's size rule too, 0.844,
//! and the false swimmers at score 0.25 on the 882 frames fall from 1,663 (every box kept) to
//! 288: most were the whole-frame pass's second box of a swimmer a tile also found.

use serde::{Deserialize, Serialize};

use super::preprocess::Region;
use super::PixelBox;

/// A tile's box within this many frame pixels of one of the tile's edges inside the frame
/// is cut by it ([`keep_in_merge`]).
pub const TILE_EDGE_MARGIN_PX: f32 = 2.0;

/// With the whole-frame pass on, a tile's box whose longer side would be at least this many
/// pixels in the whole-frame pass's model input is left to that pass ([`keep_in_merge`]):
/// 51 frame pixels for a 1280x720 frame in the shipped 800x448 input. Chosen on the tuning
/// seeds (shipped fp32 model, 1280x720, the tiles' rule alone, thresholds in frame pixels:
/// 32 px mAP50 0.837, 48 px 0.848, 64 px 0.845, 96 px 0.825, 192 px 0.820); in this
/// model-input form it is `train/evaluate.py --tile-large-px`.
pub const WHOLE_FRAME_OBJECT_PX: f32 = 32.0;

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
    /// Tile only frames whose model runs (tiles, plus the whole frame) fit in this many
    /// microseconds: at the model run time measured at load for the first frame of a size,
    /// then as the frames themselves run ([`TileGovernor`]) (`tile = "auto"`: the frame
    /// period of `tile_min_fps`); `None` tiles every frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_budget_us: Option<u64>,
}

impl Default for TilingConfig {
    fn default() -> Self {
        Self {
            tile_px: None,
            overlap_px: 64,
            include_full_frame: true,
            frame_budget_us: None,
        }
    }
}

/// Whether a detection `bbox` (frame pixels) from the model run on `region` joins a tiled
/// frame's merge. `whole_frame_scale` is the whole-frame pass's letterbox scale (model input px
/// per frame px) when that pass runs, `None` otherwise. See the module doc for the rules.
pub fn keep_in_merge(
    bbox: &PixelBox,
    region: &Region,
    frame_w: u32,
    frame_h: u32,
    whole_frame_scale: Option<f32>,
) -> bool {
    let large =
        whole_frame_scale.is_some_and(|s| bbox.w_px.max(bbox.h_px) * s >= WHOLE_FRAME_OBJECT_PX);
    if *region == Region::full(frame_w, frame_h) {
        return large || whole_frame_scale.is_none();
    }
    let (x1, y1) = (bbox.x_px, bbox.y_px);
    let (x2, y2) = (x1 + bbox.w_px, y1 + bbox.h_px);
    let (tx1, ty1) = (region.x_px as f32, region.y_px as f32);
    let (tx2, ty2) = (tx1 + region.w_px as f32, ty1 + region.h_px as f32);
    let m = TILE_EDGE_MARGIN_PX;
    let cut = (region.x_px > 0 && x1 <= tx1 + m)
        || (region.y_px > 0 && y1 <= ty1 + m)
        || (region.x_px + region.w_px < frame_w && x2 >= tx2 - m)
        || (region.y_px + region.h_px < frame_h && y2 >= ty2 - m);
    !cut && !large
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

/// Under `tile = "auto"`: whether the frames of one size are tiled, decided at the first
/// frame from the model run time measured at load, then revised in flight from the time
/// each frame's model runs took.
///
/// A start-up measurement can be wrong for the flight: on the two-drone SITL bench
/// (`scripts/bench_sitl_fleet.sh`) one mgmot measured 13.2 ms a run before the machine was
/// fully loaded, tiled its 1280x720 frames (5 runs, 66 ms of a 67 ms budget), and then took
/// 130 ms a frame: 1,070 of 3,871 frames processed, one object tracked of six. The smoothed
/// run time of the frames themselves now stops tiling when a tiled frame's runs would exceed
/// the budget by [`TileGovernor::STOP_ABOVE`], and resumes it when they would fit within
/// [`TileGovernor::RESUME_BELOW`] of it; at least [`TileGovernor::MIN_FRAMES_BETWEEN`]
/// frames apart, so that it does not flap. Pure: the detector feeds it the times.
#[derive(Debug, Clone, PartialEq)]
pub struct TileGovernor {
    budget_us: f64,
    /// Model runs of a tiled frame of this size (tiles, plus the whole frame).
    runs_tiled: usize,
    /// Smoothed time of one model run (µs), with the frame's own preprocessing and decoding.
    run_us: f64,
    on: bool,
    may_resume: bool,
    frames_since_switch: u32,
}

/// A change [`TileGovernor::observe`] made, with the smoothed run time that made it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TileSwitch {
    /// Tiling stopped: a tiled frame's runs would now take `need_us`.
    Stopped {
        /// Smoothed time of one model run (µs).
        run_us: f64,
        /// That times the runs of a tiled frame (µs).
        need_us: f64,
    },
    /// Tiling resumed: a tiled frame's runs would now take `need_us`.
    Resumed {
        /// Smoothed time of one model run (µs).
        run_us: f64,
        /// That times the runs of a tiled frame (µs).
        need_us: f64,
    },
}

impl TileGovernor {
    /// Weight of each frame's run time in the smoothed one (about the last 10 frames).
    pub const SMOOTHING: f64 = 0.1;
    /// Tiling stops when a tiled frame's runs would take this much of the budget.
    pub const STOP_ABOVE: f64 = 1.15;
    /// Tiling resumes when a tiled frame's runs would take at most this much of the budget.
    pub const RESUME_BELOW: f64 = 0.85;
    /// Frames between two changes, at least (2 s at 15 frames/s).
    pub const MIN_FRAMES_BETWEEN: u32 = 30;

    /// The decision at the first frame: tiled when `runs_tiled` runs of `run_us` (measured at
    /// load) fit in `budget_us`. `may_resume: false` keeps an untiled size untiled (the tile
    /// model was not loaded, as tiling was ruled out at load).
    pub fn new(budget_us: u64, runs_tiled: usize, run_us: u64, may_resume: bool) -> Self {
        let need = run_us.saturating_mul(runs_tiled as u64);
        Self {
            budget_us: budget_us as f64,
            runs_tiled: runs_tiled.max(1),
            run_us: run_us as f64,
            on: need <= budget_us,
            may_resume,
            frames_since_switch: 0,
        }
    }

    /// Whether this size's frames are tiled now.
    pub fn tiles(&self) -> bool {
        self.on
    }

    /// The frame budget (µs).
    pub fn budget_us(&self) -> f64 {
        self.budget_us
    }

    /// A tiled frame's runs at the smoothed run time (µs).
    pub fn need_us(&self) -> f64 {
        self.run_us * self.runs_tiled as f64
    }

    /// One frame took `elapsed_us` for `runs` model runs (`runs_tiled` when it was tiled,
    /// 1 when not): the run time is smoothed, and tiling stops or resumes when due.
    pub fn observe(&mut self, runs: usize, elapsed_us: f64) -> Option<TileSwitch> {
        if runs == 0 || !elapsed_us.is_finite() || elapsed_us < 0.0 {
            return None;
        }
        self.run_us += Self::SMOOTHING * (elapsed_us / runs as f64 - self.run_us);
        self.frames_since_switch = self.frames_since_switch.saturating_add(1);
        if self.frames_since_switch < Self::MIN_FRAMES_BETWEEN {
            return None;
        }
        let (run_us, need_us) = (self.run_us, self.need_us());
        if self.on && need_us > self.budget_us * Self::STOP_ABOVE {
            self.on = false;
            self.frames_since_switch = 0;
            return Some(TileSwitch::Stopped { run_us, need_us });
        }
        if !self.on && self.may_resume && need_us <= self.budget_us * Self::RESUME_BELOW {
            self.on = true;
            self.frames_since_switch = 0;
            return Some(TileSwitch::Resumed { run_us, need_us });
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn pbox(x: f32, y: f32, w: f32, h: f32) -> PixelBox {
        PixelBox {
            x_px: x,
            y_px: y,
            w_px: w,
            h_px: h,
        }
    }

    #[test]
    fn the_whole_frame_pass_keeps_the_large_objects_only() {
        let full = Region::full(1280, 720);
        let scale = Some(0.625);
        assert!(keep_in_merge(
            &pbox(10.0, 10.0, 60.0, 20.0),
            &full,
            1280,
            720,
            scale
        ));
        assert!(!keep_in_merge(
            &pbox(10.0, 10.0, 20.0, 20.0),
            &full,
            1280,
            720,
            scale
        ));
        // Without a whole-frame scale (no tiles), the whole frame keeps everything.
        assert!(keep_in_merge(
            &pbox(10.0, 10.0, 20.0, 20.0),
            &full,
            1280,
            720,
            None
        ));
    }

    #[test]
    fn a_tile_keeps_its_small_whole_objects_only() {
        // The top-right tile of a 1280x720 frame: its left and bottom edges lie inside the
        // frame, its top and right edges are the frame's.
        let tile = Region {
            x_px: 480,
            y_px: 0,
            w_px: 800,
            h_px: 448,
        };
        let scale = Some(0.625);
        // Small and inside: kept, also at the frame's own edges.
        assert!(keep_in_merge(
            &pbox(700.0, 200.0, 12.0, 10.0),
            &tile,
            1280,
            720,
            scale
        ));
        assert!(keep_in_merge(
            &pbox(1268.0, 0.0, 12.0, 10.0),
            &tile,
            1280,
            720,
            scale
        ));
        // Cut by the left or bottom edge: left to the neighbour or the whole frame.
        assert!(!keep_in_merge(
            &pbox(480.5, 200.0, 12.0, 10.0),
            &tile,
            1280,
            720,
            scale
        ));
        assert!(!keep_in_merge(
            &pbox(700.0, 437.0, 12.0, 10.0),
            &tile,
            1280,
            720,
            scale
        ));
        // 60 px is 37.5 px in the whole-frame pass's input: left to it...
        assert!(!keep_in_merge(
            &pbox(700.0, 200.0, 60.0, 20.0),
            &tile,
            1280,
            720,
            scale
        ));
        // ...unless that pass does not run.
        assert!(keep_in_merge(
            &pbox(700.0, 200.0, 60.0, 20.0),
            &tile,
            1280,
            720,
            None
        ));
    }

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
    #[test]
    fn the_governor_starts_from_the_load_time_measurement() {
        // 5 runs of 13 ms = 65 ms in a 67 ms budget: tiled; of 14 ms = 70 ms: not.
        assert!(TileGovernor::new(67_000, 5, 13_000, true).tiles());
        assert!(!TileGovernor::new(67_000, 5, 14_000, true).tiles());
    }

    #[test]
    fn the_governor_stops_tiling_when_the_frames_run_slower_and_resumes_when_faster() {
        // The fleet bench's case: 13.2 ms a run at load, 26 ms a run in flight.
        let mut g = TileGovernor::new(67_000, 5, 13_200, true);
        assert!(g.tiles());
        let mut stopped_at = None;
        for k in 1..=200u32 {
            if let Some(sw) = g.observe(5, 130_000.0) {
                assert!(
                    matches!(sw, TileSwitch::Stopped { need_us, .. } if need_us > 67_000.0 * 1.15)
                );
                stopped_at = Some(k);
                break;
            }
        }
        // Not before MIN_FRAMES_BETWEEN frames, and soon after.
        assert_eq!(stopped_at, Some(TileGovernor::MIN_FRAMES_BETWEEN));
        assert!(!g.tiles());
        // Whole frames (1 run) at 26 ms: 5 x 26 = 130 ms, still over; no change.
        for _ in 0..300 {
            assert_eq!(g.observe(1, 26_000.0), None);
        }
        // The machine frees up: 8 ms a run, 40 ms a tiled frame; tiling resumes.
        let resumed = (0..300).find_map(|_| g.observe(1, 8_000.0));
        assert!(
            matches!(resumed, Some(TileSwitch::Resumed { need_us, .. }) if need_us <= 67_000.0 * 0.85)
        );
        assert!(g.tiles());
    }

    #[test]
    fn the_governor_does_not_flap_near_the_budget() {
        // Tiled frames at 95-105 % of the budget, alternating: inside the hysteresis band.
        let mut g = TileGovernor::new(67_000, 5, 13_000, true);
        for k in 0..1000 {
            let frame_us = if k % 2 == 0 { 63_650.0 } else { 70_350.0 };
            assert_eq!(g.observe(5, frame_us), None, "frame {k}");
        }
        assert!(g.tiles());
    }

    #[test]
    fn the_governor_never_resumes_a_size_it_may_not() {
        let mut g = TileGovernor::new(67_000, 5, 20_000, false);
        assert!(!g.tiles());
        for _ in 0..500 {
            assert_eq!(g.observe(1, 1_000.0), None);
        }
        assert!(!g.tiles());
        // And ignores what it cannot use.
        assert_eq!(g.observe(0, 1_000.0), None);
        assert_eq!(g.observe(1, f64::NAN), None);
    }
}
