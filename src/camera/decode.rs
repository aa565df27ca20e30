//! Camera pixel formats decoded to packed RGB24: MJPG with `zune-jpeg`, YUYV and NV12 with
//! `yuvutils-rs` (SIMD converters; BT.601 limited range unless the driver says otherwise).
//!
//! Every size is checked before a converter sees the buffer: a short or inconsistent buffer is
//! a [`DecodeError`], never a panic.

use std::fmt;
use std::str::FromStr;
use yuvutils_rs::{YuvBiPlanarImage, YuvConversionMode, YuvPackedImage};
use zune_core::bytestream::ZCursor;
use zune_core::colorspace::ColorSpace;
use zune_core::options::DecoderOptions;
use zune_jpeg::JpegDecoder;

/// Largest frame side accepted (px): 8K, as for the simulator's stream.
const MAX_SIDE_PX: u32 = 7680;

/// A capture pixel format this runtime decodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PixelFormat {
    /// Motion JPEG: every buffer is a JPEG image (USB webcams at high resolution).
    Mjpg,
    /// Packed YUV 4:2:2, `Y0 U Y1 V` per pixel pair.
    Yuyv,
    /// Planar Y then interleaved `U V` at half resolution both ways (YUV 4:2:0).
    Nv12,
}

impl PixelFormat {
    /// Every supported format.
    pub const ALL: [PixelFormat; 3] = [PixelFormat::Mjpg, PixelFormat::Yuyv, PixelFormat::Nv12];

    /// The V4L2 FourCC.
    pub fn fourcc(self) -> [u8; 4] {
        match self {
            PixelFormat::Mjpg => *b"MJPG",
            PixelFormat::Yuyv => *b"YUYV",
            PixelFormat::Nv12 => *b"NV12",
        }
    }

    /// The format of a V4L2 FourCC, if supported.
    pub fn from_fourcc(fourcc: [u8; 4]) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.fourcc() == fourcc)
    }
}

impl fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PixelFormat::Mjpg => "MJPG",
            PixelFormat::Yuyv => "YUYV",
            PixelFormat::Nv12 => "NV12",
        })
    }
}

impl FromStr for PixelFormat {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let b = s.as_bytes();
        b.try_into()
            .ok()
            .and_then(Self::from_fourcc)
            .ok_or_else(|| format!("`{s}` is not one of MJPG, YUYV, NV12"))
    }
}

/// The YCbCr matrix of a YUV format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum YuvMatrix {
    /// ITU-R BT.601 (SDTV; V4L2's default for YUV at webcam resolutions).
    #[default]
    Bt601,
    /// ITU-R BT.709 (HDTV).
    Bt709,
}

/// The quantization range of a YUV format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum YuvRange {
    /// Y in 16..=235, Cb/Cr in 16..=240 (V4L2's default for YUV).
    #[default]
    Limited,
    /// Y, Cb, Cr in 0..=255 (JPEG-style).
    Full,
}

/// How the bytes of one buffer are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameLayout {
    /// Pixel format.
    pub format: PixelFormat,
    /// Width (px).
    pub width_px: u32,
    /// Height (px).
    pub height_px: u32,
    /// Bytes per row of the first plane (V4L2 `bytesperline`; rows may be padded). For NV12
    /// the chroma plane has the same stride and starts right after `stride * height` bytes.
    /// Ignored for MJPG.
    pub stride_bytes: u32,
    /// YCbCr matrix (YUYV, NV12).
    pub matrix: YuvMatrix,
    /// Quantization range (YUYV, NV12).
    pub range: YuvRange,
}

impl FrameLayout {
    /// A layout with unpadded rows, BT.601 limited range.
    pub fn packed(format: PixelFormat, width_px: u32, height_px: u32) -> Self {
        let stride_bytes = match format {
            PixelFormat::Mjpg => 0,
            PixelFormat::Yuyv => width_px.saturating_mul(2),
            PixelFormat::Nv12 => width_px,
        };
        Self {
            format,
            width_px,
            height_px,
            stride_bytes,
            matrix: YuvMatrix::Bt601,
            range: YuvRange::Limited,
        }
    }
}

