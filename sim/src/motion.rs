//! Drone and gimbal kinematics, precomputed once per scenario as a table sampled at
//! [`DRONE_DT_S`] and interpolated linearly, so that any instant can be queried in any order
//! (telemetry, frames and ground truth all read the same table).

use crate::scenario::{GimbalMode, Path2d, Scenario, YawFrame};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Sampling step of the drone/gimbal table. 50 Hz resolves gimbal swings of 200 deg/s to
/// 4 deg per step, and linear interpolation in between is exact for constant rates.
pub const DRONE_DT_S: f64 = 0.02;

/// Standard gravity, for the coordinated-turn roll and acceleration pitch.
const G_MPS2: f64 = 9.80665;

/// Multirotor forward tilt per m/s of airspeed (drag balance), a plausible quad value.
const TILT_PER_MPS_DEG: f64 = 1.2;

/// RNG stream of the gimbal program (objects use their own streams).
pub(crate) const STREAM_GIMBAL: u64 = 1;

/// The true state of the drone and its camera at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DroneState {
    /// Position in local NED (down is negative above the water).
    pub pos_ned_m: [f64; 3],
    /// Velocity in NED.
    pub vel_ned_mps: [f64; 3],
    /// Vehicle roll (right wing down positive).
    pub roll_deg: f64,
    /// Vehicle pitch (nose up positive).
    pub pitch_deg: f64,
    /// Vehicle yaw / heading, clockwise from north, in [0, 360).
    pub yaw_deg: f64,
    /// Camera heading (bearing of the optical axis), in [0, 360).
    pub cam_heading_deg: f64,
    /// Camera pitch below the horizon (90 = nadir).
    pub cam_pitch_deg: f64,
}

impl DroneState {
    /// Height above the water (= above home, which sits on the waterline).
    pub fn altitude_m(&self) -> f64 {
        -self.pos_ned_m[2]
    }

    /// Gimbal yaw relative to the vehicle heading, in (-180, 180].
    pub fn gimbal_yaw_vehicle_deg(&self) -> f64 {
        wrap_180(self.cam_heading_deg - self.yaw_deg)
    }
}

/// Precomputed drone/gimbal trajectory.
#[derive(Debug, Clone)]
pub struct DroneTrack {
    /// Samples at `k * DRONE_DT_S`; angles are unwrapped (continuous) so interpolation works.
    samples: Vec<DroneState>,
}

impl DroneTrack {
    /// Integrates the scenario's path, speed and altitude profiles and the gimbal program.
    pub fn generate(scenario: &Scenario, seed: u64) -> DroneTrack {
        let drone = &scenario.drone;
        let path = PathGeom::new(&drone.path);
        // A little beyond the end so that latency offsets never fall off the table.
        let n = ((scenario.duration_s + 2.0) / DRONE_DT_S).ceil() as usize + 1;
        let mut samples = Vec::with_capacity(n);

        let mut s_m = 0.0;
        let (mut prev_p, _) = path.at(0.0);
        let mut yaw_deg = match &drone.path {
            Path2d::Hover { heading_deg, .. } => *heading_deg,
            _ => path.at(0.0).1.to_degrees(),
        };
        let mut prev_speed = 0.0;
        let mut prev_alt =
            crate::scenario::profile_value(&drone.altitude_profile, drone.altitude_m, 0.0);
        let max_yaw_step = drone.max_yaw_rate_deg_s * DRONE_DT_S;
        let mut gimbal = GimbalProgram::new(scenario, seed);

        for k in 0..n {
            let t = k as f64 * DRONE_DT_S;
            let speed = crate::scenario::profile_value(&drone.speed_profile, drone.speed_mps, t);
            let alt = crate::scenario::profile_value(&drone.altitude_profile, drone.altitude_m, t);
            if k > 0 {
                s_m += speed * DRONE_DT_S;
            }
            let (p, tangent_rad) = path.at(s_m);
            let (vn, ve) = if k == 0 {
                (speed * tangent_rad.cos(), speed * tangent_rad.sin())
            } else {
                (
                    (p[0] - prev_p[0]) / DRONE_DT_S,
                    (p[1] - prev_p[1]) / DRONE_DT_S,
                )
            };
            let vd = if k == 0 {
                0.0
            } else {
                -(alt - prev_alt) / DRONE_DT_S
            };
            let ground_speed = vn.hypot(ve);
            let prev_yaw = yaw_deg;
            if ground_speed > 0.3 {
                let want = ve.atan2(vn).to_degrees();
                let diff = wrap_180(want - yaw_deg);
                yaw_deg += diff.clamp(-max_yaw_step, max_yaw_step);
            }
            let yaw_rate_rad_s = (yaw_deg - prev_yaw).to_radians() / DRONE_DT_S;
            let accel_fwd = if k == 0 {
                0.0
            } else {
                (ground_speed - prev_speed) / DRONE_DT_S
            };
            let roll_deg = (ground_speed * yaw_rate_rad_s / G_MPS2)
                .atan()
                .to_degrees()
                .clamp(-35.0, 35.0);
            let pitch_deg = -((accel_fwd / G_MPS2).atan().to_degrees()
                + ground_speed * TILT_PER_MPS_DEG)
                .clamp(-35.0, 35.0);
            let (cam_heading_deg, cam_pitch_deg) = gimbal.step(t, yaw_deg);
            samples.push(DroneState {
                pos_ned_m: [p[0], p[1], -alt],
                vel_ned_mps: [vn, ve, vd],
                roll_deg,
                pitch_deg,
                yaw_deg,
                cam_heading_deg,
                cam_pitch_deg,
            });
            prev_p = p;
            prev_speed = ground_speed;
            prev_alt = alt;
        }
        DroneTrack { samples }
    }

