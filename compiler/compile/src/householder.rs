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
//! versions compiled for AVX2 and FMA and for AVX-512, chosen at run time
//! ([`tridiagonalise`]), give the portable compilation's bits, and a table does not depend
//! on the processor that built it.
//!
//! The product with the trailing block is half the flops and, left to the compiler, most of
//! the time: its [`PRODUCT_COLUMNS`] columns' sums and the rows' running sums need more
//! vector registers than AVX2 has, and each row's sum is a chain of dependent multiply-adds.
//! The vector versions write that loop with intrinsics: in AVX-512 ([`product_rows_avx512`])
//! a column's [`PRODUCT_LANES`] partial sums are one register and four chunks of rows are
//! taken at a time, so that four chains are in flight; in AVX2 ([`product_rows_avx2`]) half
//! the columns at a time, in two registers each. Each performs the portable loop's very
//! operations, lane for lane and in the same order, so the bits stay those of
//! [`tridiagonalise_portable`] (`tests`).
//!
//! The matrix is copied so that every column starts a cache line ([`Lines`]), and the
//! chunks of rows start at multiples of a line: a vector load never spans two lines, which
//! an AVX-512 load at any other offset does. On a Sapphire Rapids Xeon a 400 × 400
//! reduction takes 0.75 of the time so, against the unaligned AVX2 loop; at 900 × 900 the
//! trailing block no longer fits the core's 2 MB L2, its passes stream from L3, and the
//! gain is a few percent.

/// Columns per panel: the rank of the trailing block's update.
pub(crate) const PANEL: usize = 32;

/// Interleaved partial sums of a dot product ([`dot`]).
const LANES: usize = 8;

/// Columns of the trailing block multiplied with a reflector in one pass ([`product`]).
const PRODUCT_COLUMNS: usize = 8;

/// Partial sums per column of [`product`]'s dot products: one AVX-512 register.
const PRODUCT_LANES: usize = 8;

/// The instruction sets the reduction is compiled for (`reduce`'s `ISA`): the portable
/// compilation, and the two whose product's rows are written in intrinsics.
const PORTABLE: u8 = 0;
#[cfg(target_arch = "x86_64")]
const AVX2: u8 = 1;
#[cfg(target_arch = "x86_64")]
const AVX512: u8 = 2;

/// Columns of the trailing block updated in one pass ([`update`]).
const UPDATE_COLUMNS: usize = 4;

/// Rows of [`update`]'s register tile.
const UPDATE_ROWS: usize = 8;

/// A reduction: the matrix (`n × n`, its lower triangle read) and the values to transform, to the
/// tridiagonal form's diagonal and subdiagonal ([`tridiagonalise`]).
pub(crate) type Reduction = fn(&[f64], usize, &mut [Vec<f64>]) -> (Vec<f64>, Vec<f64>);

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

/// Reduces the symmetric `n × n` matrix `a` (column-major; its lower triangle read, on a
/// copy whose columns start cache lines) to tridiagonal form `T = Qᵀ A Q` by `n − 2`
/// Householder reflections `I − τ v vᵀ` (`v` leading 1), applying them to each of `values`
/// (`z = Qᵀ y`). Returns `T`'s diagonal and subdiagonal (signed).
///
/// On x86-64 with AVX-512, or with AVX2 and FMA, the same code is compiled for them and
/// chosen at run time; the bits are those of [`tridiagonalise_portable`] (module docs).
pub(crate) fn tridiagonalise(a: &[f64], n: usize, values: &mut [Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let fastest = compilations()
        .pop()
        .map_or(tridiagonalise_portable as Reduction, |c| c.1);
    fastest(a, n, values)
}

/// The compilations of the reduction this processor runs, by name, slowest first: the
/// portable one, then those for AVX2 and FMA and for AVX-512 where it has them.
pub(crate) fn compilations() -> Vec<(&'static str, Reduction)> {
    let mut all: Vec<(&'static str, Reduction)> = vec![("portable", tridiagonalise_portable)];
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the processor has AVX2 and FMA (checked just above).
            all.push(("avx2", |a, n, values| unsafe {
                tridiagonalise_avx2(a, n, values)
            }));
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the processor has AVX-512F, AVX2 and FMA (checked above).
                all.push(("avx512", |a, n, values| unsafe {
                    tridiagonalise_avx512(a, n, values)
                }));
            }
        }
    }
    all
}

