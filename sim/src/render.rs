//! The frame renderer: a textured, moving sea with sun glint and haze, and objects drawn as
//! projected 3D silhouettes at the right pixel size for their distance and the FOV.
//!
//! Sea: each pixel's sea-plane coordinates come from the image->sea homography, fitted once
//! per frame to four pixels that [`mgmot_core::geo::CameraModel::project_to_sea`] maps to the water
//! (so the one camera model of the library decides where everything is), and evaluated
//! incrementally along each row. Two precomputed tiling textures (swell and chop), shifted
//! over time, give moving waves. Objects: their 3D parts are projected with
//! [`mgmot_core::geo::CameraModel::project_to_image`] and filled as convex silhouettes, far to near.

mod camera;
mod draw;

use crate::objects::ObjectState;
use crate::scenario::Scenario;
use crate::truth::Optics;
use crate::world::World;
use mgmot_core::geo::{CameraPose, Pixel};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Side of the square tiling textures (a power of two: indices wrap with a mask).
const TEX: usize = 256;
const TEX_MASK: i32 = (TEX as i32) - 1;

/// A tiling texture; fixed size so that masked indices need no bounds checks.
type Texture = [u8; TEX * TEX];

/// Entries of the per-frame distance look-up tables (haze, texture level of detail, glint).
const LUT: usize = 1024;

/// RNG stream of the textures.
const STREAM_TEXTURE: u64 = 3;
/// RNG stream of the foam and colour-variation textures and the sea's colour offset.
const STREAM_SEA_DETAIL: u64 = 5;

/// Bytes per pixel of the output (packed RGB24).
pub const BYTES_PER_PIXEL: usize = 3;

/// Renders frames of one scenario.
#[derive(Debug, Clone)]
pub struct Renderer {
    width: usize,
    height: usize,
    /// Swell texture: crest lines across the wave direction, one wavelength per 64 texels.
    swell: Box<Texture>,
    /// Chop texture: isotropic fine ripples (also the glint sparkle mask).
    chop: Box<Texture>,
    /// Whitecap and foam-streak opacity, on the swell texture's grid (`None`: no foam).
    foam: Option<Box<Texture>>,
    /// Large-scale colour variation (brightness in R, G-B balance from a second offset).
    tint: Box<Texture>,
    /// Strength of the colour variation (0: off).
    tint_amp: f32,
    /// Fresnel sky reflection on.
    sky_reflection: bool,
    /// Lighting and switches of the objects.
    look: draw::Look,
    /// Camera effects.
    fx: camera::CameraFx,
    /// Exposure time for the motion blur (0: no motion blur).
    exposure_s: f64,
    sea_rgb: [f32; 3],
    haze_rgb: [f32; 3],
    sky_top_rgb: [f32; 3],
    wave_amp: f32,
    wave_length_m: f64,
    wave_dir_rad: f64,
    wave_speed_mps: f64,
    sun_elevation_rad: f64,
    sun_azimuth_rad: f64,
    glint: f32,
}

/// Texels of the swell texture per wavelength along the wave direction.
const SWELL_TEXELS_PER_WAVE: f64 = 64.0;
/// The swell texture spans this many wavelengths across the wave direction (crests are long).
const SWELL_ACROSS_WAVES: f64 = 12.0;
/// Texels of the chop texture per metre.
const CHOP_TEXELS_PER_M: f64 = 24.0;
/// Metres per texel of the colour-variation texture.
const TINT_M_PER_TEXEL: f64 = 1.5;
/// Components of the swell spectrum as (cycles along, cycles across, relative amplitude)
/// over the tile of 4 wavelengths x 12 wavelengths: the dominant wave, longer and shorter
/// ones at angles up to ~40 degrees.
const SWELL_COMPONENTS: [(f64, f64, f32); 6] = [
    (4.0, 0.0, 1.0),
    (3.0, 5.0, 0.45),
    (5.0, -4.0, 0.4),
    (6.0, 2.0, 0.3),
    (9.0, -7.0, 0.18),
    (11.0, 10.0, 0.12),
];