    /// The state at `t_s` (clamped to the table), linearly interpolated; angles wrapped.
    pub fn at(&self, t_s: f64) -> DroneState {
        let x = (t_s / DRONE_DT_S).max(0.0);
        let last = self.samples.len().saturating_sub(1);
        let i = (x.floor() as usize).min(last);
        let j = (i + 1).min(last);
        let f = (x - i as f64).clamp(0.0, 1.0);
        let (a, b) = (&self.samples[i], &self.samples[j]);
        let lerp = |p: f64, q: f64| p + (q - p) * f;
        let lerp3 =
            |p: [f64; 3], q: [f64; 3]| [lerp(p[0], q[0]), lerp(p[1], q[1]), lerp(p[2], q[2])];
        DroneState {
            pos_ned_m: lerp3(a.pos_ned_m, b.pos_ned_m),
            vel_ned_mps: lerp3(a.vel_ned_mps, b.vel_ned_mps),
            roll_deg: lerp(a.roll_deg, b.roll_deg),
            pitch_deg: lerp(a.pitch_deg, b.pitch_deg),
            yaw_deg: wrap_360(lerp(a.yaw_deg, b.yaw_deg)),
            cam_heading_deg: wrap_360(lerp(a.cam_heading_deg, b.cam_heading_deg)),
            cam_pitch_deg: lerp(a.cam_pitch_deg, b.cam_pitch_deg),
        }
    }
}

/// Wraps an angle to (-180, 180].
pub fn wrap_180(deg: f64) -> f64 {
    let w = deg.rem_euclid(360.0);
    if w > 180.0 {
        w - 360.0
    } else {
        w
    }
}

/// Wraps an angle to [0, 360).
pub fn wrap_360(deg: f64) -> f64 {
    let w = deg.rem_euclid(360.0);
    if w >= 360.0 {
        0.0
    } else {
        w
    }
}

/// The horizontal path as a function of arc length.
enum PathGeom {
    Hover {
        p: [f64; 2],
        heading_rad: f64,
    },
    Polyline {
        pts: Vec<[f64; 2]>,
        cum: Vec<f64>,
        looped: bool,
    },
    Circle {
        c: [f64; 2],
        r: f64,
        clockwise: bool,
    },
}

