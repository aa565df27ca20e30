//! The camera pose at a frame's capture time, from separately timed telemetry streams:
//! position (GLOBAL_POSITION_INT), vehicle attitude (ATTITUDE) and gimbal attitude
//! (GIMBAL_DEVICE_ATTITUDE_STATUS, MOUNT_ORIENTATION or MOUNT_STATUS). Each stream is
//! interpolated on its own at the query time (position linearly, attitudes by slerp), then the
//! gimbal is composed with the vehicle attitude as its yaw frame requires.

use super::AutopilotTimeUs;
use crate::geo::attitude::{camera_from_gimbal_quaternion, GimbalYawFrame};
use crate::geo::Geodetic;
use nalgebra::UnitQuaternion;
use std::collections::VecDeque;

/// Samples kept per stream: at 50 Hz, four seconds; far more than any camera latency.
pub const STREAM_CAPACITY: usize = 200;

/// A position fix (GLOBAL_POSITION_INT).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionSample {
    /// When the autopilot measured it.
    pub time: AutopilotTimeUs,
    /// Position; `alt_m` above mean sea level.
    pub position: Geodetic,
}

/// A vehicle attitude (ATTITUDE / ATTITUDE_QUATERNION).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeSample {
    /// When the autopilot measured it.
    pub time: AutopilotTimeUs,
    /// Vehicle body (FRD) -> NED.
    pub attitude: UnitQuaternion<f64>,
}

/// A gimbal attitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GimbalSample {
    /// When the autopilot (or gimbal) measured it.
    pub time: AutopilotTimeUs,
    /// Gimbal FRD attitude, relative to the frame `frame` names.
    pub attitude: UnitQuaternion<f64>,
    /// What the quaternion is relative to (earth, vehicle yaw, or the whole vehicle body).
    pub frame: GimbalYawFrame,
}

/// Which telemetry stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// GLOBAL_POSITION_INT.
    Position,
    /// ATTITUDE.
    VehicleAttitude,
    /// The gimbal attitude messages.
    Gimbal,
}

impl std::fmt::Display for Stream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Stream::Position => "position",
            Stream::VehicleAttitude => "vehicle attitude",
            Stream::Gimbal => "gimbal attitude",
        })
    }
}

/// Why no pose can be given for a time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum NoPose {
    /// The stream never delivered a sample.
    #[error("no {0} telemetry received")]
    NoSamples(Stream),
    /// The nearest sample of the stream is further from the query time than the limit.
    #[error("{stream} telemetry is stale: nearest sample {age_us} us from the frame time")]
    Stale {
        /// The stream.
        stream: Stream,
        /// Distance from the query time to the nearest sample (µs).
        age_us: u64,
    },
}

/// The camera pose at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPoseAt {
    /// Camera position (the vehicle's; lever arms of a few cm are ignored); `alt_m` AMSL.
    pub position: Geodetic,
    /// Vehicle body (FRD) -> NED.
    pub vehicle_attitude: UnitQuaternion<f64>,
    /// Camera optical frame -> NED.
    pub camera_attitude: UnitQuaternion<f64>,
}

/// How one stream's value is blended between two samples.
trait Interpolate: Copy {
    fn time(&self) -> AutopilotTimeUs;
    /// The value a fraction `s` (0..=1) of the way from `self` to `next`.
    fn blend(&self, next: &Self, s: f64) -> Self;
}

impl Interpolate for PositionSample {
    fn time(&self) -> AutopilotTimeUs {
        self.time
    }
    fn blend(&self, next: &Self, s: f64) -> Self {
        let (a, b) = (self.position, next.position);
        // Longitude across the antimeridian: go the short way round.
        let mut dlon = b.lon_deg - a.lon_deg;
        if dlon > 180.0 {
            dlon -= 360.0;
        } else if dlon < -180.0 {
            dlon += 360.0;
        }
        let mut lon = a.lon_deg + s * dlon;
        if lon > 180.0 {
            lon -= 360.0;
        } else if lon < -180.0 {
            lon += 360.0;
        }
        PositionSample {
            time: self.time,
            position: Geodetic {
                lat_deg: a.lat_deg + s * (b.lat_deg - a.lat_deg),
                lon_deg: lon,
                alt_m: a.alt_m + s * (b.alt_m - a.alt_m),
            },
        }
    }
}

