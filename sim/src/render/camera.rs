//! Camera effects over a rendered frame: exposure and white-balance drift, vignetting and
//! sensor noise (per pixel, from the pixel's frame coordinates and the frame time, so a
//! window gets exactly the values of the whole frame there), and the whole-frame filters
//! that need neighbours: a slight lens blur and a directional motion blur.

use super::BYTES_PER_PIXEL;
use crate::scenario::Render;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// RNG stream of the camera's noise table and drift phases.
const STREAM_CAMERA: u64 = 4;

/// Entries of the noise table (a power of two).
const NOISE: usize = 1 << 16;

/// Motion blur taps at most (longer streaks are sampled sparsely).
const MAX_TAPS: usize = 8;

/// The camera's per-scenario constants.
#[derive(Debug, Clone)]
pub(super) struct CameraFx {
    noise_level: f32,
    /// Zero-mean noise, about unit standard deviation, in 1/16 units.
    noise: Box<[i8]>,
    drift: bool,
    /// Phases of the slow exposure and white-balance oscillations.
    phases: [f64; 4],
    /// Static white balance of this camera / scenario (R, G, B gains).
    wb: [f32; 3],
    vignetting: f32,
    defocus: bool,
    frame: (usize, usize),
}

impl CameraFx {
    /// Camera constants for a `width` x `height` frame.
    pub(super) fn new(settings: &Render, seed: u64, width: usize, height: usize) -> CameraFx {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(STREAM_CAMERA);
        // Triples of (R, G, B) noise sharing a luminance part; padded so that a frame row
        // can read a contiguous slice from any offset.
        let len = NOISE + width * BYTES_PER_PIXEL + BYTES_PER_PIXEL;
        let mut noise = vec![0i8; len];
        let mut gauss = || -> f32 {
            // Sum of four uniforms: close enough to a Gaussian, sigma 1.
            let s: f32 = (0..4).map(|_| rng.random::<f32>() - 0.5).sum();
            s / 0.577
        };
        for px in noise.chunks_exact_mut(BYTES_PER_PIXEL) {
            let lum = gauss();
            for v in px.iter_mut() {
                *v = ((lum * 0.8 + gauss() * 0.6) * 16.0).clamp(-127.0, 127.0) as i8;
            }
        }
        let noise = noise.into_boxed_slice();
        let phases = std::array::from_fn(|_| rng.random_range(0.0..std::f64::consts::TAU));
        let wb = if settings.exposure_drift {
            [
                1.0 + rng.random_range(-0.04f32..0.04),
                1.0,
                1.0 + rng.random_range(-0.04f32..0.04),
            ]
        } else {
            [1.0; 3]
        };
        CameraFx {
            noise_level: settings.camera_noise as f32,
            noise,
            drift: settings.exposure_drift,
            phases,
            wb,
            vignetting: settings.vignetting as f32,
            defocus: settings.defocus,
            frame: (width, height),
        }
    }

    /// Whether the point-wise effects change anything.
    fn has_pointwise(&self) -> bool {
        self.noise_level > 0.0 || self.drift || self.vignetting > 0.0
    }

    /// Vignetting gain of frame column / row `p` of a frame side of `size` pixels:
    /// (1 - v x^2)(1 - v y^2), separable, x and y over the half diagonal.
    fn vignette(&self, p: usize, size: usize) -> f32 {
        let (fw, fh) = (self.frame.0.max(1) as f32, self.frame.1.max(1) as f32);
        let diag = (fw * fw + fh * fh).sqrt() * 0.5;
        let d = (p as f32 + 0.5 - size as f32 * 0.5) / diag;
        1.0 - self.vignetting * 0.9 * d * d
    }

    /// The point-wise effects of frame time `t_s` for rows of `w` pixels starting at
    /// frame column `x0`.
    fn exposure(&self, t_s: f64, x0: usize, w: usize) -> Exposure {
        let tau = std::f64::consts::TAU;
        let ph = self.phases;
        let (exposure, wb_r, wb_b) = if self.drift {
            (
                1.0 + 0.05 * (tau * t_s / 13.0 + ph[0]).sin()
                    + 0.025 * (tau * t_s / 4.7 + ph[1]).sin(),
                1.0 + 0.02 * (tau * t_s / 19.0 + ph[2]).sin(),
                1.0 + 0.02 * (tau * t_s / 23.0 + ph[3]).sin(),
            )
        } else {
            (1.0, 1.0, 1.0)
        };
        let gain = [
            exposure as f32 * wb_r as f32 * self.wb[0],
            exposure as f32 * self.wb[1],
            exposure as f32 * wb_b as f32 * self.wb[2],
        ];
        // Per byte of a row: vignetting of the column times the channel's gain.
        let cols = (0..w * BYTES_PER_PIXEL)
            .map(|i| {
                let g = self.vignette(x0 + i / BYTES_PER_PIXEL, self.frame.0) * gain[i % 3];
                (g * 128.0).clamp(0.0, 256.0) as u16
            })
            .collect();
        let level = self.noise_level / 16.0;
        Exposure {
            x0,
            cols,
            key: t_s.to_bits().wrapping_mul(0x9E37_79B9_7F4A_7C15),
            // Noise scale a + (b * signal) / 256 (16 x the standard deviation in DN).
            a: (level * 1.2 * 256.0).clamp(0.0, 120.0) as u16,
            b: (level * 0.012 * 65536.0).clamp(0.0, 128.0) as u16,
        }
    }