impl PathGeom {
    fn new(path: &Path2d) -> PathGeom {
        match path {
            Path2d::Hover {
                at_ne_m,
                heading_deg,
            } => PathGeom::Hover {
                p: *at_ne_m,
                heading_rad: heading_deg.to_radians(),
            },
            Path2d::Waypoints {
                points_ne_m,
                looped,
            } => {
                let mut pts = points_ne_m.clone();
                if *looped {
                    pts.push(points_ne_m[0]);
                }
                PathGeom::polyline(pts, *looped)
            }
            Path2d::Loiter {
                center_ne_m,
                radius_m,
                clockwise,
            } => PathGeom::Circle {
                c: *center_ne_m,
                r: *radius_m,
                clockwise: *clockwise,
            },
            Path2d::Lawnmower {
                start_ne_m,
                heading_deg,
                leg_length_m,
                spacing_m,
                legs,
            } => {
                let h = heading_deg.to_radians();
                let fwd = [h.cos(), h.sin()];
                let right = [-h.sin(), h.cos()];
                let mut pts = Vec::new();
                for leg in 0..*legs {
                    let off = f64::from(leg) * spacing_m;
                    let base = [
                        start_ne_m[0] + right[0] * off,
                        start_ne_m[1] + right[1] * off,
                    ];
                    let end = [
                        base[0] + fwd[0] * leg_length_m,
                        base[1] + fwd[1] * leg_length_m,
                    ];
                    if leg % 2 == 0 {
                        pts.push(base);
                        pts.push(end);
                    } else {
                        pts.push(end);
                        pts.push(base);
                    }
                }
                PathGeom::polyline(pts, false)
            }
            Path2d::ExpandingSquare {
                datum_ne_m,
                first_heading_deg,
                spacing_m,
                legs,
                clockwise,
            } => PathGeom::polyline(
                expanding_square_points(
                    *datum_ne_m,
                    *first_heading_deg,
                    *spacing_m,
                    *legs,
                    *clockwise,
                ),
                false,
            ),
            Path2d::Sector {
                datum_ne_m,
                radius_m,
                first_heading_deg,
                patterns,
                clockwise,
            } => PathGeom::polyline(
                sector_points(
                    *datum_ne_m,
                    *radius_m,
                    *first_heading_deg,
                    *patterns,
                    *clockwise,
                ),
                false,
            ),
        }
    }

    fn polyline(pts: Vec<[f64; 2]>, looped: bool) -> PathGeom {
        let mut cum = vec![0.0];
        for w in pts.windows(2) {
            let d = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
            cum.push(cum.last().copied().unwrap_or(0.0) + d);
        }
        PathGeom::Polyline { pts, cum, looped }
    }

