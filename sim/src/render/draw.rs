//! Objects drawn as projected 3D parts: swimmers (head, shoulders, arms, life jackets),
//! boats of several hull types with wakes, jetskis with riders, life rings / jackets / rafts
//! and buoys of several kinds. Each part is a convex hull of 3D points in the object's frame
//! (forward, right, up; metres) filled in one colour; shading comes from drawing a part in
//! its shadow colour and then its sun-facing cap, shifted towards the sun, in its lit colour.
//!
//! Every part stays within the object's footprint (`length_m` x `width_m`) and height, the
//! volume of its ground-truth box, except wakes and spray, which trail behind.

use super::Canvas;
use crate::objects::ObjectState;
use crate::scenario::ObjectClass;
use crate::truth::Optics;
use mgmot_core::geo::CameraPose;
use nalgebra::Vector3;

/// Lighting and switches shared by every object of a frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Look {
    /// Sun bearing (radians clockwise from north).
    pub sun_azimuth_rad: f64,
    /// Sun elevation above the horizon.
    pub sun_elevation_rad: f64,
    /// Per-object variants (otherwise one look per class).
    pub variety: bool,
    /// Lit / shadow sides, highlights, waterline shadows.
    pub shading: bool,
    /// Foam wakes behind moving craft.
    pub wakes: bool,
    /// Sea colour (for the wash over partly submerged parts).
    pub sea_rgb: [u8; 3],
}

/// Colours of life jackets (orange, yellow, red, and a few more high-visibility ones).
const JACKETS: [[u8; 3]; 8] = [
    [255, 105, 0],
    [250, 210, 20],
    [220, 30, 30],
    [255, 130, 10],
    [245, 190, 0],
    [235, 60, 25],
    [255, 90, 20],
    [200, 220, 30],
];
/// Skin tones.
const SKIN: [[u8; 3]; 5] = [
    [232, 185, 150],
    [205, 145, 108],
    [160, 105, 70],
    [110, 70, 45],
    [220, 170, 135],
];
/// Hair (and swim caps).
const HAIR: [[u8; 3]; 7] = [
    [28, 22, 18],
    [62, 42, 26],
    [112, 78, 46],
    [196, 164, 108],
    [150, 148, 145],
    [225, 40, 40],
    [240, 225, 60],
];
/// Dark clothing of swimmers without a jacket.
const CLOTHES: [[u8; 3]; 5] = [
    [30, 32, 38],
    [25, 35, 70],
    [45, 55, 40],
    [70, 30, 35],
    [55, 58, 62],
];
/// Boat hull colours (mostly white, some coloured).
const HULLS: [[u8; 3]; 8] = [
    [238, 238, 234],
    [245, 245, 245],
    [228, 226, 215],
    [200, 40, 35],
    [30, 50, 110],
    [150, 155, 160],
    [235, 235, 230],
    [40, 90, 70],
];
/// RIB tube colours (grey and orange).
const TUBES: [[u8; 3]; 4] = [[72, 74, 80], [235, 100, 25], [110, 112, 118], [40, 40, 44]];
/// Jetski colours.
const JETSKI: [[u8; 3]; 6] = [
    [240, 240, 240],
    [250, 210, 20],
    [210, 30, 30],
    [30, 70, 170],
    [30, 30, 34],
    [60, 170, 80],
];

/// Variant bits of an object, a hash of its id and palette (deterministic, and drawing
/// them takes nothing from the objects' random streams, so no track changes).
fn variant(o: &ObjectState) -> u64 {
    let mut z = u64::from(o.id)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(u64::from(o.palette) << 32);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// `c` scaled by `k` (saturating).
fn scale(c: [u8; 3], k: f32) -> [u8; 3] {
    c.map(|v| (f32::from(v) * k).clamp(0.0, 255.0) as u8)
}

/// `a` mixed towards `b` by `t`.
fn mix(a: [u8; 3], b: [u8; 3], t: f32) -> [u8; 3] {
    std::array::from_fn(|i| (f32::from(a[i]) + (f32::from(b[i]) - f32::from(a[i])) * t) as u8)
}

/// An ellipse of `n` points centred at (`cf`, `cr`) with radii `rf`, `rr`, at height `up`.
fn ring(cf: f64, cr: f64, rf: f64, rr: f64, up: f64, n: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            [cf + rf * a.cos(), cr + rr * a.sin(), up]
        })
        .collect()
}

