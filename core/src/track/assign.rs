//! Gated linear assignment (Hungarian / Jonker-Volgenant) on top of the `lsap` crate, a port
//! of SciPy's `linear_sum_assignment` for rectangular cost matrices.

/// Cost standing in for a forbidden pair. Far above any real cost (IoU distances are <= 1,
/// world distances are metres) yet small enough that sums of a few hundred stay exact to
/// well below the real costs' resolution in f64.
const FORBIDDEN_COST: f64 = 1e9;

/// Solves the assignment on a row-major `rows x cols` matrix in which forbidden pairs are
/// marked by a non-finite cost, and writes the allowed matched pairs `(row, col)` to `out`
/// (ordered by row).
///
/// Forbidden pairs are replaced by a huge finite cost, so the solver maximises the number of
/// allowed matches first and minimises their summed cost second; forced pairs through a
/// forbidden entry are dropped afterwards. `cost` is modified in place.
pub(crate) fn solve_gated(
    rows: usize,
    cols: usize,
    cost: &mut Vec<f64>,
    out: &mut Vec<(usize, usize)>,
) {
    out.clear();
    if rows == 0 || cols == 0 {
        return;
    }
    debug_assert_eq!(cost.len(), rows * cols);
    let mut any_allowed = false;
    for c in cost.iter_mut() {
        if c.is_finite() {
            any_allowed = true;
        } else {
            *c = FORBIDDEN_COST;
        }
    }
    if !any_allowed {
        return;
    }
    match lsap::solve(rows, cols, cost, false) {
        Ok((r, c)) => {
            for (&i, &j) in r.iter().zip(c.iter()) {
                if cost[i * cols + j] < FORBIDDEN_COST {
                    out.push((i, j));
                }
            }
        }
        Err(e) => {
            // Cannot happen with finite costs; never take the tracker down over it.
            tracing::warn!(error = %e, rows, cols, "assignment solver failed; no matches");
        }
    }
}

/// Marks every entry above `gate` as forbidden (used for the IoU gates).
pub(crate) fn apply_gate(cost: &mut [f64], gate: f64) {
    for c in cost.iter_mut() {
        if c.is_nan() || *c > gate {
            *c = f64::INFINITY;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn picks_minimum_cost_assignment() {
        // rows 2, cols 3
        let mut c = vec![0.9, 0.1, 0.5, 0.2, 0.15, 0.8];
        let mut out = vec![];
        solve_gated(2, 3, &mut c, &mut out);
        assert_eq!(out, vec![(0, 1), (1, 0)]);
    }

    #[test]
    fn forbidden_pairs_are_never_returned() {
        let inf = f64::INFINITY;
        let mut c = vec![inf, 0.3, inf, inf];
        let mut out = vec![];
        solve_gated(2, 2, &mut c, &mut out);
        assert_eq!(out, vec![(0, 1)]);
        let mut c = vec![inf; 6];
        solve_gated(3, 2, &mut c, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn gate_forbids_above_threshold_and_nan() {
        let mut c = vec![0.2, 0.8, f64::NAN];
        apply_gate(&mut c, 0.5);
        assert_eq!(c[0], 0.2);
        assert!(c[1].is_infinite() && c[2].is_infinite());
    }

    proptest! {
        #[test]
        fn matches_are_one_to_one_and_allowed(
            rows in 0usize..8, cols in 0usize..8,
            seed in prop::collection::vec(0.0..1.0f64, 64),
        ) {
            let mut c: Vec<f64> = (0..rows * cols).map(|k| seed[k % 64]).collect();
            let orig = c.clone();
            apply_gate(&mut c, 0.6);
            let mut out = vec![];
            solve_gated(rows, cols, &mut c, &mut out);
            let mut seen_r = std::collections::HashSet::new();
            let mut seen_c = std::collections::HashSet::new();
            for &(i, j) in &out {
                prop_assert!(seen_r.insert(i) && seen_c.insert(j));
                prop_assert!(orig[i * cols + j] <= 0.6);
            }
        }
    }
}
