//! The blocked Householder reduction of a symmetric matrix to tridiagonal form, with fused
//! multiply-adds: what the likelihood search of [`crate::nugget_kriging`] spends most of
//! its time in.
//!
//! The unblocked reduction (LAPACK's `dsytd2`, [`crate::nugget_kriging`]'s reference) passes
//! over the whole trailing block twice per column, loading and storing it, for 8 flops per
//! element. Here the columns are taken in panels of [`PANEL`] (LAPACK's `dsytrd` and
//! `dlatrd`): within a panel each column needs only the product of the trailing block, not
//! yet updated, with its reflector (read, never written), corrected by the panel's earlier
//! reflectors; the panel's rank-2·[`PANEL`] update is then applied to the trailing block
//! once, from registers. Both loops take several columns at a time, so that each element
//! loaded serves several multiply-adds.
//!
//! Every operation is written out in a fixed order with [`f64::mul_add`] (a fused
//! multiply-add, rounded once) and every sum in fixed interleaved partial sums, so the
//! result is the same to the bit whether the loops run in two, four or eight lanes: the
//! version compiled for AVX2 and FMA, chosen at run time ([`tridiagonalise`]), gives the
//! portable compilation's bits, and a table does not depend on the processor that built it.
//!
//! The product with the trailing block is half the flops and, left to the compiler, most of
//! the time: its [`PRODUCT_COLUMNS`] columns' sums and the rows' running sums need more
//! vector registers than AVX2 has, and each row's sum is a chain of dependent multiply-adds.
//! The AVX2 version writes that loop with intrinsics ([`product_rows_fma`]), four chunks of
//! rows at a time so that four chains are in flight; it performs the portable loop's very
//! operations, lane for lane and in the same order, so the bits stay those of
//! [`tridiagonalise_portable`] (`tests`).

/// Columns per panel: the rank of the trailing block's update.
pub(crate) const PANEL: usize = 32;

/// Interleaved partial sums of a dot product ([`dot`]).
const LANES: usize = 8;

/// Columns of the trailing block multiplied with a reflector in one pass ([`product`]).
const PRODUCT_COLUMNS: usize = 8;

/// Partial sums per column of [`product`]'s dot products.
const PRODUCT_LANES: usize = 4;

/// Columns of the trailing block updated in one pass ([`update`]).
const UPDATE_COLUMNS: usize = 4;

/// Rows of [`update`]'s register tile.
const UPDATE_ROWS: usize = 8;

/// A reduction: the matrix (`n × n`, overwritten) and the values to transform, to the
/// tridiagonal form's diagonal and subdiagonal ([`tridiagonalise`]).
pub(crate) type Reduction = fn(&mut [f64], usize, &mut [Vec<f64>]) -> (Vec<f64>, Vec<f64>);

/// Whether [`tridiagonalise`] runs at hardware speed here: `false` only on x86-64
/// processors without FMA, where each fused multiply-add is a library call (exact, and
/// tens of times slower).
pub(crate) fn fused_in_hardware() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        true
    }
}

/// Reduces the symmetric `n × n` matrix `a` (column-major; its lower triangle read, and
/// overwritten) to tridiagonal form `T = Qᵀ A Q` by `n − 2` Householder reflections
/// `I − τ v vᵀ` (`v` leading 1), applying them to each of `values` (`z = Qᵀ y`). Returns
/// `T`'s diagonal and subdiagonal (signed).
///
/// On x86-64 with AVX2 and FMA the same code is compiled for them and chosen at run time;
/// the bits are those of [`tridiagonalise_portable`] (module docs).
pub(crate) fn tridiagonalise(
    a: &mut [f64],
    n: usize,
    values: &mut [Vec<f64>],
) -> (Vec<f64>, Vec<f64>) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the processor has AVX2 and FMA (checked just above).
        return unsafe { tridiagonalise_fma(a, n, values) };
    }
    tridiagonalise_portable(a, n, values)
}