/// A 2D outline (forward, right) at height `up`, scaled by `k` about (0, 0).
fn at(outline: &[[f64; 2]], up: f64, k: f64) -> Vec<[f64; 3]> {
    outline.iter().map(|p| [p[0] * k, p[1] * k, up]).collect()
}

/// Draws parts of one object.
struct Painter<'c, 'a, 'o> {
    canvas: &'c mut Canvas<'a>,
    optics: &'o Optics,
    pose: &'o CameraPose,
    base: Vector3<f64>,
    sin_h: f64,
    cos_h: f64,
    /// Horizontal unit vector towards the sun in the object's frame (forward, right).
    sun: [f64; 2],
    /// Brightness of surfaces facing up / facing away from the sun.
    lit: f32,
    shade: f32,
    look: Look,
}

impl Painter<'_, '_, '_> {
    fn part(&mut self, pts: &[[f64; 3]], color: [u8; 3], alpha: f32) {
        let mut out = Vec::with_capacity(pts.len());
        for p in pts {
            let world = self.base
                + Vector3::new(
                    p[0] * self.cos_h - p[1] * self.sin_h,
                    p[0] * self.sin_h + p[1] * self.cos_h,
                    -p[2],
                );
            match self.optics.model.project_to_image(self.pose, &world) {
                Ok(px) => out.push((px.u, px.v)),
                Err(_) => return,
            }
        }
        self.canvas.fill_hull(&out, color, alpha);
    }

    /// The soft dark shadow / waterline around an outline at the water.
    fn waterline(&mut self, outline: &[[f64; 2]], grow: f64, alpha: f32) {
        if !self.look.shading {
            return;
        }
        let (sf, sr) = (self.sun[0] * 0.25 * grow, self.sun[1] * 0.25 * grow);
        let pts: Vec<[f64; 3]> = outline
            .iter()
            .map(|p| [p[0] * 1.04 - sf, p[1] * 1.08 - sr, 0.0])
            .collect();
        self.part(&pts, [8, 22, 30], alpha);
    }

    /// A vertical prism between `z0` and `z1` over `outline`: sides in shadow, top lit.
    fn prism(&mut self, outline: &[[f64; 2]], z0: f64, z1: f64, color: [u8; 3]) {
        if !self.look.shading {
            let mut pts = at(outline, z0, 1.0);
            pts.extend(at(outline, z1, 1.0));
            self.part(&pts, color, 1.0);
            return;
        }
        let mut pts = at(outline, z0, 1.0);
        pts.extend(at(outline, z1, 1.0));
        self.part(&pts, scale(color, self.shade), 1.0);
        // The sun-facing wall: the top outline shifted a little towards the sun.
        let d = (z1 - z0).min(0.3) * 0.5;
        let lit_side: Vec<[f64; 3]> = outline
            .iter()
            .map(|p| {
                [
                    p[0] + self.sun[0] * d,
                    p[1] + self.sun[1] * d,
                    (z0 + z1) * 0.5,
                ]
            })
            .collect();
        let mut side = lit_side;
        side.extend(at(outline, z1, 1.0));
        self.part(&side, scale(color, (self.shade + self.lit) * 0.5), 1.0);
        self.part(&at(outline, z1, 1.0), scale(color, self.lit), 1.0);
    }

    /// A rounded blob (head, ball, shoulders): an ellipsoid between `z0` and `z1`, shadow
    /// side dark, a lit cap towards the sun and a small highlight.
    #[allow(clippy::too_many_arguments)]
    fn blob(&mut self, cf: f64, cr: f64, rf: f64, rr: f64, z0: f64, z1: f64, color: [u8; 3]) {
        let zm = (z0 + z1) * 0.5;
        let mut pts = ring(cf, cr, rf, rr, z0, 10);
        pts.extend(ring(cf, cr, rf, rr, zm, 10));
        pts.extend(ring(cf, cr, rf * 0.6, rr * 0.6, z1, 8));
        if !self.look.shading {
            self.part(&pts, color, 1.0);
            return;
        }
        self.part(&pts, scale(color, self.shade), 1.0);
        let (sf, sr) = (self.sun[0], self.sun[1]);
        let cap = ring(
            cf + sf * rf * 0.2,
            cr + sr * rr * 0.2,
            rf * 0.72,
            rr * 0.72,
            z1 - (z1 - z0) * 0.15,
            8,
        );
        self.part(&cap, scale(color, self.lit), 1.0);
        let hi = ring(
            cf + sf * rf * 0.4,
            cr + sr * rr * 0.4,
            rf * 0.25,
            rr * 0.25,
            z1,
            6,
        );
        self.part(&hi, mix(scale(color, self.lit), [255, 255, 255], 0.35), 0.7);
    }
}

