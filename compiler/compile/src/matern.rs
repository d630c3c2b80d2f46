//! The Matérn 5/2 correlation over many distances at once, four lanes at a time with AVX2
//! and FMA, to the bit of the scalar [`matern52`].
//!
//! A table's kriging nodes each sum the correlation over every sample, per component (the
//! UR5's 1,000 samples at some 50,000 nodes: 150 million exponentials), and every setting
//! of the likelihood search fills a covariance matrix with it: a fifth of a build's
//! processor time, most of it in the exponential, a library call per value. Here the
//! exponential is glibc's own algorithm (ARM's optimized routines: `2^(k/128)` from a
//! table times a polynomial in the remainder, [`EXP_TABLE`]), written in intrinsics with
//! the very fused multiply-adds, in the very order, of glibc's x86-64 FMA compilation, so
//! that where the platform's `exp` is that one the values, and so the tables, are those of
//! the scalar code to the bit. Whether it is is checked once, at first use, on a fixed set
//! of arguments ([`vector_exp_agrees`]); where it is not (another library, a processor
//! without AVX2 or FMA) the scalar code runs as before.

use std::sync::OnceLock;

/// Matérn 5/2 correlation at distance `h` for length scale `l`: the scalar definition the
/// lanes below reproduce to the bit.
#[inline]
pub fn matern52(h: f64, l: f64) -> f64 {
    let s = 5f64.sqrt() * h / l;
    (1.0 + s + s * s / 3.0) * (-s).exp()
}