/// [`tridiagonalise_portable`] compiled for AVX2 and FMA.
///
/// # Safety
///
/// The processor must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn tridiagonalise_avx2(
    a: &[f64],
    n: usize,
    values: &mut [Vec<f64>],
) -> (Vec<f64>, Vec<f64>) {
    reduce::<AVX2>(a, n, values)
}

/// [`tridiagonalise_portable`] compiled for AVX-512 (and AVX2 and FMA).
///
/// # Safety
///
/// The processor must have AVX-512F, AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn tridiagonalise_avx512(
    a: &[f64],
    n: usize,
    values: &mut [Vec<f64>],
) -> (Vec<f64>, Vec<f64>) {
    reduce::<AVX512>(a, n, values)
}

/// The reduction ([`tridiagonalise`]) in the compilation for any processor of the target.
pub(crate) fn tridiagonalise_portable(
    a: &[f64],
    n: usize,
    values: &mut [Vec<f64>],
) -> (Vec<f64>, Vec<f64>) {
    reduce::<PORTABLE>(a, n, values)
}

/// The reduction, panel by panel (module docs); with `ISA` [`AVX2`] or [`AVX512`], the
/// product's loop in that set's intrinsics, which only the compilation for it may ask for.
#[inline(always)]
fn reduce<const ISA: u8>(a: &[f64], n: usize, values: &mut [Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(a.len(), n * n, "a square matrix");
    assert!(values.iter().all(|y| y.len() == n), "one value per row");
    // The matrix's lower triangle, and the panel's reflectors `V` and their updates `W`
    // (column t zero above its first row; the trailing block, updated, is
    // `A − V Wᵀ − W Vᵀ`), each column at a multiple of `ld` from a cache line's start.
    let ld = n.next_multiple_of(LINE);
    let mut matrix = Lines::zeros(ld * n);
    let m = matrix.as_mut_slice();
    for j in 0..n {
        m[j * ld + j..j * ld + n].copy_from_slice(&a[j * n + j..(j + 1) * n]);
    }
    let mut off_diagonal = vec![0.0; n.saturating_sub(1)];
    let (mut reflectors, mut updates) = (Lines::zeros(ld * PANEL), Lines::zeros(ld * PANEL));
    let (reflectors, updates) = (reflectors.as_mut_slice(), updates.as_mut_slice());
    let mut p = Lines::zeros(n);
    let p = p.as_mut_slice();
    let mut first = 0;
    while first + 1 < n {
        let width = PANEL.min(n - 1 - first);
        for j in 0..width {
            let k = first + j;
            // Column k, from the diagonal down, updated by the panel's earlier reflections.
            let column = &mut m[k * ld + k..k * ld + n];
            for t in 0..j {
                let v = &reflectors[t * ld + k..t * ld + n];
                let w = &updates[t * ld + k..t * ld + n];
                let (wk, vk) = (w[0], v[0]);
                for ((x, &vr), &wr) in column.iter_mut().zip(v).zip(w) {
                    *x = f64::mul_add(-vr, wk, f64::mul_add(-wr, vk, *x));
                }
            }
            let (tau, beta) = reflection(&mut column[1..]);
            off_diagonal[k] = beta;
            let (done, rest) = reflectors.split_at_mut(j * ld);
            let v = &mut rest[..n];
            let w = &mut updates[j * ld..j * ld + n];
            v.fill(0.0);
            w.fill(0.0);
            if tau == 0.0 {
                continue;
            }
            v[k + 1] = 1.0;
            v[k + 2..].copy_from_slice(&m[k * ld + k + 2..k * ld + n]);
            // p = B v for the trailing block B as it is, less the panel's earlier
            // reflections' share: B v − V (Wᵀv) − W (Vᵀv).
            product::<ISA>(m, ld, k + 1, v, p);
            for t in 0..j {
                let vt = &done[t * ld + k + 1..t * ld + n];
                let wt = &updates[t * ld + k + 1..t * ld + n];
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
            let w = &mut updates[j * ld..j * ld + n];
            for ((wi, &pi), &vi) in w[k + 1..].iter_mut().zip(&p[k + 1..]).zip(&v[k + 1..]) {
                *wi = f64::mul_add(-half, vi, pi);
            }
        }
        first += width;
        update(m, ld, n, first, reflectors, updates, width);
    }
    let diagonal = (0..n).map(|i| m[i * ld + i]).collect();
    (diagonal, off_diagonal)
}

/// Doubles in a cache line (64 bytes).
const LINE: usize = 8;

/// Zeros whose first starts a cache line: the reduction's matrix and vectors. With columns
/// a multiple of [`LINE`] apart, a chunk of rows that starts at a multiple of [`LINE`] is
/// one line, and no vector load spans two.
struct Lines {
    storage: Vec<f64>,
    offset: usize,
    len: usize,
}

impl Lines {
    fn zeros(len: usize) -> Lines {
        let storage = vec![0.0; len + LINE - 1];
        // At most LINE − 1 doubles on; were the offset unknown (`usize::MAX`), merely
        // unaligned.
        let offset = (storage.as_ptr())
            .align_offset(LINE * size_of::<f64>())
            .min(LINE - 1);
        Lines {
            storage,
            offset,
            len,
        }
    }

    fn as_mut_slice(&mut self) -> &mut [f64] {
        &mut self.storage[self.offset..self.offset + self.len]
    }
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
    fold(sums) + tail
}

/// Eight interleaved partial sums added pairwise, in the one order every sum of the
/// reduction uses ([`dot`], [`product_columns`]' lane sums).
#[inline(always)]
fn fold([s0, s1, s2, s3, s4, s5, s6, s7]: [f64; 8]) -> f64 {
    ((s0 + s4) + (s2 + s6)) + ((s1 + s5) + (s3 + s7))
}

/// `p[s..] = B v[s..]` for the trailing block `B = A[s.., s..]` of `a` (column `j` at
/// `j · ld`, `p.len()` rows), its lower triangle read: [`PRODUCT_COLUMNS`] columns per
/// pass, each serving their rows' share of `p` (an update) and its own row (a dot product).
#[inline(always)]
fn product<const ISA: u8>(a: &[f64], ld: usize, s: usize, v: &[f64], p: &mut [f64]) {
    let n = p.len();
    p[s..].fill(0.0);
    let mut c = s;
    while c + PRODUCT_COLUMNS <= n {
        product_columns::<PRODUCT_COLUMNS, ISA>(a, ld, c, v, p);
        c += PRODUCT_COLUMNS;
    }
    while c < n {
        product_columns::<1, PORTABLE>(a, ld, c, v, p);
        c += 1;
    }
}

/// [`product`]'s share of columns `c..c + W`; with `ISA` [`AVX2`] or [`AVX512`] (and `W` =
/// [`PRODUCT_COLUMNS`]), its chunks of rows by [`product_rows_avx2`] or
/// [`product_rows_avx512`]. The chunks start at rows that are multiples of [`LINE`], so
/// each is a cache line of each column; the rows before the first and after the last are
/// taken one at a time.
#[inline(always)]
fn product_columns<const W: usize, const ISA: u8>(
    a: &[f64],
    ld: usize,
    c: usize,
    v: &[f64],
    p: &mut [f64],
) {
    let n = p.len();
    let column: [&[f64]; W] = std::array::from_fn(|j| &a[(c + j) * ld..(c + j) * ld + n]);
    let vc: [f64; W] = std::array::from_fn(|j| v[c + j]);
    // The block on the diagonal, its lower triangle.
    for i in 0..W {
        for j in 0..=i {
            let b = column[j][c + i];
            p[c + i] = b.mul_add(v[c + j], p[c + i]);
            if j < i {
                p[c + j] = b.mul_add(v[c + i], p[c + j]);
            }
        }
    }
    let start = c + W;
    let aligned = start.next_multiple_of(LINE).min(n);
    let mut heads = [0.0; W];
    single_rows(&column, &vc, v, p, start..aligned, &mut heads);
    let chunks = (n - aligned) / PRODUCT_LANES;
    let end = aligned + chunks * PRODUCT_LANES;
    let columns: [&[f64]; W] = std::array::from_fn(|j| &column[j][aligned..end]);
    let (vr, pr) = (&v[aligned..end], &mut p[aligned..end]);
    let mut sums = [[0.0; PRODUCT_LANES]; W];
    let done = vector_product_rows::<ISA>(&columns, &vc, vr, pr, chunks, &mut sums);
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
    single_rows(&column, &vc, v, p, end..n, &mut tails);
    for j in 0..W {
        p[c + j] += (heads[j] + fold(sums[j])) + tails[j];
    }
}

/// [`product_columns`]' `rows` one at a time: each row's share of `p`, and each column's
/// sum `ends[j]` over them in row order. (A function, not a closure: a closure does not
/// inherit the compilation's target features, and its `mul_add` would be a library call.)
#[inline(always)]
fn single_rows<const W: usize>(
    column: &[&[f64]; W],
    vc: &[f64; W],
    v: &[f64],
    p: &mut [f64],
    rows: std::ops::Range<usize>,
    ends: &mut [f64; W],
) {
    for r in rows {
        let mut acc = p[r];
        for j in 0..W {
            acc = column[j][r].mul_add(vc[j], acc);
            ends[j] = column[j][r].mul_add(v[r], ends[j]);
        }
        p[r] = acc;
    }
}

/// [`product_columns`]' rows in `ISA`'s intrinsics where they are compiled: returns the
/// chunks done (all, or none for the portable compilation).
#[inline(always)]
fn vector_product_rows<const ISA: u8>(
    columns: &[&[f64]],
    vc: &[f64],
    vr: &[f64],
    pr: &mut [f64],
    chunks: usize,
    sums: &mut [[f64; PRODUCT_LANES]],
) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        if ISA == AVX512 {
            // SAFETY: only `tridiagonalise_avx512` asks for these rows (`reduce::<AVX512>`),
            // and its caller checked that the processor has AVX-512F, AVX2 and FMA.
            unsafe { product_rows_avx512(columns, vc, vr, pr, chunks, sums) };
            return chunks;
        }
        if ISA == AVX2 {
            // SAFETY: only `tridiagonalise_avx2` asks for these rows (`reduce::<AVX2>`), and
            // its caller checked that the processor has AVX2 and FMA.
            unsafe { product_rows_avx2(columns, vc, vr, pr, chunks, sums) };
            return chunks;
        }
    }
    let _ = (columns, vc, vr, pr, chunks, sums);
    0
}

