//! Geometry consistency between the ground truth, the shared camera model and the pixels:
//! a true world position projects (through `mgmot_core::geo`) to the centre of its box within
//! 0.5 px, and the object's rendered pixels are inside that box, around its centre.

use mgmot_core::geo::Pixel;
use mgmot_sim::render::Renderer;
use mgmot_sim::scenario::Scenario;
use mgmot_sim::truth::{frame_truth, Optics};
use mgmot_sim::world::World;
use nalgebra::Vector3;

fn overlaps(a: &[f64; 4], b: &[f64; 4], margin: f64) -> bool {
    a[0] - margin < b[0] + b[2]
        && b[0] - margin < a[0] + a[2]
        && a[1] - margin < b[1] + b[3]
        && b[1] - margin < a[1] + a[3]
}

#[test]
fn rendered_objects_sit_in_their_boxes() {
    let mut checked = 0;
    for (name, times) in [
        ("calm_baseline", [22.0, 30.0, 38.0]),
        ("boats_crossing", [8.0, 12.0, 20.0]),
        ("swimmer_group", [5.0, 25.0, 45.0]),
    ] {
        let mut s = Scenario::load(name).unwrap();
        s.camera.width_px = 640;
        s.camera.height_px = 360;
        let optics = Optics::new(&s).unwrap();
        let renderer = Renderer::new(&s, 3);
        let world = World::new(s, 3);
        let mut with = vec![0u8; renderer.frame_bytes()];
        let mut without = vec![0u8; renderer.frame_bytes()];
        for t in times {
            let index = (t * world.scenario.camera.fps).round() as u64;
            let ft = frame_truth(&world, &optics, index);
            renderer.render(&world, &optics, ft.t_s, &mut with, true);
            renderer.render(&world, &optics, ft.t_s, &mut without, false);
            for b in &ft.boxes {
                // The world position projects to the box centre.
                let p = optics
                    .model
                    .project_to_image(&ft.pose, &Vector3::from(b.object.pos_ned_m))
                    .unwrap();
                if b.visibility >= 1.0 {
                    assert!((p.u - (b.bbox[0] + b.bbox[2] / 2.0)).abs() < 0.5);
                    assert!((p.v - (b.bbox[1] + b.bbox[3] / 2.0)).abs() < 0.5);
                }
                // And the sea point under the box centre is the object's position.
                let sea = optics
                    .model
                    .project_to_sea(&ft.pose, &optics.sea, Pixel::new(p.u, p.v))
                    .unwrap();
                assert!((sea - Vector3::from(b.object.pos_ned_m)).norm() < 1e-6);

                if b.visibility < 1.0 || b.bbox[2].max(b.bbox[3]) < 4.0 {
                    continue;
                }
                // Isolated objects only: wakes and trailing submerged bodies of neighbours
                // would otherwise fall into the box.
                let alone = ft
                    .boxes
                    .iter()
                    .all(|o| o.object.id == b.object.id || !overlaps(&o.bbox, &b.bbox, 25.0));
                if !alone {
                    continue;
                }
                let [x, y, w, h] = b.bbox;
                let (mut n, mut su, mut sv) = (0.0, 0.0, 0.0);
                for v in (y.floor() as usize)..((y + h).ceil() as usize).min(360) {
                    for u in (x.floor() as usize)..((x + w).ceil() as usize).min(640) {
                        let i = (v * 640 + u) * 3;
                        let d: i32 = (0..3)
                            .map(|c| (i32::from(with[i + c]) - i32::from(without[i + c])).abs())
                            .sum();
                        if d > 30 {
                            n += 1.0;
                            su += u as f64 + 0.5;
                            sv += v as f64 + 0.5;
                        }
                    }
                }
                assert!(
                    n >= 1.0,
                    "{name} t={t}: object {} drew nothing in its box {:?}",
                    b.object.id,
                    b.bbox
                );
                let (cu, cv) = (su / n, sv / n);
                let tol_u = (0.3 * w).max(1.5);
                let tol_v = (0.3 * h).max(1.5);
                assert!(
                    (cu - p.u).abs() <= tol_u && (cv - p.v).abs() <= tol_v,
                    "{name} t={t}: object {} pixels centred at ({cu:.1}, {cv:.1}), box centre ({:.1}, {:.1})",
                    b.object.id,
                    p.u,
                    p.v
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 8, "only {checked} isolated objects checked");
}

#[test]
fn rendering_is_deterministic() {
    let s = Scenario::load("gimbal_swings").unwrap();
    let optics = Optics::new(&s).unwrap();
    let r1 = Renderer::new(&s, 9);
    let r2 = Renderer::new(&s, 9);
    let world = World::new(s, 9);
    let mut a = vec![0u8; r1.frame_bytes()];
    let mut b = vec![0u8; r2.frame_bytes()];
    r1.render(&world, &optics, 7.5, &mut a, true);
    r2.render(&world, &optics, 7.5, &mut b, true);
    assert!(a == b);
}