/// Draws object `o` seen from `pose`.
pub(super) fn draw_object(
    canvas: &mut Canvas<'_>,
    optics: &Optics,
    pose: &CameraPose,
    o: &ObjectState,
    look: &Look,
) {
    let (sin_h, cos_h) = o.heading_rad.sin_cos();
    let rel = look.sun_azimuth_rad - o.heading_rad;
    let el = look.sun_elevation_rad.clamp(0.05, 1.5) as f32;
    let mut p = Painter {
        canvas,
        optics,
        pose,
        base: Vector3::from(o.pos_ned_m),
        sin_h,
        cos_h,
        sun: [rel.cos(), rel.sin()],
        lit: 0.92 + 0.16 * el.sin(),
        shade: 0.45 + 0.15 * el.sin(),
        look: *look,
    };
    let var = if look.variety { variant(o) } else { 0 };
    match o.class {
        ObjectClass::Swimmer => swimmer(&mut p, o, var),
        ObjectClass::Boat => boat(&mut p, o, var),
        ObjectClass::Jetski => jetski(&mut p, o, var),
        ObjectClass::Buoy => buoy(&mut p, o, var),
        ObjectClass::LifeSavingAppliance => appliance(&mut p, o, var),
    }
}

fn swimmer(p: &mut Painter<'_, '_, '_>, o: &ObjectState, var: u64) {
    let (l, w, h) = (o.length_m, o.width_m, o.height_m);
    let pal = o.palette as usize;
    // 0: head only; 1: head and shoulders; 2: head, shoulders and arms.
    let pose = (var % 3) as u8;
    let skin = SKIN[((var >> 4) as usize) % SKIN.len()];
    let hair = HAIR[((var >> 8) as usize) % HAIR.len()];
    let clothes = CLOTHES[((var >> 12) as usize) % CLOTHES.len()];
    // How far a passing wave covers the body now (moves as the swimmer drifts).
    let wave = 0.5 + 0.5 * (o.pos_ned_m[0] * 0.9 + o.pos_ned_m[1] * 0.6 + (var & 7) as f64).sin();
    let under = (0.35 * wave) as f32;
    let hf = l * 0.12;
    // The submerged torso, faintly through the water.
    p.part(
        &ring(-l * 0.12, 0.0, l * 0.32, w * 0.3, -0.05, 10),
        mix(clothes, p.look.sea_rgb, 0.55),
        0.35,
    );
    let show_shoulders = pose > 0 || o.lifejacket;
    if show_shoulders {
        let oval: Vec<[f64; 2]> = ring(-l * 0.02, 0.0, l * 0.4, w * 0.46, 0.0, 12)
            .iter()
            .map(|q| [q[0], q[1]])
            .collect();
        p.waterline(&oval, 0.2, 0.25);
    }
    if pose == 2 {
        // Arms: forward-reaching, partly under water.
        for side in [-1.0, 1.0] {
            p.part(
                &[
                    [-0.04, side * w * 0.3, 0.03],
                    [-0.04, side * w * 0.5, 0.03],
                    [l * 0.48, side * w * 0.46, 0.0],
                    [l * 0.48, side * w * 0.3, 0.0],
                ],
                if o.lifejacket { skin } else { clothes },
                0.9 - under,
            );
            p.part(
                &ring(l * 0.46, side * w * 0.38, 0.05, 0.045, 0.02, 6),
                skin,
                0.8 - under,
            );
        }
    }
    if o.lifejacket {
        let jacket = JACKETS[pal % JACKETS.len()];
        let outline = [
            [-l * 0.42, -w * 0.42],
            [l * 0.15, -w * 0.5],
            [l * 0.38, -w * 0.32],
            [l * 0.38, w * 0.32],
            [l * 0.15, w * 0.5],
            [-l * 0.42, w * 0.42],
        ];
        p.prism(&outline, 0.0, h * 0.45, jacket);
        // Reflective strip and the collar's inner shadow.
        p.part(
            &at(
                &[
                    [-l * 0.05, -w * 0.45],
                    [-l * 0.05, w * 0.45],
                    [-l * 0.1, w * 0.45],
                    [-l * 0.1, -w * 0.45],
                ],
                h * 0.46,
                1.0,
            ),
            [210, 210, 200],
            0.6,
        );
        p.part(
            &ring(hf, 0.0, 0.13, 0.14, h * 0.46, 8),
            scale(jacket, 0.4),
            0.9,
        );
    } else if pose > 0 {
        let bare = (var >> 16) & 1 == 0;
        let c = if bare { skin } else { clothes };
        p.blob(-l * 0.02, 0.0, l * 0.22, w * 0.46, -0.02, h * 0.25, c);
        p.part(
            &ring(-l * 0.02, 0.0, l * 0.24, w * 0.48, 0.0, 10),
            p.look.sea_rgb,
            under,
        );
    }
    // The head: face towards the front, hair on the back and top.
    p.blob(hf, 0.0, 0.11, 0.1, 0.0, h, skin);
    let mut back = ring(hf - 0.03, 0.0, 0.095, 0.095, h * 0.55, 8);
    back.extend(ring(hf - 0.02, 0.0, 0.08, 0.085, h * 0.97, 8));
    p.part(&back, hair, 1.0);
    if p.look.shading {
        let s = p.sun;
        p.part(
            &ring(hf - 0.02 + s[0] * 0.02, s[1] * 0.02, 0.05, 0.05, h, 6),
            mix(hair, [255, 255, 255], 0.25),
            0.5,
        );
    }
    if !show_shoulders {
        // A wave lapping at the neck.
        p.part(
            &ring(hf, 0.0, 0.13, 0.12, 0.0, 10),
            [200, 215, 215],
            0.25 * wave as f32,
        );
    }
}

