//! The detection simulator: detections derived from the ground truth with a detector's
//! typical errors (misses that grow as boxes shrink, box jitter proportional to size,
//! false positives on glint and wave crests, confidence scores), so the tracker can be
//! benchmarked without running a detector.

use crate::render::Renderer;
use crate::scenario::{Detector, ObjectClass};
use crate::truth::{FrameTruth, Optics};
use crate::world::World;
use mgmot_core::geo::Pixel;
use mgmot_core::track::{Appearance, BBox, RgbImage};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Poisson, StandardNormal};
use serde::Serialize;
use std::fmt::Write as _;

/// First RNG stream of the per-frame detector noise; frame `k` uses `STREAM_DETECTIONS + k`,
/// so any frame's detections are reproducible on their own.
const STREAM_DETECTIONS: u64 = 1 << 32;

/// Probability that a detection gets a neighbouring class (swimmer <-> appliance,
/// boat <-> jetski).
const CLASS_CONFUSION: f64 = 0.02;

/// One simulated detection (COCO results entry).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Detection {
    /// Image id (frame index + 1, as in the SeaDronesSee JSON).
    pub image_id: u64,
    /// Category id.
    pub category_id: u32,
    /// `[x, y, w, h]` in pixels.
    pub bbox: [f64; 4],
    /// Confidence in (0, 1).
    pub score: f64,
    /// Ground-truth track id, or `None` for a false positive (not written to COCO results).
    #[serde(skip)]
    pub truth_id: Option<u32>,
    /// Colour signature of the box's rendered pixels ([`with_appearance`]); `None` until
    /// computed, or when the box shows too little to say. In COCO results: an extra field
    /// `appearance` in hex, as `mgmot detect` writes it.
    #[serde(
        skip_serializing_if = "Option::is_none",
        serialize_with = "signature_hex"
    )]
    pub appearance: Option<Appearance>,
}

fn signature_hex<S: serde::Serializer>(a: &Option<Appearance>, s: S) -> Result<S::Ok, S::Error> {
    match a {
        Some(a) => s.serialize_str(&a.to_hex()),
        None => s.serialize_none(),
    }
}

/// Pixels of sea rendered around a box for its signature (the background ring needs one).
const SIGNATURE_MARGIN_PX: f64 = 2.0;

