//! The Cholesky factorisation of a kriging system: nalgebra's, to the bit, in a fraction of
//! its time.
//!
//! nalgebra's `Cholesky::new` is left-looking: column `j` receives, for `k = 0..j` in
//! order, `y ← (−L[j, k]) · L[·, k] + y` on its rows from the diagonal down, then the square
//! root of its diagonal and the division of the rows below it. Each of those updates is a
//! pass of its own, loading and storing the column: local kriging's 128-sample systems,
//! factored for every block of nodes, spent a third of a large evaluation there.
//!
//! Here [`PANEL`] columns at a time receive the updates of every earlier column, a tile of
//! [`TILE_ROWS`] of their rows held in registers while `k` runs; then, within the panel,
//! each column receives its panel predecessors' updates and is finished as nalgebra finishes
//! it. Every element sees the same operations in the same order — a product then a sum,
//! each rounded (no fused multiply-add), then one division — so the factor is nalgebra's
//! bit for bit, its upper triangle untouched as nalgebra leaves it (`tests`), and the
//! solves that follow are nalgebra's own ([`Cholesky::pack_dirty`]). Without fused
//! operations the lanes' width changes no bit, so the AVX2 compilation, chosen at run
//! time, gives the portable one's factor.

use nalgebra::{Cholesky, DMatrix, Dyn};

/// Columns factored together: the width of the register tile.
const PANEL: usize = 4;

/// Rows of the register tile (two AVX2 vectors per column).
const TILE_ROWS: usize = 8;

/// The Cholesky factor of the symmetric `matrix` (its lower triangle read), as
/// `matrix.cholesky()` gives it to the bit; `None` where that gives `None` (a diagonal
/// zero, negative or not a number on the way: not positive definite in floating point).
pub(crate) fn cholesky(mut matrix: DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    let n = matrix.nrows();
    assert_eq!(n, matrix.ncols(), "a square matrix");
    let factored = {
        let a = matrix.as_mut_slice();
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2 (checked just above).
            unsafe { factor_avx2(a, n) }
        } else {
            factor(a, n)
        }
        #[cfg(not(target_arch = "x86_64"))]
        factor(a, n)
    };
    factored.then(|| Cholesky::pack_dirty(matrix))
}

/// [`factor`] compiled for AVX2.
///
/// # Safety
///
/// The processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn factor_avx2(a: &mut [f64], n: usize) -> bool {
    factor(a, n)
}

/// Factors the column-major `n × n` matrix `a` in place, lower triangle (module docs);
/// `false` at the first column whose diagonal has no positive square root.
#[inline(always)]
fn factor(a: &mut [f64], n: usize) -> bool {
    let mut first = 0;
    while first < n {
        let width = PANEL.min(n - first);
        if width == PANEL {
            panel_update(a, n, first);
        } else {
            for j in first..first + width {
                for k in 0..first {
                    column_update(a, n, j, k);
                }
            }
        }
        for j in first..first + width {
            for k in first..j {
                column_update(a, n, j, k);
            }
            let diagonal = a[j * n + j];
            // nalgebra's test: a zero, or a value without a square root (negative, NaN).
            if diagonal <= 0.0 || diagonal.is_nan() {
                return false;
            }
            let root = diagonal.sqrt();
            a[j * n + j] = root;
            for x in &mut a[j * n + j + 1..(j + 1) * n] {
                *x /= root;
            }
        }
        first += width;
    }
    true
}

/// Column `j`'s update by the finished column `k < j`, on its rows from the diagonal down:
/// nalgebra's `axpy`, `y ← (−L[j, k]) · x + y`.
#[inline(always)]
fn column_update(a: &mut [f64], n: usize, j: usize, k: usize) {
    let f = -a[k * n + j];
    let (done, rest) = a.split_at_mut(j * n);
    let x = &done[k * n + j..(k + 1) * n];
    for (y, &x) in rest[j..n].iter_mut().zip(x) {
        *y += f * x;
    }
}

/// The updates of every finished column `k < first` to the [`PANEL`] columns from `first`,
/// each element's in order of `k`, [`TILE_ROWS`] rows at a time. Rows above a column's
/// diagonal are computed in the first tile and not stored.
#[inline(always)]
fn panel_update(a: &mut [f64], n: usize, first: usize) {
    let mut row = first;
    while row + TILE_ROWS <= n {
        full_tile(a, n, first, row);
        row += TILE_ROWS;
    }
    for r in row..n {
        for c in 0..PANEL {
            let j = first + c;
            if r < j {
                continue;
            }
            let mut y = a[j * n + r];
            for k in 0..first {
                y += -a[k * n + j] * a[k * n + r];
            }
            a[j * n + r] = y;
        }
    }
}