/// Why a buffer could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// A size the format cannot have (zero, too large, odd width for YUYV, stride too short).
    #[error("{format} {width_px}x{height_px}: {problem}")]
    Size {
        /// Pixel format.
        format: PixelFormat,
        /// Width (px).
        width_px: u32,
        /// Height (px).
        height_px: u32,
        /// What is wrong.
        problem: String,
    },
    /// The buffer is shorter than the layout needs.
    #[error("{format} {width_px}x{height_px}: buffer of {got} bytes, need {need}")]
    Truncated {
        /// Pixel format.
        format: PixelFormat,
        /// Width (px).
        width_px: u32,
        /// Height (px).
        height_px: u32,
        /// Bytes given.
        got: usize,
        /// Bytes needed.
        need: usize,
    },
    /// The JPEG decoder refused the data.
    #[error("MJPG: {0}")]
    Jpeg(String),
    /// The JPEG is a different size than the device announced.
    #[error("MJPG: image is {got_w}x{got_h}, the device announced {width_px}x{height_px}")]
    JpegSize {
        /// Announced width (px).
        width_px: u32,
        /// Announced height (px).
        height_px: u32,
        /// Decoded width (px).
        got_w: u32,
        /// Decoded height (px).
        got_h: u32,
    },
    /// The YUV converter refused the data (after our own size checks; not expected).
    #[error("{format}: {problem}")]
    Yuv {
        /// Pixel format.
        format: PixelFormat,
        /// The converter's message.
        problem: String,
    },
}

/// Decodes one buffer into `rgb` (resized to `width * height * 3`, rows not padded).
pub fn decode_to_rgb(
    layout: &FrameLayout,
    data: &[u8],
    rgb: &mut Vec<u8>,
) -> Result<(), DecodeError> {
    let (w, h) = (layout.width_px, layout.height_px);
    let size_err = |problem: String| DecodeError::Size {
        format: layout.format,
        width_px: w,
        height_px: h,
        problem,
    };
    if w == 0 || h == 0 || w > MAX_SIDE_PX || h > MAX_SIDE_PX {
        return Err(size_err(format!(
            "width and height must be within 1..={MAX_SIDE_PX}"
        )));
    }
    let (w_us, h_us) = (w as usize, h as usize);
    let truncated = |need: usize| DecodeError::Truncated {
        format: layout.format,
        width_px: w,
        height_px: h,
        got: data.len(),
        need,
    };
    rgb.resize(w_us * h_us * 3, 0);
    let stride = layout.stride_bytes as usize;
    match layout.format {
        PixelFormat::Mjpg => decode_jpeg(data, w, h, rgb),
        PixelFormat::Yuyv => {
            if w % 2 != 0 {
                return Err(size_err("YUYV needs an even width".into()));
            }
            let row = w_us * 2;
            if stride < row {
                return Err(size_err(format!("stride {stride} < 2 * width")));
            }
            let need = stride * (h_us - 1) + row;
            if data.len() < need {
                return Err(truncated(need));
            }
            let (range, matrix) = yuv_params(layout);
            let yuv_err = |e: yuvutils_rs::YuvError| DecodeError::Yuv {
                format: layout.format,
                problem: e.to_string(),
            };
            if stride == row {
                let img = YuvPackedImage {
                    yuy: &data[..row * h_us],
                    yuy_stride: w * 2,
                    width: w,
                    height: h,
                };
                yuvutils_rs::yuyv422_to_rgb(&img, rgb, w * 3, range, matrix).map_err(yuv_err)
            } else {
                // The converter wants unpadded rows: convert padded ones one by one.
                for (y, out) in rgb.chunks_exact_mut(w_us * 3).enumerate() {
                    let img = YuvPackedImage {
                        yuy: &data[y * stride..y * stride + row],
                        yuy_stride: w * 2,
                        width: w,
                        height: 1,
                    };
                    yuvutils_rs::yuyv422_to_rgb(&img, out, w * 3, range, matrix)
                        .map_err(yuv_err)?;
                }
                Ok(())
            }
        }
        PixelFormat::Nv12 => {
            if stride < w_us {
                return Err(size_err(format!("stride {stride} < width")));
            }
            let chroma_rows = h_us.div_ceil(2);
            let chroma_row = w_us.div_ceil(2) * 2;
            if stride < chroma_row {
                return Err(size_err(format!(
                    "stride {stride} < chroma row of {chroma_row} bytes"
                )));
            }
            let y_len = stride * h_us;
            let need = y_len + stride * (chroma_rows - 1) + chroma_row;
            if data.len() < need {
                return Err(truncated(need));
            }
            let (range, matrix) = yuv_params(layout);
            // The converter takes a padded luma plane but wants the chroma rows unpadded.
            let uv_padded = &data[y_len..need];
            let uv_compact: Vec<u8>;
            let uv_plane = if stride == chroma_row {
                uv_padded
            } else {
                uv_compact = (0..chroma_rows)
                    .flat_map(|r| &uv_padded[r * stride..r * stride + chroma_row])
                    .copied()
                    .collect();
                &uv_compact
            };
            let img = YuvBiPlanarImage {
                y_plane: &data[..y_len],
                y_stride: layout.stride_bytes,
                uv_plane,
                uv_stride: chroma_row as u32,
                width: w,
                height: h,
            };
            yuvutils_rs::yuv_nv12_to_rgb(
                &img,
                rgb,
                w * 3,
                range,
                matrix,
                YuvConversionMode::Balanced,
            )
            .map_err(|e| DecodeError::Yuv {
                format: layout.format,
                problem: e.to_string(),
            })
        }
    }
}