/// `2^(k/128) ≈ H[k] (1 + T[k])` for `k < 128`: `EXP_TABLE[2k]` holds the bits of `T[k]`
/// (the relative error of `H[k]`, rounded), `EXP_TABLE[2k + 1]` those of `H[k]` (rounded)
/// less `k << 45`, so that adding the integer part of the exponent shifted by 45 gives the
/// scale's bits. glibc's `__exp_data.tab`, regenerated from this definition.
#[rustfmt::skip]
const EXP_TABLE: [u64; 256] = [
    0x0000000000000000, 0x3ff0000000000000, 0x3c9b3b4f1a88bf6e, 0x3feff63da9fb3335,
    0xbc7160139cd8dc5d, 0x3fefec9a3e778061, 0xbc905e7a108766d1, 0x3fefe315e86e7f85,
    0x3c8cd2523567f613, 0x3fefd9b0d3158574, 0xbc8bce8023f98efa, 0x3fefd06b29ddf6de,
    0x3c60f74e61e6c861, 0x3fefc74518759bc8, 0x3c90a3e45b33d399, 0x3fefbe3ecac6f383,
    0x3c979aa65d837b6d, 0x3fefb5586cf9890f, 0x3c8eb51a92fdeffc, 0x3fefac922b7247f7,
    0x3c3ebe3d702f9cd1, 0x3fefa3ec32d3d1a2, 0xbc6a033489906e0b, 0x3fef9b66affed31b,
    0xbc9556522a2fbd0e, 0x3fef9301d0125b51, 0xbc5080ef8c4eea55, 0x3fef8abdc06c31cc,
    0xbc91c923b9d5f416, 0x3fef829aaea92de0, 0x3c80d3e3e95c55af, 0x3fef7a98c8a58e51,
    0xbc801b15eaa59348, 0x3fef72b83c7d517b, 0xbc8f1ff055de323d, 0x3fef6af9388c8dea,
    0x3c8b898c3f1353bf, 0x3fef635beb6fcb75, 0xbc96d99c7611eb26, 0x3fef5be084045cd4,
    0x3c9aecf73e3a2f60, 0x3fef54873168b9aa, 0xbc8fe782cb86389d, 0x3fef4d5022fcd91d,
    0x3c8a6f4144a6c38d, 0x3fef463b88628cd6, 0x3c807a05b0e4047d, 0x3fef3f49917ddc96,
    0x3c968efde3a8a894, 0x3fef387a6e756238, 0x3c875e18f274487d, 0x3fef31ce4fb2a63f,
    0x3c80472b981fe7f2, 0x3fef2b4565e27cdd, 0xbc96b87b3f71085e, 0x3fef24dfe1f56381,
    0x3c82f7e16d09ab31, 0x3fef1e9df51fdee1, 0xbc3d219b1a6fbffa, 0x3fef187fd0dad990,
    0x3c8b3782720c0ab4, 0x3fef1285a6e4030b, 0x3c6e149289cecb8f, 0x3fef0cafa93e2f56,
    0x3c834d754db0abb6, 0x3fef06fe0a31b715, 0x3c864201e2ac744c, 0x3fef0170fc4cd831,
    0x3c8fdd395dd3f84a, 0x3feefc08b26416ff, 0xbc86a3803b8e5b04, 0x3feef6c55f929ff1,
    0xbc924aedcc4b5068, 0x3feef1a7373aa9cb, 0xbc9907f81b512d8e, 0x3feeecae6d05d866,
    0xbc71d1e83e9436d2, 0x3feee7db34e59ff7, 0xbc991919b3ce1b15, 0x3feee32dc313a8e5,
    0x3c859f48a72a4c6d, 0x3feedea64c123422, 0xbc9312607a28698a, 0x3feeda4504ac801c,
    0xbc58a78f4817895b, 0x3feed60a21f72e2a, 0xbc7c2c9b67499a1b, 0x3feed1f5d950a897,
    0x3c4363ed60c2ac11, 0x3feece086061892d, 0x3c9666093b0664ef, 0x3feeca41ed1d0057,
    0x3c6ecce1daa10379, 0x3feec6a2b5c13cd0, 0x3c93ff8e3f0f1230, 0x3feec32af0d7d3de,
    0x3c7690cebb7aafb0, 0x3feebfdad5362a27, 0x3c931dbdeb54e077, 0x3feebcb299fddd0d,
    0xbc8f94340071a38e, 0x3feeb9b2769d2ca7, 0xbc87deccdc93a349, 0x3feeb6daa2cf6642,
    0xbc78dec6bd0f385f, 0x3feeb42b569d4f82, 0xbc861246ec7b5cf6, 0x3feeb1a4ca5d920f,
    0x3c93350518fdd78e, 0x3feeaf4736b527da, 0x3c7b98b72f8a9b05, 0x3feead12d497c7fd,
    0x3c9063e1e21c5409, 0x3feeab07dd485429, 0x3c34c7855019c6ea, 0x3feea9268a5946b7,
    0x3c9432e62b64c035, 0x3feea76f15ad2148, 0xbc8ce44a6199769f, 0x3feea5e1b976dc09,
    0xbc8c33c53bef4da8, 0x3feea47eb03a5585, 0xbc845378892be9ae, 0x3feea34634ccc320,
    0xbc93cedd78565858, 0x3feea23882552225, 0x3c5710aa807e1964, 0x3feea155d44ca973,
    0xbc93b3efbf5e2228, 0x3feea09e667f3bcd, 0xbc6a12ad8734b982, 0x3feea012750bdabf,
    0xbc6367efb86da9ee, 0x3fee9fb23c651a2f, 0xbc80dc3d54e08851, 0x3fee9f7df9519484,
    0xbc781f647e5a3ecf, 0x3fee9f75e8ec5f74, 0xbc86ee4ac08b7db0, 0x3fee9f9a48a58174,
    0xbc8619321e55e68a, 0x3fee9feb564267c9, 0x3c909ccb5e09d4d3, 0x3feea0694fde5d3f,
    0xbc7b32dcb94da51d, 0x3feea11473eb0187, 0x3c94ecfd5467c06b, 0x3feea1ed0130c132,
    0x3c65ebe1abd66c55, 0x3feea2f336cf4e62, 0xbc88a1c52fb3cf42, 0x3feea427543e1a12,
    0xbc9369b6f13b3734, 0x3feea589994cce13, 0xbc805e843a19ff1e, 0x3feea71a4623c7ad,
    0xbc94d450d872576e, 0x3feea8d99b4492ed, 0x3c90ad675b0e8a00, 0x3feeaac7d98a6699,
    0x3c8db72fc1f0eab4, 0x3feeace5422aa0db, 0xbc65b6609cc5e7ff, 0x3feeaf3216b5448c,
    0x3c7bf68359f35f44, 0x3feeb1ae99157736, 0xbc93091fa71e3d83, 0x3feeb45b0b91ffc6,
    0xbc5da9b88b6c1e29, 0x3feeb737b0cdc5e5, 0xbc6c23f97c90b959, 0x3feeba44cbc8520f,
    0xbc92434322f4f9aa, 0x3feebd829fde4e50, 0xbc85ca6cd7668e4b, 0x3feec0f170ca07ba,
    0x3c71affc2b91ce27, 0x3feec49182a3f090, 0x3c6dd235e10a73bb, 0x3feec86319e32323,
    0xbc87c50422622263, 0x3feecc667b5de565, 0x3c8b1c86e3e231d5, 0x3feed09bec4a2d33,
    0xbc91bbd1d3bcbb15, 0x3feed503b23e255d, 0x3c90cc319cee31d2, 0x3feed99e1330b358,
    0x3c8469846e735ab3, 0x3feede6b5579fdbf, 0xbc82dfcd978e9db4, 0x3feee36bbfd3f37a,
    0x3c8c1a7792cb3387, 0x3feee89f995ad3ad, 0xbc907b8f4ad1d9fa, 0x3feeee07298db666,
    0xbc55c3d956dcaeba, 0x3feef3a2b84f15fb, 0xbc90a40e3da6f640, 0x3feef9728de5593a,
    0xbc68d6f438ad9334, 0x3feeff76f2fb5e47, 0xbc91eee26b588a35, 0x3fef05b030a1064a,
    0x3c74ffd70a5fddcd, 0x3fef0c1e904bc1d2, 0xbc91bdfbfa9298ac, 0x3fef12c25bd71e09,
    0x3c736eae30af0cb3, 0x3fef199bdd85529c, 0x3c8ee3325c9ffd94, 0x3fef20ab5fffd07a,
    0x3c84e08fd10959ac, 0x3fef27f12e57d14b, 0x3c63cdaf384e1a67, 0x3fef2f6d9406e7b5,
    0x3c676b2c6c921968, 0x3fef3720dcef9069, 0xbc808a1883ccb5d2, 0x3fef3f0b555dc3fa,
    0xbc8fad5d3ffffa6f, 0x3fef472d4a07897c, 0xbc900dae3875a949, 0x3fef4f87080d89f2,
    0x3c74a385a63d07a7, 0x3fef5818dcfba487, 0xbc82919e2040220f, 0x3fef60e316c98398,
    0x3c8e5a50d5c192ac, 0x3fef69e603db3285, 0x3c843a59ac016b4b, 0x3fef7321f301b460,
    0xbc82d52107b43e1f, 0x3fef7c97337b9b5f, 0xbc892ab93b470dc9, 0x3fef864614f5a129,
    0x3c74b604603a88d3, 0x3fef902ee78b3ff6, 0x3c83c5ec519d7271, 0x3fef9a51fbc74c83,
    0xbc8ff7128fd391f0, 0x3fefa4afa2a490da, 0xbc8dae98e223747d, 0x3fefaf482d8e67f1,
    0x3c8ec3bc41aa2008, 0x3fefba1bee615a27, 0x3c842b94c3a9eb32, 0x3fefc52b376bba97,
    0x3c8a64a931d185ee, 0x3fefd0765b6e4540, 0xbc8e37bae43be3ed, 0x3fefdbfdad9cbe14,
    0x3c77893b4d91cd9d, 0x3fefe7c1819e90d8, 0x3c5305c14160cc89, 0x3feff3c22b8f71f1,
];

