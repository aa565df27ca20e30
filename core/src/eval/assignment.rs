//! Optimal assignment, as TrackEval calls scipy's `linear_sum_assignment`.

/// The `(row, col)` pairs of `scipy.optimize.linear_sum_assignment(-score)` for
/// a row-major `rows x cols` score matrix (maximises the total score).
///
/// The `lsap` crate is a port of scipy's solver, so ties between equally good
/// assignments resolve as they do in TrackEval. The solver only fails for NaN
/// or infinite entries, which the callers never produce (IoUs and products of
/// IoUs and ratios are finite); should it fail anyway the failure is logged and
/// no pairs are returned.
pub(crate) fn maximise_score(rows: usize, cols: usize, score: &[f64]) -> Vec<(usize, usize)> {
    if rows == 0 || cols == 0 {
        return Vec::new();
    }
    let cost: Vec<f64> = score.iter().map(|s| -s).collect();
    match lsap::solve(rows, cols, &cost, false) {
        Ok((r, c)) => r.into_iter().zip(c).collect(),
        Err(e) => {
            tracing::error!(rows, cols, error = %e, "assignment solver failed");
            Vec::new()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn picks_the_best_total() {
        // [[1, 0.9], [0.9, 0]]: diagonal gives 1, anti-diagonal 1.8.
        let pairs = maximise_score(2, 2, &[1.0, 0.9, 0.9, 0.0]);
        assert_eq!(pairs, vec![(0, 1), (1, 0)]);
    }

    #[test]
    fn rectangular_matrices_assign_the_smaller_side() {
        let tall = maximise_score(3, 1, &[0.1, 0.7, 0.2]);
        assert_eq!(tall, vec![(1, 0)]);
        let wide = maximise_score(1, 3, &[0.1, 0.7, 0.2]);
        assert_eq!(wide, vec![(0, 1)]);
    }

    #[test]
    fn constant_matrix_gives_identity_like_scipy() {
        assert_eq!(maximise_score(2, 2, &[0.0; 4]), vec![(0, 0), (1, 1)]);
    }
}