    /// Point and tangent direction (radians from north) at arc length `s`.
    fn at(&self, s: f64) -> ([f64; 2], f64) {
        match self {
            PathGeom::Hover { p, heading_rad } => (*p, *heading_rad),
            PathGeom::Circle { c, r, clockwise } => {
                // Start due north of the centre; bearing of the drone from the centre.
                let sign = if *clockwise { 1.0 } else { -1.0 };
                let bearing = sign * s / r;
                let p = [c[0] + r * bearing.cos(), c[1] + r * bearing.sin()];
                (p, bearing + sign * std::f64::consts::FRAC_PI_2)
            }
            PathGeom::Polyline { pts, cum, looped } => {
                let total = cum.last().copied().unwrap_or(0.0);
                if total <= 0.0 || pts.len() < 2 {
                    return (pts.first().copied().unwrap_or([0.0, 0.0]), 0.0);
                }
                let s = if *looped {
                    s.rem_euclid(total)
                } else {
                    s.min(total)
                };
                let seg = cum.partition_point(|c| *c <= s).clamp(1, pts.len() - 1) - 1;
                let (a, b) = (pts[seg], pts[seg + 1]);
                let len = cum[seg + 1] - cum[seg];
                let f = if len > 0.0 {
                    ((s - cum[seg]) / len).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let p = [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f];
                ((p), (b[1] - a[1]).atan2(b[0] - a[0]))
            }
        }
    }
}

/// The point `dist_m` from `from` along bearing `bearing_deg`.
fn along(from: [f64; 2], bearing_deg: f64, dist_m: f64) -> [f64; 2] {
    let b = bearing_deg.to_radians();
    [from[0] + dist_m * b.cos(), from[1] + dist_m * b.sin()]
}

/// Corners of an IAMSAR expanding square search: from the datum, leg `i` (0-based) is
/// `(i / 2 + 1) * spacing_m` long on bearing `first_heading_deg +- 90 * i` (+ when
/// `clockwise`). Returns `legs + 1` points.
pub(crate) fn expanding_square_points(
    datum_ne_m: [f64; 2],
    first_heading_deg: f64,
    spacing_m: f64,
    legs: u32,
    clockwise: bool,
) -> Vec<[f64; 2]> {
    let turn = if clockwise { 90.0 } else { -90.0 };
    let mut pts = vec![datum_ne_m];
    let mut p = datum_ne_m;
    for i in 0..legs {
        let len = f64::from(i / 2 + 1) * spacing_m;
        p = along(p, first_heading_deg + turn * f64::from(i), len);
        pts.push(p);
    }
    pts
}

/// Corners of an IAMSAR sector search: per pattern, three equilateral triangles of side
/// `radius_m` with a corner on the datum, flown datum -> out -> across -> datum with 120 deg
/// turns; the outbound legs of a pattern are on bearings `h`, `h + 240`, `h + 120` (the
/// flight goes straight on through the datum into the next triangle), with
/// `h = first_heading_deg + 30 * pattern` (signs mirrored when not `clockwise`). Returns
/// `9 * patterns + 1` points, every third one the datum.
pub(crate) fn sector_points(
    datum_ne_m: [f64; 2],
    radius_m: f64,
    first_heading_deg: f64,
    patterns: u32,
    clockwise: bool,
) -> Vec<[f64; 2]> {
    let sign = if clockwise { 1.0 } else { -1.0 };
    let mut pts = vec![datum_ne_m];
    for pattern in 0..patterns {
        let h = first_heading_deg + sign * 30.0 * f64::from(pattern);
        for out in [0.0, 240.0, 120.0] {
            let out = h + sign * out;
            pts.push(along(datum_ne_m, out, radius_m));
            pts.push(along(datum_ne_m, out + sign * 60.0, radius_m));
            pts.push(datum_ne_m);
        }
    }
    pts
}

/// The gimbal's commanded program, stepped at `DRONE_DT_S`.
struct GimbalProgram {
    mode: GimbalMode,
    pitch_deg: f64,
    yaw_deg: f64,
    reference: YawFrame,
    sweep_yaw_amp: f64,
    sweep_pitch_amp: f64,
    sweep_period_s: f64,
    swing_interval_s: f64,
    swing_yaw_amp: f64,
    swing_pitch_amp: f64,
    swing_step_deg: f64,
    next_swing_s: f64,
    target: (f64, f64),
    current: (f64, f64),
    rng: ChaCha8Rng,
    /// Unwrapped camera heading of the previous step, so the output stays continuous.
    last_heading: Option<f64>,
}

impl GimbalProgram {
    fn new(scenario: &Scenario, seed: u64) -> GimbalProgram {
        let g = &scenario.gimbal;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(scenario.vehicle_stream(STREAM_GIMBAL));
        GimbalProgram {
            mode: g.mode,
            pitch_deg: g.pitch_deg,
            yaw_deg: g.yaw_deg,
            reference: g.yaw_reference,
            sweep_yaw_amp: g.sweep_yaw_amplitude_deg,
            sweep_pitch_amp: g.sweep_pitch_amplitude_deg,
            sweep_period_s: g.sweep_period_s,
            swing_interval_s: g.swing_interval_s,
            swing_yaw_amp: g.swing_yaw_amplitude_deg,
            swing_pitch_amp: g.swing_pitch_amplitude_deg,
            swing_step_deg: g.swing_rate_deg_s * DRONE_DT_S,
            next_swing_s: g.swing_interval_s,
            target: (0.0, 0.0),
            current: (0.0, 0.0),
            rng,
            last_heading: None,
        }
    }