/// [`tridiagonalise_portable`] compiled for AVX2 and FMA.
///
/// # Safety
///
/// The processor must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn tridiagonalise_fma(
    a: &mut [f64],
    n: usize,
    values: &mut [Vec<f64>],
) -> (Vec<f64>, Vec<f64>) {
    reduce::<true>(a, n, values)
}

/// The reduction ([`tridiagonalise`]) in the compilation for any processor of the target.
pub(crate) fn tridiagonalise_portable(
    a: &mut [f64],
    n: usize,
    values: &mut [Vec<f64>],
) -> (Vec<f64>, Vec<f64>) {
    reduce::<false>(a, n, values)
}

/// The reduction, panel by panel (module docs); with `FMA`, the product's loop in AVX2 and
/// FMA intrinsics ([`product_rows_fma`]), which only [`tridiagonalise_fma`] may ask for.
#[inline(always)]
fn reduce<const FMA: bool>(
    a: &mut [f64],
    n: usize,
    values: &mut [Vec<f64>],
) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(a.len(), n * n, "a square matrix");
    assert!(values.iter().all(|y| y.len() == n), "one value per row");
    let mut off_diagonal = vec![0.0; n.saturating_sub(1)];
    // The panel's reflectors `V` and their updates `W` (column t at t·n, zero above its
    // first row), such that the trailing block, updated, is `A − V Wᵀ − W Vᵀ`.
    let mut reflectors = vec![0.0; n * PANEL];
    let mut updates = vec![0.0; n * PANEL];
    let mut p = vec![0.0; n];
    let mut first = 0;
    while first + 1 < n {
        let width = PANEL.min(n - 1 - first);
        for j in 0..width {
            let k = first + j;
            // Column k, from the diagonal down, updated by the panel's earlier reflections.
            let column = &mut a[k * n + k..(k + 1) * n];
            for t in 0..j {
                let v = &reflectors[t * n + k..(t + 1) * n];
                let w = &updates[t * n + k..(t + 1) * n];
                let (wk, vk) = (w[0], v[0]);
                for ((x, &vr), &wr) in column.iter_mut().zip(v).zip(w) {
                    *x = f64::mul_add(-vr, wk, f64::mul_add(-wr, vk, *x));
                }
            }
            let (tau, beta) = reflection(&mut column[1..]);
            off_diagonal[k] = beta;
            let (done, rest) = reflectors.split_at_mut(j * n);
            let v = &mut rest[..n];
            let w = &mut updates[j * n..(j + 1) * n];
            v.fill(0.0);
            w.fill(0.0);
            if tau == 0.0 {
                continue;
            }
            v[k + 1] = 1.0;
            v[k + 2..].copy_from_slice(&a[k * n + k + 2..(k + 1) * n]);
            // p = B v for the trailing block B as it is, less the panel's earlier
            // reflections' share: B v − V (Wᵀv) − W (Vᵀv).
            product::<FMA>(a, n, k + 1, v, &mut p);
            for t in 0..j {
                let vt = &done[t * n + k + 1..(t + 1) * n];
                let wt = &updates[t * n + k + 1..(t + 1) * n];
                let x = dot(wt, &v[k + 1..]);
                let y = dot(vt, &v[k + 1..]);
                for ((pr, &vr), &wr) in p[k + 1..].iter_mut().zip(vt).zip(wt) {
                    *pr = f64::mul_add(-vr, x, f64::mul_add(-wr, y, *pr));
                }
            }
            for y in values.iter_mut() {
                let s = tau * dot(&v[k + 1..], &y[k + 1..]);
                for (yi, &vi) in y[k + 1..].iter_mut().zip(&v[k + 1..]) {
                    *yi = f64::mul_add(-s, vi, *yi);
                }
            }
            // w = τ p − (τ/2)(τ pᵀv) v, so that H B H = B − v wᵀ − w vᵀ.
            p[k + 1..].iter_mut().for_each(|x| *x *= tau);
            let half = 0.5 * tau * dot(&p[k + 1..], &v[k + 1..]);
            let w = &mut updates[j * n..(j + 1) * n];
            for ((wi, &pi), &vi) in w[k + 1..].iter_mut().zip(&p[k + 1..]).zip(&v[k + 1..]) {
                *wi = f64::mul_add(-half, vi, pi);
            }
        }
        first += width;
        update(a, n, first, &reflectors, &updates, width);
    }
    let diagonal = (0..n).map(|i| a[i * n + i]).collect();
    (diagonal, off_diagonal)
}

