//! The radius of the circle that holds a horizontal position with a given probability: what
//! Cursor-on-Target's `ce` and a map's uncertainty circle show.
//!
//! For a zero-mean bivariate normal with covariance eigenvalues `l1 >= l2 >= 0` (m^2), write
//! the position as `(sqrt(l1) u, sqrt(l2) v)` with `(u, v)` standard normal, in polar
//! coordinates `(rho, phi)`. Integrating `rho` out leaves
//! `P(r) = 1/(2 pi) * integral over phi of (1 - exp(-r^2 / (2 k(phi))))`,
//! `k(phi) = l1 cos^2(phi) + l2 sin^2(phi)`: a smooth, periodic integrand for every ratio of the
//! axes (even `l2 = 0`), so the trapezoid rule over a quarter turn converges fast. The radius
//! for a probability is found by Newton's method inside a bracket (a few microseconds: it
//! runs for every reported track). The two limits are exact: a circular error
//! (`l1 = l2 = s^2`) gives `s * sqrt(-2 ln(1 - p))` (2.4477 s at 95 %), a degenerate one
//! (`l2 = 0`) the normal quantile (1.95996 `sqrt(l1)` at 95 %).

use nalgebra::Matrix2;

/// Angle samples of the trapezoid rule over a quarter turn (the integrand is symmetric in
/// both axes; 32 keep the probability within 1e-4 of the sampled truth at every axis ratio,
/// see the property test).
const ANGLE_SAMPLES: usize = 32;

/// The radius (m) of the circle around the estimate that holds the true position with
/// probability `p` (0 < p < 1), for a horizontal position covariance `cov` (m^2). A covariance
/// that is not finite or not positive semi-definite gives `None`; a zero covariance gives 0.
pub fn circular_error_m(cov: &Matrix2<f64>, p: f64) -> Option<f64> {
    if !(p > 0.0 && p < 1.0) || cov.iter().any(|v| !v.is_finite()) {
        return None;
    }
    // Eigenvalues of the symmetric part, in closed form.
    let (a, b, d) = (cov[(0, 0)], 0.5 * (cov[(0, 1)] + cov[(1, 0)]), cov[(1, 1)]);
    let mean = 0.5 * (a + d);
    let spread = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (l1, l2) = (mean + spread, mean - spread);
    // Rounding may leave a tiny negative second eigenvalue on a degenerate covariance.
    if l1 < 0.0 || l2 < -1e-9 * l1 {
        return None;
    }
    let l2 = l2.max(0.0);
    if l1 == 0.0 {
        return Some(0.0);
    }
    // Newton's method from the circular radius of the mean variance (exact when circular),
    // kept inside a bracket that always holds the answer: the circular radius of the whole
    // variance bounds both limits from above.
    let k = (-2.0 * (1.0 - p).ln()).sqrt();
    let (mut lo, mut hi) = (0.0, k * (l1 + l2).sqrt());
    let mut r = k * (0.5 * (l1 + l2)).sqrt();
    for _ in 0..50 {
        let (prob, slope) = probability_within(l1, l2, r);
        if prob < p {
            lo = r;
        } else {
            hi = r;
        }
        let step = if slope > 0.0 {
            (prob - p) / slope
        } else {
            f64::INFINITY
        };
        let mut next = r - step;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - r).abs() <= 1e-7 * r {
            return Some(next);
        }
        r = next;
    }
    Some(r)
}