    /// Camera (heading, pitch below horizon) at time `t` for vehicle yaw `vehicle_yaw_deg`.
    fn step(&mut self, t: f64, vehicle_yaw_deg: f64) -> (f64, f64) {
        let (dyaw, dpitch) = match self.mode {
            GimbalMode::Fixed => (0.0, 0.0),
            GimbalMode::Sweep => {
                let ph = std::f64::consts::TAU * t / self.sweep_period_s;
                (
                    self.sweep_yaw_amp * ph.sin(),
                    self.sweep_pitch_amp * (2.0 * ph).sin(),
                )
            }
            GimbalMode::Swings => {
                if t >= self.next_swing_s {
                    self.next_swing_s += self.swing_interval_s;
                    let y = self.rng.random_range(-1.0..=1.0) * self.swing_yaw_amp;
                    let p = self.rng.random_range(-1.0..=1.0) * self.swing_pitch_amp;
                    self.target = (y, p);
                }
                let move_towards =
                    |cur: f64, tgt: f64, step: f64| cur + (tgt - cur).clamp(-step, step);
                // Move both axes at the slew rate (a real gimbal's axes are independent).
                self.current = (
                    move_towards(self.current.0, self.target.0, self.swing_step_deg),
                    move_towards(self.current.1, self.target.1, self.swing_step_deg),
                );
                self.current
            }
        };
        let pitch = (self.pitch_deg + dpitch).clamp(0.0, 90.0);
        let yaw = self.yaw_deg + dyaw;
        let heading = match self.reference {
            YawFrame::Vehicle => vehicle_yaw_deg + yaw,
            YawFrame::Earth => yaw,
        };
        // Keep the heading continuous across steps (unwrapped) for interpolation.
        let heading = match self.last_heading {
            Some(last) => last + wrap_180(heading - last),
            None => heading,
        };
        self.last_heading = Some(heading);
        (heading, pitch)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    #[test]
    fn straight_flight_moves_at_speed_and_altitude() {
        let s = Scenario::load("calm_baseline").unwrap();
        let track = DroneTrack::generate(&s, s.seed);
        let a = track.at(10.0);
        let b = track.at(20.0);
        let dist = (b.pos_ned_m[0] - a.pos_ned_m[0]).hypot(b.pos_ned_m[1] - a.pos_ned_m[1]);
        assert!((dist - 10.0 * s.drone.speed_mps).abs() < 0.1, "{dist}");
        assert!((a.pos_ned_m[2] + s.drone.altitude_m).abs() < 1e-9);
        assert!(a.yaw_deg.abs() < 1e-6 || (a.yaw_deg - 360.0).abs() < 1e-6);
        assert!((a.cam_pitch_deg - s.gimbal.pitch_deg).abs() < 1e-9);
        // A multirotor flying forward pitches its nose down.
        assert!(a.pitch_deg < 0.0);
    }

    #[test]
    fn loiter_stays_on_circle() {
        let s = Scenario::load("gimbal_swings").unwrap();
        let track = DroneTrack::generate(&s, s.seed);
        for t in [0.0, 5.0, 17.3, 59.0] {
            let st = track.at(t);
            let r = st.pos_ned_m[0].hypot(st.pos_ned_m[1]);
            assert!((r - 30.0).abs() < 0.05, "t={t} r={r}");
        }
    }

    #[test]
    fn swings_respect_slew_rate() {
        let s = Scenario::load("gimbal_swings").unwrap();
        let track = DroneTrack::generate(&s, s.seed);
        let mut max_rate: f64 = 0.0;
        let mut prev = track.at(0.0);
        for k in 1..3000 {
            let st = track.at(k as f64 * DRONE_DT_S);
            let rate = wrap_180(st.cam_heading_deg - prev.cam_heading_deg).abs() / DRONE_DT_S;
            max_rate = max_rate.max(rate);
            prev = st;
        }
        assert!(max_rate > 100.0 && max_rate <= 180.0 + 1e-6, "{max_rate}");
    }

    fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
        (a[0] - b[0]).hypot(a[1] - b[1])
    }

    fn bearing(a: [f64; 2], b: [f64; 2]) -> f64 {
        wrap_360((b[1] - a[1]).atan2(b[0] - a[0]).to_degrees())
    }