/// Slerp that never panics: two attitudes half a turn apart have no unique path between them,
/// and the nearer sample is then the honest answer.
fn slerp(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, s: f64) -> UnitQuaternion<f64> {
    a.try_slerp(b, s, 1e-9)
        .unwrap_or(if s < 0.5 { *a } else { *b })
}

impl Interpolate for AttitudeSample {
    fn time(&self) -> AutopilotTimeUs {
        self.time
    }
    fn blend(&self, next: &Self, s: f64) -> Self {
        AttitudeSample {
            time: self.time,
            attitude: slerp(&self.attitude, &next.attitude, s),
        }
    }
}

impl Interpolate for GimbalSample {
    fn time(&self) -> AutopilotTimeUs {
        self.time
    }
    fn blend(&self, next: &Self, s: f64) -> Self {
        if self.frame != next.frame {
            // The gimbal switched its yaw reference between the samples: no blend is
            // meaningful, take the nearer one.
            return if s < 0.5 { *self } else { *next };
        }
        GimbalSample {
            time: self.time,
            attitude: slerp(&self.attitude, &next.attitude, s),
            frame: self.frame,
        }
    }
}

/// One stream's recent samples, in time order.
#[derive(Debug, Clone)]
struct Series<T> {
    samples: VecDeque<T>,
}

impl<T> Default for Series<T> {
    fn default() -> Self {
        Self {
            samples: VecDeque::new(),
        }
    }
}

impl<T: Interpolate> Series<T> {
    fn push(&mut self, sample: T) {
        // Out-of-order or repeated stamps (a message relayed twice) would break the bracketing.
        // A stamp far in the past is no reboot by itself (a stray or forged message): only a
        // confirmed reboot empties the history ([`PoseBuffer::clear`]).
        if self
            .samples
            .back()
            .is_some_and(|last| sample.time() <= last.time())
        {
            return;
        }
        if self.samples.len() == STREAM_CAPACITY {
            self.samples.pop_front();
        }
        self.samples.push_back(sample);
    }

    /// The value at `t`: interpolated between the bracketing samples, or the nearest sample
    /// when `t` is outside the history; either way the nearest sample must be within
    /// `max_age_us` of `t`.
    fn at(&self, t: AutopilotTimeUs, max_age_us: u64, stream: Stream) -> Result<T, NoPose> {
        let (Some(first), Some(last)) = (self.samples.front(), self.samples.back()) else {
            return Err(NoPose::NoSamples(stream));
        };
        let stale = |nearest: &T| {
            let age_us = nearest.time().0.abs_diff(t.0);
            if age_us > max_age_us {
                Err(NoPose::Stale { stream, age_us })
            } else {
                Ok(*nearest)
            }
        };
        if t <= first.time() {
            return stale(first);
        }
        if t >= last.time() {
            return stale(last);
        }
        // First sample after t; index >= 1 because t > first.time().
        let k = self.samples.partition_point(|s| s.time() <= t);
        let (a, b) = (&self.samples[k - 1], &self.samples[k]);
        let nearest = if t.0 - a.time().0 <= b.time().0 - t.0 {
            a
        } else {
            b
        };
        stale(nearest)?;
        let span = (b.time().0 - a.time().0) as f64;
        let s = (t.0 - a.time().0) as f64 / span;
        Ok(a.blend(b, s))
    }

    fn latest(&self) -> Option<AutopilotTimeUs> {
        self.samples.back().map(Interpolate::time)
    }
}

