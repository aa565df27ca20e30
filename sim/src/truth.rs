//! Ground truth of one frame: the true camera pose and every visible object's box, class,
//! id and world position. All projection goes through [`mgmot_core::geo`].

use crate::motion::DroneState;
use crate::objects::ObjectState;
use crate::scenario::Scenario;
use crate::world::World;
use mgmot_core::geo::attitude::camera_from_heading_pitch_deg;
use mgmot_core::geo::{CameraModel, CameraPose, GeoError, Geodetic, LocalTangentFrame, SeaPlane};
use nalgebra::Vector3;

/// Boxes whose clipped size is below this (on their longer side) are not ground truth: an
/// annotator cannot see a one-pixel object either.
pub const MIN_BOX_PX: f64 = 2.0;

/// Boxes with less than this fraction inside the image are not ground truth.
pub const MIN_VISIBILITY: f64 = 0.25;

/// The camera of a scenario plus the frame of reference, built once per run.
#[derive(Debug, Clone)]
pub struct Optics {
    /// The shared camera model (ideal pinhole from the horizontal FOV).
    pub model: CameraModel,
    /// Local NED around home (home sits on the waterline).
    pub frame: LocalTangentFrame,
    /// The sea surface.
    pub sea: SeaPlane,
}

impl Optics {
    /// From the scenario's camera and origin.
    pub fn new(scenario: &Scenario) -> Result<Optics, GeoError> {
        let c = &scenario.camera;
        let origin = Geodetic::new(
            scenario.origin.lat_deg,
            scenario.origin.lon_deg,
            scenario.origin.alt_amsl_m,
        )?;
        Ok(Optics {
            model: CameraModel::from_hfov(c.width_px, c.height_px, c.hfov_deg)?,
            frame: LocalTangentFrame::new(origin),
            sea: SeaPlane::default(),
        })
    }

    /// The geo camera pose of a drone state (camera at the drone's position, stabilised
    /// gimbal: roll 0).
    pub fn pose(&self, state: &DroneState) -> CameraPose {
        CameraPose {
            position_ned: Vector3::from(state.pos_ned_m),
            attitude: camera_from_heading_pitch_deg(
                state.cam_heading_deg,
                state.cam_pitch_deg,
                0.0,
            ),
        }
    }
}

/// A ground-truth box of one object in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthBox {
    /// The object's state (id, class, world position, ...).
    pub object: ObjectState,
    /// Box `[x, y, w, h]` clipped to the image (pixels, top-left origin).
    pub bbox: [f64; 4],
    /// Unclipped box, centred on the projection of the object's reference point.
    pub full_bbox: [f64; 4],
    /// Fraction of the unclipped box inside the image.
    pub visibility: f64,
    /// Pixel of the object's reference point (its position on the water).
    pub center_px: [f64; 2],
    /// Distance from the camera.
    pub range_m: f64,
}

/// Ground truth of one frame.
#[derive(Debug, Clone)]
pub struct FrameTruth {
    /// Frame index (0-based).
    pub index: u64,
    /// True capture time (sim seconds).
    pub t_s: f64,
    /// True drone / camera state.
    pub drone: DroneState,
    /// True camera pose.
    pub pose: CameraPose,
    /// The frame's timestamp on the autopilot clock (µs since its boot).
    pub stamp_us: u64,
    /// What the drone reported for this frame (the SeaDronesSee `meta`).
    pub reported: DroneState,
    /// Visible objects, in id order.
    pub boxes: Vec<TruthBox>,
}

/// 3D points (NED) spanning an object's visible volume: the footprint rectangle at the
/// waterline and at its height.
pub fn extent_points(o: &ObjectState) -> [Vector3<f64>; 8] {
    let (s, c) = o.heading_rad.sin_cos();
    let fwd = Vector3::new(c, s, 0.0);
    let right = Vector3::new(-s, c, 0.0);
    let p = Vector3::from(o.pos_ned_m);
    let (hl, hw) = (o.length_m / 2.0, o.width_m / 2.0);
    let up = Vector3::new(0.0, 0.0, -o.height_m);
    let mut out = [Vector3::zeros(); 8];
    let corners = [(hl, hw), (hl, -hw), (-hl, -hw), (-hl, hw)];
    for (k, (a, b)) in corners.iter().enumerate() {
        let base = p + fwd * *a + right * *b;
        out[2 * k] = base;
        out[2 * k + 1] = base + up;
    }
    out
}