/// The bounds every load and store of [`product_rows_avx2`] and [`product_rows_avx512`]
/// stays within: [`PRODUCT_COLUMNS`] columns, each as long as the rows, and `chunks` whole
/// chunks of [`PRODUCT_LANES`] rows.
#[cfg(target_arch = "x86_64")]
fn check_product_rows(
    columns: &[&[f64]],
    vc: &[f64],
    vr: &[f64],
    pr: &[f64],
    chunks: usize,
    sums: &[[f64; PRODUCT_LANES]],
) {
    const W: usize = PRODUCT_COLUMNS;
    assert!(columns.len() == W && vc.len() == W && sums.len() == W);
    assert!(vr.len() == pr.len() && columns.iter().all(|c| c.len() == vr.len()));
    assert!(chunks * PRODUCT_LANES <= vr.len());
}

/// [`product_columns`]' loop over its first `chunks` chunks of [`PRODUCT_LANES`] rows, in
/// AVX-512 intrinsics: per chunk, the rows' sums `p[r] += Σ_j B[r, c + j] v[c + j]` taken
/// over the columns in order, and each column's lane sums `sums[j][l] += B[r, c + j] v[r]`,
/// the portable loop's operations exactly; four chunks at a time (then one), so that their
/// chains of dependent multiply-adds overlap. Its 28 registers fit AVX-512's 32.
///
/// # Safety
///
/// The processor must have AVX-512F, AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn product_rows_avx512(
    columns: &[&[f64]],
    vc: &[f64],
    vr: &[f64],
    pr: &mut [f64],
    chunks: usize,
    sums: &mut [[f64; PRODUCT_LANES]],
) {
    use std::arch::x86_64::{
        __m512d, _mm512_fmadd_pd, _mm512_loadu_pd, _mm512_set1_pd, _mm512_setzero_pd,
        _mm512_storeu_pd,
    };
    const W: usize = PRODUCT_COLUMNS;
    check_product_rows(columns, vc, vr, pr, chunks, sums);
    let column: [*const f64; W] = std::array::from_fn(|j| columns[j].as_ptr());
    let vc: [__m512d; W] = std::array::from_fn(|j| _mm512_set1_pd(vc[j]));
    let mut s: [__m512d; W] = [_mm512_setzero_pd(); W];
    let (vr, pr) = (vr.as_ptr(), pr.as_mut_ptr());
    // SAFETY (every load and store): rows r..r + PRODUCT_LANES for r below
    // chunks · PRODUCT_LANES, within every slice (`check_product_rows`).
    let mut q = 0;
    while q + 4 <= chunks {
        let r: [usize; 4] = std::array::from_fn(|c| (q + c) * PRODUCT_LANES);
        let mut acc = r.map(|r| _mm512_loadu_pd(pr.add(r)));
        let vq = r.map(|r| _mm512_loadu_pd(vr.add(r)));
        for j in 0..W {
            let b = r.map(|r| _mm512_loadu_pd(column[j].add(r)));
            for c in 0..4 {
                acc[c] = _mm512_fmadd_pd(b[c], vc[j], acc[c]);
            }
            let mut sum = s[j];
            for c in 0..4 {
                sum = _mm512_fmadd_pd(b[c], vq[c], sum);
            }
            s[j] = sum;
        }
        for c in 0..4 {
            _mm512_storeu_pd(pr.add(r[c]), acc[c]);
        }
        q += 4;
    }
    while q < chunks {
        let r0 = q * PRODUCT_LANES;
        let mut acc = _mm512_loadu_pd(pr.add(r0));
        let vq = _mm512_loadu_pd(vr.add(r0));
        for j in 0..W {
            let b = _mm512_loadu_pd(column[j].add(r0));
            acc = _mm512_fmadd_pd(b, vc[j], acc);
            s[j] = _mm512_fmadd_pd(b, vq, s[j]);
        }
        _mm512_storeu_pd(pr.add(r0), acc);
        q += 1;
    }
    for (sum, s) in sums.iter_mut().zip(s) {
        _mm512_storeu_pd(sum.as_mut_ptr(), s);
    }
}