/// Gives every detection of frame `ft` the colour signature of its box as the frame would
/// be rendered ([`Renderer::render_window`]: the box and a margin only, so a long mission
/// costs seconds instead of the hours a full render takes), computed by
/// [`Appearance::from_box`], the function `mgmot` applies to real frames.
pub fn with_appearance(
    renderer: &Renderer,
    world: &World,
    optics: &Optics,
    ft: &FrameTruth,
    dets: &mut [Detection],
) {
    if dets.is_empty() {
        return;
    }
    let objects = renderer.objects_in_view(world, optics, &ft.pose, ft.t_s);
    let mut rgb = Vec::new();
    for d in dets {
        let [x, y, w, h] = d.bbox;
        let x0 = (x - SIGNATURE_MARGIN_PX).floor().max(0.0);
        let y0 = (y - SIGNATURE_MARGIN_PX).floor().max(0.0);
        let x1 = (x + w + SIGNATURE_MARGIN_PX).ceil().max(x0);
        let y1 = (y + h + SIGNATURE_MARGIN_PX).ceil().max(y0);
        let window = (
            x0 as usize,
            y0 as usize,
            (x1 - x0) as usize,
            (y1 - y0) as usize,
        );
        let (width, height) =
            renderer.render_window(optics, &ft.pose, ft.t_s, &objects, window, &mut rgb);
        let image = RgbImage {
            rgb: &rgb,
            width,
            height,
        };
        d.appearance = Appearance::from_box(&image, &BBox::new(x - x0, y - y0, w, h));
    }
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// Probability that the detector misses a box of size `size_px` (sqrt of area).
pub fn miss_probability(det: &Detector, size_px: f64, visibility: f64) -> f64 {
    let half = det.miss_half_size_px.max(0.5);
    let small = 1.0 / (1.0 + ((size_px - half) / (0.25 * half)).exp());
    let p = det.miss_floor + (1.0 - det.miss_floor) * small;
    // Objects cut by the image border are harder.
    (p + (1.0 - visibility) * 0.3).clamp(0.0, 1.0)
}

/// Simulated detections of one frame.
pub fn detect(world: &World, optics: &Optics, ft: &FrameTruth) -> Vec<Detection> {
    let det = &world.scenario.detector;
    let mut rng = ChaCha8Rng::seed_from_u64(world.seed);
    rng.set_stream(world.scenario.vehicle_stream(STREAM_DETECTIONS + ft.index));
    let (w_img, h_img) = (
        f64::from(world.scenario.camera.width_px),
        f64::from(world.scenario.camera.height_px),
    );
    let image_id = ft.index + 1;
    let mut out = Vec::new();
    for b in &ft.boxes {
        let [x, y, w, h] = b.bbox;
        let size = (w * h).sqrt();
        // Draw every random number whether or not it is used, so that one object's fate
        // does not shift the others'.
        let u_miss: f64 = rng.random();
        let noise = [
            gauss(&mut rng),
            gauss(&mut rng),
            gauss(&mut rng),
            gauss(&mut rng),
        ];
        let score_noise = gauss(&mut rng);
        let u_class: f64 = rng.random();
        if u_miss < miss_probability(det, size, b.visibility) {
            continue;
        }
        let j = det.jitter_fraction;
        let cx = x + w / 2.0 + noise[0] * j * w;
        let cy = y + h / 2.0 + noise[1] * j * h;
        let nw = (w * (1.0 + noise[2] * j)).max(1.0);
        let nh = (h * (1.0 + noise[3] * j)).max(1.0);
        let bbox = clip([cx - nw / 2.0, cy - nh / 2.0, nw, nh], w_img, h_img);
        let Some(bbox) = bbox else { continue };
        let score =
            (0.3 + 0.62 * (1.0 - (-size / 18.0).exp()) + 0.08 * score_noise).clamp(0.02, 0.99);
        if score < det.min_score {
            continue;
        }
        let class = if u_class < CLASS_CONFUSION {
            match b.object.class {
                ObjectClass::Swimmer => ObjectClass::LifeSavingAppliance,
                ObjectClass::LifeSavingAppliance => ObjectClass::Swimmer,
                ObjectClass::Boat => ObjectClass::Jetski,
                ObjectClass::Jetski => ObjectClass::Boat,
                ObjectClass::Buoy => ObjectClass::Buoy,
            }
        } else {
            b.object.class
        };
        out.push(Detection {
            image_id,
            category_id: class.category_id(),
            bbox,
            score,
            truth_id: Some(b.object.id),
            appearance: None,
        });
    }
    // False positives: glint sparkles near the sun's specular point and wave crests anywhere
    // on the water, mostly taken for swimmers, with low scores.
    let n_fp = if det.false_positives_per_frame > 0.0 {
        Poisson::new(det.false_positives_per_frame)
            .map(|p| p.sample(&mut rng) as u32)
            .unwrap_or(0)
    } else {
        0
    };
    let glint_px = glint_pixel(world, optics, ft);
    for _ in 0..n_fp {
        let (u, v) = match glint_px {
            Some((gu, gv)) if rng.random::<f64>() < 0.5 => (
                gu + gauss(&mut rng) * w_img * 0.05,
                gv + gauss(&mut rng) * h_img * 0.05,
            ),
            _ => (
                rng.random_range(0.0..w_img),
                rng.random_range(h_img * 0.3..h_img),
            ),
        };
        // Only on the water (a crest has to be on the sea).
        if optics
            .model
            .project_to_sea(&ft.pose, &optics.sea, Pixel::new(u, v))
            .is_err()
        {
            continue;
        }
        let size = rng.random_range(3.0..18.0);
        let aspect = rng.random_range(0.6..1.6);
        let (bw, bh) = (size * aspect, size / aspect);
        let Some(bbox) = clip([u - bw / 2.0, v - bh / 2.0, bw, bh], w_img, h_img) else {
            continue;
        };
        let category_id = if rng.random::<f64>() < 0.8 { 1 } else { 5 };
        let score = rng.random_range(0.05..0.45);
        if score < det.min_score {
            continue;
        }
        out.push(Detection {
            image_id,
            category_id,
            bbox,
            score,
            truth_id: None,
            appearance: None,
        });
    }
    out
}

/// Pixel of the sun's specular reflection on the sea, if it is in front of the camera.
fn glint_pixel(world: &World, optics: &Optics, ft: &FrameTruth) -> Option<(f64, f64)> {
    let sea = &world.scenario.sea;
    let alt = -ft.pose.position_ned.z;
    let d = alt / sea.sun_elevation_deg.to_radians().tan().max(0.05);
    let az = sea.sun_azimuth_deg.to_radians();
    let p = Vector3::new(
        ft.pose.position_ned.x + d * az.cos(),
        ft.pose.position_ned.y + d * az.sin(),
        optics.sea.down_m,
    );
    let px = optics.model.project_to_image(&ft.pose, &p).ok()?;
    optics.model.intrinsics.contains(px).then_some((px.u, px.v))
}

fn clip(b: [f64; 4], w_img: f64, h_img: f64) -> Option<[f64; 4]> {
    let x0 = b[0].max(0.0);
    let y0 = b[1].max(0.0);
    let x1 = (b[0] + b[2]).min(w_img);
    let y1 = (b[1] + b[3]).min(h_img);
    (x1 - x0 >= 1.0 && y1 - y0 >= 1.0).then(|| {
        let r = |v: f64| (v * 100.0).round() / 100.0;
        [r(x0), r(y0), r(x1 - x0), r(y1 - y0)]
    })
}

/// MOTChallenge detection lines: `frame,-1,x,y,w,h,score,class,-1,-1` (the class column carries
/// the SeaDronesSee category id, which `mgmot track` reads for its class-wise ReID), and an
/// eleventh column with the box's colour signature in hex ([`Appearance::to_hex`]) where the
/// detection has one.
pub fn mot_det_lines(frame_index: u64, dets: &[Detection]) -> String {
    let mut s = String::new();
    for d in dets {
        let _ = write!(
            s,
            "{},-1,{:.2},{:.2},{:.2},{:.2},{:.4},{},-1,-1",
            frame_index + 1,
            d.bbox[0],
            d.bbox[1],
            d.bbox[2],
            d.bbox[3],
            d.score,
            d.category_id
        );
        if let Some(a) = &d.appearance {
            let _ = write!(s, ",{}", a.to_hex());
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;
    use crate::truth::frame_truth;

    #[test]
    fn small_boxes_are_missed_more() {
        let d = Detector::default();
        assert!(miss_probability(&d, 3.0, 1.0) > 0.8);
        assert!(miss_probability(&d, 40.0, 1.0) < 0.05);
        assert!(miss_probability(&d, 40.0, 0.3) > miss_probability(&d, 40.0, 1.0));
    }

    /// The signatures rendered for the boxes of one swimmer are closer to each other than
    /// to another swimmer's in a different jacket, and most boxes get one.
    #[test]
    fn signatures_tell_the_jackets_of_a_group_apart() {
        let s = Scenario::load("swimmer_group").unwrap();
        let optics = Optics::new(&s).unwrap();
        let renderer = Renderer::new(&s, 1);
        let world = World::new(s, 1);
        let mut by_object: std::collections::BTreeMap<u32, Vec<Appearance>> =
            std::collections::BTreeMap::new();
        let (mut with, mut total) = (0, 0);
        for index in (0..600).step_by(20) {
            let ft = frame_truth(&world, &optics, index);
            let mut dets = detect(&world, &optics, &ft);
            with_appearance(&renderer, &world, &optics, &ft, &mut dets);
            for d in dets.iter().filter(|d| d.truth_id.is_some()) {
                total += 1;
                if let (Some(id), Some(a)) = (d.truth_id, d.appearance) {
                    with += 1;
                    by_object.entry(id).or_default().push(a);
                }
            }
        }
        assert!(
            with * 10 > total * 8,
            "{with} of {total} boxes have a signature"
        );
        // Jacket colour of the swimmers that wear one throughout.
        let jacket = |id: u32| {
            let at = |t: f64| world.objects_at(t).into_iter().find(|o| o.id == id);
            match (at(0.0), at(20.0)) {
                (Some(a), Some(b))
                    if a.class == ObjectClass::Swimmer && a.lifejacket && b.lifejacket =>
                {
                    Some(a.palette % 8)
                }
                _ => None,
            }
        };
        let mean = |a: &[Appearance], b: &[Appearance]| {
            let mut sum = 0.0;
            for x in a {
                for y in b {
                    sum += x.distance(y);
                }
            }
            sum / (a.len() * b.len()) as f64
        };
        let ids: Vec<u32> = by_object.keys().copied().collect();
        let mut compared = 0;
        for &i in &ids {
            for &j in &ids {
                if i >= j || jacket(i).is_none() || jacket(j).is_none() || jacket(i) == jacket(j) {
                    continue;
                }
                let (a, b) = (&by_object[&i], &by_object[&j]);
                let within = mean(a, a).max(mean(b, b));
                let between = mean(a, b);
                assert!(
                    between > within,
                    "objects {i} and {j}: between {between:.3}, within {within:.3}"
                );
                compared += 1;
            }
        }
        assert!(compared > 0);
    }

    #[test]
    fn detections_track_the_truth_and_are_reproducible() {
        let s = Scenario::load("calm_baseline").unwrap();
        let optics = Optics::new(&s).unwrap();
        let world = World::new(s, 1);
        let (mut tp, mut gt, mut fp) = (0, 0, 0);
        for index in (0..1800).step_by(10) {
            let ft = frame_truth(&world, &optics, index);
            let dets = detect(&world, &optics, &ft);
            assert_eq!(dets, detect(&world, &optics, &ft));
            gt += ft.boxes.len();
            for d in &dets {
                match d.truth_id {
                    Some(id) => {
                        tp += 1;
                        let b = ft.boxes.iter().find(|b| b.object.id == id).unwrap();
                        let dx = (d.bbox[0] + d.bbox[2] / 2.0) - (b.bbox[0] + b.bbox[2] / 2.0);
                        assert!(dx.abs() < 0.5 * b.bbox[2].max(4.0), "{dx}");
                    }
                    None => fp += 1,
                }
            }
        }
        assert!(tp as f64 > 0.7 * gt as f64 && tp < gt, "tp {tp} gt {gt}");
        assert!(fp > 0);
    }
}