/// `128 / ln 2`.
const INV_LN2_N: f64 = 184.6649652337873;
/// `−ln 2 / 128`, high part (its low bits zero, so that `k` times it is exact).
const NEG_LN2_HI_N: f64 = -0.005415212348111709;
/// `−ln 2 / 128`, the rest.
const NEG_LN2_LO_N: f64 = -1.2864023111638346e-14;
/// `1.5 · 2^52`: added, rounds to an integer in the low bits.
const SHIFT: f64 = 6755399441055744.0;
/// The polynomial's coefficients of `r²` to `r⁵` (`exp(r) − 1 − r`, fitted).
const C2: f64 = 0.49999999999996786;
const C3: f64 = 0.16666666666665886;
const C4: f64 = 0.0416666808410674;
const C5: f64 = 0.008333335853059549;

/// The biased exponents (bits 52 to 62) of the arguments the table's path takes,
/// `2^−54 ≤ |x| < 512`; the others (zero, tiny, huge, not finite) go to the library.
const FIRST_TOP: u64 = 0x3c9;
const END_TOP: u64 = 0x408;

/// `exp(x)` by the algorithm of the module docs, scalar and portable, for `x` with
/// `2^−54 ≤ |x| < 512`; `None` for the others. The reference the lanes are held to, and
/// what fixes the arguments [`vector_exp_agrees`] checks.
pub(crate) fn exp_by_table(x: f64) -> Option<f64> {
    let top = x.to_bits() >> 52 & 0x7ff;
    if !(FIRST_TOP..END_TOP).contains(&top) {
        return None;
    }
    let shifted = x.mul_add(INV_LN2_N, SHIFT);
    let k_bits = shifted.to_bits();
    let kd = shifted - SHIFT;
    let r = kd.mul_add(NEG_LN2_LO_N, kd.mul_add(NEG_LN2_HI_N, x));
    let index = 2 * (k_bits % 128) as usize;
    let tail = f64::from_bits(EXP_TABLE[index]);
    let scale = f64::from_bits(EXP_TABLE[index + 1].wrapping_add(k_bits << 45));
    let r2 = r * r;
    let low = r.mul_add(C3, C2).mul_add(r2, r + tail);
    let tmp = (r2 * r2).mul_add(r.mul_add(C5, C4), low);
    Some(scale.mul_add(tmp, scale))
}