/// A boat hull outline: transom at the stern, widest amidships, pointed (or rounded) bow.
fn hull_outline(l: f64, w: f64, bow: f64) -> Vec<[f64; 2]> {
    let (hl, hw) = (l * 0.5, w * 0.5);
    vec![
        [-hl, -hw * 0.86],
        [-hl * 0.4, -hw],
        [hl * 0.2, -hw * 0.97],
        [hl * 0.62, -hw * 0.7],
        [hl * 0.9, -hw * bow],
        [hl, 0.0],
        [hl * 0.9, hw * bow],
        [hl * 0.62, hw * 0.7],
        [hl * 0.2, hw * 0.97],
        [-hl * 0.4, hw],
        [-hl, hw * 0.86],
    ]
}

fn rect(f0: f64, f1: f64, r0: f64, r1: f64) -> Vec<[f64; 2]> {
    vec![[f0, r0], [f1, r0], [f1, r1], [f0, r1]]
}

fn wake(p: &mut Painter<'_, '_, '_>, o: &ObjectState, small: bool) {
    if !p.look.wakes || o.speed_mps <= 0.8 {
        return;
    }
    let (l, w) = (o.length_m, o.width_m);
    let len = (o.speed_mps * if small { 1.3 } else { 1.6 }).min(20.0);
    let strength = ((o.speed_mps - 0.8) / 6.0).clamp(0.25, 1.0) as f32;
    let foam = [228, 236, 236];
    // Kelvin arms from the bow, opening at ~19.5 degrees, widening and fading out.
    let arm = len * 1.3;
    let spread = arm * 0.354;
    let pieces = 5;
    for side in [-1.0, 1.0] {
        for k in 0..pieces {
            let a = k as f64 / pieces as f64;
            let b = (k + 1) as f64 / pieces as f64;
            let pt = |t: f64, off: f64| {
                [
                    l * 0.35 - (l * 0.85 + arm) * t,
                    side * (w * 0.5 + spread * t + off * (0.15 + 0.8 * t)),
                    0.0,
                ]
            };
            p.part(
                &[pt(a, -0.3), pt(b, -0.3), pt(b, 0.6), pt(a, 0.6)],
                foam,
                0.22 * strength * (1.0 - a as f32).powi(2),
            );
        }
    }
    // Turbulent wash behind the stern (propeller), brightest at the transom, spreading.
    // Overlapping pieces (each reaches into the next) soften the steps between them.
    for k in 0..6 {
        let a = k as f64 / 6.0;
        let b = ((k + 2) as f64 / 6.0).min(1.0);
        let wa = w * 0.25 * (1.0 + a * 1.5);
        let wb = w * 0.25 * (1.0 + b * 1.5);
        p.part(
            &[
                [-l * 0.5 - len * a, -wa, 0.0],
                [-l * 0.5 - len * a, wa, 0.0],
                [-l * 0.5 - len * b, wb, 0.0],
                [-l * 0.5 - len * b, -wb, 0.0],
            ],
            foam,
            0.35 * strength * (1.0 - a as f32).powi(2),
        );
    }
    // Bow wave along the sides.
    for side in [-1.0, 1.0] {
        p.part(
            &[
                [l * 0.45, side * w * 0.1, 0.0],
                [l * 0.1, side * w * 0.58, 0.0],
                [-l * 0.3, side * w * 0.6, 0.0],
                [l * 0.1, side * w * 0.48, 0.0],
            ],
            foam,
            0.4 * strength,
        );
    }
}