impl Renderer {
    /// Builds the textures and colours of `scenario`.
    pub fn new(scenario: &Scenario, seed: u64) -> Renderer {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(STREAM_TEXTURE);
        let phase = value_noise(&mut rng, &[(4, 1.0), (8, 0.5)]);
        let amp = value_noise(&mut rng, &[(4, 1.0), (16, 0.4)]);
        let sea = &scenario.sea;
        let settings = &scenario.render;
        let mut detail = ChaCha8Rng::seed_from_u64(seed);
        detail.set_stream(STREAM_SEA_DETAIL);
        // A rougher sea has relatively more short, crossing components.
        let rough = (sea.wave_height_m as f32).clamp(0.0, 2.0) * 0.5;
        let comp_phase: Vec<f32> = SWELL_COMPONENTS
            .iter()
            .map(|_| detail.random_range(0.0..std::f32::consts::TAU))
            .collect();
        let mut raw = vec![0f32; TEX * TEX];
        let (mut lo, mut hi) = (f32::MAX, f32::MIN);
        for y in 0..TEX {
            for x in 0..TEX {
                let i = y * TEX + x;
                let mut v = 0.0;
                for (k, &(ca, cb, a)) in SWELL_COMPONENTS.iter().enumerate() {
                    let a = if k == 0 { a } else { a * (0.6 + rough) };
                    let ph = ((ca * x as f64 + cb * y as f64) / TEX as f64) as f32
                        * std::f32::consts::TAU
                        + comp_phase[k]
                        + if k == 0 {
                            1.5 * std::f32::consts::TAU * phase[i]
                        } else {
                            0.0
                        };
                    // Sharper crests than troughs, like real waves.
                    let s = 0.5 + 0.5 * ph.sin();
                    v += a * s * s;
                }
                v *= 0.4 + 0.9 * amp[i];
                raw[i] = v;
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        let span = (hi - lo).max(1e-6);
        let mut swell: Box<Texture> = Box::new([0u8; TEX * TEX]);
        for (t, v) in swell.iter_mut().zip(&raw) {
            *t = (((v - lo) / span).clamp(0.0, 1.0) * 255.0) as u8;
        }
        let foam = if settings.whitecaps {
            make_foam(&mut detail, &raw, sea.wave_height_m)
        } else {
            None
        };
        let tint_f = value_noise(&mut detail, &[(4, 1.0), (8, 0.6), (16, 0.3)]);
        let mut tint: Box<Texture> = Box::new([0u8; TEX * TEX]);
        for (t, v) in tint.iter_mut().zip(tint_f.iter()) {
            *t = (v.clamp(0.0, 1.0) * 255.0) as u8;
        }
        // A seeded offset of the sea's colour: bluer, greener or greyer water.
        let c = sea.color_rgb;
        let mut sea_rgb = [f32::from(c[0]), f32::from(c[1]), f32::from(c[2])];
        if settings.color_variation {
            let grey = detail.random_range(0.0f32..0.3);
            let mean = (sea_rgb[0] + sea_rgb[1] + sea_rgb[2]) / 3.0;
            let green = detail.random_range(-0.1f32..0.12);
            let bright = detail.random_range(0.88f32..1.12);
            for v in &mut sea_rgb {
                *v += (mean - *v) * grey;
            }
            sea_rgb[1] *= 1.0 + green;
            sea_rgb[2] *= 1.0 - green * 0.5;
            for v in &mut sea_rgb {
                *v *= bright;
            }
        }
        let chop_f = value_noise(&mut rng, &[(16, 1.0), (32, 0.6), (64, 0.35)]);
        let mut chop: Box<Texture> = Box::new([0u8; TEX * TEX]);
        for (c, v) in chop.iter_mut().zip(chop_f.iter()) {
            *c = (v.clamp(0.0, 1.0) * 255.0) as u8;
        }
        let (width, height) = (
            scenario.camera.width_px as usize,
            scenario.camera.height_px as usize,
        );
        let look = draw::Look {
            sun_azimuth_rad: sea.sun_azimuth_deg.to_radians(),
            sun_elevation_rad: sea.sun_elevation_deg.to_radians(),
            variety: settings.object_variety,
            shading: settings.object_shading,
            wakes: settings.wakes,
            sea_rgb: sea_rgb.map(|v| v.clamp(0.0, 255.0) as u8),
        };
        Renderer {
            width,
            height,
            swell,
            chop,
            foam,
            tint,
            tint_amp: if settings.color_variation { 1.0 } else { 0.0 },
            sky_reflection: settings.sky_reflection,
            look,
            fx: camera::CameraFx::new(settings, seed, width, height),
            exposure_s: if settings.motion_blur {
                settings.exposure_s
            } else {
                0.0
            },
            sea_rgb,
            haze_rgb: [150.0, 170.0, 180.0],
            sky_top_rgb: [95.0, 140.0, 200.0],
            wave_amp: (sea.wave_height_m as f32).clamp(0.1, 2.0),
            wave_length_m: sea.wave_length_m,
            wave_dir_rad: sea.wave_direction_deg.to_radians(),
            wave_speed_mps: sea.wave_speed_mps,
            sun_elevation_rad: sea.sun_elevation_deg.to_radians(),
            sun_azimuth_rad: sea.sun_azimuth_deg.to_radians(),
            glint: sea.glint as f32,
        }
    }

    /// Image width.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Size of one RGB24 frame in bytes.
    pub fn frame_bytes(&self) -> usize {
        self.width * self.height * BYTES_PER_PIXEL
    }

    /// Renders the frame captured at true time `t_s` into `rgb` (RGB24, `frame_bytes()`
    /// long); `with_objects = false` draws the sea only (used by tests). Camera effects
    /// included: the point-wise ones, the lens blur and the motion blur of the flight's
    /// motion during the exposure.
    pub fn render(
        &self,
        world: &World,
        optics: &Optics,
        t_s: f64,
        rgb: &mut [u8],
        with_objects: bool,
    ) {
        let pose = optics.pose(&world.truth(t_s));
        self.render_scene(world, optics, &pose, t_s, rgb, with_objects);
        let motion = if self.exposure_s > 0.0 {
            let before = optics.pose(&world.truth(t_s - self.exposure_s));
            self.image_motion(optics, &pose, &before)
        } else {
            None
        };
        self.fx.whole_frame(rgb, t_s, motion);
    }

    /// The image motion (pixels) of the sea near the image centre from `before` to `pose`.
    fn image_motion(
        &self,
        optics: &Optics,
        pose: &CameraPose,
        before: &CameraPose,
    ) -> Option<(f64, f64)> {
        let (w, h) = (self.width as f64, self.height as f64);
        for (u, v) in [(w * 0.5, h * 0.5), (w * 0.5, h * 0.8), (w * 0.5, h * 0.98)] {
            let Ok(sea) = optics
                .model
                .project_to_sea(pose, &optics.sea, Pixel::new(u, v))
            else {
                continue;
            };
            let p = optics.model.project_to_image(before, &sea).ok()?;
            let d = (u - p.u, v - p.v);
            return (d.0.is_finite() && d.1.is_finite() && d.0.hypot(d.1) < 200.0).then_some(d);
        }
        None
    }

    /// The sea and the objects, before the camera effects.
    fn render_scene(
        &self,
        world: &World,
        optics: &Optics,
        pose: &CameraPose,
        t_s: f64,
        rgb: &mut [u8],
        with_objects: bool,
    ) {
        let pose = *pose;
        self.render_sea(optics, &pose, t_s, rgb);
        if with_objects {
            let objects = self.objects_in_view(world, optics, &pose, t_s);
            let mut canvas = Canvas {
                rgb,
                origin: (0, 0),
                width: self.width,
                height: self.height,
            };
            for (o, _) in &objects {
                draw::draw_object(&mut canvas, optics, &pose, o, &self.look);
            }
        }
    }

    /// Renders the world at time `t_s` seen from `pose` (instead of the scenario's own
    /// flight: `mgmot-sim follow`) into `rgb`.
    pub fn render_pose(
        &self,
        world: &World,
        optics: &Optics,
        pose: &CameraPose,
        t_s: f64,
        rgb: &mut [u8],
        with_objects: bool,
    ) {
        self.render_scene(world, optics, pose, t_s, rgb, with_objects);
        // No motion blur: the pose's rates are not known here.
        self.fx.whole_frame(rgb, t_s, None);
    }

    /// Renders the window `[x0, x0 + w) x [y0, y0 + h)` of the frame captured at true time
    /// `t_s` into `rgb` (RGB24, `w * h * 3` long after the call): the same pixels
    /// [`Renderer::render`] gives there (every sea pixel evaluated exactly instead of
    /// interpolated along spans, a difference of a unit or two) before its whole-frame
    /// filters (lens and motion blur, which need the neighbours: `render.defocus` and
    /// `render.motion_blur`), at the cost of the window alone. `objects` are the world's objects at `t_s` (far to near) with their image
    /// positions, from [`Renderer::objects_in_view`]; only those near the window are drawn.
    /// Returns the window's width and height once cut to the frame.
    pub fn render_window(
        &self,
        optics: &Optics,
        pose: &CameraPose,
        t_s: f64,
        objects: &[(ObjectState, Option<(f64, f64)>)],
        window: (usize, usize, usize, usize),
        rgb: &mut Vec<u8>,
    ) -> (usize, usize) {
        let (x0, y0, w, h) = window;
        let x1 = (x0 + w).min(self.width);
        let y1 = (y0 + h).min(self.height);
        let (w, h) = (x1.saturating_sub(x0), y1.saturating_sub(y0));
        rgb.clear();
        rgb.resize(w * h * BYTES_PER_PIXEL, 0);
        if w == 0 || h == 0 {
            return (w, h);
        }
        let ctx = self.sea_frame(optics, pose, t_s);
        for v in y0..y1 {
            let sky = self.sky_at(v).map(|c| c.clamp(0.0, 255.0) as u8);
            for x in x0..x1 {
                let c = match &ctx {
                    Some(ctx) => self.shade_exact(ctx, x, v, sky),
                    None => sky,
                };
                let i = ((v - y0) * w + (x - x0)) * BYTES_PER_PIXEL;
                rgb[i..i + BYTES_PER_PIXEL].copy_from_slice(&c);
            }
        }
        let mut canvas = Canvas {
            rgb,
            origin: (x0, y0),
            width: w,
            height: h,
        };
        for (o, centre) in objects {
            // An object whose centre projects far from the window cannot reach it (the
            // largest boats span a few hundred pixels only when very close).
            let near = centre.is_none_or(|(u, v)| {
                let reach = 400.0;
                u > x0 as f64 - reach
                    && u < x1 as f64 + reach
                    && v > y0 as f64 - reach
                    && v < y1 as f64 + reach
            });
            if near {
                draw::draw_object(&mut canvas, optics, pose, o, &self.look);
            }
        }
        self.fx.pointwise(rgb, (x0, y0), w, h, t_s);
        (w, h)
    }

    /// The world's objects at `t_s`, far to near from `pose`, each with its centre's image
    /// position (`None` when it does not project), for [`Renderer::render_window`].
    pub fn objects_in_view(
        &self,
        world: &World,
        optics: &Optics,
        pose: &CameraPose,
        t_s: f64,
    ) -> Vec<(ObjectState, Option<(f64, f64)>)> {
        let mut objects = world.objects_at(t_s);
        let cam = pose.position_ned;
        objects.sort_by(|a, b| {
            let da = (Vector3::from(a.pos_ned_m) - cam).norm_squared();
            let db = (Vector3::from(b.pos_ned_m) - cam).norm_squared();
            db.total_cmp(&da)
        });
        objects
            .into_iter()
            .map(|o| {
                let px = optics
                    .model
                    .project_to_image(pose, &Vector3::from(o.pos_ned_m))
                    .ok()
                    .map(|p| (p.u, p.v));
                (o, px)
            })
            .collect()
    }

    /// Fits the pixel -> (north, east, 1) homography from four pixels on the water.
    fn image_to_sea(&self, optics: &Optics, pose: &CameraPose) -> Option<Matrix3<f64>> {
        let (w, h) = (self.width as f64, self.height as f64);
        let sea = |u: f64, v: f64| {
            optics
                .model
                .project_to_sea(pose, &optics.sea, Pixel::new(u, v))
                .ok()
        };
        let bottom = [(0.0, h), (w, h)];
        let b0 = sea(bottom[0].0, bottom[0].1)?;
        let b1 = sea(bottom[1].0, bottom[1].1)?;
        // The highest row (smallest v) still fully on the water, among a few candidates.
        let mut top = None;
        for frac in [0.0, 0.2, 0.4, 0.6, 0.75, 0.9] {
            let v = h * frac;
            if let (Some(a), Some(b)) = (sea(0.0, v), sea(w, v)) {
                top = Some((v, a, b));
                break;
            }
        }
        let (vt, t0, t1) = top?;
        let src = [(0.0, h), (w, h), (0.0, vt), (w, vt)];
        let dst = [b0, b1, t0, t1];
        fit_homography(&src, &dst.map(|p| (p.x, p.y)))
    }

    fn render_sea(&self, optics: &Optics, pose: &CameraPose, t_s: f64, rgb: &mut [u8]) {
        let (w, h) = (self.width, self.height);
        let Some(ctx) = self.sea_frame(optics, pose, t_s) else {
            self.fill_sky(rgb, 0, h);
            return;
        };
        for v in 0..h {
            let line = &mut rgb[v * w * BYTES_PER_PIXEL..(v + 1) * w * BYTES_PER_PIXEL];
            self.render_row(&ctx, v, line);
        }
    }

    /// The per-frame constants of the sea shading seen from `pose` at `t_s`, or `None` when
    /// no part of the image shows the sea.
    fn sea_frame(&self, optics: &Optics, pose: &CameraPose, t_s: f64) -> Option<SeaFrame> {
        let hm = self.image_to_sea(optics, pose)?;
        let cam_n = pose.position_ned.x;
        let cam_e = pose.position_ned.y;
        let alt = (optics.sea.down_m - pose.position_ned.z).max(0.1);
        let f = optics.model.intrinsics.fx;

        // Linear forms over homogeneous pixels (u, v, 1): each row r gives r.p / (w.p).
        let row = |i: usize| SVector::<f64, 3>::new(hm[(i, 0)], hm[(i, 1)], hm[(i, 2)]);
        let (rn, re, rw) = (row(0), row(1), row(2));
        // Relative to the camera's ground point, so the numbers stay small.
        let rel_n = rn - rw * cam_n;
        let rel_e = re - rw * cam_e;
        // Swell texture coordinates: along / across the wave direction, animated.
        let (sd, cd) = self.wave_dir_rad.sin_cos();
        let sa = SWELL_TEXELS_PER_WAVE / self.wave_length_m;
        let sc = TEX as f64 / (SWELL_ACROSS_WAVES * self.wave_length_m);
        let swell_u = (rn * cd + re * sd) * sa;
        let swell_v = (-rn * sd + re * cd) * sc;
        let swell_off = -(t_s * self.wave_speed_mps * sa);
        // Chop: a slower drift in another direction.
        let (sd2, cd2) = (self.wave_dir_rad + 0.9).sin_cos();
        let chop_u = rn * CHOP_TEXELS_PER_M;
        let chop_v = re * CHOP_TEXELS_PER_M;
        let chop_off = (
            -(t_s * 0.35 * cd2 * CHOP_TEXELS_PER_M),
            -(t_s * 0.35 * sd2 * CHOP_TEXELS_PER_M),
        );
        // Specular point of the sun, relative to the camera's ground point.
        let spec_d = alt / self.sun_elevation_rad.tan().max(0.05);
        let (sn, se) = (
            spec_d * self.sun_azimuth_rad.cos(),
            spec_d * self.sun_azimuth_rad.sin(),
        );
        let glint_sigma = alt * (0.18 + 0.08 * f64::from(self.wave_amp));
        // Per-frame look-up tables over squared ground distance.
        let fog_r2 = (alt * 25.0).max(400.0).powi(2);
        let d2_max = fog_r2 * 12.0;
        let d2_scale = (LUT - 1) as f64 / d2_max;
        let lod_a_r2 = self.wave_length_m / 6.0 * f * alt;
        let lod_b_r2 = 0.15 * f * alt;
        let mut lut_fog = [0f32; LUT];
        let mut lut_lod_a = [0f32; LUT];
        let mut lut_lod_b = [0f32; LUT];
        for i in 0..LUT {
            let d2 = i as f64 / d2_scale;
            let slant2 = d2 + alt * alt;
            lut_fog[i] = (d2 / (d2 + fog_r2)) as f32;
            lut_lod_a[i] = (lod_a_r2 / (slant2.max(lod_a_r2))) as f32;
            lut_lod_b[i] = (lod_b_r2 / (slant2.max(lod_b_r2))) as f32;
        }
        let g2_max = glint_sigma * glint_sigma * 9.0;
        let g2_scale = (LUT - 1) as f64 / g2_max;
        let mut lut_glint = [0f32; LUT];
        for (i, g) in lut_glint.iter_mut().enumerate() {
            let d2 = i as f64 / g2_scale;
            *g = (-d2 / (2.0 * glint_sigma * glint_sigma)).exp() as f32;
        }
        // Fresnel reflectance of the sky over the viewing angle (Schlick), and the sky
        // colour it reflects (brighter and greyer towards the horizon).
        let mut lut_fresnel = [0f32; LUT];
        if self.sky_reflection {
            for (i, fr) in lut_fresnel.iter_mut().enumerate() {
                let d2 = i as f64 / d2_scale;
                let cos = alt / (d2 + alt * alt).sqrt();
                *fr = (0.02 + 0.98 * (1.0 - cos).powi(5)) as f32;
            }
        }
        let tint_k = 1.0 / TINT_M_PER_TEXEL;
        Some(SeaFrame {
            forms: [rel_n, rel_e, swell_u, swell_v, chop_u, chop_v, rw],
            tint_forms: [rn * tint_k, re * tint_k],
            lut_fresnel,
            swell_off,
            chop_off,
            spec_ne: (sn, se),
            d2_scale,
            g2_scale,
            lut_fog,
            lut_lod_a,
            lut_lod_b,
            lut_glint,
        })
    }

    /// Shading inputs of one pixel position, computed exactly (with the perspective
    /// division) at span ends and interpolated linearly in between.
    fn sea_point(&self, ctx: &SeaFrame, u: f64, v: f64) -> Option<SeaPoint> {
        let p = SVector::<f64, 3>::new(u, v, 1.0);
        let wgt = ctx.forms[6].dot(&p);
        if wgt <= 1e-12 {
            return None;
        }
        let inv = 1.0 / wgt;
        let dn = ctx.forms[0].dot(&p) * inv;
        let de = ctx.forms[1].dot(&p) * inv;
        let d2 = dn * dn + de * de;
        let k = ((d2 * ctx.d2_scale) as usize).min(LUT - 1);
        let fog = ctx.lut_fog[k];
        let (gn, ge) = (dn - ctx.spec_ne.0, de - ctx.spec_ne.1);
        let gk = (((gn * gn + ge * ge) * ctx.g2_scale) as usize).min(LUT - 1);
        let g = ctx.lut_glint[gk] * self.glint;
        let fres = ctx.lut_fresnel[k];
        // Large-scale colour variation: brightness and a green / blue balance.
        let (tn, te) = (
            ctx.tint_forms[0].dot(&p) * inv,
            ctx.tint_forms[1].dot(&p) * inv,
        );
        let t1 = sample_bilinear_fixed(
            &self.tint,
            (tn * 256.0) as i64 as i32,
            (te * 256.0) as i64 as i32,
        );
        // The second field: the same texture, transposed and shifted, nearest texel (it
        // is interpolated along the span anyway).
        let t2 = f32::from(self.tint[tex_index(te as i64 as i32 + 157, tn as i64 as i32 + 66)]);
        let (b, gb) = (
            1.0 + self.tint_amp * 0.22 * (t1 / 255.0 - 0.5),
            self.tint_amp * 0.16 * (t2 / 255.0 - 0.5),
        );
        let tinted = [
            self.sea_rgb[0] * b,
            self.sea_rgb[1] * b * (1.0 + gb),
            self.sea_rgb[2] * b * (1.0 - gb),
        ];
        let sky = self.sky_reflected();
        let mut c0 = [0f32; 3];
        let mut c1 = [0f32; 3];
        for c in 0..3 {
            c0[c] = (tinted[c] * (1.0 - fres) + sky[c] * fres) * (1.0 - fog);
            c1[c] = self.haze_rgb[c] * fog + g * 35.0;
        }
        // Texture coordinates in 24.8 fixed point, wrapping (the textures tile).
        let fx = |x: f64| ((x * 256.0) as i64) as i32;
        Some(
            SeaPoint {
                su: ctx.forms[2].dot(&p) * inv + ctx.swell_off,
                sv: ctx.forms[3].dot(&p) * inv,
                cu: ctx.forms[4].dot(&p) * inv + ctx.chop_off.0,
                cv: ctx.forms[5].dot(&p) * inv + ctx.chop_off.1,
                fixed: [0; 4],
                c0,
                c1,
                amp_a: self.wave_amp * 0.45 / 128.0 * ctx.lut_lod_a[k] * (1.0 - fog),
                amp_b: 0.22 / 128.0 * ctx.lut_lod_b[k] * (1.0 - fog),
                sparkle: 6.0 * g,
                // Whitecaps come in groups: a large-scale field (not tiling with the swell
                // texture) lets them appear in some areas only.
                foam: (ctx.lut_lod_a[k] * 1.5).min(1.0)
                    * (1.0 - fog)
                    * ((t2 / 255.0 - 0.42) * 4.0).clamp(0.0, 0.9),
            }
            .with_fixed(fx),
        )
    }

    fn render_row(&self, ctx: &SeaFrame, v: usize, line: &mut [u8]) {
        let w = self.width;
        let vc = v as f64 + 0.5;
        let sky = self.sky_at(v).map(|c| c.clamp(0.0, 255.0) as u8);
        let mut u = 0;
        let mut left = self.sea_point(ctx, 0.5, vc);
        while u < w {
            let end = (u + SPAN).min(w);
            let n = end - u;
            let right = self.sea_point(ctx, end as f64 + 0.5, vc);
            match (&left, &right) {
                (Some(a), Some(b)) => {
                    let inv_n = 1.0 / n as f32;
                    let d = |x: f64, y: f64| (((y - x) * 256.0) / n as f64) as i32;
                    let dfx = [d(a.su, b.su), d(a.sv, b.sv), d(a.cu, b.cu), d(a.cv, b.cv)];
                    let mut fxy = a.fixed;
                    let mut c0 = a.c0;
                    let mut c1 = a.c1;
                    let mut dc0 = [0f32; 3];
                    let mut dc1 = [0f32; 3];
                    for c in 0..3 {
                        dc0[c] = (b.c0[c] - a.c0[c]) * inv_n;
                        dc1[c] = (b.c1[c] - a.c1[c]) * inv_n;
                    }
                    let (mut amp_a, mut amp_b, mut sparkle, mut foam) =
                        (a.amp_a, a.amp_b, a.sparkle, a.foam);
                    let damp_a = (b.amp_a - a.amp_a) * inv_n;
                    let damp_b = (b.amp_b - a.amp_b) * inv_n;
                    let dsparkle = (b.sparkle - a.sparkle) * inv_n;
                    let dfoam = (b.foam - a.foam) * inv_n;
                    for px in line[u * BYTES_PER_PIXEL..end * BYTES_PER_PIXEL]
                        .chunks_exact_mut(BYTES_PER_PIXEL)
                    {
                        let c = self.shade_px(&fxy, &c0, &c1, amp_a, amp_b, sparkle, foam);
                        px.copy_from_slice(&c);
                        for k in 0..4 {
                            fxy[k] = fxy[k].wrapping_add(dfx[k]);
                        }
                        for c in 0..3 {
                            c0[c] += dc0[c];
                            c1[c] += dc1[c];
                        }
                        amp_a += damp_a;
                        amp_b += damp_b;
                        sparkle += dsparkle;
                        foam += dfoam;
                    }
                }
                _ => {
                    // Near or above the horizon: every pixel exactly.
                    for x in u..end {
                        let px = &mut line[x * BYTES_PER_PIXEL..(x + 1) * BYTES_PER_PIXEL];
                        px.copy_from_slice(&self.shade_exact(ctx, x, v, sky));
                    }
                }
            }
            left = right;
            u = end;
        }
    }

    /// The colour of pixel `(x, v)`, evaluated exactly (`sky` above the horizon).
    fn shade_exact(&self, ctx: &SeaFrame, x: usize, v: usize, sky: [u8; 3]) -> [u8; 3] {
        let Some(p) = self.sea_point(ctx, x as f64 + 0.5, v as f64 + 0.5) else {
            return sky;
        };
        self.shade_px(&p.fixed, &p.c0, &p.c1, p.amp_a, p.amp_b, p.sparkle, p.foam)
    }

    /// The colour of a sea pixel from its texture coordinates and shading inputs.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn shade_px(
        &self,
        fxy: &[i32; 4],
        c0: &[f32; 3],
        c1: &[f32; 3],
        amp_a: f32,
        amp_b: f32,
        sparkle: f32,
        foam: f32,
    ) -> [u8; 3] {
        let swell = sample_bilinear_fixed(&self.swell, fxy[0], fxy[1]);
        let chop = f32::from(self.chop[tex_index(fxy[2] >> 8, fxy[3] >> 8)]);
        let shade = 1.0 + amp_a * (swell - 100.0) + amp_b * (chop - 128.0);
        // Glitter: the sun's reflection in the facets of the ripples that face it.
        let spark = if chop > 185.0 {
            (chop - 185.0) * sparkle
        } else {
            0.0
        };
        // Float-to-int `as` saturates to 0..=255.
        let mut out: [f32; 3] = std::array::from_fn(|c| c0[c] * shade + c1[c] + spark);
        if let Some(tex) = &self.foam {
            let f = tex[tex_index(fxy[0] >> 8, fxy[1] >> 8)];
            if f > 0 {
                let a = f32::from(f) * (1.0 / 255.0) * foam;
                for (o, white) in out.iter_mut().zip(FOAM_RGB) {
                    *o += (white * (0.8 + 0.2 * chop / 255.0) - *o) * a;
                }
            }
        }
        out.map(|v| v as u8)
    }

    /// The sky colour the water reflects.
    fn sky_reflected(&self) -> [f32; 3] {
        std::array::from_fn(|c| (self.sky_top_rgb[c] + self.haze_rgb[c]) * 0.5 + 20.0)
    }

    fn sky_at(&self, v: usize) -> [f32; 3] {
        let f = (v as f32 / self.height.max(1) as f32).min(1.0);
        let mut c = [0f32; 3];
        for (k, ck) in c.iter_mut().enumerate() {
            *ck = self.sky_top_rgb[k] + (self.haze_rgb[k] + 30.0 - self.sky_top_rgb[k]) * f;
        }
        c
    }

    fn fill_sky(&self, rgb: &mut [u8], v0: usize, v1: usize) {
        for v in v0..v1 {
            let c = self.sky_at(v);
            let line =
                &mut rgb[v * self.width * BYTES_PER_PIXEL..(v + 1) * self.width * BYTES_PER_PIXEL];
            for px in line.chunks_exact_mut(BYTES_PER_PIXEL) {
                px[0] = c[0] as u8;
                px[1] = c[1] as u8;
                px[2] = c[2] as u8;
            }
        }
    }
}

/// Colour of whitecaps and foam.
const FOAM_RGB: [f32; 3] = [236.0, 242.0, 244.0];

/// Whitecaps on the swell texture's grid: patches on the highest crests, covering a
/// fraction growing with the wave height (none below 0.45 m), and faint
/// foam streaks along the wave (wind) direction; `None` when there would be none. The
/// renderer shows them only in part of the area (whitecaps come in groups).
fn make_foam(rng: &mut ChaCha8Rng, swell: &[f32], wave_height_m: f64) -> Option<Box<Texture>> {
    let cover = ((wave_height_m - 0.45) * 0.05).clamp(0.0, 0.1) as f32;
    if cover <= 0.0 {
        return None;
    }
    let patches = value_noise(rng, &[(16, 1.0), (64, 0.5)]);
    // Streaks: elongated along the texture's u axis (the wave direction).
    let streak_f = value_noise(rng, &[(64, 1.0), (128, 0.5)]);
    let mut score: Vec<f32> = swell
        .iter()
        .zip(&patches)
        .map(|(s, p)| s * (0.1 + 1.8 * p * p))
        .collect();
    let mut sorted = score.clone();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let idx = ((1.0 - cover) * (sorted.len() - 1) as f32) as usize;
    let thr = sorted[idx.min(sorted.len() - 1)];
    let top = sorted[sorted.len() - 1].max(thr + 1e-6);
    let streak_amt = (cover * 6.0).min(0.35);
    let mut out: Box<Texture> = Box::new([0u8; TEX * TEX]);
    for y in 0..TEX {
        for x in 0..TEX {
            let i = y * TEX + x;
            let cap = ((score[i] - thr) / (top - thr)).clamp(0.0, 1.0);
            let cap = (cap * 2.5).min(1.0);
            // Streak noise sampled stretched along u (x / 8).
            let s = streak_f[y * TEX + (x / 8)];
            let streak = ((s - 0.62) * 5.0).clamp(0.0, 1.0) * streak_amt;
            out[i] = ((cap.max(streak)) * 255.0) as u8;
        }
    }
    score.clear();
    Some(out)
}

/// Pixels between exact (perspective-divided) evaluations of the sea coordinates; in
/// between they are interpolated linearly (the error is far below a texel except next to
/// the horizon, where spans that cross it are evaluated per pixel).
const SPAN: usize = 16;

/// Per-frame constants of the sea shading.
struct SeaFrame {
    /// Linear forms over (u, v, 1): north and east relative to the camera, swell u/v, chop
    /// u/v (texels), and the homogeneous weight.
    forms: [SVector<f64, 3>; 7],
    /// Texel coordinates of the colour-variation texture (absolute north / east).
    tint_forms: [SVector<f64, 3>; 2],
    /// Fresnel reflectance of the sky over squared ground distance.
    lut_fresnel: [f32; LUT],
    swell_off: f64,
    chop_off: (f64, f64),
    spec_ne: (f64, f64),
    d2_scale: f64,
    g2_scale: f64,
    lut_fog: [f32; LUT],
    lut_lod_a: [f32; LUT],
    lut_lod_b: [f32; LUT],
    lut_glint: [f32; LUT],
}

/// Shading inputs at one pixel position.
struct SeaPoint {
    su: f64,
    sv: f64,
    cu: f64,
    cv: f64,
    /// `su, sv, cu, cv` in wrapping 24.8 fixed point.
    fixed: [i32; 4],
    /// Colour = c0 * shade + c1 (+ sparkle).
    c0: [f32; 3],
    c1: [f32; 3],
    amp_a: f32,
    amp_b: f32,
    sparkle: f32,
    /// Visibility of whitecaps (they fade where a texel is below a pixel).
    foam: f32,
}

impl SeaPoint {
    fn with_fixed(mut self, fx: impl Fn(f64) -> i32) -> SeaPoint {
        self.fixed = [fx(self.su), fx(self.sv), fx(self.cu), fx(self.cv)];
        self
    }
}

#[inline]
fn tex_index(x: i32, y: i32) -> usize {
    ((y & TEX_MASK) as usize) * TEX + (x & TEX_MASK) as usize
}

/// Bilinear sample at 24.8 fixed-point texel coordinates (arithmetic shifts floor).
#[inline]
fn sample_bilinear_fixed(tex: &Texture, u: i32, v: i32) -> f32 {
    let (x0, y0) = (u >> 8, v >> 8);
    let (fu, fv) = ((u & 255) as u32, (v & 255) as u32);
    let a = u32::from(tex[tex_index(x0, y0)]);
    let b = u32::from(tex[tex_index(x0 + 1, y0)]);
    let c = u32::from(tex[tex_index(x0, y0 + 1)]);
    let d = u32::from(tex[tex_index(x0 + 1, y0 + 1)]);
    // Wrapping arithmetic (no overflow: 255 * 256 * 256 < 2^32) vectorises and skips the
    // release profile's overflow checks.
    let (gu, gv) = (256u32.wrapping_sub(fu), 256u32.wrapping_sub(fv));
    let top = a.wrapping_mul(gu).wrapping_add(b.wrapping_mul(fu));
    let bot = c.wrapping_mul(gu).wrapping_add(d.wrapping_mul(fu));
    top.wrapping_mul(gv).wrapping_add(bot.wrapping_mul(fv)) as f32 * (1.0 / 65536.0)
}

/// Tiling value noise on a TEX x TEX grid: `(cells, weight)` octaves, normalised to [0, 1].
fn value_noise(rng: &mut ChaCha8Rng, octaves: &[(usize, f32)]) -> Vec<f32> {
    let mut out = vec![0f32; TEX * TEX];
    let mut total = 0.0;
    for &(cells, weight) in octaves {
        let lattice: Vec<f32> = (0..cells * cells).map(|_| rng.random::<f32>()).collect();
        let cell = TEX as f32 / cells as f32;
        for y in 0..TEX {
            for x in 0..TEX {
                let gx = x as f32 / cell;
                let gy = y as f32 / cell;
                let (ix, iy) = (gx.floor() as usize, gy.floor() as usize);
                let (fx, fy) = (smooth(gx.fract()), smooth(gy.fract()));
                let at = |i: usize, j: usize| lattice[(j % cells) * cells + (i % cells)];
                let top = at(ix, iy) + (at(ix + 1, iy) - at(ix, iy)) * fx;
                let bot = at(ix, iy + 1) + (at(ix + 1, iy + 1) - at(ix, iy + 1)) * fx;
                out[y * TEX + x] += weight * (top + (bot - top) * fy);
            }
        }
        total += weight;
    }
    for v in &mut out {
        *v /= total;
    }
    out
}

fn smooth(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// Solves the projective map taking the four `src` pixels to the four `dst` sea points
/// (direct linear transform with h33 = 1), normalised so that w > 0 on the water.
fn fit_homography(src: &[(f64, f64); 4], dst: &[(f64, f64); 4]) -> Option<Matrix3<f64>> {
    let mut a = SMatrix::<f64, 8, 8>::zeros();
    let mut b = SVector::<f64, 8>::zeros();
    for k in 0..4 {
        let (x, y) = src[k];
        let (sx, sy) = (dst[k].0, dst[k].1);
        let r = 2 * k;
        let row0 = [x, y, 1.0, 0.0, 0.0, 0.0, -x * sx, -y * sx];
        let row1 = [0.0, 0.0, 0.0, x, y, 1.0, -x * sy, -y * sy];
        for j in 0..8 {
            a[(r, j)] = row0[j];
            a[(r + 1, j)] = row1[j];
        }
        b[r] = sx;
        b[r + 1] = sy;
    }
    let sol = a.lu().solve(&b)?;
    let m = Matrix3::new(
        sol[0], sol[1], sol[2], sol[3], sol[4], sol[5], sol[6], sol[7], 1.0,
    );
    // Orientation: w must be positive at the water pixels used for the fit.
    let w0 = m[(2, 0)] * src[0].0 + m[(2, 1)] * src[0].1 + m[(2, 2)];
    let m = if w0 < 0.0 { -m } else { m };
    m.iter().all(|v| v.is_finite()).then_some(m)
}

/// An RGB24 image being drawn on: the window of the frame whose top-left pixel is
/// `origin` (the whole frame: origin (0, 0)).
struct Canvas<'a> {
    rgb: &'a mut [u8],
    origin: (usize, usize),
    width: usize,
    height: usize,
}

impl Canvas<'_> {
    /// One past the last frame column / row of the window.
    fn x_end(&self) -> usize {
        self.origin.0 + self.width
    }