    /// Applies `e` to `line`, the part of frame row `fy` that `e` was made for.
    fn apply_row(&self, e: &Exposure, fy: usize, line: &mut [u8]) {
        let row_gain = self.vignette(fy, self.frame.1);
        // A random offset into the noise table per frame row, a whole pixel.
        let mut z = e.key ^ (fy as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
        z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z ^= z >> 32;
        let off = (z as usize % (NOISE / BYTES_PER_PIXEL) + e.x0) * BYTES_PER_PIXEL;
        let Some(noise) = self.noise.get(off..off + line.len()) else {
            return;
        };
        // 16-bit wrapping arithmetic vectorises (8 lanes even on baseline x86-64) and skips
        // the release profile's overflow checks; the ranges keep it from wrapping: pixel
        // <= 255 times column gain <= 256 (1/128 units), signal <= 510 times row gain <= 128,
        // |noise| <= 78 times the noise scale <= 375.
        let row = (row_gain.clamp(0.0, 1.0) * 128.0) as u16;
        for ((px, &g), &nv) in line.iter_mut().zip(&e.cols).zip(noise) {
            let s = u16::from(*px).wrapping_mul(g) >> 7;
            let s = s.wrapping_mul(row) >> 7;
            // Shot noise grows with the signal.
            let m = e.a.wrapping_add(s.wrapping_mul(e.b) >> 8);
            let n = i16::from(nv).wrapping_mul(m as i16) >> 8;
            *px = (s as i16).wrapping_add(n).clamp(0, 255) as u8;
        }
    }

    /// Exposure, white balance, vignetting and noise of the pixels of window `rgb`
    /// (`w` x `h`, top-left at frame pixel `origin`) at frame time `t_s`.
    pub(super) fn pointwise(
        &self,
        rgb: &mut [u8],
        origin: (usize, usize),
        w: usize,
        h: usize,
        t_s: f64,
    ) {
        if !self.has_pointwise() || w == 0 {
            return;
        }
        let e = self.exposure(t_s, origin.0, w);
        for (y, line) in rgb
            .chunks_exact_mut(w * BYTES_PER_PIXEL)
            .take(h)
            .enumerate()
        {
            self.apply_row(&e, origin.1 + y, line);
        }
    }

    /// Every effect over a whole frame rendered at `t_s`, in the camera's order: motion
    /// blur along `motion_px` (the image motion during the exposure) when it is a pixel or
    /// more, the lens blur, then exposure, white balance, vignetting and noise.
    pub(super) fn whole_frame(&self, rgb: &mut [u8], t_s: f64, motion_px: Option<(f64, f64)>) {
        let (w, h) = self.frame;
        if let Some((dx, dy)) = motion_px {
            if dx.hypot(dy) >= 1.0 {
                motion_blur(rgb, w, h, dx, dy);
            }
        }
        if self.defocus {
            let e = self.has_pointwise().then(|| self.exposure(t_s, 0, w));
            lens_blur(rgb, w, h, |y, line| {
                if let Some(e) = &e {
                    self.apply_row(e, y, line);
                }
            });
        } else {
            self.pointwise(rgb, (0, 0), w, h, t_s);
        }
    }
}

/// The point-wise effects of one frame, for rows starting at column `x0`.
struct Exposure {
    x0: usize,
    /// Gain per byte of a row (vignetting of the column times the channel's gain), in
    /// 1/128 units.
    cols: Vec<u16>,
    /// Frame key of the noise offsets.
    key: u64,
    a: u16,
    b: u16,
}

/// Separable [1 2 1] blur, in place, with three horizontally filtered rows in flight;
/// `then(y, row)` runs on each finished row while it is in the cache.
fn lens_blur(rgb: &mut [u8], w: usize, h: usize, mut then: impl FnMut(usize, &mut [u8])) {
    if w < 3 || h < 3 || rgb.len() < w * h * BYTES_PER_PIXEL {
        for (y, line) in rgb.chunks_exact_mut(w.max(1) * BYTES_PER_PIXEL).enumerate() {
            then(y, line);
        }
        return;
    }
    let stride = w * BYTES_PER_PIXEL;
    let hrow = |src: &[u8], out: &mut [u16]| {
        for c in 0..BYTES_PER_PIXEL {
            out[c] = 3 * u16::from(src[c]) + u16::from(src[BYTES_PER_PIXEL + c]);
            let e = stride - BYTES_PER_PIXEL + c;
            out[e] = 3 * u16::from(src[e]) + u16::from(src[e - BYTES_PER_PIXEL]);
        }
        let n = stride - 2 * BYTES_PER_PIXEL;
        let mid = &mut out[BYTES_PER_PIXEL..BYTES_PER_PIXEL + n];
        let l = &src[..n];
        let c = &src[BYTES_PER_PIXEL..BYTES_PER_PIXEL + n];
        let r = &src[2 * BYTES_PER_PIXEL..2 * BYTES_PER_PIXEL + n];
        for (((o, &l), &c), &r) in mid.iter_mut().zip(l).zip(c).zip(r) {
            *o = u16::from(l)
                .wrapping_add(u16::from(c) << 1)
                .wrapping_add(u16::from(r));
        }
    };
    let mut rows = [vec![0u16; stride], vec![0u16; stride], vec![0u16; stride]];
    // rows: [y - 1, y, y + 1] at the top of the loop (the edge rows repeat).
    hrow(&rgb[..stride], &mut rows[0]);
    hrow(&rgb[..stride], &mut rows[1]);
    hrow(&rgb[stride..2 * stride], &mut rows[2]);
    for y in 0..h {
        let out = &mut rgb[y * stride..(y + 1) * stride];
        let [a, b, c] = &rows;
        for (((o, &a), &b), &c) in out.iter_mut().zip(a).zip(b).zip(c) {
            *o = (a.wrapping_add(b << 1).wrapping_add(c).wrapping_add(8) >> 4) as u8;
        }
        then(y, out);
        rows.rotate_left(1);
        // Row y + 2 is still the original (only rows up to y were written).
        let next = (y + 2).min(h - 1);
        hrow(&rgb[next * stride..(next + 1) * stride], &mut rows[2]);
    }
}

/// Box blur of `rgb` along `(dx, dy)` pixels, centred (the image does not shift).
fn motion_blur(rgb: &mut [u8], w: usize, h: usize, dx: f64, dy: f64) {
    let len = dx.hypot(dy);
    let taps = ((len.ceil() as usize) + 1).clamp(2, MAX_TAPS);
    let offsets: Vec<(isize, isize)> = (0..taps)
        .map(|k| {
            let f = k as f64 / (taps - 1) as f64 - 0.5;
            ((f * dx).round() as isize, (f * dy).round() as isize)
        })
        .collect();
    let src = rgb.to_vec();
    let stride = w * BYTES_PER_PIXEL;
    let inv = (65536 / taps) as u32;
    let mut acc = vec![0u16; stride];
    for y in 0..h {
        acc.fill(0);
        for &(ox, oy) in &offsets {
            let sy = (y as isize + oy).clamp(0, h as isize - 1) as usize;
            let row = &src[sy * stride..(sy + 1) * stride];
            // acc[x] += row[x + ox], the edge pixel repeating past the ends.
            let sh = (ox.unsigned_abs() * BYTES_PER_PIXEL).min(stride);
            let n = stride - sh;
            if ox >= 0 {
                for (a, &v) in acc[..n].iter_mut().zip(&row[sh..]) {
                    *a = a.wrapping_add(u16::from(v));
                }
                let last = &row[stride - BYTES_PER_PIXEL..];
                for (i, a) in acc[n..].iter_mut().enumerate() {
                    *a = a.wrapping_add(u16::from(last[i % BYTES_PER_PIXEL]));
                }
            } else {
                for (a, &v) in acc[sh..].iter_mut().zip(&row[..n]) {
                    *a = a.wrapping_add(u16::from(v));
                }
                for (i, a) in acc[..sh].iter_mut().enumerate() {
                    *a = a.wrapping_add(u16::from(row[i % BYTES_PER_PIXEL]));
                }
            }
        }
        let out = &mut rgb[y * stride..(y + 1) * stride];
        for (o, &a) in out.iter_mut().zip(&acc) {
            *o = (u32::from(a).wrapping_mul(inv) >> 16).min(255) as u8;
        }
    }
}