fn boat(p: &mut Painter<'_, '_, '_>, o: &ObjectState, var: u64) {
    let (l, w, h) = (o.length_m, o.width_m, o.height_m);
    let pal = o.palette as usize;
    wake(p, o, false);
    let kind = (var % 4) as u8;
    let color = HULLS[pal % HULLS.len()];
    match kind {
        // RIB: tubes all round, grey floor, console amidships, outboard at the stern.
        1 => {
            let tube = TUBES[((var >> 8) as usize) % TUBES.len()];
            let outline = hull_outline(l, w, 0.4);
            p.waterline(&outline, 0.5, 0.45);
            let fb = (h * 0.35).min(0.55);
            p.prism(&outline, 0.0, fb, tube);
            let inner: Vec<[f64; 2]> = outline.iter().map(|q| [q[0] * 0.86, q[1] * 0.72]).collect();
            p.part(&at(&inner, fb, 1.0), [118, 120, 118], 1.0);
            p.prism(
                &rect(-l * 0.05, l * 0.12, -w * 0.15, w * 0.15),
                fb,
                fb + 0.5,
                [225, 225, 222],
            );
            p.part(
                &at(
                    &rect(l * 0.08, l * 0.13, -w * 0.15, w * 0.15),
                    fb + 0.52,
                    1.0,
                ),
                [40, 50, 60],
                0.8,
            );
            p.prism(
                &rect(-l * 0.5, -l * 0.42, -w * 0.1, w * 0.1),
                fb,
                fb + 0.5,
                [30, 30, 32],
            );
        }
        // Small open boat / dinghy: thin gunwale, coloured interior, thwarts, outboard.
        2 => {
            let outline = hull_outline(l, w, 0.3);
            p.waterline(&outline, 0.4, 0.4);
            let fb = (h * 0.4).min(0.6);
            p.prism(&outline, 0.0, fb, color);
            let inner: Vec<[f64; 2]> = outline.iter().map(|q| [q[0] * 0.9, q[1] * 0.84]).collect();
            let floor = if (var >> 10) & 1 == 0 {
                [160, 165, 165]
            } else {
                [150, 120, 85]
            };
            p.part(&at(&inner, fb, 1.0), scale(floor, p.lit), 1.0);
            for f in [-0.25, 0.05, 0.3] {
                p.part(
                    &at(
                        &rect(l * f - 0.12, l * f + 0.12, -w * 0.42, w * 0.42),
                        fb,
                        1.0,
                    ),
                    [175, 140, 95],
                    1.0,
                );
            }
            p.prism(
                &rect(-l * 0.5, -l * 0.44, -w * 0.08, w * 0.08),
                fb,
                fb + 0.4,
                [25, 25, 28],
            );
        }
        // Sailing yacht: white hull, beige deck, cabin top with dark windows, boom and
        // furled sail along the centre line.
        3 => {
            let outline = hull_outline(l, w, 0.2);
            p.waterline(&outline, 0.6, 0.45);
            let deck = h * 0.5;
            p.prism(&outline, 0.0, deck, [240, 240, 238]);
            let inner: Vec<[f64; 2]> = outline.iter().map(|q| [q[0] * 0.95, q[1] * 0.9]).collect();
            p.part(&at(&inner, deck, 1.0), scale([196, 184, 160], p.lit), 1.0);
            let cabin = rect(-l * 0.2, l * 0.2, -w * 0.28, w * 0.28);
            p.prism(&cabin, deck, h * 0.8, [236, 236, 232]);
            for side in [-1.0, 1.0] {
                p.part(
                    &at(
                        &rect(-l * 0.1, l * 0.12, side * w * 0.27, side * w * 0.29),
                        h * 0.78,
                        1.0,
                    ),
                    [30, 40, 50],
                    1.0,
                );
            }
            let sail = if (var >> 9) & 1 == 0 {
                [30, 50, 100]
            } else {
                [230, 230, 225]
            };
            p.prism(&rect(-l * 0.4, l * 0.1, -0.1, 0.1), h * 0.8, h, sail);
            p.part(
                &at(&rect(l * 0.1, l * 0.13, -0.05, 0.05), h, 1.0),
                [200, 200, 205],
                1.0,
            );
        }
        // Motorboat: hull, deck, cabin with a dark windscreen, rails.
        _ => {
            let outline = hull_outline(l, w, 0.25);
            p.waterline(&outline, 0.5, 0.45);
            let deck = h * 0.45;
            p.prism(&outline, 0.0, deck, color);
            let inner: Vec<[f64; 2]> = outline.iter().map(|q| [q[0] * 0.93, q[1] * 0.86]).collect();
            let deck_c = if (var >> 9) & 1 == 0 {
                [225, 225, 220]
            } else {
                [180, 150, 110]
            };
            p.part(&at(&inner, deck, 1.0), scale(deck_c, p.lit), 1.0);
            let cabin = rect(-l * 0.3, l * 0.08, -w * 0.32, w * 0.32);
            p.prism(&cabin, deck, h, [232, 234, 236]);
            p.part(
                &at(&rect(l * 0.02, l * 0.1, -w * 0.3, w * 0.3), h * 0.98, 1.0),
                [35, 45, 55],
                1.0,
            );
            p.part(
                &at(&rect(-l * 0.46, -l * 0.3, -w * 0.38, w * 0.38), deck, 1.0),
                [110, 112, 115],
                0.6,
            );
        }
    }
}

