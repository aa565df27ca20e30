//! Per-track world (sea-surface) state: a constant-velocity Kalman filter in local NED
//! north/east metres, fed with the geolocated box of every matched detection.

use nalgebra::{Matrix2, Matrix4, Vector2, Vector4};
use serde::{Deserialize, Serialize};

/// A geolocated observation of a detection: its sea-surface point in the sequence's fixed
/// local NED frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorldObservation {
    /// North/east position of the box's sea-surface point, m.
    pub pos_ne_m: Vector2<f64>,
    /// Covariance of that position, m^2 (from the geolocation uncertainty).
    pub cov_ne_m2: Matrix2<f64>,
}

impl WorldObservation {
    /// The sea-surface observation of a box: its centre (the paper's `X^2D` hat, Sec. 3.2)
    /// geolocated in `frame`; `None` when the centre's ray misses the sea.
    pub fn of_box(frame: &crate::geo::FrameGeometry<'_>, bbox: &super::bbox::BBox) -> Option<Self> {
        let (cx, cy) = bbox.center();
        let g = frame.locate(crate::geo::Pixel::new(cx, cy)).ok()?;
        Some(Self {
            pos_ne_m: g.ned_m.xy(),
            cov_ne_m2: g.cov_ne_m2,
        })
    }
}

/// A track's world state: position, velocity and the full 4x4 covariance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorldState {
    /// North/east position, m.
    pub pos_ne_m: Vector2<f64>,
    /// North/east velocity, m/s.
    pub vel_ne_m_s: Vector2<f64>,
    /// Covariance of `[n, e, vn, ve]` (m^2, m^2/s, m^2/s^2 blocks).
    pub cov: Matrix4<f64>,
}

impl WorldState {
    /// Horizontal position covariance (the top-left 2x2 block), m^2.
    pub fn pos_cov_m2(&self) -> Matrix2<f64> {
        self.cov.fixed_view::<2, 2>(0, 0).into_owned()
    }
}

/// Initial velocity standard deviation, m/s: a fast boat's speed, so the first few
/// observations decide the velocity.
const INITIAL_VEL_STD_M_S: f64 = 10.0;

/// Constant-velocity filter over [`WorldState`], time in seconds.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldFilter {
    state: WorldState,
    /// Capture time of the state, s.
    time_s: f64,
}

