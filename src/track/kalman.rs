//! The BoT-SORT image-plane Kalman filter and camera-motion compensation.
//!
//! State `[cx, cy, w, h, vcx, vcy, vw, vh]` (box centre, width, height in px and their rates
//! in px per frame), constant-velocity model, noise proportional to the box size as in
//! BoT-SORT (`std_weight_position = 1/20`, `std_weight_velocity = 1/160`).

use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, Vector2};

use super::bbox::BBox;

/// 8-dimensional state vector.
pub type BoxState = SVector<f64, 8>;
/// 8x8 state covariance.
pub type BoxCov = SMatrix<f64, 8, 8>;

/// Standard deviation of the position, as a fraction of the box size (BoT-SORT 1/20).
const STD_WEIGHT_POSITION: f64 = 1.0 / 20.0;
/// Standard deviation of the velocity, as a fraction of the box size (BoT-SORT 1/160).
const STD_WEIGHT_VELOCITY: f64 = 1.0 / 160.0;
/// Smallest box side used in the noise model, px: keeps the covariance positive definite
/// when a degenerate prediction shrinks a box to zero.
const MIN_SIDE_PX: f64 = 1.0;

/// Gaussian estimate of one box's state.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxKalman {
    /// Mean state.
    pub mean: BoxState,
    /// State covariance.
    pub cov: BoxCov,
}

impl BoxKalman {
    /// Starts a filter at a measured box with zero velocity and the BoT-SORT initial spread.
    pub fn initiate(bbox: &BBox) -> Self {
        let (cx, cy) = bbox.center();
        let mean = BoxState::from_column_slice(&[cx, cy, bbox.w, bbox.h, 0.0, 0.0, 0.0, 0.0]);
        let (w, h) = (bbox.w.max(MIN_SIDE_PX), bbox.h.max(MIN_SIDE_PX));
        let p = 2.0 * STD_WEIGHT_POSITION;
        let v = 10.0 * STD_WEIGHT_VELOCITY;
        let std = [p * w, p * h, p * w, p * h, v * w, v * h, v * w, v * h];
        let cov = BoxCov::from_diagonal(&BoxState::from_iterator(std.iter().map(|s| s * s)));
        Self { mean, cov }
    }

    /// The box of the current mean.
    pub fn bbox(&self) -> BBox {
        BBox::from_center(self.mean[0], self.mean[1], self.mean[2], self.mean[3])
    }

    /// Predicts `dt_frames` frames ahead (1 for consecutive frames; more when frames were
    /// dropped). Process noise is scaled by `dt_frames` (random-walk growth).
    pub fn predict(&mut self, dt_frames: f64) {
        let mut f = BoxCov::identity();
        for i in 0..4 {
            f[(i, i + 4)] = dt_frames;
        }
        let (w, h) = (
            self.mean[2].abs().max(MIN_SIDE_PX),
            self.mean[3].abs().max(MIN_SIDE_PX),
        );
        let p = STD_WEIGHT_POSITION;
        let v = STD_WEIGHT_VELOCITY;
        let std = [p * w, p * h, p * w, p * h, v * w, v * h, v * w, v * h];
        let q = BoxCov::from_diagonal(&BoxState::from_iterator(
            std.iter().map(|s| s * s * dt_frames),
        ));
        self.mean = f * self.mean;
        self.cov = f * self.cov * f.transpose() + q;
    }

    /// Kalman update with a measured box. Returns `false` (and leaves the state untouched)
    /// when the innovation covariance is singular, which only non-finite input can cause.
    pub fn update(&mut self, bbox: &BBox) -> bool {
        let (cx, cy) = bbox.center();
        let z = SVector::<f64, 4>::new(cx, cy, bbox.w, bbox.h);
        let (w, h) = (
            self.mean[2].abs().max(MIN_SIDE_PX),
            self.mean[3].abs().max(MIN_SIDE_PX),
        );
        let p = STD_WEIGHT_POSITION;
        let r = SMatrix::<f64, 4, 4>::from_diagonal(&SVector::<f64, 4>::new(
            (p * w).powi(2),
            (p * h).powi(2),
            (p * w).powi(2),
            (p * h).powi(2),
        ));
        // H = [I4 0]: projections are the top-left blocks.
        let proj_mean = self.mean.fixed_rows::<4>(0).into_owned();
        let s = self.cov.fixed_view::<4, 4>(0, 0).into_owned() + r;
        let Some(chol) = s.cholesky() else {
            return false;
        };
        // K = P H^T S^-1, P H^T = first 4 columns of P.
        let pht = self.cov.fixed_columns::<4>(0).into_owned();
        let kt = chol.solve(&pht.transpose()); // S^-1 (P H^T)^T = K^T
        let k = kt.transpose();
        let innovation = z - proj_mean;
        self.mean += k * innovation;
        // P = P - K S K^T
        self.cov -= k * s * k.transpose();
        self.cov = (self.cov + self.cov.transpose()) * 0.5;
        true
    }

