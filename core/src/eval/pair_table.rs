//! Per (gt id, predicted id) accumulators that stay small for long sequences.

use std::collections::HashMap;

/// Above this many id pairs the table is kept sparse: most pairs never
/// overlap, and a dense table for thousands of ids on each side would take
/// gigabytes. Below it a dense table is faster than hashing.
const DENSE_LIMIT: usize = 1 << 18;

/// A value per (gt id, predicted id) pair, `T::default()` where never written.
pub(crate) enum PairTable<T> {
    Dense {
        cols: usize,
        values: Vec<T>,
    },
    Sparse {
        cols: usize,
        values: HashMap<u64, T>,
    },
}

impl<T: Copy + Default + PartialEq> PairTable<T> {
    pub(crate) fn new(rows: usize, cols: usize) -> Self {
        match rows.checked_mul(cols) {
            Some(n) if n <= DENSE_LIMIT => PairTable::Dense {
                cols,
                values: vec![T::default(); n],
            },
            _ => PairTable::Sparse {
                cols,
                values: HashMap::new(),
            },
        }
    }

    pub(crate) fn get(&self, row: usize, col: usize) -> T {
        match self {
            PairTable::Dense { cols, values } => values[row * cols + col],
            PairTable::Sparse { cols, values } => values
                .get(&(row as u64 * *cols as u64 + col as u64))
                .copied()
                .unwrap_or_default(),
        }
    }

    pub(crate) fn get_mut(&mut self, row: usize, col: usize) -> &mut T {
        match self {
            PairTable::Dense { cols, values } => &mut values[row * *cols + col],
            PairTable::Sparse { cols, values } => values
                .entry(row as u64 * *cols as u64 + col as u64)
                .or_default(),
        }
    }

    /// Written pairs (those not equal to the default), in (row, col) order so
    /// that sums over them do not depend on hashing.
    pub(crate) fn into_sorted_entries(self) -> Vec<((usize, usize), T)> {
        let zero = T::default();
        match self {
            PairTable::Dense { cols, values } => values
                .into_iter()
                .enumerate()
                .filter(|(_, v)| *v != zero)
                .map(|(i, v)| ((i / cols, i % cols), v))
                .collect(),
            PairTable::Sparse { cols, values } => {
                let mut entries: Vec<(u64, T)> =
                    values.into_iter().filter(|(_, v)| *v != zero).collect();
                entries.sort_unstable_by_key(|(k, _)| *k);
                let cols = cols as u64;
                entries
                    .into_iter()
                    .map(|(k, v)| (((k / cols) as usize, (k % cols) as usize), v))
                    .collect()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_and_sparse_tables_agree() {
        let mut dense: PairTable<u32> = PairTable::new(3, 4);
        let mut sparse: PairTable<u32> = PairTable::new(DENSE_LIMIT, 4);
        assert!(matches!(dense, PairTable::Dense { .. }));
        assert!(matches!(sparse, PairTable::Sparse { .. }));
        for t in [&mut dense, &mut sparse] {
            *t.get_mut(2, 1) += 3;
            *t.get_mut(0, 3) += 1;
            *t.get_mut(0, 3) += 1;
        }
        for t in [&dense, &sparse] {
            assert_eq!((t.get(2, 1), t.get(0, 3), t.get(1, 1)), (3, 2, 0));
        }
        let expected = vec![((0, 3), 2), ((2, 1), 3)];
        assert_eq!(dense.into_sorted_entries(), expected);
        assert_eq!(sparse.into_sorted_entries(), expected);
    }
}