/// The Householder reflection `I − τ v vᵀ` (`v₀ = 1`) taking `x` to `β e₀`: returns
/// `(τ, β)` and leaves `v` below `x[0]`; `τ = 0` when `x` is already there.
#[inline(always)]
fn reflection(x: &mut [f64]) -> (f64, f64) {
    let alpha = x[0];
    let norm = dot(&x[1..], &x[1..]).sqrt();
    if norm == 0.0 {
        return (0.0, alpha);
    }
    let beta = -alpha.signum() * alpha.hypot(norm);
    let scale = 1.0 / (alpha - beta);
    x[1..].iter_mut().for_each(|v| *v *= scale);
    ((beta - alpha) / beta, beta)
}

/// A dot product in [`LANES`] interleaved fused sums, folded pairwise.
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut sums = [0.0; LANES];
    let (chunks_a, chunks_b) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let mut tail = 0.0;
    for (x, y) in chunks_a.remainder().iter().zip(chunks_b.remainder()) {
        tail = x.mul_add(*y, tail);
    }
    for (x, y) in chunks_a.zip(chunks_b) {
        for t in 0..LANES {
            sums[t] = x[t].mul_add(y[t], sums[t]);
        }
    }
    ((sums[0] + sums[4]) + (sums[2] + sums[6])) + ((sums[1] + sums[5]) + (sums[3] + sums[7])) + tail
}

/// `p[s..] = B v[s..]` for the trailing block `B = A[s.., s..]`, its lower triangle read:
/// [`PRODUCT_COLUMNS`] columns per pass, each serving their rows' share of `p` (an update)
/// and its own row (a dot product).
#[inline(always)]
fn product<const FMA: bool>(a: &[f64], n: usize, s: usize, v: &[f64], p: &mut [f64]) {
    p[s..].fill(0.0);
    let mut c = s;
    while c + PRODUCT_COLUMNS <= n {
        product_columns::<PRODUCT_COLUMNS, FMA>(a, n, c, v, p);
        c += PRODUCT_COLUMNS;
    }
    while c < n {
        product_columns::<1, false>(a, n, c, v, p);
        c += 1;
    }
}

/// [`product`]'s share of columns `c..c + W`; with `FMA` (and `W` = [`PRODUCT_COLUMNS`]),
/// its rows by [`product_rows_fma`].
#[inline(always)]
fn product_columns<const W: usize, const FMA: bool>(
    a: &[f64],
    n: usize,
    c: usize,
    v: &[f64],
    p: &mut [f64],
) {
    // The block on the diagonal, its lower triangle.
    for i in 0..W {
        for j in 0..=i {
            let b = a[(c + j) * n + c + i];
            p[c + i] = b.mul_add(v[c + j], p[c + i]);
            if j < i {
                p[c + j] = b.mul_add(v[c + i], p[c + j]);
            }
        }
    }
    let start = c + W;
    let rows = n - start;
    let columns: [&[f64]; W] = std::array::from_fn(|j| &a[(c + j) * n + start..(c + j + 1) * n]);
    let vc: [f64; W] = std::array::from_fn(|j| v[c + j]);
    let (vr, pr) = (&v[start..n], &mut p[start..n]);
    let mut sums = [[0.0; PRODUCT_LANES]; W];
    let chunks = rows / PRODUCT_LANES;
    let done = if FMA {
        fused_product_rows(&columns, &vc, vr, pr, chunks, &mut sums)
    } else {
        0
    };
    for q in done..chunks {
        let base = q * PRODUCT_LANES;
        let pq = &mut pr[base..base + PRODUCT_LANES];
        let vq = &vr[base..base + PRODUCT_LANES];
        let bq: [&[f64]; W] = std::array::from_fn(|j| &columns[j][base..base + PRODUCT_LANES]);
        for l in 0..PRODUCT_LANES {
            let mut acc = pq[l];
            for j in 0..W {
                acc = bq[j][l].mul_add(vc[j], acc);
                sums[j][l] = bq[j][l].mul_add(vq[l], sums[j][l]);
            }
            pq[l] = acc;
        }
    }
    let mut tails = [0.0; W];
    for r in chunks * PRODUCT_LANES..rows {
        let mut acc = pr[r];
        for j in 0..W {
            acc = columns[j][r].mul_add(vc[j], acc);
            tails[j] = columns[j][r].mul_add(vr[r], tails[j]);
        }
        pr[r] = acc;
    }
    for j in 0..W {
        let [s0, s1, s2, s3] = sums[j];
        p[c + j] += ((s0 + s2) + (s1 + s3)) + tails[j];
    }
}

