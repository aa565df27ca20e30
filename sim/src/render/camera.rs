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
        let noise: Box<[i8]> = (0..NOISE)
            .map(|_| {
                // Sum of four uniforms: close enough to a Gaussian, sigma 16.
                let s: f32 = (0..4).map(|_| rng.random::<f32>() - 0.5).sum();
                (s * 16.0 / 0.577).clamp(-127.0, 127.0) as i8
            })
            .collect();
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

    /// Whether [`CameraFx::pointwise`] changes anything.
    fn has_pointwise(&self) -> bool {
        self.noise_level > 0.0 || self.drift || self.vignetting > 0.0
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
        if !self.has_pointwise() {
            return;
        }
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
        let (fw, fh) = (self.frame.0.max(1) as f32, self.frame.1.max(1) as f32);
        // Separable vignetting: (1 - v x^2)(1 - v y^2), x and y from -1 to 1 over the
        // frame's diagonal-normalised half sizes.
        let diag = (fw * fw + fh * fh).sqrt() * 0.5;
        let vig = |p: usize, size: f32| {
            let d = (p as f32 + 0.5 - size * 0.5) / diag;
            1.0 - self.vignetting * 0.9 * d * d
        };
        let cols: Vec<f32> = (0..w).map(|x| vig(origin.0 + x, fw)).collect();
        let key = t_s.to_bits().wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let level = self.noise_level / 16.0;
        for y in 0..h {
            let fy = origin.1 + y;
            let row_gain = vig(fy, fh);
            let g = gain.map(|c| c * row_gain);
            // A random offset into the noise table per frame row.
            let mut z = key ^ (fy as u64).wrapping_mul(0xD1B5_4A32_D192_ED03);
            z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z ^= z >> 32;
            let row_off = z as usize + origin.0 * BYTES_PER_PIXEL;
            let line = &mut rgb[y * w * BYTES_PER_PIXEL..(y + 1) * w * BYTES_PER_PIXEL];
            for (x, px) in line.chunks_exact_mut(BYTES_PER_PIXEL).enumerate() {
                let v = cols[x];
                let i = row_off + x * BYTES_PER_PIXEL;
                // Luminance noise shared by the channels, plus a little per channel;
                // shot noise grows with the signal.
                let lum = f32::from(self.noise[i & (NOISE - 1)]);
                for c in 0..BYTES_PER_PIXEL {
                    let s = f32::from(px[c]) * g[c] * v;
                    let n = lum * 0.8 + 0.6 * f32::from(self.noise[(i + c + 7919) & (NOISE - 1)]);
                    px[c] = (s + n * level * (1.2 + s * 0.012)) as u8;
                }
            }
        }
    }

    /// The whole-frame filters: a [1 2 1] x [1 2 1] lens blur, then a box blur along
    /// `motion_px` (the image motion during the exposure) when it is a pixel or more.
    pub(super) fn whole_frame(&self, rgb: &mut [u8], motion_px: Option<(f64, f64)>) {
        let (w, h) = self.frame;
        if self.defocus {
            lens_blur(rgb, w, h);
        }
        if let Some((dx, dy)) = motion_px {
            if dx.hypot(dy) >= 1.0 {
                motion_blur(rgb, w, h, dx, dy);
            }
        }
    }
}

/// Separable [1 2 1] blur, in place, with three horizontally filtered rows in flight.
fn lens_blur(rgb: &mut [u8], w: usize, h: usize) {
    if w < 3 || h < 3 || rgb.len() < w * h * BYTES_PER_PIXEL {
        return;
    }
    let stride = w * BYTES_PER_PIXEL;
    let hrow = |src: &[u8], out: &mut [u16]| {
        for c in 0..BYTES_PER_PIXEL {
            out[c] = 3 * u16::from(src[c]) + u16::from(src[BYTES_PER_PIXEL + c]);
            let e = stride - BYTES_PER_PIXEL + c;
            out[e] = 3 * u16::from(src[e]) + u16::from(src[e - BYTES_PER_PIXEL]);
        }
        for i in BYTES_PER_PIXEL..stride - BYTES_PER_PIXEL {
            out[i] = u16::from(src[i - BYTES_PER_PIXEL])
                + 2 * u16::from(src[i])
                + u16::from(src[i + BYTES_PER_PIXEL]);
        }
    };
    let mut rows = [vec![0u16; stride], vec![0u16; stride], vec![0u16; stride]];
    // rows: [y - 1, y, y + 1] at the top of the loop (the edge rows repeat).
    hrow(&rgb[..stride], &mut rows[0]);
    hrow(&rgb[..stride], &mut rows[1]);
    hrow(&rgb[stride..2 * stride], &mut rows[2]);
    for y in 0..h {
        let out = &mut rgb[y * stride..(y + 1) * stride];
        for (i, o) in out.iter_mut().enumerate() {
            *o = ((rows[0][i] + 2 * rows[1][i] + rows[2][i] + 8) >> 4) as u8;
        }
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
    let (wi, hi) = (w as isize, h as isize);
    for y in 0..hi {
        for x in 0..wi {
            let mut acc = [0u32; 3];
            for &(ox, oy) in &offsets {
                let sx = (x + ox).clamp(0, wi - 1) as usize;
                let sy = (y + oy).clamp(0, hi - 1) as usize;
                let i = sy * stride + sx * BYTES_PER_PIXEL;
                acc[0] += u32::from(src[i]);
                acc[1] += u32::from(src[i + 1]);
                acc[2] += u32::from(src[i + 2]);
            }
            let o = y as usize * stride + x as usize * BYTES_PER_PIXEL;
            for c in 0..3 {
                rgb[o + c] = ((acc[c] * inv) >> 16).min(255) as u8;
            }
        }
    }
}
