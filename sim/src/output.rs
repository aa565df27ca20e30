//! Ground-truth writers: MOTChallenge `gt.txt`, the world-truth and camera-pose CSVs, and a
//! SeaDronesSee-style COCO JSON (images with the dataset's `meta`, annotations with
//! `track_id`). Pure formatting: callers own the files.

use crate::truth::{FrameTruth, Optics};
use crate::world::{Reported, World};
use nalgebra::Vector3;
use serde::Serialize;
use std::fmt::Write as _;

/// Header line of the world-truth CSV.
pub const WORLD_CSV_HEADER: &str =
    "frame,time_s,id,class,lat_deg,lon_deg,north_m,east_m,down_m,speed_mps,heading_deg,box_x,box_y,box_w,box_h,visibility\n";

/// Header line of the camera-pose CSV.
pub const CAMERA_CSV_HEADER: &str = "frame,time_s,frame_stamp_us,lat_deg,lon_deg,alt_amsl_m,north_m,east_m,down_m,heading_deg,pitch_below_horizon_deg,qw,qx,qy,qz,vehicle_roll_deg,vehicle_pitch_deg,vehicle_yaw_deg\n";

/// MOTChallenge gt lines of one frame: `frame,id,x,y,w,h,1,class,visibility` (frame 1-based,
/// class = SeaDronesSee category id).
pub fn mot_gt_lines(ft: &FrameTruth) -> String {
    let mut s = String::new();
    for b in &ft.boxes {
        let _ = writeln!(
            s,
            "{},{},{:.2},{:.2},{:.2},{:.2},1,{},{:.3}",
            ft.index + 1,
            b.object.id,
            b.bbox[0],
            b.bbox[1],
            b.bbox[2],
            b.bbox[3],
            b.object.class.category_id(),
            b.visibility
        );
    }
    s
}

/// World-truth CSV lines of one frame: true position of every visible object.
pub fn world_csv_lines(ft: &FrameTruth, optics: &Optics) -> String {
    let mut s = String::new();
    for b in &ft.boxes {
        let o = &b.object;
        let g = optics.frame.to_geodetic(&Vector3::from(o.pos_ned_m));
        let _ = writeln!(
            s,
            "{},{:.4},{},{},{:.8},{:.8},{:.3},{:.3},{:.3},{:.3},{:.2},{:.2},{:.2},{:.2},{:.2},{:.3}",
            ft.index + 1,
            ft.t_s,
            o.id,
            o.class.name(),
            g.lat_deg,
            g.lon_deg,
            o.pos_ned_m[0],
            o.pos_ned_m[1],
            o.pos_ned_m[2],
            o.speed_mps,
            crate::motion::wrap_360(o.heading_rad.to_degrees()),
            b.bbox[0],
            b.bbox[1],
            b.bbox[2],
            b.bbox[3],
            b.visibility
        );
    }
    s
}

/// Camera-pose CSV line of one frame (the true pose; the quaternion is the pose's attitude,
/// heading and pitch those of its optical axis, the timestamp the frame's).
pub fn camera_csv_line(ft: &FrameTruth, optics: &Optics) -> String {
    let d = &ft.drone;
    let g = optics.frame.to_geodetic(&Vector3::from(d.pos_ned_m));
    let q = ft.pose.attitude;
    format!(
        "{},{:.4},{},{:.8},{:.8},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.9},{:.9},{:.9},{:.9},{:.3},{:.3},{:.3}\n",
        ft.index + 1,
        ft.t_s,
        ft.stamp_us,
        g.lat_deg,
        g.lon_deg,
        g.alt_m,
        d.pos_ned_m[0],
        d.pos_ned_m[1],
        d.pos_ned_m[2],
        d.cam_heading_deg,
        d.cam_pitch_deg,
        q.w,
        q.i,
        q.j,
        q.k,
        d.roll_deg,
        d.pitch_deg,
        d.yaw_deg
    )
}

/// A SeaDronesSee-style dataset being accumulated frame by frame.
#[derive(Debug, Serialize)]
pub struct SeaDronesSee {
    info: Info,
    licenses: Vec<License>,
    categories: Vec<Category>,
    videos: Vec<Video>,
    images: Vec<Image>,
    annotations: Vec<Annotation>,
}

#[derive(Debug, Serialize)]
struct Info {
    year: String,
    version: String,
    description: String,
    contributor: String,
    url: String,
    date_created: String,
}

#[derive(Debug, Serialize)]
struct License {
    id: u32,
    url: String,
    name: String,
}

#[derive(Debug, Serialize)]
struct Category {
    supercategory: &'static str,
    id: u32,
    name: &'static str,
}

#[derive(Debug, Serialize)]
struct Video {
    id: u32,
    name: String,
    folder_name: String,
    fps: f64,
    width: u32,
    height: u32,
}

#[derive(Debug, Serialize)]
struct Image {
    id: u64,
    file_name: String,
    height: u32,
    width: u32,
    source: Source,
    video_id: u32,
    frame_index: u64,
    date_time: String,
    meta: Meta,
}

#[derive(Debug, Serialize)]
struct Source {
    drone: &'static str,
    folder_name: String,
    video: String,
    frame_no: u64,
}