/// Whether the lanes run here: AVX2 and FMA, and the platform's `exp` the algorithm of the
/// module docs to the bit on a fixed spread of arguments (every exponent the table's path
/// takes, with many mantissas, and the Matérn's typical range densely).
pub(crate) fn vector_exp_agrees() -> bool {
    static AGREES: OnceLock<bool> = OnceLock::new();
    *AGREES.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return check_arguments()
                .all(|x| exp_by_table(x).map(f64::to_bits) == Some(x.exp().to_bits()));
        }
        false
    })
}

/// The arguments [`vector_exp_agrees`] checks: for each biased exponent of the table's
/// path, 32 mantissas (a fixed multiplicative sequence), both signs; and 4,096 evenly
/// spaced in `[−64, 0)`.
fn check_arguments() -> impl Iterator<Item = f64> {
    let spread = (FIRST_TOP..END_TOP).flat_map(|top| {
        (0..32u64).flat_map(move |m| {
            let mantissa = m.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 12;
            let x = f64::from_bits(top << 52 | mantissa);
            [x, -x]
        })
    });
    spread.chain((1..=4096).map(|i| -64.0 * i as f64 / 4096.0))
}

/// `out[i] = matern52(h[i], l)` ([`matern52`], to the bit): four at
/// a time where the lanes run ([`vector_exp_agrees`]), else one by one.
///
/// # Panics
///
/// If `h` and `out` differ in length.
pub(crate) fn matern52_many(h: &[f64], l: f64, out: &mut [f64]) {
    assert_eq!(h.len(), out.len(), "one output per distance");
    #[cfg(target_arch = "x86_64")]
    if vector_exp_agrees() {
        // SAFETY: the processor has AVX2 and FMA (checked by `vector_exp_agrees`).
        unsafe { matern52_avx2(h, l, out) };
        return;
    }
    for (o, &h) in out.iter_mut().zip(h) {
        *o = matern52(h, l);
    }
}

/// `h[i] = √((dx[i]² + dy[i]²) + dz[i]²)`, the distances of
/// [`crate::nugget_kriging::scaled_distance`] from the coordinates' differences (the
/// vertical one scaled), to the bit: in AVX2 lanes where the processor has them.
///
/// # Panics
///
/// If the slices differ in length.
pub(crate) fn distances_3d(dx: &[f64], dy: &[f64], dz: &[f64], h: &mut [f64]) {
    assert!(dx.len() == h.len() && dy.len() == h.len() && dz.len() == h.len());
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2 (checked just above).
        unsafe { distances_3d_avx2(dx, dy, dz, h) };
        return;
    }
    distances_3d_portable(dx, dy, dz, h);
}