fn jetski(p: &mut Painter<'_, '_, '_>, o: &ObjectState, var: u64) {
    let (l, w, h) = (o.length_m, o.width_m, o.height_m);
    let pal = o.palette as usize;
    wake(p, o, true);
    if p.look.wakes && o.speed_mps > 3.0 {
        // Spray fanning out from the stern.
        for side in [-1.0, 1.0] {
            p.part(
                &[
                    [-l * 0.45, side * w * 0.2, 0.0],
                    [-l * 0.5 - 2.5, side * (w * 0.5 + 1.2), 0.0],
                    [-l * 0.5 - 3.5, side * w * 0.3, 0.0],
                ],
                [240, 245, 245],
                0.45,
            );
        }
    }
    let color = JETSKI[(pal + (var as usize >> 3)) % JETSKI.len()];
    let outline = hull_outline(l, w, 0.3);
    p.waterline(&outline, 0.3, 0.4);
    let deck = h * 0.35;
    p.prism(&outline, 0.0, deck, color);
    let stripe = if color[0] > 200 && color[1] > 200 {
        [30, 30, 34]
    } else {
        [240, 240, 240]
    };
    p.part(
        &at(&rect(l * 0.05, l * 0.4, -w * 0.35, w * 0.35), deck, 1.0),
        stripe,
        0.8,
    );
    // Seat.
    p.prism(
        &rect(-l * 0.38, l * 0.05, -w * 0.17, w * 0.17),
        deck,
        deck + 0.15,
        [25, 25, 28],
    );
    // Handlebars.
    p.part(
        &at(&rect(l * 0.1, l * 0.14, -w * 0.33, w * 0.33), h * 0.6, 1.0),
        [20, 20, 22],
        1.0,
    );
    // Rider: legs, torso in a vest, head or helmet.
    let vest = JACKETS[((var >> 6) as usize) % JACKETS.len()];
    p.blob(-l * 0.12, 0.0, 0.3, 0.22, deck, h * 0.85, vest);
    let head = if (var >> 11) & 1 == 0 {
        SKIN[((var >> 12) as usize) % SKIN.len()]
    } else {
        [235, 235, 235]
    };
    p.blob(-l * 0.04, 0.0, 0.11, 0.1, h * 0.8, h, head);
}

