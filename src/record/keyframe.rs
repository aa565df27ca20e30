//! Keyframes: a frame downscaled to `recording.keyframe_width_px` and written as JPEG (in
//! the recorder's thread, off the frame path).

use fast_image_resize::images::Image;
use fast_image_resize::{PixelType, ResizeOptions, Resizer};
use image::codecs::jpeg::JpegEncoder;
use std::io;
use std::path::Path;

/// JPEG quality of keyframes (they are for people, not for the detector).
const QUALITY: u8 = 80;

/// A frame's pixels for a keyframe (packed RGB24).
#[derive(Debug, Clone)]
pub struct KeyframeImage {
    /// Width (px).
    pub width_px: u32,
    /// Height (px).
    pub height_px: u32,
    /// Packed RGB24.
    pub rgb: Vec<u8>,
}

/// Downscales `k` to at most `width_px` wide (keeping the aspect) and writes it as JPEG.
pub fn write(path: &Path, mut k: KeyframeImage, width_px: u32) -> io::Result<()> {
    let expected = u64::from(k.width_px) * u64::from(k.height_px) * 3;
    if k.width_px == 0 || k.height_px == 0 || k.rgb.len() as u64 != expected {
        return Err(io::Error::other("keyframe: pixels do not match the size"));
    }
    let w = width_px.min(k.width_px);
    let h = ((u64::from(k.height_px) * u64::from(w)) / u64::from(k.width_px)).max(1) as u32;
    let src = Image::from_slice_u8(k.width_px, k.height_px, &mut k.rgb, PixelType::U8x3)
        .map_err(io::Error::other)?;
    let mut dst = Image::new(w, h, PixelType::U8x3);
    Resizer::new()
        .resize(&src, &mut dst, &ResizeOptions::new())
        .map_err(io::Error::other)?;
    // `keyframes/` only, never the flight's folder above it: a folder deleted mid-flight is
    // not recreated here (the recorder notices and says so).
    if let Some(parent) = path.parent() {
        match std::fs::create_dir(parent) {
            Err(e) if e.kind() != io::ErrorKind::AlreadyExists => return Err(e),
            _ => {}
        }
    }
    let tmp = path.with_extension("jpg.part");
    {
        let file = std::fs::File::create(&tmp)?;
        let mut out = io::BufWriter::new(file);
        JpegEncoder::new_with_quality(&mut out, QUALITY)
            .encode(dst.buffer(), w, h, image::ExtendedColorType::Rgb8)
            .map_err(io::Error::other)?;
        io::Write::flush(&mut out)?;
    }
    std::fs::rename(&tmp, path)
}