/// [`product_rows_fma`] where it is compiled: returns the chunks it did (all, or none
/// elsewhere).
#[inline(always)]
fn fused_product_rows(
    columns: &[&[f64]],
    vc: &[f64],
    vr: &[f64],
    pr: &mut [f64],
    chunks: usize,
    sums: &mut [[f64; PRODUCT_LANES]],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: only `tridiagonalise_fma` asks for the fused rows (`reduce::<true>`), and
        // its caller checked that the processor has AVX2 and FMA.
        unsafe { product_rows_fma(columns, vc, vr, pr, chunks, sums) };
        chunks
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (columns, vc, vr, pr, chunks, sums);
        0
    }
}

/// [`product_columns`]' loop over its first `chunks` chunks of [`PRODUCT_LANES`] rows, in
/// AVX2 and FMA intrinsics: per chunk, the rows' sums `p[r] += Σ_j B[r, c + j] v[c + j]`
/// taken over the columns in order, and each column's lane sums `sums[j][l] += B[r, c + j]
/// v[r]`, the portable loop's operations exactly; four chunks at a time (then two, then
/// one), so that their chains of dependent multiply-adds overlap.
///
/// # Safety
///
/// The processor must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn product_rows_fma(
    columns: &[&[f64]],
    vc: &[f64],
    vr: &[f64],
    pr: &mut [f64],
    chunks: usize,
    sums: &mut [[f64; PRODUCT_LANES]],
) {
    use std::arch::x86_64::{
        __m256d, _mm256_fmadd_pd, _mm256_loadu_pd, _mm256_set1_pd, _mm256_setzero_pd,
        _mm256_storeu_pd,
    };
    const W: usize = PRODUCT_COLUMNS;
    // The bounds every load and store below stays within.
    assert!(columns.len() == W && vc.len() == W && sums.len() == W);
    assert!(vr.len() == pr.len() && columns.iter().all(|c| c.len() == vr.len()));
    assert!(chunks * PRODUCT_LANES <= vr.len());
    let column: [*const f64; W] = std::array::from_fn(|j| columns[j].as_ptr());
    let vc: [__m256d; W] = std::array::from_fn(|j| _mm256_set1_pd(vc[j]));
    let mut s: [__m256d; W] = [_mm256_setzero_pd(); W];
    let (vr, pr) = (vr.as_ptr(), pr.as_mut_ptr());
    // SAFETY (every load and store): rows r..r + PRODUCT_LANES for r below
    // chunks · PRODUCT_LANES, within every slice (asserted above).
    let mut q = 0;
    // Four chunks at a time: four chains of the rows' sums in flight (each a chain of W
    // dependent multiply-adds, which two chains left waiting on their latency).
    while q + 4 <= chunks {
        let r: [usize; 4] = std::array::from_fn(|c| (q + c) * PRODUCT_LANES);
        let mut acc = r.map(|r| _mm256_loadu_pd(pr.add(r)));
        let vq = r.map(|r| _mm256_loadu_pd(vr.add(r)));
        for j in 0..W {
            let b = r.map(|r| _mm256_loadu_pd(column[j].add(r)));
            for c in 0..4 {
                acc[c] = _mm256_fmadd_pd(b[c], vc[j], acc[c]);
            }
            let mut sum = s[j];
            for c in 0..4 {
                sum = _mm256_fmadd_pd(b[c], vq[c], sum);
            }
            s[j] = sum;
        }
        for c in 0..4 {
            _mm256_storeu_pd(pr.add(r[c]), acc[c]);
        }
        q += 4;
    }
    while q + 2 <= chunks {
        let (r0, r1) = (q * PRODUCT_LANES, (q + 1) * PRODUCT_LANES);
        let mut acc = [_mm256_loadu_pd(pr.add(r0)), _mm256_loadu_pd(pr.add(r1))];
        let vq = [_mm256_loadu_pd(vr.add(r0)), _mm256_loadu_pd(vr.add(r1))];
        for j in 0..W {
            let b = [
                _mm256_loadu_pd(column[j].add(r0)),
                _mm256_loadu_pd(column[j].add(r1)),
            ];
            acc[0] = _mm256_fmadd_pd(b[0], vc[j], acc[0]);
            acc[1] = _mm256_fmadd_pd(b[1], vc[j], acc[1]);
            s[j] = _mm256_fmadd_pd(b[1], vq[1], _mm256_fmadd_pd(b[0], vq[0], s[j]));
        }
        _mm256_storeu_pd(pr.add(r0), acc[0]);
        _mm256_storeu_pd(pr.add(r1), acc[1]);
        q += 2;
    }
    if q < chunks {
        let r0 = q * PRODUCT_LANES;
        let mut acc = _mm256_loadu_pd(pr.add(r0));
        let vq = _mm256_loadu_pd(vr.add(r0));
        for j in 0..W {
            let b = _mm256_loadu_pd(column[j].add(r0));
            acc = _mm256_fmadd_pd(b, vc[j], acc);
            s[j] = _mm256_fmadd_pd(b, vq, s[j]);
        }
        _mm256_storeu_pd(pr.add(r0), acc);
    }
    for (sum, s) in sums.iter_mut().zip(s) {
        _mm256_storeu_pd(sum.as_mut_ptr(), s);
    }
}