fn buoy(p: &mut Painter<'_, '_, '_>, o: &ObjectState, var: u64) {
    let (l, w, h) = (o.length_m, o.width_m, o.height_m);
    let pal = o.palette as usize;
    let round = ring(0.0, 0.0, l * 0.5, w * 0.5, 0.0, 14);
    let fp: Vec<[f64; 2]> = round.iter().map(|q| [q[0], q[1]]).collect();
    p.waterline(&fp, 0.6, 0.4);
    match (var % 4) as u8 {
        // Spar / lateral mark: a narrow red or green can with a top mark.
        1 => {
            let c = if (var >> 8) & 1 == 0 {
                [200, 35, 30]
            } else {
                [30, 140, 60]
            };
            p.blob(0.0, 0.0, l * 0.5, w * 0.5, 0.0, h * 0.25, c);
            let body: Vec<[f64; 2]> = fp.iter().map(|q| [q[0] * 0.45, q[1] * 0.45]).collect();
            p.prism(&body, h * 0.2, h * 0.85, c);
            let top: Vec<[f64; 2]> = fp.iter().map(|q| [q[0] * 0.3, q[1] * 0.3]).collect();
            p.prism(&top, h * 0.85, h, scale(c, 0.9));
        }
        // Yellow special mark: yellow body, X top mark.
        2 => {
            let c = [245, 205, 25];
            p.blob(0.0, 0.0, l * 0.5, w * 0.5, 0.0, h * 0.35, c);
            let body: Vec<[f64; 2]> = fp.iter().map(|q| [q[0] * 0.35, q[1] * 0.35]).collect();
            p.prism(&body, h * 0.3, h * 0.9, c);
            p.part(
                &at(&rect(-l * 0.3, l * 0.3, -0.04, 0.04), h, 1.0),
                [225, 185, 20],
                1.0,
            );
            p.part(
                &at(&rect(-0.04, 0.04, -w * 0.3, w * 0.3), h, 1.0),
                [225, 185, 20],
                1.0,
            );
        }
        // Pillar buoy: wide float, banded body.
        3 => {
            let c = if (var >> 8) & 1 == 0 {
                [205, 40, 30]
            } else {
                [30, 130, 55]
            };
            p.prism(&fp, 0.0, h * 0.2, scale(c, 0.85));
            let body: Vec<[f64; 2]> = fp.iter().map(|q| [q[0] * 0.55, q[1] * 0.55]).collect();
            p.prism(&body, h * 0.2, h * 0.7, c);
            let top: Vec<[f64; 2]> = fp.iter().map(|q| [q[0] * 0.35, q[1] * 0.35]).collect();
            p.prism(&top, h * 0.7, h, [235, 235, 230]);
        }
        // Round mooring ball: orange, red, yellow or white.
        _ => {
            let balls = [
                [250, 110, 20],
                [215, 35, 30],
                [245, 200, 30],
                [238, 238, 232],
            ];
            let c = balls[pal % balls.len()];
            p.blob(0.0, 0.0, l * 0.5, w * 0.5, 0.0, h * 0.6, c);
            p.part(&ring(0.0, 0.0, 0.05, 0.05, h * 0.62, 6), [60, 60, 60], 0.9);
        }
    }
}