impl WorldFilter {
    /// Starts at an observation with zero velocity.
    pub fn initiate(obs: &WorldObservation, time_s: f64) -> Self {
        let mut cov = Matrix4::zeros();
        cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&obs.cov_ne_m2);
        cov[(2, 2)] = INITIAL_VEL_STD_M_S.powi(2);
        cov[(3, 3)] = INITIAL_VEL_STD_M_S.powi(2);
        Self {
            state: WorldState {
                pos_ne_m: obs.pos_ne_m,
                vel_ne_m_s: Vector2::zeros(),
                cov,
            },
            time_s,
        }
    }

    /// Current estimate.
    pub fn state(&self) -> &WorldState {
        &self.state
    }

    /// Time of the current estimate, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The estimate predicted to `time_s` without changing the filter (for reporting a
    /// coasting track).
    pub fn predicted(&self, time_s: f64, accel_std_m_s2: f64) -> WorldState {
        let mut f = self.clone();
        f.predict(time_s, accel_std_m_s2);
        f.state
    }

    /// Predicts to `time_s` with a white-noise acceleration model of standard deviation
    /// `accel_std_m_s2`. Times in the past are ignored (the state never runs backwards).
    pub fn predict(&mut self, time_s: f64, accel_std_m_s2: f64) {
        let dt = time_s - self.time_s;
        if dt.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return;
        }
        let mut f = Matrix4::identity();
        f[(0, 2)] = dt;
        f[(1, 3)] = dt;
        let q = accel_std_m_s2 * accel_std_m_s2;
        let (dt2, dt3, dt4) = (dt * dt, dt * dt * dt, dt * dt * dt * dt);
        let mut qm = Matrix4::zeros();
        for i in 0..2 {
            qm[(i, i)] = dt4 / 4.0 * q;
            qm[(i, i + 2)] = dt3 / 2.0 * q;
            qm[(i + 2, i)] = dt3 / 2.0 * q;
            qm[(i + 2, i + 2)] = dt2 * q;
        }
        let x = f * self.vector();
        self.set_vector(&x);
        self.state.cov = f * self.state.cov * f.transpose() + qm;
        self.time_s = time_s;
    }

    /// Kalman update with a position observation (predict to its time first). Returns `false`
    /// and leaves the state untouched when the observation is not finite or its covariance
    /// makes the innovation singular.
    pub fn update(&mut self, obs: &WorldObservation) -> bool {
        if !(obs.pos_ne_m.iter().all(|v| v.is_finite())
            && obs.cov_ne_m2.iter().all(|v| v.is_finite()))
        {
            return false;
        }
        let p = self.state.cov;
        let s = p.fixed_view::<2, 2>(0, 0).into_owned() + obs.cov_ne_m2;
        let Some(s_inv) = s.try_inverse() else {
            return false;
        };
        let pht = p.fixed_columns::<2>(0).into_owned();
        let k = pht * s_inv;
        let innovation = obs.pos_ne_m - self.state.pos_ne_m;
        let x = self.vector() + k * innovation;
        self.set_vector(&x);
        let cov = p - k * s * k.transpose();
        self.state.cov = (cov + cov.transpose()) * 0.5;
        true
    }

    fn vector(&self) -> Vector4<f64> {
        let s = &self.state;
        Vector4::new(s.pos_ne_m.x, s.pos_ne_m.y, s.vel_ne_m_s.x, s.vel_ne_m_s.y)
    }

    fn set_vector(&mut self, x: &Vector4<f64>) {
        self.state.pos_ne_m = Vector2::new(x[0], x[1]);
        self.state.vel_ne_m_s = Vector2::new(x[2], x[3]);
    }
}

/// Squared Mahalanobis distance `d^T S^-1 d` of a north/east offset `d` with covariance `S`
/// (the online world stage and the ReID gates); `None` when `S` is singular or the result is
/// not finite.
pub(crate) fn mahalanobis2(d: Vector2<f64>, s: Matrix2<f64>) -> Option<f64> {
    let d2 = d.dot(&(s.try_inverse()? * d));
    (d2.is_finite() && d2 >= 0.0).then_some(d2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn obs(n: f64, e: f64) -> WorldObservation {
        WorldObservation {
            pos_ne_m: Vector2::new(n, e),
            cov_ne_m2: Matrix2::identity() * 0.25,
        }
    }

    #[test]
    fn estimates_velocity_in_metres_per_second() {
        let mut f = WorldFilter::initiate(&obs(0.0, 0.0), 0.0);
        // 0.1 s steps, 2 m/s north, -1 m/s east
        for k in 1..100 {
            let t = k as f64 * 0.1;
            f.predict(t, 0.3);
            assert!(f.update(&obs(2.0 * t, -t)));
        }
        assert_relative_eq!(f.state().vel_ne_m_s.x, 2.0, epsilon = 0.1);
        assert_relative_eq!(f.state().vel_ne_m_s.y, -1.0, epsilon = 0.1);
        let p = f.predicted(f.time_s() + 1.0, 0.3);
        assert_relative_eq!(p.pos_ne_m.x, f.state().pos_ne_m.x + 2.0, epsilon = 0.2);
        assert!(p.cov[(0, 0)] > f.state().cov[(0, 0)]);
    }

    #[test]
    fn rejects_non_finite_observation_and_ignores_past_time() {
        let mut f = WorldFilter::initiate(&obs(1.0, 1.0), 5.0);
        let before = f.clone();
        assert!(!f.update(&obs(f64::NAN, 0.0)));
        f.predict(4.0, 1.0);
        assert_eq!(f, before);
    }
}