/// The dataset's per-image drone metadata, keys exactly as in SeaDronesSee.
#[derive(Debug, Serialize)]
struct Meta {
    image_name: String,
    #[serde(rename = "datetime(utc)")]
    datetime_utc: String,
    latitude: f64,
    longitude: f64,
    #[serde(rename = "height_above_takeoff(meter)")]
    height_above_takeoff_m: f64,
    #[serde(rename = "speed(m/s)")]
    speed_mps: f64,
    #[serde(rename = "xspeed(m/s)")]
    xspeed_mps: f64,
    #[serde(rename = "yspeed(m/s)")]
    yspeed_mps: f64,
    #[serde(rename = "zspeed(m/s)")]
    zspeed_mps: f64,
    #[serde(rename = "compass_heading(degrees)")]
    compass_heading_deg: f64,
    #[serde(rename = "gimbal_heading(degrees)")]
    gimbal_heading_deg: f64,
    #[serde(rename = "gimbal_pitch(degrees)")]
    gimbal_pitch_deg: f64,
}

#[derive(Debug, Serialize)]
struct Annotation {
    id: u64,
    image_id: u64,
    bbox: [f64; 4],
    area: f64,
    category_id: u32,
    track_id: u32,
    iscrowd: u8,
}

/// Rounds to a fixed number of decimals so that the JSON is compact and stable.
fn round(v: f64, decimals: i32) -> f64 {
    let p = 10f64.powi(decimals);
    (v * p).round() / p
}

/// `YYYY-MM-DDTHH:MM:SS.ffffff` (UTC) of a Unix time.
pub fn iso_time(unix_s: f64) -> String {
    let secs = unix_s.floor();
    let nanos = ((unix_s - secs) * 1e9).round().clamp(0.0, 999_999_999.0) as u32;
    chrono::DateTime::from_timestamp(secs as i64, nanos)
        .map(|t| t.format("%Y-%m-%dT%H:%M:%S%.6f").to_string())
        .unwrap_or_default()
}

impl SeaDronesSee {
    /// An empty dataset for `world`'s scenario.
    pub fn new(world: &World) -> SeaDronesSee {
        let s = &world.scenario;
        SeaDronesSee {
            info: Info {
                year: "2024".into(),
                version: "mgmot-sim".into(),
                description: format!(
                    "mgmot-sim scenario {} seed {}: {}",
                    s.name, world.seed, s.description
                ),
                contributor: "mgmot-sim".into(),
                url: String::new(),
                date_created: iso_time(s.origin.start_unix_s),
            },
            licenses: vec![License {
                id: 1,
                url: String::new(),
                name: "generated".into(),
            }],
            categories: vec![
                Category {
                    supercategory: "ignored",
                    id: 0,
                    name: "ignored",
                },
                Category {
                    supercategory: "person",
                    id: 1,
                    name: "swimmer",
                },
                Category {
                    supercategory: "boat",
                    id: 2,
                    name: "boat",
                },
                Category {
                    supercategory: "boat",
                    id: 3,
                    name: "jetski",
                },
                Category {
                    supercategory: "object",
                    id: 4,
                    name: "life_saving_appliances",
                },
                Category {
                    supercategory: "object",
                    id: 5,
                    name: "buoy",
                },
            ],
            videos: vec![Video {
                id: 1,
                name: format!("{}.mp4", s.name),
                folder_name: s.name.clone(),
                fps: s.camera.fps,
                width: s.camera.width_px,
                height: s.camera.height_px,
            }],
            images: Vec::new(),
            annotations: Vec::new(),
        }
    }

    /// Adds one frame: the image entry (metadata as the drone reported it for this frame)
    /// and one annotation per ground-truth box.
    pub fn add_frame(&mut self, world: &World, optics: &Optics, ft: &FrameTruth, file_name: &str) {
        let s = &world.scenario;
        let rep: Reported = ft.reported;
        let g = optics.frame.to_geodetic(&Vector3::from(rep.pos_ned_m));
        let image_id = ft.index + 1;
        let unix = s.origin.start_unix_s + ft.t_s;
        let [vn, ve, vd] = rep.vel_ned_mps;
        self.images.push(Image {
            id: image_id,
            file_name: file_name.to_string(),
            height: s.camera.height_px,
            width: s.camera.width_px,
            source: Source {
                drone: "mgmot-sim",
                folder_name: s.name.clone(),
                video: format!("{}.mp4", s.name),
                frame_no: ft.index,
            },
            video_id: 1,
            frame_index: ft.index,
            date_time: iso_time(unix),
            meta: Meta {
                image_name: file_name.to_string(),
                datetime_utc: iso_time(unix.floor())
                    .replace('T', " ")
                    .chars()
                    .take(19)
                    .collect(),
                latitude: round(g.lat_deg, 8),
                longitude: round(g.lon_deg, 8),
                height_above_takeoff_m: round(rep.altitude_m(), 3),
                speed_mps: round((vn * vn + ve * ve + vd * vd).sqrt(), 3),
                xspeed_mps: round(vn, 3),
                yspeed_mps: round(ve, 3),
                zspeed_mps: round(vd, 3),
                compass_heading_deg: round(rep.yaw_deg, 2),
                gimbal_heading_deg: round(rep.cam_heading_deg, 2),
                gimbal_pitch_deg: round(rep.cam_pitch_deg, 2),
            },
        });
        for b in &ft.boxes {
            let bbox = [
                round(b.bbox[0], 2),
                round(b.bbox[1], 2),
                round(b.bbox[2], 2),
                round(b.bbox[3], 2),
            ];
            self.annotations.push(Annotation {
                id: self.annotations.len() as u64 + 1,
                image_id,
                bbox,
                area: round(bbox[2] * bbox[3], 2),
                category_id: b.object.class.category_id(),
                track_id: b.object.id,
                iscrowd: 0,
            });
        }
    }

    /// The JSON text.
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        serde_json::to_string(self)
    }
}