    /// Camera-motion compensation with a homography `h` mapping the previous frame's pixels to
    /// this frame's.
    ///
    /// The centre is mapped exactly; everything else uses the local affine approximation
    /// `A` (the Jacobian of `h` at the centre): centre velocity and its covariance through `A`,
    /// width/height and their rates through `|A|` (element-wise absolute value), which gives
    /// the axis-aligned bounding box of the transformed box and stays correct for large gimbal
    /// yaw (a 90 degree turn swaps width and height). For an affine `h` this is the BoT-SORT
    /// GMC update. Returns `false` (state untouched) if the centre maps to infinity.
    pub fn apply_homography(&mut self, h: &Matrix3<f64>) -> bool {
        let (cx, cy) = (self.mean[0], self.mean[1]);
        let den = h[(2, 0)] * cx + h[(2, 1)] * cy + h[(2, 2)];
        if !den.is_finite() || den.abs() < 1e-12 {
            return false;
        }
        let u = (h[(0, 0)] * cx + h[(0, 1)] * cy + h[(0, 2)]) / den;
        let v = (h[(1, 0)] * cx + h[(1, 1)] * cy + h[(1, 2)]) / den;
        // Jacobian of the projective map at (cx, cy).
        let a = Matrix2::new(
            (h[(0, 0)] - u * h[(2, 0)]) / den,
            (h[(0, 1)] - u * h[(2, 1)]) / den,
            (h[(1, 0)] - v * h[(2, 0)]) / den,
            (h[(1, 1)] - v * h[(2, 1)]) / den,
        );
        if !(u.is_finite() && v.is_finite() && a.iter().all(|x| x.is_finite())) {
            return false;
        }
        let a_abs = a.abs();
        let mut t = BoxCov::zeros();
        for (block, m) in [(0, &a), (2, &a_abs), (4, &a), (6, &a_abs)] {
            t.fixed_view_mut::<2, 2>(block, block).copy_from(m);
        }
        let mut mean = t * self.mean;
        mean[0] = u;
        mean[1] = v;
        self.mean = mean;
        self.cov = t * self.cov * t.transpose();
        true
    }

    /// Centre velocity in px per frame.
    pub fn center_velocity(&self) -> Vector2<f64> {
        Vector2::new(self.mean[4], self.mean[5])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn initiate_has_zero_velocity_and_positive_definite_cov() {
        let kf = BoxKalman::initiate(&BBox::new(10.0, 20.0, 40.0, 20.0));
        assert_relative_eq!(kf.mean[0], 30.0);
        assert_relative_eq!(kf.mean[1], 30.0);
        assert_eq!(kf.center_velocity(), Vector2::zeros());
        assert!(kf.cov.cholesky().is_some());
    }

    #[test]
    fn learns_constant_velocity() {
        let mut kf = BoxKalman::initiate(&BBox::new(0.0, 0.0, 20.0, 20.0));
        for k in 1..40 {
            kf.predict(1.0);
            assert!(kf.update(&BBox::new(3.0 * k as f64, -(k as f64), 20.0, 20.0)));
        }
        assert_relative_eq!(kf.mean[4], 3.0, epsilon = 0.05);
        assert_relative_eq!(kf.mean[5], -1.0, epsilon = 0.05);
        let before = kf.mean[0];
        kf.predict(2.0);
        assert_relative_eq!(kf.mean[0] - before, 6.0, epsilon = 0.1);
    }

    #[test]
    fn predict_grows_and_update_shrinks_uncertainty() {
        let b = BBox::new(0.0, 0.0, 20.0, 20.0);
        let mut kf = BoxKalman::initiate(&b);
        let p0 = kf.cov[(0, 0)];
        kf.predict(1.0);
        let p1 = kf.cov[(0, 0)];
        assert!(p1 > p0);
        kf.update(&b);
        assert!(kf.cov[(0, 0)] < p1);
        // covariance stays symmetric positive definite
        assert!(kf.cov.cholesky().is_some());
        assert_relative_eq!(kf.cov, kf.cov.transpose(), epsilon = 1e-12);
    }

    #[test]
    fn update_pulls_mean_towards_measurement() {
        let mut kf = BoxKalman::initiate(&BBox::new(0.0, 0.0, 20.0, 20.0));
        kf.predict(1.0);
        kf.update(&BBox::new(4.0, 0.0, 20.0, 20.0));
        assert!(kf.mean[0] > 10.0 && kf.mean[0] < 14.0);
    }

    #[test]
    fn homography_translation_and_rotation() {
        let mut kf = BoxKalman::initiate(&BBox::from_center(100.0, 50.0, 40.0, 10.0));
        kf.mean[4] = 2.0;
        let shift = Matrix3::new(1.0, 0.0, 5.0, 0.0, 1.0, -3.0, 0.0, 0.0, 1.0);
        assert!(kf.apply_homography(&shift));
        assert_relative_eq!(kf.mean[0], 105.0);
        assert_relative_eq!(kf.mean[1], 47.0);
        assert_relative_eq!(kf.mean[4], 2.0);
        // rotate by 90 degrees about the origin: (x, y) -> (-y, x); box w/h swap
        let rot = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        assert!(kf.apply_homography(&rot));
        assert_relative_eq!(kf.mean[0], -47.0);
        assert_relative_eq!(kf.mean[1], 105.0);
        assert_relative_eq!(kf.mean[2], 10.0);
        assert_relative_eq!(kf.mean[3], 40.0);
        assert_relative_eq!(kf.mean[5], 2.0); // velocity rotated too
        assert!(kf.cov.cholesky().is_some());
    }

    #[test]
    fn homography_to_infinity_is_rejected() {
        let mut kf = BoxKalman::initiate(&BBox::from_center(1.0, 0.0, 4.0, 4.0));
        let before = kf.clone();
        let h = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 1.0); // den = 0 at x = 1
        assert!(!kf.apply_homography(&h));
        assert_eq!(kf, before);
    }
}