/// [`product_rows_avx512`] in AVX2 and FMA intrinsics: a chunk's eight lanes in two
/// registers, so half the columns at a time (their sums, sixteen registers, would not fit
/// with all), each half a pass over the rows; a row's sum over the columns is taken in the
/// same order, the second pass carrying on from the first's.
///
/// # Safety
///
/// The processor must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn product_rows_avx2(
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
    const HALF: usize = PRODUCT_COLUMNS / 2;
    check_product_rows(columns, vc, vr, pr, chunks, sums);
    let (vr, pr) = (vr.as_ptr(), pr.as_mut_ptr());
    for first in [0, HALF] {
        let column: [*const f64; HALF] = std::array::from_fn(|j| columns[first + j].as_ptr());
        let vc: [__m256d; HALF] = std::array::from_fn(|j| _mm256_set1_pd(vc[first + j]));
        let mut s: [[__m256d; 2]; HALF] = [[_mm256_setzero_pd(); 2]; HALF];
        // SAFETY (every load and store): rows r..r + PRODUCT_LANES for r below
        // chunks · PRODUCT_LANES, within every slice (`check_product_rows`).
        for q in 0..chunks {
            let r = [q * PRODUCT_LANES, q * PRODUCT_LANES + 4];
            let mut acc = r.map(|r| _mm256_loadu_pd(pr.add(r)));
            let vq = r.map(|r| _mm256_loadu_pd(vr.add(r)));
            for j in 0..HALF {
                let b = r.map(|r| _mm256_loadu_pd(column[j].add(r)));
                for h in 0..2 {
                    acc[h] = _mm256_fmadd_pd(b[h], vc[j], acc[h]);
                    s[j][h] = _mm256_fmadd_pd(b[h], vq[h], s[j][h]);
                }
            }
            for h in 0..2 {
                _mm256_storeu_pd(pr.add(r[h]), acc[h]);
            }
        }
        for (sum, s) in sums[first..first + HALF].iter_mut().zip(s) {
            _mm256_storeu_pd(sum.as_mut_ptr(), s[0]);
            _mm256_storeu_pd(sum.as_mut_ptr().add(4), s[1]);
        }
    }
}