/// [`panel_update`] on the rows `row..row + TILE_ROWS`, held in registers while `k` runs
/// (fixed sizes throughout, so that the tile is never spilled).
#[inline(always)]
fn full_tile(a: &mut [f64], n: usize, first: usize, row: usize) {
    let mut tile = [[0.0f64; TILE_ROWS]; PANEL];
    for (c, t) in tile.iter_mut().enumerate() {
        *t = a[(first + c) * n + row..][..TILE_ROWS]
            .try_into()
            .expect("a tile's rows");
    }
    for k in 0..first {
        let column = &a[k * n..(k + 1) * n];
        let x: [f64; TILE_ROWS] = column[row..row + TILE_ROWS]
            .try_into()
            .expect("a tile's rows");
        let f: [f64; PANEL] = column[first..first + PANEL]
            .try_into()
            .expect("the panel's rows");
        for (t, f) in tile.iter_mut().zip(f) {
            for (y, x) in t.iter_mut().zip(x) {
                *y += -f * x;
            }
        }
    }
    for (c, t) in tile.iter().enumerate() {
        let j = first + c;
        for (r, &y) in t.iter().enumerate() {
            if row + r >= j {
                a[j * n + row + r] = y;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `B Bᵀ + d I` for a random `B` (`n × n`), with a random upper triangle (never read).
    fn spd(n: usize, d: f64, rng: &mut ChaCha8Rng) -> DMatrix<f64> {
        let b = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
        let mut m = &b * b.transpose() + DMatrix::identity(n, n) * d;
        for j in 0..n {
            for i in 0..j {
                m[(i, j)] = rng.gen_range(-5.0..5.0);
            }
        }
        m
    }

    fn same_bits(a: &DMatrix<f64>, b: &DMatrix<f64>) -> bool {
        a.iter()
            .zip(b.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits())
    }

    #[test]
    fn the_factor_is_nalgebras_to_the_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for n in (0..40).chain([63, 64, 65, 127, 128, 129, 200, 301]) {
            for d in [1e-9, 1e-3, 1.0] {
                let m = spd(n, d, &mut rng);
                let ours = cholesky(m.clone()).expect("positive definite");
                let theirs = m.clone().cholesky().expect("positive definite");
                assert!(same_bits(ours.l_dirty(), theirs.l_dirty()), "n {n}, d {d}");
                let ours = factor_portable(m.clone());
                assert!(
                    same_bits(&ours.expect("factored"), theirs.l_dirty()),
                    "n {n}"
                );
            }
        }
    }

    /// The portable compilation's factor.
    fn factor_portable(mut m: DMatrix<f64>) -> Option<DMatrix<f64>> {
        let n = m.nrows();
        factor(m.as_mut_slice(), n).then_some(m)
    }

    #[test]
    fn what_nalgebra_refuses_is_refused() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        for n in [1, 3, 4, 5, 9, 17, 70] {
            for bad in 0..n {
                let mut m = spd(n, 0.1, &mut rng);
                // Not positive definite at column `bad`: a negative, a zero, or a NaN.
                for (value, what) in [(-3.0, "negative"), (0.0, "zero"), (f64::NAN, "nan")] {
                    let mut m = m.clone();
                    m[(bad, bad)] = if what == "zero" {
                        // The diagonal that leaves exactly zero after the updates is hard
                        // to make; a zero matrix row and column is.
                        for i in 0..n {
                            m[(i, bad)] = 0.0;
                            m[(bad, i)] = 0.0;
                        }
                        0.0
                    } else {
                        value
                    };
                    assert_eq!(
                        cholesky(m.clone()).is_none(),
                        m.clone().cholesky().is_none(),
                        "n {n}, column {bad}, {what}"
                    );
                    assert!(cholesky(m).is_none(), "n {n}, column {bad}, {what}");
                }
                m[(bad, bad)] += 1.0;
                assert!(cholesky(m).is_some());
            }
        }
    }

    #[test]
    fn a_nan_below_the_diagonal_is_refused_as_nalgebra_refuses_it() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut m = spd(12, 1.0, &mut rng);
        m[(9, 2)] = f64::NAN;
        assert!(m.clone().cholesky().is_none());
        assert!(cholesky(m).is_none());
    }
}