/// Recent telemetry, queried for the camera pose at frame times.
#[derive(Debug, Clone)]
pub struct PoseBuffer {
    /// Largest distance (µs) from a query time to the nearest sample of each stream for the
    /// stream to count: beyond it the pose is [`NoPose::Stale`].
    max_age_us: u64,
    positions: Series<PositionSample>,
    attitudes: Series<AttitudeSample>,
    gimbals: Series<GimbalSample>,
    /// A camera hard-mounted to the body (no gimbal telemetry): its FRD attitude relative to
    /// the vehicle body. `None` means gimbal telemetry is required.
    fixed_mount: Option<UnitQuaternion<f64>>,
}

impl PoseBuffer {
    /// An empty buffer with the staleness limit `max_age_us`; the camera's attitude comes from
    /// gimbal telemetry.
    pub fn new(max_age_us: u64) -> Self {
        Self {
            max_age_us,
            positions: Series::default(),
            attitudes: Series::default(),
            gimbals: Series::default(),
            fixed_mount: None,
        }
    }

    /// Uses a fixed camera mount (FRD relative to the vehicle body) instead of gimbal telemetry.
    pub fn with_fixed_mount(mut self, mount_frd_in_body: UnitQuaternion<f64>) -> Self {
        self.fixed_mount = Some(mount_frd_in_body);
        self
    }

    /// The staleness limit (µs).
    pub fn max_age_us(&self) -> u64 {
        self.max_age_us
    }

    /// Forgets every sample: the autopilot rebooted (a confirmed
    /// [`super::StampVerdict::Rebooted`]) and the history is on its old clock.
    pub fn clear(&mut self) {
        self.positions.samples.clear();
        self.attitudes.samples.clear();
        self.gimbals.samples.clear();
    }

    /// Adds a position fix.
    pub fn push_position(&mut self, s: PositionSample) {
        self.positions.push(s);
    }

    /// Adds a vehicle attitude.
    pub fn push_attitude(&mut self, s: AttitudeSample) {
        self.attitudes.push(s);
    }

    /// Adds a gimbal attitude.
    pub fn push_gimbal(&mut self, s: GimbalSample) {
        self.gimbals.push(s);
    }

    /// The newest sample time of each stream that has one (for health reporting).
    pub fn latest(&self, stream: Stream) -> Option<AutopilotTimeUs> {
        match stream {
            Stream::Position => self.positions.latest(),
            Stream::VehicleAttitude => self.attitudes.latest(),
            Stream::Gimbal => self.gimbals.latest(),
        }
    }