/// The panel's update of the trailing block `A[s.., s..]` (column `j` at `j · ld`, `n`
/// rows), lower triangle: `A −= V Wᵀ + W Vᵀ` over its `width` reflectors,
/// [`UPDATE_COLUMNS`] columns at a time in tiles of [`UPDATE_ROWS`] rows held while all
/// the reflectors pass.
#[inline(always)]
fn update(
    a: &mut [f64],
    ld: usize,
    n: usize,
    s: usize,
    reflectors: &[f64],
    updates: &[f64],
    width: usize,
) {
    let mut c = s;
    while c + UPDATE_COLUMNS <= n {
        update_columns::<UPDATE_COLUMNS>(a, ld, n, c, reflectors, updates, width);
        c += UPDATE_COLUMNS;
    }
    while c < n {
        update_columns::<1>(a, ld, n, c, reflectors, updates, width);
        c += 1;
    }
}

/// [`update`]'s share of columns `c..c + W`, rows from `c` down (the few above the
/// diagonal are updated too, and never read): in tiles that start at rows that are
/// multiples of [`LINE`], the rows before the first and after the last one at a time.
/// Each element's multiply-adds are over the reflectors in order, however the rows are
/// grouped.
#[inline(always)]
fn update_columns<const W: usize>(
    a: &mut [f64],
    ld: usize,
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
            *pair = [updates[t * ld + c + j], reflectors[t * ld + c + j]];
        }
    }
    let aligned = c.next_multiple_of(LINE).min(n);
    let chunks = (n - aligned) / UPDATE_ROWS;
    for q in 0..chunks {
        let r0 = aligned + q * UPDATE_ROWS;
        let mut tile = [[0.0; UPDATE_ROWS]; W];
        for (j, rows) in tile.iter_mut().enumerate() {
            rows.copy_from_slice(&a[(c + j) * ld + r0..(c + j) * ld + r0 + UPDATE_ROWS]);
        }
        for (t, row) in coefficients.iter().enumerate().take(width) {
            let vt = &reflectors[t * ld + r0..t * ld + r0 + UPDATE_ROWS];
            let wt = &updates[t * ld + r0..t * ld + r0 + UPDATE_ROWS];
            for (rows, &[wc, vc]) in tile.iter_mut().zip(row) {
                for l in 0..UPDATE_ROWS {
                    rows[l] = f64::mul_add(-vt[l], wc, f64::mul_add(-wt[l], vc, rows[l]));
                }
            }
        }
        for (j, rows) in tile.iter().enumerate() {
            a[(c + j) * ld + r0..(c + j) * ld + r0 + UPDATE_ROWS].copy_from_slice(rows);
        }
    }
    for r in (c..aligned).chain(aligned + chunks * UPDATE_ROWS..n) {
        for j in 0..W {
            let mut x = a[(c + j) * ld + r];
            for (t, row) in coefficients.iter().enumerate().take(width) {
                let [wc, vc] = row[j];
                x = f64::mul_add(
                    -reflectors[t * ld + r],
                    wc,
                    f64::mul_add(-updates[t * ld + r], vc, x),
                );
            }
            a[(c + j) * ld + r] = x;
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

    fn bits((d, e): &(Vec<f64>, Vec<f64>), values: &[Vec<f64>]) -> Vec<u64> {
        (d.iter().chain(e).chain(values.iter().flatten()))
            .map(|v| v.to_bits())
            .collect()
    }

    /// Property: every compilation of the reduction this processor runs (with the
    /// product's rows in AVX2 or AVX-512 intrinsics where it has them), and the one chosen
    /// at run time, give the portable compilation's bits: the diagonal, the subdiagonal and
    /// the transformed values, on sizes below, at and across a panel, with every count of
    /// chunks of rows modulo four in the product's passes and rows left over, and on random
    /// sizes to 300.
    #[test]
    fn every_compilation_of_the_reduction_is_the_portable_one_to_the_bit() {
        if !fused_in_hardware() {
            // The portable compilation's fused multiply-adds would be library calls: the
            // processor-independent bits are checked where they are fast.
            return;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(41);
        let mut sizes: Vec<usize> = (1..=48).collect();
        sizes.extend([63, 64, 65, 95, 96, 97, 128, 129, 131]);
        sizes.extend((0..12).map(|_| rng.gen_range(100..300)));
        let mut compilations = compilations();
        compilations.push(("dispatched", tridiagonalise));
        for n in sizes {
            let width = 1 + n % 3;
            let (a, values) = case(n, width, &mut rng);
            let mut slow_values = values.clone();
            let want = tridiagonalise_portable(&a, n, &mut slow_values);
            for (name, reduce) in &compilations {
                let mut fast_values = values.clone();
                let got = reduce(&a, n, &mut fast_values);
                assert_eq!(
                    bits(&got, &fast_values),
                    bits(&want, &slow_values),
                    "{name}, n = {n}"
                );
            }
        }
    }
}