/// Projects one object; `None` when it is behind the camera, beyond the horizon or too small
/// or too little of it is inside the image.
pub fn project_object(optics: &Optics, pose: &CameraPose, o: &ObjectState) -> Option<TruthBox> {
    let center = Vector3::from(o.pos_ned_m);
    let range_m = (center - pose.position_ned).norm();
    // A point on the water is visible only below the horizon, i.e. it projects from the sea.
    let c = optics.model.project_to_image(pose, &center).ok()?;
    let mut half_w: f64 = 0.0;
    let mut half_h: f64 = 0.0;
    for p in extent_points(o) {
        let px = optics.model.project_to_image(pose, &p).ok()?;
        half_w = half_w.max((px.u - c.u).abs());
        half_h = half_h.max((px.v - c.v).abs());
    }
    let full = [c.u - half_w, c.v - half_h, 2.0 * half_w, 2.0 * half_h];
    let k = &optics.model.intrinsics;
    let (w_img, h_img) = (f64::from(k.width_px), f64::from(k.height_px));
    let x0 = full[0].max(0.0);
    let y0 = full[1].max(0.0);
    let x1 = (full[0] + full[2]).min(w_img);
    let y1 = (full[1] + full[3]).min(h_img);
    if x1 <= x0 || y1 <= y0 {
        return None;
    }
    let clipped = [x0, y0, x1 - x0, y1 - y0];
    let area = full[2] * full[3];
    let visibility = if area > 0.0 {
        (clipped[2] * clipped[3] / area).min(1.0)
    } else {
        0.0
    };
    if clipped[2].max(clipped[3]) < MIN_BOX_PX || visibility < MIN_VISIBILITY {
        return None;
    }
    Some(TruthBox {
        object: *o,
        bbox: clipped,
        full_bbox: full,
        visibility,
        center_px: [c.u, c.v],
        range_m,
    })
}

/// The ground truth of frame `index` of the scenario's own flight.
pub fn frame_truth(world: &World, optics: &Optics, index: u64) -> FrameTruth {
    let t_s = world.frame_time_s(index);
    let drone = world.truth(t_s);
    let pose = optics.pose(&drone);
    let mut ft = frame_truth_posed(world, optics, index, t_s, drone, pose);
    ft.stamp_us = world.frame_stamp_us(t_s);
    ft.reported = world.frame_metadata(t_s);
    ft
}

/// The ground truth of a frame taken at scenario time `t_s` from a pose that does not come
/// from the scenario's flight (`mgmot-sim follow`: the pose a real autopilot reported;
/// `drone` is the same pose in the truth's terms). The stamp is the world's clock at `t_s`
/// and the reported state the pose itself; callers with a clock of their own set
/// `stamp_us`.
pub fn frame_truth_posed(
    world: &World,
    optics: &Optics,
    index: u64,
    t_s: f64,
    drone: DroneState,
    pose: CameraPose,
) -> FrameTruth {
    let boxes = world
        .objects_at(t_s)
        .iter()
        .filter_map(|o| project_object(optics, &pose, o))
        .collect();
    FrameTruth {
        index,
        t_s,
        drone,
        pose,
        stamp_us: world.autopilot_time_us(t_s),
        reported: drone,
        boxes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::ObjectClass;

    #[test]
    fn world_position_projects_to_box_centre() {
        let s = Scenario::load("calm_baseline").unwrap();
        let optics = Optics::new(&s).unwrap();
        let world = World::new(s, 1);
        let mut checked = 0;
        for index in (0..1800).step_by(30) {
            let ft = frame_truth(&world, &optics, index);
            for b in &ft.boxes {
                if b.visibility < 1.0 {
                    continue;
                }
                let cx = b.bbox[0] + b.bbox[2] / 2.0;
                let cy = b.bbox[1] + b.bbox[3] / 2.0;
                let p = optics
                    .model
                    .project_to_image(&ft.pose, &Vector3::from(b.object.pos_ned_m))
                    .unwrap();
                assert!((p.u - cx).abs() < 0.5 && (p.v - cy).abs() < 0.5);
                checked += 1;
            }
        }
        assert!(checked > 50, "only {checked} boxes checked");
    }

    #[test]
    fn swimmers_at_high_altitude_are_tiny() {
        let s = Scenario::load("high_altitude_tiny").unwrap();
        let optics = Optics::new(&s).unwrap();
        let world = World::new(s, 5);
        let mut n = 0;
        for index in (0..1800).step_by(60) {
            for b in frame_truth(&world, &optics, index).boxes {
                if b.object.class == ObjectClass::Swimmer {
                    assert!(
                        b.full_bbox[2].max(b.full_bbox[3]) <= 10.0,
                        "{:?}",
                        b.full_bbox
                    );
                    n += 1;
                }
            }
        }
        assert!(n > 10, "{n}");
    }

    #[test]
    fn leave_and_return_targets_come_back_after_5_to_60_s() {
        let s = Scenario::load("leave_and_return").unwrap();
        let optics = Optics::new(&s).unwrap();
        let world = World::new(s, 4);
        let n = world.scenario.frame_count();
        let mut seen: std::collections::HashMap<u32, Vec<u64>> = Default::default();
        for index in 0..n {
            for b in frame_truth(&world, &optics, index).boxes {
                seen.entry(b.object.id).or_default().push(index);
            }
        }
        let mut returns = 0;
        for frames in seen.values() {
            for w in frames.windows(2) {
                let gap_s = (w[1] - w[0]) as f64 / world.scenario.camera.fps;
                if gap_s > 1.0 {
                    assert!((5.0..=60.0).contains(&gap_s), "gap {gap_s} s");
                    returns += 1;
                }
            }
        }
        assert!(returns >= 10, "{returns}");
    }
}