/// The probability that a zero-mean normal with axis variances `l1 >= l2 >= 0` lies within
/// radius `r`, and its derivative in `r`.
fn probability_within(l1: f64, l2: f64, r: f64) -> (f64, f64) {
    let step = std::f64::consts::FRAC_PI_2 / ANGLE_SAMPLES as f64;
    let (mut sum, mut slope) = (0.0, 0.0);
    for k in 0..=ANGLE_SAMPLES {
        let (s, c) = (k as f64 * step).sin_cos();
        let var = l1 * c * c + l2 * s * s;
        let w = if k == 0 || k == ANGLE_SAMPLES {
            0.5
        } else {
            1.0
        };
        if var > 0.0 {
            let e = (-0.5 * r * r / var).exp();
            sum += w * (1.0 - e);
            slope += w * r / var * e;
        } else {
            sum += w;
        }
    }
    // The quarter turn's integral (step * sum) is a quarter of the whole, over 2 pi.
    let scale = step * 4.0 / std::f64::consts::TAU;
    ((sum * scale).clamp(0.0, 1.0), slope * scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The error function by its Maclaurin series (enough for |x| <= 6, test only).
    fn erf(x: f64) -> f64 {
        let x = x.clamp(-6.0, 6.0);
        let (x2, mut term, mut sum) = (x * x, x, x);
        for n in 1..400 {
            term *= -x2 / n as f64;
            let add = term / (2 * n + 1) as f64;
            sum += add;
            if add.abs() < 1e-18 {
                break;
            }
        }
        (sum * 2.0 / std::f64::consts::PI.sqrt()).clamp(-1.0, 1.0)
    }

    /// The standard normal quantile by bisection on erf.
    fn normal_quantile(p: f64) -> f64 {
        let (mut lo, mut hi) = (-8.0, 8.0);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if 0.5 * (1.0 + erf(mid / std::f64::consts::SQRT_2)) < p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    #[test]
    fn a_circular_error_has_the_closed_form_radius() {
        let s = 3.0;
        let r = circular_error_m(&Matrix2::new(s * s, 0.0, 0.0, s * s), 0.95).unwrap();
        let expected = s * (-2.0 * 0.05f64.ln()).sqrt();
        assert!((r - expected).abs() < 1e-6 * expected, "{r} vs {expected}");
    }

    #[test]
    fn a_degenerate_error_is_the_normal_quantile() {
        let r = circular_error_m(&Matrix2::new(4.0, 0.0, 0.0, 0.0), 0.95).unwrap();
        assert!((r - 1.959_964 * 2.0).abs() < 1e-4, "{r}");
        let r = circular_error_m(&Matrix2::new(0.0, 0.0, 0.0, 9.0), 0.95).unwrap();
        assert!((r - 1.959_964 * 3.0).abs() < 1e-4, "{r}");
    }

    #[test]
    fn erf_of_the_test_matches_known_values() {
        for (x, v) in [
            (0.5, 0.520_499_877_813_046_5),
            (2.0, 0.995_322_265_018_952_7),
        ] {
            assert!((erf(x) - v).abs() < 1e-12, "erf({x}) = {} vs {v}", erf(x));
        }
    }

    #[test]
    fn bad_input_has_no_radius() {
        assert_eq!(
            circular_error_m(&Matrix2::new(-1.0, 0.0, 0.0, 1.0), 0.95),
            None
        );
        assert_eq!(
            circular_error_m(&Matrix2::new(1.0, 2.0, 2.0, 1.0), 0.95),
            None
        );
        assert_eq!(
            circular_error_m(&Matrix2::new(f64::NAN, 0.0, 0.0, 1.0), 0.95),
            None
        );
        assert_eq!(circular_error_m(&Matrix2::identity(), 1.0), None);
        assert_eq!(circular_error_m(&Matrix2::zeros(), 0.95), Some(0.0));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The radius holds the probability it names: the share of a stratified grid over the
        /// two axes' normal quantiles that falls inside it is 95 %, for any axes and rotation.
        #[test]
        fn the_radius_holds_its_probability(
            s1 in 0.1f64..20.0, ratio in 0.0f64..1.0, angle in 0.0f64..3.0,
        ) {
            let s2 = s1 * ratio;
            let (sn, cs) = angle.sin_cos();
            let rot = Matrix2::new(cs, -sn, sn, cs);
            let cov = rot * Matrix2::new(s1 * s1, 0.0, 0.0, s2 * s2) * rot.transpose();
            let r = circular_error_m(&cov, 0.95).unwrap();
            let lower = 1.959_964 * s1 * (1.0 - 1e-6);
            let upper = (s1 * s1 + s2 * s2).sqrt() * 2.447_747 * (1.0 + 1e-6);
            prop_assert!(r >= lower && r <= upper, "r {r} not in [{lower}, {upper}]");
            let n = 300;
            let q: Vec<f64> = (0..n).map(|i| normal_quantile((f64::from(i) + 0.5) / f64::from(n))).collect();
            let inside = q
                .iter()
                .flat_map(|u| q.iter().map(move |v| (s1 * u).hypot(s2 * v)))
                .filter(|d| *d <= r)
                .count();
            let share = inside as f64 / f64::from(n * n);
            prop_assert!((share - 0.95).abs() < 0.005, "share {share} inside r {r}");
        }
    }
}