/// The panel's update of the trailing block `A[s.., s..]`, lower triangle:
/// `A −= V Wᵀ + W Vᵀ` over its `width` reflectors, [`UPDATE_COLUMNS`] columns at a time
/// in tiles of [`UPDATE_ROWS`] rows held while all the reflectors pass.
#[inline(always)]
fn update(a: &mut [f64], n: usize, s: usize, reflectors: &[f64], updates: &[f64], width: usize) {
    let mut c = s;
    while c + UPDATE_COLUMNS <= n {
        update_columns::<UPDATE_COLUMNS>(a, n, c, reflectors, updates, width);
        c += UPDATE_COLUMNS;
    }
    while c < n {
        update_columns::<1>(a, n, c, reflectors, updates, width);
        c += 1;
    }
}

/// [`update`]'s share of columns `c..c + W`, rows from `c` down (the few above the
/// diagonal in the first tile are updated too, and never read).
#[inline(always)]
fn update_columns<const W: usize>(
    a: &mut [f64],
    n: usize,
    c: usize,
    reflectors: &[f64],
    updates: &[f64],
    width: usize,
) {
    // Per reflector t and column j: W[c + j, t], V[c + j, t].
    let mut coefficients = [[[0.0; 2]; W]; PANEL];
    for (t, row) in coefficients.iter_mut().enumerate().take(width) {
        for (j, pair) in row.iter_mut().enumerate() {
            *pair = [updates[t * n + c + j], reflectors[t * n + c + j]];
        }
    }
    let chunks = (n - c) / UPDATE_ROWS;
    for q in 0..chunks {
        let r0 = c + q * UPDATE_ROWS;
        let mut tile = [[0.0; UPDATE_ROWS]; W];
        for (j, rows) in tile.iter_mut().enumerate() {
            rows.copy_from_slice(&a[(c + j) * n + r0..(c + j) * n + r0 + UPDATE_ROWS]);
        }
        for (t, row) in coefficients.iter().enumerate().take(width) {
            let vt = &reflectors[t * n + r0..t * n + r0 + UPDATE_ROWS];
            let wt = &updates[t * n + r0..t * n + r0 + UPDATE_ROWS];
            for (rows, &[wc, vc]) in tile.iter_mut().zip(row) {
                for l in 0..UPDATE_ROWS {
                    rows[l] = f64::mul_add(-vt[l], wc, f64::mul_add(-wt[l], vc, rows[l]));
                }
            }
        }
        for (j, rows) in tile.iter().enumerate() {
            a[(c + j) * n + r0..(c + j) * n + r0 + UPDATE_ROWS].copy_from_slice(rows);
        }
    }
    for r in c + chunks * UPDATE_ROWS..n {
        for j in 0..W {
            let mut x = a[(c + j) * n + r];
            for (t, row) in coefficients.iter().enumerate().take(width) {
                let [wc, vc] = row[j];
                x = f64::mul_add(
                    -reflectors[t * n + r],
                    wc,
                    f64::mul_add(-updates[t * n + r], vc, x),
                );
            }
            a[(c + j) * n + r] = x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random symmetric `n × n` matrix (column-major) with a heavy diagonal, as a
    /// covariance has, and `width` vectors to transform.
    fn case(n: usize, width: usize, rng: &mut ChaCha8Rng) -> (Vec<f64>, Vec<Vec<f64>>) {
        let mut a = vec![0.0; n * n];
        for j in 0..n {
            for i in j..n {
                let x = if i == j {
                    n as f64 + rng.gen_range(0.0..1.0)
                } else {
                    rng.gen_range(-1.0..1.0)
                };
                a[j * n + i] = x;
                a[i * n + j] = x;
            }
        }
        let values = (0..width)
            .map(|_| (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect())
            .collect();
        (a, values)
    }

    fn bits(a: &[f64], (d, e): &(Vec<f64>, Vec<f64>), values: &[Vec<f64>]) -> Vec<u64> {
        (d.iter().chain(e).chain(values.iter().flatten()))
            .chain(a.iter().step_by(a.len().isqrt() + 1))
            .map(|v| v.to_bits())
            .collect()
    }

    /// Property: the reduction chosen at run time (with the product's rows in AVX2 and FMA
    /// intrinsics where the processor has them) gives the portable compilation's bits:
    /// the diagonal, the subdiagonal and the transformed values, on sizes below, at and
    /// across a panel, with an odd and an even count of chunks of rows in the product's
    /// passes and rows left over, and on random sizes to 300.
    #[test]
    fn the_dispatched_reduction_is_the_portable_one_to_the_bit() {
        if !fused_in_hardware() {
            // The portable compilation's fused multiply-adds would be library calls: the
            // processor-independent bits are checked where they are fast.
            return;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(41);
        let mut sizes: Vec<usize> = (1..=48).collect();
        sizes.extend([63, 64, 65, 95, 96, 97, 128, 129, 131]);
        sizes.extend((0..12).map(|_| rng.gen_range(100..300)));
        for n in sizes {
            let width = 1 + n % 3;
            let (a, values) = case(n, width, &mut rng);
            let (mut fast, mut fast_values) = (a.clone(), values.clone());
            let got = tridiagonalise(&mut fast, n, &mut fast_values);
            let (mut slow, mut slow_values) = (a, values);
            let want = tridiagonalise_portable(&mut slow, n, &mut slow_values);
            assert_eq!(
                bits(&fast, &got, &fast_values),
                bits(&slow, &want, &slow_values),
                "n = {n}"
            );
        }
    }
}