fn appliance(p: &mut Painter<'_, '_, '_>, o: &ObjectState, var: u64) {
    let (l, w, h) = (o.length_m, o.width_m, o.height_m);
    let pal = o.palette as usize;
    if l >= 1.5 {
        // Life raft: black buoyancy tube, orange canopy.
        let oct = ring(0.0, 0.0, l * 0.5, w * 0.5, 0.0, 8);
        let fp: Vec<[f64; 2]> = oct.iter().map(|q| [q[0], q[1]]).collect();
        p.waterline(&fp, 0.5, 0.4);
        p.prism(&fp, 0.0, h * 0.35, [35, 35, 38]);
        p.blob(0.0, 0.0, l * 0.42, w * 0.42, h * 0.3, h, [250, 100, 20]);
        return;
    }
    if (l - w).abs() > 0.08 {
        // A life jacket floating flat: body, straps.
        let c = JACKETS[pal % JACKETS.len()];
        let outline = rect(-l * 0.5, l * 0.5, -w * 0.5, w * 0.5);
        p.waterline(&outline, 0.2, 0.3);
        p.prism(&outline, 0.0, h * 0.7, c);
        p.part(
            &at(&rect(-l * 0.1, l * 0.5, -w * 0.1, w * 0.1), h * 0.72, 1.0),
            scale(c, 0.45),
            0.8,
        );
        for f in [-0.2, 0.15] {
            p.part(
                &at(
                    &rect(l * f - 0.02, l * f + 0.02, -w * 0.5, w * 0.5),
                    h * 0.72,
                    1.0,
                ),
                [30, 30, 34],
                0.9,
            );
        }
        return;
    }
    // Life ring: a torus, orange, or white with red / orange quarter bands.
    let banded = !var.is_multiple_of(3);
    let (base, band) = if banded {
        (
            [240, 240, 236],
            if (var >> 5) & 1 == 0 {
                [215, 35, 30]
            } else {
                [250, 110, 20]
            },
        )
    } else {
        ([250, 105, 15], [250, 105, 15])
    };
    let n = 16;
    let (ro, ri) = (0.5, 0.28);
    let ring_fp: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            [l * 0.5 * a.cos(), w * 0.5 * a.sin()]
        })
        .collect();
    p.waterline(&ring_fp, 0.3, 0.3);
    for i in 0..n {
        let a0 = std::f64::consts::TAU * i as f64 / n as f64;
        let a1 = std::f64::consts::TAU * (i + 1) as f64 / n as f64;
        let am = (a0 + a1) * 0.5;
        let c = if banded && i % 4 < 2 { band } else { base };
        // Shading: the part of the torus facing the sun is lit, the far side shaded.
        let facing = (am.cos() * p.sun[0] + am.sin() * p.sun[1]) as f32;
        let k = if p.look.shading {
            (p.shade + p.lit) * 0.5 + (p.lit - p.shade) * 0.5 * facing
        } else {
            1.0
        };
        let pt = |a: f64, r: f64, z: f64| [l * r * a.cos(), w * r * a.sin(), z];
        p.part(
            &[
                pt(a0, ro, 0.0),
                pt(a1, ro, 0.0),
                pt(a1, ri, 0.0),
                pt(a0, ri, 0.0),
                pt(a0, (ro + ri) * 0.5, h),
                pt(a1, (ro + ri) * 0.5, h),
            ],
            scale(c, k),
            1.0,
        );
    }
}