    #[test]
    fn expanding_square_legs_grow_1_1_2_2_and_turn_90() {
        let pts = expanding_square_points([10.0, 20.0], 30.0, 50.0, 7, true);
        assert_eq!(pts.len(), 8);
        assert_eq!(pts[0], [10.0, 20.0]);
        for (i, w) in pts.windows(2).enumerate() {
            let want_len = 50.0 * (i / 2 + 1) as f64;
            assert!((dist(w[0], w[1]) - want_len).abs() < 1e-9, "leg {i}");
            let want_bearing = wrap_360(30.0 + 90.0 * i as f64);
            assert!(
                wrap_180(bearing(w[0], w[1]) - want_bearing).abs() < 1e-9,
                "leg {i}"
            );
        }
        // After legs 1, 1, 2, 2 the square is closed on the diagonal: one spacing back
        // along the first heading's opposite and one to its left.
        let p4 = pts[4];
        let back = along(along([10.0, 20.0], 30.0 + 180.0, 50.0), 30.0 - 90.0, 50.0);
        assert!(dist(p4, back) < 1e-9, "{p4:?} {back:?}");
        // Counter-clockwise mirrors the turns.
        let ccw = expanding_square_points([0.0, 0.0], 0.0, 10.0, 2, false);
        assert!(dist(ccw[2], [10.0, -10.0]) < 1e-9, "{ccw:?}");
    }

    #[test]
    fn sector_triangles_pass_the_datum_and_turn_120() {
        let datum = [-40.0, 70.0];
        let pts = sector_points(datum, 200.0, 10.0, 2, true);
        assert_eq!(pts.len(), 19);
        for (i, p) in pts.iter().enumerate() {
            if i % 3 == 0 {
                assert!(dist(*p, datum) < 1e-9, "point {i} {p:?}");
            } else {
                assert!((dist(*p, datum) - 200.0).abs() < 1e-9, "point {i}");
            }
        }
        let legs: Vec<([f64; 2], [f64; 2])> = pts.windows(2).map(|w| (w[0], w[1])).collect();
        for (i, (a, b)) in legs.iter().enumerate() {
            assert!((dist(*a, *b) - 200.0).abs() < 1e-9, "leg {i}");
        }
        // 120 deg to the right at the outer corners, straight on through the datum, 30 deg
        // into the second pattern.
        for i in 1..legs.len() {
            let turn =
                wrap_180(bearing(legs[i].0, legs[i].1) - bearing(legs[i - 1].0, legs[i - 1].1));
            let want = match (i % 3, i) {
                (0, 9) => 30.0,
                (0, _) => 0.0,
                _ => 120.0,
            };
            assert!((turn - want).abs() < 1e-9, "turn {i}: {turn}");
        }
        // The outbound legs of the first pattern cover 10, 250, 130 deg; the second pattern
        // is rotated 30 deg.
        for (leg, want) in [
            (0, 10.0),
            (3, 250.0),
            (6, 130.0),
            (9, 40.0),
            (12, 280.0),
            (15, 160.0),
        ] {
            let got = bearing(legs[leg].0, legs[leg].1);
            assert!(wrap_180(got - want).abs() < 1e-9, "leg {leg}: {got}");
        }
    }

    #[test]
    fn search_patterns_are_flown_at_speed() {
        let mut s = Scenario::load("calm_baseline").unwrap();
        s.drone.path = Path2d::Sector {
            datum_ne_m: [0.0, 0.0],
            radius_m: 100.0,
            first_heading_deg: 0.0,
            patterns: 1,
            clockwise: true,
        };
        let track = DroneTrack::generate(&s, s.seed);
        // 3 s/m along the first leg: 30 m north of the datum after 10 s.
        let p = track.at(10.0).pos_ned_m;
        assert!(dist([p[0], p[1]], [30.0, 0.0]) < 0.1, "{p:?}");
    }

    #[test]
    fn wraps() {
        assert_eq!(wrap_180(190.0), -170.0);
        assert_eq!(wrap_360(-10.0), 350.0);
        assert_eq!(wrap_180(180.0), 180.0);
    }
}