fn yuv_params(layout: &FrameLayout) -> (yuvutils_rs::YuvRange, yuvutils_rs::YuvStandardMatrix) {
    let range = match layout.range {
        YuvRange::Limited => yuvutils_rs::YuvRange::Limited,
        YuvRange::Full => yuvutils_rs::YuvRange::Full,
    };
    let matrix = match layout.matrix {
        YuvMatrix::Bt601 => yuvutils_rs::YuvStandardMatrix::Bt601,
        YuvMatrix::Bt709 => yuvutils_rs::YuvStandardMatrix::Bt709,
    };
    (range, matrix)
}

fn decode_jpeg(data: &[u8], w: u32, h: u32, rgb: &mut [u8]) -> Result<(), DecodeError> {
    let options = DecoderOptions::new_fast()
        .jpeg_set_out_colorspace(ColorSpace::RGB)
        .set_max_width(MAX_SIDE_PX as usize)
        .set_max_height(MAX_SIDE_PX as usize);
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(data), options);
    decoder
        .decode_headers()
        .map_err(|e| DecodeError::Jpeg(e.to_string()))?;
    let (got_w, got_h) = decoder
        .info()
        .map_or((0, 0), |i| (u32::from(i.width), u32::from(i.height)));
    if (got_w, got_h) != (w, h) {
        return Err(DecodeError::JpegSize {
            width_px: w,
            height_px: h,
            got_w,
            got_h,
        });
    }
    decoder
        .decode_into(rgb)
        .map_err(|e| DecodeError::Jpeg(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// BT.601 limited-range YCbCr of an RGB pixel (the reference the converters must invert).
    fn ycbcr_601_limited([r, g, b]: [u8; 3]) -> [u8; 3] {
        let (r, g, b) = (f64::from(r), f64::from(g), f64::from(b));
        let y = 16.0 + (65.481 * r + 128.553 * g + 24.966 * b) / 255.0;
        let cb = 128.0 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255.0;
        let cr = 128.0 + (112.0 * r - 93.786 * g - 18.214 * b) / 255.0;
        [y.round() as u8, cb.round() as u8, cr.round() as u8]
    }

    /// A test picture in 2x2 blocks of one colour each (so 4:2:0 chroma is exact).
    fn blocks(w: u32, h: u32) -> Vec<u8> {
        let palette = [
            [200u8, 30, 40],
            [20, 180, 60],
            [30, 40, 210],
            [128, 128, 128],
            [240, 240, 30],
            [16, 16, 16],
        ];
        let mut rgb = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let k = ((x / 2) * 7 + (y / 2) * 3) as usize % palette.len();
                rgb.extend_from_slice(&palette[k]);
            }
        }
        rgb
    }

    fn yuyv_of(rgb: &[u8], w: u32, h: u32, stride: usize) -> Vec<u8> {
        let mut out = vec![0u8; stride * h as usize];
        for y in 0..h as usize {
            for x in (0..w as usize).step_by(2) {
                let p = |x: usize| {
                    let i = (y * w as usize + x) * 3;
                    ycbcr_601_limited([rgb[i], rgb[i + 1], rgb[i + 2]])
                };
                let (a, b) = (p(x), p(x + 1));
                let o = y * stride + x * 2;
                out[o..o + 4].copy_from_slice(&[a[0], a[1], b[0], a[2]]);
            }
        }
        out
    }

    fn nv12_of(rgb: &[u8], w: u32, h: u32, stride: usize) -> Vec<u8> {
        let (w, h) = (w as usize, h as usize);
        let ch = h.div_ceil(2);
        let mut out = vec![0u8; stride * (h + ch)];
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) * 3;
                let c = ycbcr_601_limited([rgb[i], rgb[i + 1], rgb[i + 2]]);
                out[y * stride + x] = c[0];
                if y % 2 == 0 && x % 2 == 0 {
                    let o = stride * h + (y / 2) * stride + x;
                    out[o] = c[1];
                    out[o + 1] = c[2];
                }
            }
        }
        out
    }

    fn max_diff(a: &[u8], b: &[u8]) -> u8 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn yuyv_to_rgb_within_rounding() {
        for (w, h, pad) in [(64, 48, 0), (6, 5, 0), (10, 3, 12)] {
            let rgb = blocks(w, h);
            let stride = w as usize * 2 + pad;
            let layout = FrameLayout {
                stride_bytes: stride as u32,
                ..FrameLayout::packed(PixelFormat::Yuyv, w, h)
            };
            let mut out = Vec::new();
            decode_to_rgb(&layout, &yuyv_of(&rgb, w, h, stride), &mut out).unwrap();
            let d = max_diff(&out, &rgb);
            assert!(d <= 3, "{w}x{h} stride {stride}: max difference {d}");
        }
    }

    #[test]
    fn nv12_to_rgb_within_rounding_odd_sizes_too() {
        for (w, h, pad) in [(64, 48, 0), (8, 5, 0), (7, 5, 1), (9, 4, 7)] {
            let rgb = blocks(w, h);
            let stride = w as usize + pad;
            let layout = FrameLayout {
                stride_bytes: stride as u32,
                ..FrameLayout::packed(PixelFormat::Nv12, w, h)
            };
            let mut out = Vec::new();
            decode_to_rgb(&layout, &nv12_of(&rgb, w, h, stride), &mut out).unwrap();
            let d = max_diff(&out, &rgb);
            assert!(d <= 3, "{w}x{h} stride {stride}: max difference {d}");
        }
    }

    #[test]
    fn full_range_and_bt709_change_the_result() {
        // Y = 235 is white in limited range, light grey in full range.
        let layout = FrameLayout::packed(PixelFormat::Yuyv, 2, 1);
        let data = [235, 128, 235, 128];
        let mut out = Vec::new();
        decode_to_rgb(&layout, &data, &mut out).unwrap();
        assert!(out.iter().all(|&v| v >= 254), "{out:?}");
        let full = FrameLayout {
            range: YuvRange::Full,
            ..layout
        };
        decode_to_rgb(&full, &data, &mut out).unwrap();
        assert!(out.iter().all(|&v| v.abs_diff(235) <= 1), "{out:?}");
        // Saturated red differs between the matrices.
        let red = [81u8, 90, 81, 240];
        let mut a = Vec::new();
        let mut b = Vec::new();
        decode_to_rgb(&layout, &red, &mut a).unwrap();
        let bt709 = FrameLayout {
            matrix: YuvMatrix::Bt709,
            ..layout
        };
        decode_to_rgb(&bt709, &red, &mut b).unwrap();
        assert!(a[0] >= 250 && a[1] <= 3, "{a:?}");
        assert_ne!(a, b);
    }

    fn jpeg_of(rgb: &[u8], w: u32, h: u32) -> Vec<u8> {
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 95)
            .encode(rgb, w, h, image::ExtendedColorType::Rgb8)
            .unwrap();
        out
    }

    #[test]
    fn mjpg_to_rgb_close_to_the_source() {
        // Smooth gradients (JPEG's strength), 4:2:0 subsampled by the encoder.
        for (w, h) in [(64, 48), (33, 17)] {
            let mut rgb = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    rgb.extend_from_slice(&[(x * 255 / w) as u8, (y * 255 / h) as u8, 100]);
                }
            }
            let layout = FrameLayout::packed(PixelFormat::Mjpg, w, h);
            let mut out = Vec::new();
            decode_to_rgb(&layout, &jpeg_of(&rgb, w, h), &mut out).unwrap();
            let mean = out
                .iter()
                .zip(&rgb)
                .map(|(a, b)| f64::from(a.abs_diff(*b)))
                .sum::<f64>()
                / rgb.len() as f64;
            assert!(mean < 3.0, "{w}x{h}: mean abs difference {mean}");
            assert!(max_diff(&out, &rgb) < 40);
        }
    }

    #[test]
    fn wrong_sizes_and_short_buffers_are_errors() {
        let mut out = Vec::new();
        let yuyv = FrameLayout::packed(PixelFormat::Yuyv, 4, 2);
        assert_eq!(
            decode_to_rgb(&yuyv, &[0; 15], &mut out),
            Err(DecodeError::Truncated {
                format: PixelFormat::Yuyv,
                width_px: 4,
                height_px: 2,
                got: 15,
                need: 16
            })
        );
        let odd = FrameLayout::packed(PixelFormat::Yuyv, 3, 2);
        assert!(matches!(
            decode_to_rgb(&odd, &[0; 100], &mut out),
            Err(DecodeError::Size { .. })
        ));
        let nv12 = FrameLayout::packed(PixelFormat::Nv12, 5, 3);
        // 5x3 luma + 2 chroma rows of 6 bytes (stride 5 < 6).
        assert!(matches!(
            decode_to_rgb(&nv12, &[0; 100], &mut out),
            Err(DecodeError::Size { .. })
        ));
        let nv12 = FrameLayout {
            stride_bytes: 6,
            ..FrameLayout::packed(PixelFormat::Nv12, 5, 3)
        };
        assert!(decode_to_rgb(&nv12, &[16; 30], &mut out).is_ok());
        assert!(matches!(
            decode_to_rgb(&nv12, &[16; 29], &mut out),
            Err(DecodeError::Truncated { need: 30, .. })
        ));
        let zero = FrameLayout::packed(PixelFormat::Nv12, 0, 3);
        assert!(matches!(
            decode_to_rgb(&zero, &[0; 100], &mut out),
            Err(DecodeError::Size { .. })
        ));
        let huge = FrameLayout::packed(PixelFormat::Yuyv, 1 << 20, 1 << 20);
        assert!(matches!(
            decode_to_rgb(&huge, &[0; 100], &mut out),
            Err(DecodeError::Size { .. })
        ));
    }

    #[test]
    fn broken_jpegs_are_errors() {
        let w = 32;
        let jpeg = jpeg_of(&blocks(w, 16), w, 16);
        let layout = FrameLayout::packed(PixelFormat::Mjpg, w, 16);
        let mut out = Vec::new();
        for cut in [0, 2, 20, jpeg.len() / 2] {
            // A cut JPEG may decode to a partial image (zune-jpeg pads), but must not panic.
            let _ = decode_to_rgb(&layout, &jpeg[..cut], &mut out);
        }
        assert!(matches!(
            decode_to_rgb(&layout, &jpeg[..2], &mut out),
            Err(DecodeError::Jpeg(_))
        ));
        assert!(matches!(
            decode_to_rgb(&layout, b"not a jpeg at all", &mut out),
            Err(DecodeError::Jpeg(_))
        ));
        let other = FrameLayout::packed(PixelFormat::Mjpg, 64, 16);
        assert!(matches!(
            decode_to_rgb(&other, &jpeg, &mut out),
            Err(DecodeError::JpegSize { got_w: 32, .. })
        ));
    }

    #[test]
    fn pixel_format_names() {
        for f in PixelFormat::ALL {
            assert_eq!(f.to_string().parse::<PixelFormat>(), Ok(f));
        }
        assert!("RGB3".parse::<PixelFormat>().is_err());
        assert!("MJPEG".parse::<PixelFormat>().is_err());
    }
}