    /// The camera pose at `t` (already corrected for the camera's latency by the caller), or
    /// why there is none.
    pub fn pose_at(&self, t: AutopilotTimeUs) -> Result<CameraPoseAt, NoPose> {
        let position = self.positions.at(t, self.max_age_us, Stream::Position)?;
        let (gimbal, frame) = match self.fixed_mount {
            Some(q) => (q, GimbalYawFrame::Body),
            None => {
                let g = self.gimbals.at(t, self.max_age_us, Stream::Gimbal)?;
                (g.attitude, g.frame)
            }
        };
        let vehicle = match frame {
            // An earth-frame gimbal needs no vehicle attitude; use it if there is one.
            GimbalYawFrame::Earth => self
                .attitudes
                .at(t, self.max_age_us, Stream::VehicleAttitude)
                .map(|a| a.attitude)
                .unwrap_or_else(|_| UnitQuaternion::identity()),
            _ => {
                self.attitudes
                    .at(t, self.max_age_us, Stream::VehicleAttitude)?
                    .attitude
            }
        };
        Ok(CameraPoseAt {
            position: position.position,
            vehicle_attitude: vehicle,
            camera_attitude: camera_from_gimbal_quaternion(&gimbal, frame, &vehicle),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::attitude::camera_from_heading_pitch_deg;
    use nalgebra::Vector3;
    use proptest::prelude::*;

    fn pos(t_us: u64, lat: f64, lon: f64, alt: f64) -> PositionSample {
        PositionSample {
            time: AutopilotTimeUs(t_us),
            position: Geodetic {
                lat_deg: lat,
                lon_deg: lon,
                alt_m: alt,
            },
        }
    }

    fn yaw(t_us: u64, yaw_rad: f64) -> AttitudeSample {
        AttitudeSample {
            time: AutopilotTimeUs(t_us),
            attitude: UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad),
        }
    }

    fn earth_gimbal(t_us: u64, pitch_rad: f64) -> GimbalSample {
        GimbalSample {
            time: AutopilotTimeUs(t_us),
            attitude: UnitQuaternion::from_euler_angles(0.0, pitch_rad, 0.0),
            frame: GimbalYawFrame::Earth,
        }
    }

    fn buffer() -> PoseBuffer {
        let mut b = PoseBuffer::new(100_000);
        b.push_position(pos(1_000_000, 47.0, 9.0, 400.0));
        b.push_position(pos(1_100_000, 47.001, 9.002, 410.0));
        b.push_attitude(yaw(1_000_000, 0.0));
        b.push_attitude(yaw(1_100_000, 0.2));
        b.push_gimbal(earth_gimbal(1_000_000, -0.5));
        b.push_gimbal(earth_gimbal(1_100_000, -0.7));
        b
    }

    #[test]
    fn interpolates_position_linearly_and_attitude_by_slerp() {
        let p = buffer().pose_at(AutopilotTimeUs(1_025_000)).unwrap();
        assert!((p.position.lat_deg - 47.00025).abs() < 1e-12);
        assert!((p.position.lon_deg - 9.0005).abs() < 1e-12);
        assert!((p.position.alt_m - 402.5).abs() < 1e-9);
        let (_, _, y) = p.vehicle_attitude.euler_angles();
        assert!((y - 0.05).abs() < 1e-9);
        // Earth-frame gimbal pitched -0.55 rad (nose-up positive in FRD): the optical axis (z)
        // points north, 0.55 rad below the horizon.
        let fwd = p.camera_attitude * Vector3::z();
        assert!((fwd.z - 0.55f64.sin()).abs() < 1e-9, "{fwd}");
        assert!(fwd.y.abs() < 1e-9 && fwd.x > 0.0, "{fwd}");
    }

    #[test]
    fn stale_and_missing_are_typed() {
        let b = buffer();
        assert_eq!(
            b.pose_at(AutopilotTimeUs(1_300_000)),
            Err(NoPose::Stale {
                stream: Stream::Position,
                age_us: 200_000
            })
        );
        // Within the limit past the newest sample: the newest sample is held.
        let p = b.pose_at(AutopilotTimeUs(1_150_000)).unwrap();
        assert_eq!(p.position.alt_m, 410.0);
        let mut no_gimbal = PoseBuffer::new(100_000);
        no_gimbal.push_position(pos(0, 0.0, 0.0, 0.0));
        assert_eq!(
            no_gimbal.pose_at(AutopilotTimeUs(0)),
            Err(NoPose::NoSamples(Stream::Gimbal))
        );
    }

    #[test]
    fn gap_in_the_middle_is_stale() {
        let mut b = PoseBuffer::new(50_000);
        b.push_position(pos(0, 0.0, 0.0, 0.0));
        b.push_position(pos(1_000_000, 0.0, 0.0, 0.0));
        assert!(matches!(
            b.positions
                .at(AutopilotTimeUs(500_000), 50_000, Stream::Position),
            Err(NoPose::Stale { .. })
        ));
    }

    #[test]
    fn vehicle_frame_gimbal_composes_vehicle_yaw() {
        let mut b = PoseBuffer::new(100_000);
        b.push_position(pos(0, 0.0, 0.0, 30.0));
        b.push_attitude(AttitudeSample {
            time: AutopilotTimeUs(0),
            attitude: UnitQuaternion::from_euler_angles(0.1, 0.0, std::f64::consts::FRAC_PI_2),
        });
        b.push_gimbal(GimbalSample {
            time: AutopilotTimeUs(0),
            attitude: UnitQuaternion::from_euler_angles(0.0, -std::f64::consts::FRAC_PI_4, 0.0),
            frame: GimbalYawFrame::Vehicle,
        });
        let p = b.pose_at(AutopilotTimeUs(0)).unwrap();
        let expected = camera_from_heading_pitch_deg(90.0, 45.0, 0.0);
        assert!(p.camera_attitude.angle_to(&expected) < 1e-9);
    }

    #[test]
    fn fixed_mount_needs_no_gimbal() {
        let mut b = PoseBuffer::new(100_000)
            .with_fixed_mount(UnitQuaternion::from_euler_angles(0.0, -1.0, 0.0));
        b.push_position(pos(0, 0.0, 0.0, 30.0));
        b.push_attitude(yaw(0, 0.0));
        assert!(b.pose_at(AutopilotTimeUs(0)).is_ok());
    }

    #[test]
    fn out_of_order_samples_are_ignored_and_only_a_confirmed_reboot_clears() {
        let mut b = PoseBuffer::new(100_000);
        b.push_position(pos(10_000_000, 1.0, 0.0, 0.0));
        b.push_position(pos(9_990_000, 2.0, 0.0, 0.0));
        assert_eq!(b.positions.samples.len(), 1);
        // A lone stamp near zero (stray, forged) neither clears the history nor joins it.
        b.push_position(pos(1_000, 3.0, 0.0, 0.0));
        assert_eq!(b.positions.samples.len(), 1);
        assert_eq!(
            b.latest(Stream::Position),
            Some(AutopilotTimeUs(10_000_000))
        );
        b.clear();
        b.push_position(pos(1_000, 3.0, 0.0, 0.0));
        assert_eq!(b.latest(Stream::Position), Some(AutopilotTimeUs(1_000)));
    }

    proptest! {
        /// At a sample's own time the sample comes back; between two samples the position lies
        /// between them and the attitude's angle to each end is its share of the whole turn.
        #[test]
        fn interpolation_invariants(
            dt in 1u64..100_000, s in 0.0f64..=1.0,
            lat0 in -80.0f64..80.0, dlat in -0.01f64..0.01,
            y0 in -3.0f64..3.0, dy in -1.5f64..1.5,
        ) {
            let mut series = Series::default();
            series.push(pos(1_000, lat0, 0.0, 0.0));
            series.push(pos(1_000 + dt, lat0 + dlat, 0.0, 0.0));
            let t = 1_000 + (s * dt as f64).round() as u64;
            let p = series.at(AutopilotTimeUs(t), u64::MAX, Stream::Position).unwrap();
            let lo = lat0.min(lat0 + dlat) - 1e-12;
            let hi = lat0.max(lat0 + dlat) + 1e-12;
            prop_assert!(p.position.lat_deg >= lo && p.position.lat_deg <= hi);
            let back = series.at(AutopilotTimeUs(1_000), u64::MAX, Stream::Position).unwrap();
            prop_assert_eq!(back.position.lat_deg, lat0);

            let mut att = Series::default();
            att.push(yaw(1_000, y0));
            att.push(yaw(1_000 + dt, y0 + dy));
            let a = att.at(AutopilotTimeUs(t), u64::MAX, Stream::VehicleAttitude).unwrap();
            let (q0, q1) = (att.samples[0].attitude, att.samples[1].attitude);
            let whole = q0.angle_to(&q1);
            let frac = (t - 1_000) as f64 / dt as f64;
            prop_assert!((a.attitude.angle_to(&q0) - frac * whole).abs() < 1e-6);
            prop_assert!((a.attitude.angle_to(&q1) - (1.0 - frac) * whole).abs() < 1e-6);
        }
    }
}