    fn y_end(&self) -> usize {
        self.origin.1 + self.height
    }

    /// Blends frame pixel `(x, y)` towards `c`.
    fn blend(&mut self, x: usize, y: usize, c: [u8; 3], alpha: f32) {
        if x < self.origin.0 || y < self.origin.1 || x >= self.x_end() || y >= self.y_end() {
            return;
        }
        let i = ((y - self.origin.1) * self.width + (x - self.origin.0)) * BYTES_PER_PIXEL;
        for (px, ck) in self.rgb[i..i + BYTES_PER_PIXEL].iter_mut().zip(c) {
            let old = f32::from(*px);
            *px = (old + (f32::from(ck) - old) * alpha) as u8;
        }
    }

    /// Fills the convex hull of `pts` (pixels); tiny hulls that cover no pixel centre are
    /// blended into the pixel under their centroid with their area as opacity.
    fn fill_hull(&mut self, pts: &[(f64, f64)], c: [u8; 3], alpha: f32) {
        let hull = convex_hull(pts);
        if hull.len() < 3 {
            return;
        }
        let area = polygon_area(&hull).abs();
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in &hull {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        let (ox, oy) = (self.origin.0 as f64, self.origin.1 as f64);
        if x1 < ox || y1 < oy || x0 > self.x_end() as f64 || y0 > self.y_end() as f64 {
            return;
        }
        let mut drawn = false;
        let ys = (y0 - 0.5).ceil().max(oy) as usize;
        let ye = ((y1 - 0.5).floor().min(self.y_end() as f64 - 1.0)).max(-1.0);
        if ye >= 0.0 {
            for y in ys..=(ye as usize) {
                let yc = y as f64 + 0.5;
                let (mut lo, mut hi) = (f64::MAX, f64::MIN);
                for i in 0..hull.len() {
                    let (ax, ay) = hull[i];
                    let (bx, by) = hull[(i + 1) % hull.len()];
                    if (ay <= yc && by > yc) || (by <= yc && ay > yc) {
                        let x = ax + (yc - ay) / (by - ay) * (bx - ax);
                        lo = lo.min(x);
                        hi = hi.max(x);
                    }
                }
                if lo > hi {
                    continue;
                }
                let xs = (lo - 0.5).ceil().max(ox);
                let xe = (hi - 0.5).floor().min(self.x_end() as f64 - 1.0);
                if xe < xs {
                    continue;
                }
                for x in (xs as usize)..=(xe as usize) {
                    self.blend(x, y, c, alpha);
                    drawn = true;
                }
            }
        }
        if !drawn && area > 0.0 {
            let (mut cx, mut cy) = (0.0, 0.0);
            for &(x, y) in &hull {
                cx += x;
                cy += y;
            }
            cx /= hull.len() as f64;
            cy /= hull.len() as f64;
            if cx >= 0.0 && cy >= 0.0 {
                self.blend(cx as usize, cy as usize, c, alpha * (area as f32).min(1.0));
            }
        }
    }
}

fn polygon_area(p: &[(f64, f64)]) -> f64 {
    let mut a = 0.0;
    for i in 0..p.len() {
        let (x0, y0) = p[i];
        let (x1, y1) = p[(i + 1) % p.len()];
        a += x0 * y1 - x1 * y0;
    }
    a / 2.0
}

/// Andrew's monotone chain.
fn convex_hull(pts: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut p: Vec<(f64, f64)> = pts
        .iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let mut lower: Vec<(f64, f64)> = Vec::new();
    for &q in &p {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], q) <= 0.0 {
            lower.pop();
        }
        lower.push(q);
    }
    let mut upper: Vec<(f64, f64)> = Vec::new();
    for &q in p.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], q) <= 0.0 {
            upper.pop();
        }
        upper.push(q);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A window renders the pixels of the whole frame there (the sea within the span
    /// interpolation's unit or two, the objects exactly), point-wise camera effects
    /// (exposure, white balance, vignetting, noise) included. The whole-frame filters
    /// (lens and motion blur) are switched off: a window does not apply them.
    #[test]
    fn a_window_shows_what_the_frame_shows_there() {
        let mut s = Scenario::load("swimmer_group").unwrap();
        s.render.defocus = false;
        s.render.motion_blur = false;
        let optics = Optics::new(&s).unwrap();
        let world = World::new(s.clone(), 1);
        let r = Renderer::new(&s, 1);
        let t = 5.0;
        let mut frame = vec![0u8; r.frame_bytes()];
        r.render(&world, &optics, t, &mut frame, true);
        let pose = optics.pose(&world.truth(t));
        let objects = r.objects_in_view(&world, &optics, &pose, t);
        let on_screen: Vec<(f64, f64)> = objects
            .iter()
            .filter_map(|(_, c)| *c)
            .filter(|&(u, v)| {
                u > 40.0 && v > 40.0 && u < r.width() as f64 - 40.0 && v < r.height() as f64 - 40.0
            })
            .collect();
        assert!(!on_screen.is_empty());
        let mut win = Vec::new();
        for (u, v) in on_screen {
            let (x0, y0, w, h) = (u as usize - 30, v as usize - 30, 60, 60);
            let size = r.render_window(&optics, &pose, t, &objects, (x0, y0, w, h), &mut win);
            assert_eq!(size, (w, h));
            assert_eq!(win.len(), w * h * BYTES_PER_PIXEL);
            let mut worst = 0;
            for y in 0..h {
                for x in 0..w {
                    for c in 0..BYTES_PER_PIXEL {
                        let a = frame[((y0 + y) * r.width() + x0 + x) * BYTES_PER_PIXEL + c];
                        let b = win[(y * w + x) * BYTES_PER_PIXEL + c];
                        worst = worst.max(a.abs_diff(b));
                    }
                }
            }
            assert!(worst <= 4, "window at ({x0}, {y0}) differs by {worst}");
        }
        // A window past the frame's edge is cut to it.
        let size = r.render_window(
            &optics,
            &pose,
            t,
            &objects,
            (r.width() - 5, 0, 20, 10),
            &mut win,
        );
        assert_eq!(size, (5, 10));
        assert_eq!(win.len(), 5 * 10 * BYTES_PER_PIXEL);
    }

    #[test]
    fn homography_fit_matches_project_to_sea() {
        let s = Scenario::load("calm_baseline").unwrap();
        let optics = Optics::new(&s).unwrap();
        let world = World::new(s.clone(), 1);
        let r = Renderer::new(&s, 1);
        let pose = optics.pose(&world.truth(10.0));
        let hm = r.image_to_sea(&optics, &pose).unwrap();
        for (u, v) in [
            (100.0, 500.0),
            (640.0, 360.0),
            (1200.0, 700.0),
            (10.0, 250.0),
        ] {
            let p = optics
                .model
                .project_to_sea(&pose, &optics.sea, Pixel::new(u, v))
                .unwrap();
            let q = hm * Vector3::new(u, v, 1.0);
            assert!(q.z > 0.0);
            assert!((q.x / q.z - p.x).abs() < 1e-6 && (q.y / q.z - p.y).abs() < 1e-6);
        }
    }

    /// Thread CPU time (user + system, from /proc) in seconds.
    fn thread_cpu_s() -> f64 {
        let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap();
        let rest = &stat[stat.rfind(')').unwrap() + 2..];
        let f: Vec<&str> = rest.split(' ').collect();
        (f[11].parse::<f64>().unwrap() + f[12].parse::<f64>().unwrap()) / 100.0
    }

    /// CPU time per 1280x720 frame on one core (`cargo test -p mgmot-sim --release --lib
    /// cpu_time_per_frame -- --ignored --nocapture`): CPU time, not wall time, so that other
    /// processes on the machine do not count.
    #[test]
    #[ignore]
    fn cpu_time_per_frame() {
        for name in [
            "calm_baseline",
            "boats_crossing",
            "high_altitude_tiny",
            "gimbal_swings",
        ] {
            let s = Scenario::load(name).unwrap();
            let optics = Optics::new(&s).unwrap();
            let r = Renderer::new(&s, 1);
            let world = World::new(s, 1);
            let mut rgb = vec![0u8; r.frame_bytes()];
            r.render(&world, &optics, 20.0, &mut rgb, true);
            let n = 150;
            let t0 = thread_cpu_s();
            for k in 0..n {
                r.render(&world, &optics, 20.0 + k as f64 / 30.0, &mut rgb, true);
            }
            let ms = (thread_cpu_s() - t0) * 1000.0 / n as f64;
            println!(
                "cpu_time_per_frame {name} {}x{}: {ms:.2} ms",
                r.width(),
                r.height()
            );
        }
    }

    /// Whitecaps only in a rough enough sea; the `[render]` switches change the pixels and
    /// the same renderer renders the same frame twice.
    #[test]
    fn render_switches_and_whitecaps() {
        let mut s = Scenario::load("boats_crossing").unwrap();
        s.camera.width_px = 320;
        s.camera.height_px = 180;
        s.sea.wave_height_m = 0.3;
        assert!(Renderer::new(&s, 1).foam.is_none());
        s.sea.wave_height_m = 1.5;
        assert!(Renderer::new(&s, 1).foam.is_some());
        s.render.whitecaps = false;
        assert!(Renderer::new(&s, 1).foam.is_none());
        s.render.whitecaps = true;

        let optics = Optics::new(&s).unwrap();
        let world = World::new(s.clone(), 1);
        let r = Renderer::new(&s, 1);
        let mut a = vec![0u8; r.frame_bytes()];
        let mut b = vec![0u8; r.frame_bytes()];
        r.render(&world, &optics, 12.0, &mut a, true);
        r.render(&world, &optics, 12.0, &mut b, true);
        assert!(a == b);
        let mut plain = s.clone();
        plain.render = crate::scenario::Render::off();
        let rp = Renderer::new(&plain, 1);
        rp.render(&world, &optics, 12.0, &mut b, true);
        assert!(a != b);
        // The noise differs from frame to frame.
        r.render(&world, &optics, 12.0, &mut a, false);
        r.render(&world, &optics, 12.0 + 1e-6, &mut b, false);
        assert!(a != b);
    }

    #[test]
    fn hull_of_square() {
        let h = convex_hull(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.5, 0.5)]);
        assert_eq!(h.len(), 4);
        assert!((polygon_area(&h).abs() - 1.0).abs() < 1e-12);
    }
}
