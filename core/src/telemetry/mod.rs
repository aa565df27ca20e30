//! Telemetry, made usable for geolocation: the autopilot's clock mapped onto the companion's,
//! and the camera pose interpolated at each frame's capture time.
//!
//! Pure and synchronous (no IO, no tokio, no clock read): the MAVLink edge (`mgmot::mavlink`) turns messages
//! into the samples defined here and the pipeline asks [`PoseBuffer::pose_at`] for a frame's
//! pose. A pose that cannot be trusted (no samples, or the nearest one older than the
//! configured limit) is a typed [`NoPose`], never a silently stale value.

mod clock;
mod plausibility;
mod pose;

pub use clock::{
    ClockSource, ClockSync, RebootDetector, StampVerdict, REBOOT_JUMP_US, TIMESYNC_WINDOW,
};
pub use plausibility::{
    Implausible, PlausibilityLimits, PoseGate, PositionFix, POSITION_SLACK_M,
    QUATERNION_NORM_TOLERANCE, VELOCITY_SLACK_MPS,
};
pub use pose::{
    AttitudeSample, CameraPoseAt, GimbalSample, NoPose, PoseBuffer, PositionSample, Stream,
};

/// A time on the companion computer's monotonic clock, microseconds. Frames are stamped on it
/// (V4L2 buffer timestamps) and telemetry arrival is measured on it. The core never reads the
/// clock: the `mgmot` crate's `clock::now` does, at the edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CompanionTimeUs(pub u64);

impl CompanionTimeUs {
    /// From a `(seconds, microseconds)` pair such as a V4L2 buffer's `timeval`; negative
    /// parts (never produced by a monotonic clock) clamp to zero.
    pub fn from_timespec(sec: i64, usec: i64) -> Self {
        let us = sec.saturating_mul(1_000_000).saturating_add(usec);
        Self(u64::try_from(us).unwrap_or(0))
    }
}

/// A time on the autopilot's clock (time since its boot, as in `time_boot_ms`), microseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct AutopilotTimeUs(pub u64);

impl AutopilotTimeUs {
    /// From a MAVLink `time_boot_ms` field.
    pub fn from_boot_ms(time_boot_ms: u32) -> Self {
        Self(u64::from(time_boot_ms) * 1000)
    }

    /// This time minus `us`, saturating at the autopilot's boot.
    pub fn saturating_sub_us(self, us: u64) -> Self {
        Self(self.0.saturating_sub(us))
    }
}
