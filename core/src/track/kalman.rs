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
        let (w, h) = (
            self.mean[2].abs().max(MIN_SIDE_PX),
            self.mean[3].abs().max(MIN_SIDE_PX),
        );
        let p = STD_WEIGHT_POSITION;
        let v = STD_WEIGHT_VELOCITY;
        let std = [p * w, p * h, p * w, p * h, v * w, v * h, v * w, v * h];
        let dt = dt_frames;
        for i in 0..4 {
            self.mean[i] += dt * self.mean[i + 4];
        }
        // F P F^T with F = [[I, dt I], [0, I]] in 4x4 blocks, P = [[A, B], [B^T, C]]:
        // [[A + dt (B + B^T) + dt^2 C, B + dt C], [B^T + dt C, C]], written out to avoid two
        // dense 8x8 products per track and frame.
        let a = self.cov.fixed_view::<4, 4>(0, 0).into_owned();
        let b = self.cov.fixed_view::<4, 4>(0, 4).into_owned();
        let c = self.cov.fixed_view::<4, 4>(4, 4).into_owned();
        let b_new = b + c * dt;
        let a_new = a + (b + b.transpose()) * dt + c * (dt * dt);
        self.cov.fixed_view_mut::<4, 4>(0, 0).copy_from(&a_new);
        self.cov.fixed_view_mut::<4, 4>(0, 4).copy_from(&b_new);
        self.cov
            .fixed_view_mut::<4, 4>(4, 0)
            .copy_from(&b_new.transpose());
        for (i, s) in std.iter().enumerate() {
            self.cov[(i, i)] += s * s * dt;
        }
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
        // nalgebra inverts a 4x4 in closed form: cheaper than a Cholesky solve with eight
        // right-hand sides, and S is well conditioned (R is positive definite).
        let Some(s_inv) = s.try_inverse() else {
            return false;
        };
        // K = P H^T S^-1, with P H^T the first four columns of P.
        let pht = self.cov.fixed_columns::<4>(0).into_owned();
        let k = pht * s_inv;
        let innovation = z - proj_mean;
        self.mean += k * innovation;
        // P = P - K S K^T = P - K (P H^T)^T
        self.cov -= k * pht.transpose();
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
        // T is block-diagonal with 2x2 blocks: transform block by block.
        let blocks = [a, a_abs, a, a_abs];
        for (k, m) in blocks.iter().enumerate() {
            let x = m * Vector2::new(self.mean[2 * k], self.mean[2 * k + 1]);
            self.mean[2 * k] = x[0];
            self.mean[2 * k + 1] = x[1];
        }
        self.mean[0] = u;
        self.mean[1] = v;
        for (bi, mi) in blocks.iter().enumerate() {
            for (bj, mj) in blocks.iter().enumerate() {
                let blk = self.cov.fixed_view::<2, 2>(2 * bi, 2 * bj).into_owned();
                let out = mi * blk * mj.transpose();
                self.cov
                    .fixed_view_mut::<2, 2>(2 * bi, 2 * bj)
                    .copy_from(&out);
            }
        }
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

    /// A filter with a dense, non-trivial covariance (after a few updates and a rotation).
    fn busy_filter() -> BoxKalman {
        let mut kf = BoxKalman::initiate(&BBox::new(10.0, 20.0, 30.0, 12.0));
        for k in 1..5 {
            kf.predict(1.0);
            kf.update(&BBox::new(
                10.0 + 2.0 * k as f64,
                20.0 - k as f64,
                30.0,
                12.0 + k as f64,
            ));
        }
        kf
    }

    #[test]
    fn predict_matches_dense_formula() {
        let kf0 = busy_filter();
        let mut kf = kf0.clone();
        kf.predict(3.0);
        let mut f = BoxCov::identity();
        for i in 0..4 {
            f[(i, i + 4)] = 3.0;
        }
        let (w, h) = (kf0.mean[2], kf0.mean[3]);
        let (p, v) = (STD_WEIGHT_POSITION, STD_WEIGHT_VELOCITY);
        let std = [p * w, p * h, p * w, p * h, v * w, v * h, v * w, v * h];
        let q = BoxCov::from_diagonal(&BoxState::from_iterator(std.iter().map(|s| s * s * 3.0)));
        assert_relative_eq!(kf.mean, f * kf0.mean, epsilon = 1e-9);
        assert_relative_eq!(kf.cov, f * kf0.cov * f.transpose() + q, epsilon = 1e-9);
    }

    #[test]
    fn update_matches_dense_formula() {
        let kf0 = busy_filter();
        let mut kf = kf0.clone();
        let z = BBox::new(21.0, 14.0, 29.0, 17.0);
        assert!(kf.update(&z));
        let mut hm = SMatrix::<f64, 4, 8>::zeros();
        for i in 0..4 {
            hm[(i, i)] = 1.0;
        }
        let (w, h) = (kf0.mean[2], kf0.mean[3]);
        let p = STD_WEIGHT_POSITION;
        let r = SMatrix::<f64, 4, 4>::from_diagonal(&SVector::<f64, 4>::new(
            (p * w).powi(2),
            (p * h).powi(2),
            (p * w).powi(2),
            (p * h).powi(2),
        ));
        let s = hm * kf0.cov * hm.transpose() + r;
        let k = kf0.cov * hm.transpose() * s.try_inverse().unwrap();
        let (cx, cy) = z.center();
        let zv = SVector::<f64, 4>::new(cx, cy, z.w, z.h);
        assert_relative_eq!(kf.mean, kf0.mean + k * (zv - hm * kf0.mean), epsilon = 1e-9);
        let expected_cov = (BoxCov::identity() - k * hm) * kf0.cov;
        assert_relative_eq!(kf.cov, expected_cov, epsilon = 1e-9);
    }

    #[test]
    fn compensation_matches_dense_affine_formula() {
        let kf0 = busy_filter();
        let mut kf = kf0.clone();
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let h = Matrix3::new(
            1.1 * c,
            -1.1 * s,
            7.0,
            1.1 * s,
            1.1 * c,
            -2.0,
            0.0,
            0.0,
            1.0,
        );
        assert!(kf.apply_homography(&h));
        let a = h.fixed_view::<2, 2>(0, 0).into_owned();
        let mut t = BoxCov::zeros();
        for (k, m) in [a, a.abs(), a, a.abs()].iter().enumerate() {
            t.fixed_view_mut::<2, 2>(2 * k, 2 * k).copy_from(m);
        }
        let mut mean = t * kf0.mean;
        mean[0] += 7.0;
        mean[1] -= 2.0;
        assert_relative_eq!(kf.mean, mean, epsilon = 1e-9);
        assert_relative_eq!(kf.cov, t * kf0.cov * t.transpose(), epsilon = 1e-9);
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
