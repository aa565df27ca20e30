//! Telemetry that cannot be true is refused before it reaches the pose buffer.
//!
//! The autopilot's own system and component ids do not make a message true: a GNSS glitch, an
//! EKF gone wrong, a fuzzer or a forger on the link can all send positions kilometres off,
//! altitudes under the sea or a quaternion that is no rotation. A track geolocated with such a
//! pose is moved by it, and the operator is sent to the wrong water. [`PoseGate`] checks every
//! sample against what a vehicle can do:
//!
//! - the height: not below the sea surface by more than
//!   [`PlausibilityLimits::min_height_above_water_m`], not above home by more than
//!   [`PlausibilityLimits::max_height_above_home_m`];
//! - the distance from home (when home is known);
//! - the reported velocity (GLOBAL_POSITION_INT's), at most
//!   [`PlausibilityLimits::max_speed_mps`], and its change since the last accepted sample, at
//!   most [`PlausibilityLimits::max_accel_mps2`];
//! - the distance from the last accepted position: what the vehicle can fly in the time
//!   between, plus [`POSITION_SLACK_M`] for GNSS noise and EKF resets. Refused samples never
//!   become the reference, so a position held off the true one stays refused until the
//!   vehicle could have flown there; the true one is taken back at once;
//! - a gimbal quaternion's norm: within [`QUATERNION_NORM_TOLERANCE`] of 1.
//!
//! Pure: the caller passes times and home, counts the verdicts and reports episodes (the
//! runtime: STATUSTEXT and log on the first refusal, again when plausible again). The texts
//! fit one STATUSTEXT after "mgmot: telemetry refused: ".

use super::{AutopilotTimeUs, PositionSample};
use crate::geo::Geodetic;
use nalgebra::Vector3;

/// Slack added to the flyable distance between two positions (m): GNSS noise and EKF resets
/// move a reported position by metres to tens of metres without the vehicle moving.
pub const POSITION_SLACK_M: f64 = 25.0;

/// Slack added to the velocity change a vehicle can make between two samples (m/s).
pub const VELOCITY_SLACK_MPS: f64 = 3.0;

/// The shortest time the acceleration bound is applied over (s): an autopilot's velocity
/// estimate can turn a corner or reset between two 50 Hz samples faster than the vehicle
/// accelerates, so a velocity may change by `max_accel_mps2` times this at any step.
pub const ACCEL_WINDOW_S: f64 = 0.5;

/// How far from 1 a quaternion's norm may be. MAVLink gimbals send unit quaternions as
/// floats (norm within 1e-6 of 1); one further off was not written as a rotation.
pub const QUATERNION_NORM_TOLERANCE: f64 = 0.02;

/// What a vehicle can do. The defaults fit the multirotors and VTOLs of maritime search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlausibilityLimits {
    /// Fastest ground speed (m/s), horizontal.
    pub max_speed_mps: f64,
    /// Fastest climb or descent (m/s).
    pub max_vertical_speed_mps: f64,
    /// Largest acceleration (m/s²), from the reported velocities.
    pub max_accel_mps2: f64,
    /// Furthest from home (m), when home is known.
    pub max_distance_from_home_m: f64,
    /// Lowest height above the sea surface (m, negative: below it).
    pub min_height_above_water_m: f64,
    /// Highest height above home (m).
    pub max_height_above_home_m: f64,
}

impl Default for PlausibilityLimits {
    fn default() -> Self {
        Self {
            max_speed_mps: 60.0,
            max_vertical_speed_mps: 30.0,
            max_accel_mps2: 40.0,
            max_distance_from_home_m: 30_000.0,
            min_height_above_water_m: -20.0,
            max_height_above_home_m: 2_000.0,
        }
    }
}

/// Why a sample was refused.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum Implausible {
    /// Under the sea surface.
    #[error("{height_m:.0} m above the sea")]
    BelowWater {
        /// Height above the sea surface (m).
        height_m: f64,
    },
    /// Too high above home.
    #[error("{height_m:.0} m above home")]
    AboveHome {
        /// Height above home (m).
        height_m: f64,
    },
    /// Too far from home.
    #[error("{:.1} km from home", distance_m / 1e3)]
    FarFromHome {
        /// Horizontal distance from home (m).
        distance_m: f64,
    },
    /// A reported velocity faster than the vehicle flies.
    #[error("speed {speed_mps:.0} m/s")]
    Speed {
        /// Reported speed (m/s).
        speed_mps: f64,
    },
    /// A velocity change no vehicle makes.
    #[error("accel {accel_mps2:.0} m/s2")]
    Acceleration {
        /// Velocity change over the time between the samples (m/s²).
        accel_mps2: f64,
    },
    /// A position further from the last accepted one than the vehicle could fly meanwhile.
    #[error("jump {} in {dt_s:.1} s", distance(*distance_m))]
    Jump {
        /// Distance from the last accepted position (m), 3D.
        distance_m: f64,
        /// Time since it (s).
        dt_s: f64,
    },
    /// A quaternion that is no rotation.
    #[error("quaternion norm {norm:.3}")]
    QuaternionNorm {
        /// Its norm.
        norm: f64,
    },
}