/// [`distances_3d`] compiled for AVX2 (elementwise, and a square root is correctly
/// rounded: the same bits in any number of lanes).
///
/// # Safety
///
/// The processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn distances_3d_avx2(dx: &[f64], dy: &[f64], dz: &[f64], h: &mut [f64]) {
    distances_3d_portable(dx, dy, dz, h);
}

#[inline(always)]
fn distances_3d_portable(dx: &[f64], dy: &[f64], dz: &[f64], h: &mut [f64]) {
    for (((h, &x), &y), &z) in h.iter_mut().zip(dx).zip(dy).zip(dz) {
        *h = (x * x + y * y + z * z).sqrt();
    }
}

/// [`matern52_many`] in AVX2 and FMA: per four distances `s = √5 h / l`, `exp(−s)` by the
/// table (lanes outside its arguments by the library), `(1 + s + s²/3) exp(−s)`, each
/// operation that of the scalar code.
///
/// # Safety
///
/// The processor must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn matern52_avx2(h: &[f64], l: f64, out: &mut [f64]) {
    use std::arch::x86_64::{
        _mm256_add_epi64, _mm256_add_pd, _mm256_and_si256, _mm256_castpd_si256,
        _mm256_castsi256_pd, _mm256_cmpgt_epi64, _mm256_div_pd, _mm256_fmadd_pd,
        _mm256_i64gather_epi64, _mm256_i64gather_pd, _mm256_loadu_pd, _mm256_movemask_pd,
        _mm256_mul_pd, _mm256_set1_epi64x, _mm256_set1_pd, _mm256_slli_epi64, _mm256_srli_epi64,
        _mm256_storeu_pd, _mm256_sub_pd, _mm256_xor_pd,
    };
    let chunks = h.len() / 4;
    let root5 = _mm256_set1_pd(5f64.sqrt());
    let length = _mm256_set1_pd(l);
    let (one, three) = (_mm256_set1_pd(1.0), _mm256_set1_pd(3.0));
    let sign = _mm256_set1_pd(-0.0);
    let (inv_ln2_n, shift) = (_mm256_set1_pd(INV_LN2_N), _mm256_set1_pd(SHIFT));
    let (neg_ln2_hi, neg_ln2_lo) = (_mm256_set1_pd(NEG_LN2_HI_N), _mm256_set1_pd(NEG_LN2_LO_N));
    let (c2, c3, c4, c5) = (
        _mm256_set1_pd(C2),
        _mm256_set1_pd(C3),
        _mm256_set1_pd(C4),
        _mm256_set1_pd(C5),
    );
    let exponent_mask = _mm256_set1_epi64x(0x7ff);
    let (below, end) = (
        _mm256_set1_epi64x(FIRST_TOP as i64 - 1),
        _mm256_set1_epi64x(END_TOP as i64),
    );
    let index_mask = _mm256_set1_epi64x(127);
    let table = EXP_TABLE.as_ptr();
    for q in 0..chunks {
        // SAFETY: lanes 4q..4q + 4 of `h` and `out` (equal lengths, asserted by the caller).
        let hv = _mm256_loadu_pd(h.as_ptr().add(4 * q));
        let s = _mm256_div_pd(_mm256_mul_pd(root5, hv), length);
        let x = _mm256_xor_pd(s, sign);
        let top = _mm256_and_si256(
            _mm256_srli_epi64::<52>(_mm256_castpd_si256(x)),
            exponent_mask,
        );
        let inside = _mm256_and_si256(_mm256_cmpgt_epi64(top, below), _mm256_cmpgt_epi64(end, top));
        let shifted = _mm256_fmadd_pd(x, inv_ln2_n, shift);
        let k_bits = _mm256_castpd_si256(shifted);
        let kd = _mm256_sub_pd(shifted, shift);
        let r = _mm256_fmadd_pd(kd, neg_ln2_lo, _mm256_fmadd_pd(kd, neg_ln2_hi, x));
        let index = _mm256_slli_epi64::<1>(_mm256_and_si256(k_bits, index_mask));
        // SAFETY: indices below 256 and 255 (masked to 127, doubled), within the table.
        let tail = _mm256_i64gather_pd::<8>(table.cast::<f64>(), index);
        let scale_bits = _mm256_i64gather_epi64::<8>(table.add(1).cast::<i64>(), index);
        let scale = _mm256_castsi256_pd(_mm256_add_epi64(
            scale_bits,
            _mm256_slli_epi64::<45>(k_bits),
        ));
        let r2 = _mm256_mul_pd(r, r);
        let low = _mm256_fmadd_pd(_mm256_fmadd_pd(r, c3, c2), r2, _mm256_add_pd(r, tail));
        let tmp = _mm256_fmadd_pd(_mm256_mul_pd(r2, r2), _mm256_fmadd_pd(r, c5, c4), low);
        let e = _mm256_fmadd_pd(scale, tmp, scale);
        let polynomial = _mm256_add_pd(
            _mm256_add_pd(one, s),
            _mm256_div_pd(_mm256_mul_pd(s, s), three),
        );
        let o = out.as_mut_ptr().add(4 * q);
        _mm256_storeu_pd(o, _mm256_mul_pd(polynomial, e));
        let outside = !_mm256_movemask_pd(_mm256_castsi256_pd(inside)) & 0xf;
        if outside != 0 {
            for lane in 0..4 {
                if outside >> lane & 1 != 0 {
                    let i = 4 * q + lane;
                    out[i] = matern52(h[i], l);
                }
            }
        }
    }
    for i in 4 * chunks..h.len() {
        out[i] = matern52(h[i], l);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The table is its definition: `H[k]` is `2^(k/128)` rounded, and `H[k] (1 + T[k])`
    /// is nearer it than `H[k]`'s rounding error (what the tail corrects).
    #[test]
    fn the_table_is_its_definition() {
        for k in 0..128u64 {
            let h = f64::from_bits(EXP_TABLE[2 * k as usize + 1] + (k << 45));
            let t = f64::from_bits(EXP_TABLE[2 * k as usize]);
            let want = (k as f64 / 128.0).exp2();
            assert!((h - want).abs() <= 0.5 * f64::EPSILON * want, "k {k}");
            assert!(t.abs() <= f64::EPSILON, "k {k}: tail {t}");
        }
    }

    /// Property: where the platform's `exp` is the table's algorithm (glibc on x86-64 with
    /// FMA), it equals [`exp_by_table`] to the bit on a million random arguments of the
    /// table's path, spread over every exponent and over the Matérn's range; and where the
    /// check says so, [`vector_exp_agrees`] agrees.
    #[test]
    fn the_table_exp_is_the_platforms_where_the_lanes_run() {
        if !vector_exp_agrees() {
            return;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(61);
        for i in 0..1_000_000 {
            let x = if i % 2 == 0 {
                -rng.gen_range(0.0..120.0)
            } else {
                let top = rng.gen_range(FIRST_TOP..END_TOP);
                let x = f64::from_bits(top << 52 | rng.gen_range(0..1u64 << 52));
                if rng.gen_bool(0.5) {
                    x
                } else {
                    -x
                }
            };
            if let Some(got) = exp_by_table(x) {
                assert_eq!(got.to_bits(), x.exp().to_bits(), "exp({x:e})");
            }
        }
    }

    /// Property: the lanes give the scalar [`matern52`]'s bits for every distance: random
    /// distances at random length scales, counts that leave 0 to 3 lanes over, and the
    /// arguments outside the table's path (zero, tiny, beyond 512 length scales, infinite,
    /// NaN), in every lane.
    #[test]
    fn the_lanes_are_the_scalar_matern_to_the_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(62);
        let odd = [
            0.0,
            1e-300,
            1e-17,
            5e-324,
            300.0,
            1e4,
            f64::INFINITY,
            f64::NAN,
        ];
        for case in 0..2000 {
            let count = rng.gen_range(0..40);
            let l = rng.gen_range(0.1f64.ln()..1000f64.ln()).exp();
            let mut h: Vec<f64> = (0..count).map(|_| rng.gen_range(0.0..40.0 * l)).collect();
            if case % 3 == 0 && count > 0 {
                let at = rng.gen_range(0..count);
                h[at] = odd[rng.gen_range(0..odd.len())] * l;
            }
            let mut got = vec![0.0; count];
            matern52_many(&h, l, &mut got);
            for (g, &h) in got.iter().zip(&h) {
                assert_eq!(g.to_bits(), matern52(h, l).to_bits(), "h {h:e}, ℓ {l}");
            }
        }
    }
}
