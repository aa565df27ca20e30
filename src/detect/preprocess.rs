//! Letterboxing a frame (or a region of it) into the model's input tensor.
//!
//! The geometry matches Ultralytics and `train/data.py`: scale to fit keeping
//! the aspect ratio, centre, pad with grey 114, RGB, CHW, values in `[0, 1]`.

use fast_image_resize::images::Image;
use fast_image_resize::{FilterType, PixelType, ResizeAlg, ResizeOptions, Resizer};
use image::RgbImage;

/// Grey level of the letterbox padding (Ultralytics' choice, also used in training).
pub const PAD_VALUE: u8 = 114;

/// A source rectangle in frame pixels (integer, inside the frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// Left edge.
    pub x_px: u32,
    /// Top edge.
    pub y_px: u32,
    /// Width, > 0.
    pub w_px: u32,
    /// Height, > 0.
    pub h_px: u32,
}

impl Region {
    /// The whole of a `width x height` frame.
    pub fn full(width: u32, height: u32) -> Self {
        Self {
            x_px: 0,
            y_px: 0,
            w_px: width,
            h_px: height,
        }
    }
}

/// How a region was mapped into the input: `input = (frame - origin) * scale + pad`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    /// Input pixels per frame pixel.
    pub scale: f32,
    /// Left padding in input pixels.
    pub pad_x_px: f32,
    /// Top padding in input pixels.
    pub pad_y_px: f32,
    /// Left edge of the source region in frame pixels.
    pub origin_x_px: f32,
    /// Top edge of the source region in frame pixels.
    pub origin_y_px: f32,
}

impl Letterbox {
    /// Maps a point from model-input pixels back to frame pixels.
    pub fn to_frame(&self, x_in: f32, y_in: f32) -> (f32, f32) {
        (
            (x_in - self.pad_x_px) / self.scale + self.origin_x_px,
            (y_in - self.pad_y_px) / self.scale + self.origin_y_px,
        )
    }
}

/// Reusable letterboxing buffers (one per detector: no allocation per frame).
pub struct Preprocessor {
    resizer: Resizer,
    /// Scratch image the resized region is written into.
    resized: Vec<u8>,
}

impl Default for Preprocessor {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for Preprocessor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Preprocessor").finish_non_exhaustive()
    }
}

impl Preprocessor {
    /// A preprocessor with empty buffers.
    pub fn new() -> Self {
        Self {
            resizer: Resizer::new(),
            resized: Vec::new(),
        }
    }

    /// Letterboxes `region` of `frame` into `tensor`, a `3 x in_h x in_w` CHW
    /// float buffer (resized here as needed). `region` must lie inside the
    /// frame and be non-empty (callers build it from the frame's size).
    pub fn letterbox(
        &mut self,
        frame: &RgbImage,
        region: Region,
        in_w: u32,
        in_h: u32,
        tensor: &mut Vec<f32>,
    ) -> Letterbox {
        let scale = (in_w as f32 / region.w_px as f32).min(in_h as f32 / region.h_px as f32);
        let new_w = ((region.w_px as f32 * scale).round() as u32).clamp(1, in_w);
        let new_h = ((region.h_px as f32 * scale).round() as u32).clamp(1, in_h);
        let pad_x = (in_w - new_w) / 2;
        let pad_y = (in_h - new_h) / 2;

        let plane = (in_w * in_h) as usize;
        tensor.clear();
        tensor.resize(3 * plane, PAD_VALUE as f32 / 255.0);

        self.resized.clear();
        self.resized.resize((new_w * new_h * 3) as usize, 0);
        let resized_ok =
            match Image::from_slice_u8(new_w, new_h, &mut self.resized, PixelType::U8x3) {
                Ok(mut dst) => {
                    let options = ResizeOptions::new()
                        .resize_alg(ResizeAlg::Convolution(FilterType::Bilinear))
                        .crop(
                            region.x_px as f64,
                            region.y_px as f64,
                            region.w_px as f64,
                            region.h_px as f64,
                        );
                    self.resizer.resize(frame, &mut dst, &options).is_ok()
                }
                Err(_) => false,
            };
        if !resized_ok {
            // Only reachable with an inconsistent region; fall back to padding only.
            tracing::warn!(?region, "letterbox resize failed; input left as padding");
        } else {
            let inv = 1.0 / 255.0;
            for y in 0..new_h as usize {
                let row = &self.resized[y * new_w as usize * 3..(y + 1) * new_w as usize * 3];
                let base = (y + pad_y as usize) * in_w as usize + pad_x as usize;
                for (x, px) in row.chunks_exact(3).enumerate() {
                    tensor[base + x] = px[0] as f32 * inv;
                    tensor[plane + base + x] = px[1] as f32 * inv;
                    tensor[2 * plane + base + x] = px[2] as f32 * inv;
                }
            }
        }
        Letterbox {
            scale,
            pad_x_px: pad_x as f32,
            pad_y_px: pad_y as f32,
            origin_x_px: region.x_px as f32,
            origin_y_px: region.y_px as f32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wide_frame_is_padded_top_and_bottom() {
        let frame = RgbImage::from_pixel(64, 32, image::Rgb([255, 0, 0]));
        let mut pre = Preprocessor::new();
        let mut t = Vec::new();
        let lb = pre.letterbox(&frame, Region::full(64, 32), 32, 32, &mut t);
        assert_eq!(t.len(), 3 * 32 * 32);
        assert_eq!(lb.scale, 0.5);
        assert_eq!((lb.pad_x_px, lb.pad_y_px), (0.0, 8.0));
        let pad = PAD_VALUE as f32 / 255.0;
        assert_eq!(t[0], pad); // row 0 is padding
        assert_eq!(t[16 * 32 + 5], 1.0); // red channel inside the image
        assert_eq!(t[32 * 32 + 16 * 32 + 5], 0.0); // green channel
        assert_eq!(t[31 * 32], pad); // last row is padding
        let (x, y) = lb.to_frame(16.0, 16.0);
        assert_eq!((x, y), (32.0, 16.0));
    }

    #[test]
    fn region_maps_back_to_frame_coordinates() {
        let frame = RgbImage::new(100, 100);
        let mut pre = Preprocessor::new();
        let mut t = Vec::new();
        let region = Region {
            x_px: 40,
            y_px: 20,
            w_px: 50,
            h_px: 50,
        };
        let lb = pre.letterbox(&frame, region, 50, 50, &mut t);
        assert_eq!(lb.to_frame(0.0, 0.0), (40.0, 20.0));
        assert_eq!(lb.to_frame(50.0, 50.0), (90.0, 70.0));
    }
}