fn distance(m: f64) -> String {
    if m >= 1e3 {
        format!("{:.1} km", m / 1e3)
    } else {
        format!("{m:.0} m")
    }
}

/// A position fix with the velocity reported with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionFix {
    /// The position and its time.
    pub sample: PositionSample,
    /// The velocity (NED, m/s), when the message carries one.
    pub velocity_ned_mps: Option<Vector3<f64>>,
}

/// The last accepted fix, the reference for the next.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Accepted {
    time: AutopilotTimeUs,
    position: Geodetic,
    velocity_ned_mps: Option<Vector3<f64>>,
}

/// Checks telemetry samples one by one (see the module doc).
#[derive(Debug, Clone, Default)]
pub struct PoseGate {
    limits: PlausibilityLimits,
    last: Option<Accepted>,
    refused: u64,
}

impl PoseGate {
    /// A gate with these limits and no reference yet.
    pub fn new(limits: PlausibilityLimits) -> Self {
        Self {
            limits,
            last: None,
            refused: 0,
        }
    }

    /// Samples refused so far.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// The autopilot rebooted: the reference's time is on its old clock. The next fix is
    /// checked against home and the sea only.
    pub fn reset(&mut self) {
        self.last = None;
    }

    /// Checks a position fix against the limits, home (when known) and the sea surface's
    /// altitude AMSL (when known; else home's); an accepted fix becomes the reference.
    pub fn check_position(
        &mut self,
        fix: &PositionFix,
        home: Option<&Geodetic>,
        water_amsl_m: Option<f64>,
    ) -> Result<(), Implausible> {
        let verdict = self.judge(fix, home, water_amsl_m);
        match verdict {
            Ok(()) => {
                self.last = Some(Accepted {
                    time: fix.sample.time,
                    position: fix.sample.position,
                    velocity_ned_mps: fix.velocity_ned_mps,
                })
            }
            Err(_) => self.refused += 1,
        }
        verdict
    }

    /// Checks the norm of a quaternion as it came (before normalising it).
    pub fn check_quaternion_norm(&mut self, norm: f64) -> Result<(), Implausible> {
        if norm.is_finite() && (norm - 1.0).abs() <= QUATERNION_NORM_TOLERANCE {
            Ok(())
        } else {
            self.refused += 1;
            Err(Implausible::QuaternionNorm { norm })
        }
    }

    fn judge(
        &self,
        fix: &PositionFix,
        home: Option<&Geodetic>,
        water_amsl_m: Option<f64>,
    ) -> Result<(), Implausible> {
        let l = &self.limits;
        let p = &fix.sample.position;
        if let Some(water) = water_amsl_m.or(home.map(|h| h.alt_m)) {
            let height_m = p.alt_m - water;
            if height_m < l.min_height_above_water_m {
                return Err(Implausible::BelowWater { height_m });
            }
        }
        if let Some(h) = home {
            let height_m = p.alt_m - h.alt_m;
            if height_m > l.max_height_above_home_m {
                return Err(Implausible::AboveHome { height_m });
            }
            let distance_m = horizontal_m(h, p);
            if distance_m > l.max_distance_from_home_m {
                return Err(Implausible::FarFromHome { distance_m });
            }
        }
        if let Some(v) = fix.velocity_ned_mps {
            let speed_mps = v.xy().norm();
            if speed_mps > l.max_speed_mps + VELOCITY_SLACK_MPS
                || v.z.abs() > l.max_vertical_speed_mps + VELOCITY_SLACK_MPS
            {
                return Err(Implausible::Speed {
                    speed_mps: v.norm(),
                });
            }
        }
        let Some(last) = &self.last else {
            return Ok(());
        };
        let dt_s = fix.sample.time.0.saturating_sub(last.time.0) as f64 / 1e6;
        let horizontal = horizontal_m(&last.position, p);
        let vertical = (p.alt_m - last.position.alt_m).abs();
        if horizontal > l.max_speed_mps * dt_s + POSITION_SLACK_M
            || vertical > l.max_vertical_speed_mps * dt_s + POSITION_SLACK_M
        {
            return Err(Implausible::Jump {
                distance_m: horizontal.hypot(vertical),
                dt_s,
            });
        }
        if let (Some(v), Some(v0)) = (fix.velocity_ned_mps, last.velocity_ned_mps) {
            let dv = (v - v0).norm();
            if dv > l.max_accel_mps2 * dt_s.max(ACCEL_WINDOW_S) + VELOCITY_SLACK_MPS {
                return Err(Implausible::Acceleration {
                    accel_mps2: dv / dt_s.max(1e-3),
                });
            }
        }
        Ok(())
    }
}

