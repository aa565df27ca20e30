//! CAMERA_FOV_STATUS from the frame step (`outputs.camera_fov_hz`): where the camera is and
//! looks, for a ground station's footprint.

use super::telemetry::FramePose;
use crate::geo::{CameraView, Geolocator, Pixel};
use crate::mavlink::Outputs;
use crate::telemetry::AutopilotTimeUs;
use std::time::Duration;

/// Sends CAMERA_FOV_STATUS at its rate, from frames with a pose.
pub(super) struct CameraFovStep {
    every_us: u64,
    last_us: Option<u64>,
}

impl CameraFovStep {
    /// `None` when `outputs.camera_fov_hz` is 0.
    pub fn new(every: Option<Duration>) -> Option<Self> {
        every.map(|e| Self {
            every_us: u64::try_from(e.as_micros()).unwrap_or(u64::MAX),
            last_us: None,
        })
    }

    /// Sends the frame's view when due. `now_us` is the tracker's clock (which the rate is
    /// measured on), `size` the frame's size (px).
    pub fn frame(
        &mut self,
        outputs: &Outputs,
        now_us: u64,
        pose: &FramePose,
        geolocator: Option<&Geolocator>,
        (width_px, height_px): (u32, u32),
    ) {
        if self
            .last_us
            .is_some_and(|at| now_us.saturating_sub(at) < self.every_us && now_us >= at)
        {
            return;
        }
        let (Some(g), Ok(meta)) = (geolocator, &pose.meta) else {
            return;
        };
        let i = &g.camera().intrinsics;
        let fov_deg = |px: u32, f: f64| 2.0 * (f64::from(px) / (2.0 * f)).atan().to_degrees();
        let view =
            CameraView::of_frame(meta, fov_deg(i.width_px, i.fx), fov_deg(i.height_px, i.fy));
        let centre = g.frame(meta).ok().and_then(|f| {
            f.locate(Pixel::new(
                f64::from(width_px) / 2.0,
                f64::from(height_px) / 2.0,
            ))
            .ok()
            .map(|l| l.geodetic)
        });
        outputs.camera_fov(
            pose.frame_time.unwrap_or(AutopilotTimeUs(0)),
            &view,
            centre.as_ref(),
        );
        self.last_us = Some(now_us);
    }
}