/// Horizontal distance between two points (m), on the local sphere: exact enough for limits of
/// tens of metres to tens of kilometres, and finite for any pair of valid coordinates.
fn horizontal_m(a: &Geodetic, b: &Geodetic) -> f64 {
    const EARTH_RADIUS_M: f64 = 6_371_000.0;
    let (la, lb) = (a.lat_deg.to_radians(), b.lat_deg.to_radians());
    let dlat = lb - la;
    let dlon = (b.lon_deg - a.lon_deg).to_radians();
    let h = (dlat / 2.0).sin().powi(2) + la.cos() * lb.cos() * (dlon / 2.0).sin().powi(2);
    2.0 * EARTH_RADIUS_M * h.sqrt().min(1.0).asin()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const HOME: Geodetic = Geodetic {
        lat_deg: 54.0,
        lon_deg: 10.0,
        alt_m: 2.0,
    };

    /// A fix `north_m` north of home, `alt_m` AMSL, at `t_s`, hovering.
    fn fix(t_s: f64, north_m: f64, alt_m: f64) -> PositionFix {
        PositionFix {
            sample: PositionSample {
                time: AutopilotTimeUs((t_s * 1e6) as u64),
                position: Geodetic {
                    lat_deg: HOME.lat_deg + north_m / 111_195.0,
                    lon_deg: HOME.lon_deg,
                    alt_m,
                },
            },
            velocity_ned_mps: Some(Vector3::zeros()),
        }
    }

    fn gate() -> PoseGate {
        PoseGate::new(PlausibilityLimits::default())
    }

    #[test]
    fn a_flight_is_accepted() {
        let mut g = gate();
        // 15 m/s north at 50 Hz for a minute, 40 m up.
        for k in 0..3000 {
            let t = k as f64 / 50.0;
            let mut f = fix(t, 15.0 * t, 42.0);
            f.velocity_ned_mps = Some(Vector3::new(15.0, 0.0, 0.0));
            assert_eq!(
                g.check_position(&f, Some(&HOME), None),
                Ok(()),
                "sample {k}"
            );
        }
        assert_eq!(g.refused(), 0);
    }

    #[test]
    fn a_position_jumping_50_km_every_other_message_is_refused_every_time() {
        let mut g = gate();
        for k in 0..1000 {
            let t = k as f64 / 10.0;
            let north = if k % 2 == 1 { 50_000.0 } else { 100.0 };
            let r = g.check_position(&fix(t, north, 40.0), Some(&HOME), None);
            assert_eq!(r.is_err(), k % 2 == 1, "sample {k}: {r:?}");
        }
        // Without home the jump alone refuses it.
        let mut g = gate();
        for k in 0..1000 {
            let t = k as f64 / 10.0;
            let north = if k % 2 == 1 { 50_000.0 } else { 100.0 };
            let r = g.check_position(&fix(t, north, 40.0), None, Some(0.0));
            assert_eq!(r.is_err(), k % 2 == 1, "sample {k}: {r:?}");
            if k % 2 == 1 {
                assert!(matches!(r, Err(Implausible::Jump { .. })), "{r:?}");
            }
        }
    }

    #[test]
    fn a_position_held_50_km_off_stays_refused_and_the_true_one_is_taken_back() {
        let mut g = gate();
        assert!(g
            .check_position(&fix(0.0, 0.0, 40.0), Some(&HOME), None)
            .is_ok());
        for k in 1..=6000 {
            let r = g.check_position(&fix(k as f64 / 10.0, 50_000.0, 40.0), Some(&HOME), None);
            assert!(r.is_err(), "sample {k} accepted");
        }
        assert!(g
            .check_position(&fix(600.1, 20.0, 40.0), Some(&HOME), None)
            .is_ok());
    }

    #[test]
    fn altitude_under_the_sea_or_far_above_home_is_refused() {
        let mut g = gate();
        assert_eq!(
            g.check_position(&fix(0.0, 0.0, -1000.0), Some(&HOME), None),
            Err(Implausible::BelowWater { height_m: -1002.0 })
        );
        // The water level, when configured, is the reference rather than home.
        assert!(g
            .check_position(&fix(0.1, 0.0, -5.0), Some(&HOME), Some(-10.0))
            .is_ok());
        assert!(matches!(
            g.check_position(&fix(0.2, 0.0, 5000.0), Some(&HOME), None),
            Err(Implausible::AboveHome { .. })
        ));
    }

    #[test]
    fn speed_and_acceleration_are_bounded() {
        let mut g = gate();
        let mut f = fix(0.0, 0.0, 40.0);
        f.velocity_ned_mps = Some(Vector3::new(300.0, 0.0, 0.0));
        assert!(matches!(
            g.check_position(&f, Some(&HOME), None),
            Err(Implausible::Speed { .. })
        ));
        f.velocity_ned_mps = Some(Vector3::new(10.0, 0.0, 0.0));
        assert!(g.check_position(&f, Some(&HOME), None).is_ok());
        // A corner of a 12 m/s path turned between two samples is no refusal.
        let mut f = fix(0.02, 0.2, 40.0);
        f.velocity_ned_mps = Some(Vector3::new(0.0, 12.0, 0.0));
        assert!(g.check_position(&f, Some(&HOME), None).is_ok());
        // 12 m/s east -> 45 m/s west in 20 ms.
        let mut f = fix(0.04, 0.4, 40.0);
        f.velocity_ned_mps = Some(Vector3::new(0.0, -45.0, 0.0));
        assert!(matches!(
            g.check_position(&f, Some(&HOME), None),
            Err(Implausible::Acceleration { .. })
        ));
    }

    #[test]
    fn a_reboot_drops_the_reference_time() {
        let mut g = gate();
        assert!(g.check_position(&fix(300.0, 0.0, 40.0), None, None).is_ok());
        // The new boot's first fix is stamped 1 s: no time has passed on any one clock.
        g.reset();
        assert!(g.check_position(&fix(1.0, 10.0, 40.0), None, None).is_ok());
    }

    #[test]
    fn every_reason_fits_one_statustext() {
        let reasons = [
            Implausible::BelowWater { height_m: -1002.0 },
            Implausible::AboveHome { height_m: 19_999.0 },
            Implausible::FarFromHome {
                distance_m: 8_374_000.0,
            },
            Implausible::Speed { speed_mps: 999.0 },
            Implausible::Acceleration {
                accel_mps2: 99_999.0,
            },
            Implausible::Jump {
                distance_m: 8_374_000.0,
                dt_s: 99.9,
            },
            Implausible::QuaternionNorm { norm: 1.2 },
        ];
        for r in reasons {
            let text = format!("mgmot: telemetry refused: {r}");
            assert!(text.len() <= 50, "{text} ({} chars)", text.len());
        }
    }

    #[test]
    fn quaternion_norms() {
        let mut g = gate();
        assert!(g.check_quaternion_norm(1.0 + 1e-6).is_ok());
        assert!(g.check_quaternion_norm(1.2).is_err());
        assert!(g.check_quaternion_norm(0.9).is_err());
        assert!(g.check_quaternion_norm(f64::NAN).is_err());
        assert_eq!(g.refused(), 3);
    }

    proptest! {
        /// Whatever garbage comes between them, a vehicle hovering near home at 10 Hz is
        /// accepted at every one of its own samples, and nothing refused is ever the
        /// reference: garbage is never accepted right after garbage that jumped.
        #[test]
        fn garbage_never_displaces_the_truth(
            garbage in proptest::collection::vec((-90.0f64..90.0, -180.0f64..180.0, -5000.0f64..20000.0), 1..100)
        ) {
            let mut g = gate();
            for (k, (lat, lon, alt)) in garbage.iter().enumerate() {
                let t = k as f64 / 10.0;
                prop_assert!(g.check_position(&fix(t, 5.0, 40.0), Some(&HOME), None).is_ok());
                let bad = PositionFix {
                    sample: PositionSample {
                        time: AutopilotTimeUs(((t + 0.05) * 1e6) as u64),
                        position: Geodetic { lat_deg: *lat, lon_deg: *lon, alt_m: *alt },
                    },
                    velocity_ned_mps: None,
                };
                let near = horizontal_m(&HOME, &bad.sample.position) < 40.0
                    && (bad.sample.position.alt_m - 40.0).abs() < 27.0;
                if g.check_position(&bad, Some(&HOME), None).is_ok() {
                    prop_assert!(near, "accepted {:?}", bad.sample.position);
                }
            }
        }
    }
}
