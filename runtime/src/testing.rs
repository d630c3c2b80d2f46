//! Rewriting a table's integrity fields after deliberate damage, for the mutation tests and
//! the fuzz targets: a mutated table must reach rkyv validation and the semantic checks
//! instead of stopping at a checksum; and the slow obvious references of the query path's
//! fast ones, for the tests that hold them equal. Not part of the supported API; a
//! resealed table is no evidence of an intact one.

use crate::format::{ENDIAN_MARK, FORMAT_VERSION, HEADER_LEN, MAGIC, RKYV_FLAGS};
use crate::kinematics::pose_error;
use crate::model::{ModelAt, PreparedModel};

/// The offset of the header checksum, which covers bytes `0..HEADER_CHECKSUM_AT`.
pub const HEADER_CHECKSUM_AT: usize = 248;

/// Recomputes the header checksum only: after editing header fields, so that exactly the
/// edited fields are wrong. Does nothing to fewer than [`HEADER_LEN`] bytes.
pub fn seal_header(bytes: &mut [u8]) {
    if bytes.len() < HEADER_LEN {
        return;
    }
    let checksum = xxhash_rust::xxh3::xxh3_64(&bytes[..HEADER_CHECKSUM_AT]);
    bytes[HEADER_CHECKSUM_AT..HEADER_LEN].copy_from_slice(&checksum.to_le_bytes());
}

/// Sets the payload length to the bytes after the header and recomputes both checksums:
/// after editing, truncating or splicing the payload. Does nothing to fewer than
/// [`HEADER_LEN`] bytes.
pub fn reseal(bytes: &mut [u8]) {
    if bytes.len() < HEADER_LEN {
        return;
    }
    let payload_len = (bytes.len() - HEADER_LEN) as u64;
    bytes[24..32].copy_from_slice(&payload_len.to_le_bytes());
    let payload = xxhash_rust::xxh3::xxh3_64(&bytes[HEADER_LEN..]);
    bytes[32..40].copy_from_slice(&payload.to_le_bytes());
    seal_header(bytes);
}

/// [`reseal`], after rewriting the identification fields that random damage almost
/// always breaks: magic, endianness mark, version, header length and rkyv flags. What
/// remains is the build parameters, the grid and the payload, as mutated.
pub fn repair_header(bytes: &mut [u8]) {
    if bytes.len() < HEADER_LEN {
        return;
    }
    bytes[0..8].copy_from_slice(&MAGIC);
    bytes[8..10].copy_from_slice(&ENDIAN_MARK.to_le_bytes());
    // The newest version of the payload the content flags name: version 5 holds
    // joint-space terms, and only it; version 4 any other payload.
    let flags = u32::from_le_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]);
    let version = if flags & crate::format::CONTENT_JOINT_TERMS != 0 {
        FORMAT_VERSION
    } else {
        4
    };
    bytes[10..12].copy_from_slice(&version.to_le_bytes());
    bytes[12..16].copy_from_slice(&(HEADER_LEN as u32).to_le_bytes());
    bytes[16..20].copy_from_slice(&RKYV_FLAGS.to_le_bytes());
    reseal(bytes);
}

/// A version-1 table of `data` under `header`, as the version-1 writer made them: for
/// tests that damage a version-1 table's contents and re-encode it (the compiler writes
/// version 2 only).
pub fn encode_v1(
    header: &crate::format::Header,
    data: &crate::format::v1::TableData,
) -> Result<Vec<u8>, rkyv::rancor::Error> {
    let payload = rkyv::to_bytes::<rkyv::rancor::Error>(data)?;
    let mut header = *header;
    header.version = 1;
    header.rkyv_flags = RKYV_FLAGS;
    let mut out = header.to_bytes().to_vec();
    out.extend_from_slice(&payload);
    reseal(&mut out);
    Ok(out)
}

/// [`PreparedModel::at`] by each chain's own forward kinematics ([`crate::chain::Chain::tcp_pose`],
/// [`crate::chain::Chain::loaded_tcp_pose`]), joint by joint: the reference the folded query
/// path is held to.
pub fn model_at_by_chains(model: &PreparedModel, q: &[f64]) -> Option<ModelAt> {
    let nominal = model.nominal().tcp_pose(q)?;
    let calibrated = model.calibrated().loaded_tcp_pose(q)?;
    let (position_mm, rotation_rad) = pose_error(&nominal, &calibrated);
    let r = &nominal.rotation;
    Some(ModelAt {
        position_mm,
        rotation_rad,
        approach: [r[0][2], r[1][2], r[2][2]],
        nominal_tcp_mm: nominal.translation_mm,
        nominal_rotation: Some(nominal.rotation),
    })
}

/// A xorshift generator's next value in `[0, 1)`, from and into `state` (not zero): the
/// tests' and benches' random targets and joint values, the same on every platform.
pub fn uniform(state: &mut u64) -> f64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    (*state >> 11) as f64 / (1u64 << 53) as f64
}

/// The factor on a version-6 hybrid table's residual at commanded `q` (rad), by its
/// definition, for the tests that hold [`PreparedModel::residual_scale`] to it: the largest
/// angle a joint lies from its range `ranges_rad[j]` (the nearest of `q + 2πk`, by brute
/// force over a few turns), through the smoothstep of `1 − d / 3°`.
pub fn reference_residual_scale(q: &[f64], ranges_rad: &[[f64; 2]]) -> f64 {
    let mut worst = 0.0f64;
    for (&v, &[lo, hi]) in q.iter().zip(ranges_rad) {
        let apart = (-3..=3)
            .map(|k| v + f64::from(k) * std::f64::consts::TAU)
            .map(|w| (lo - w).max(w - hi).max(0.0))
            .fold(f64::INFINITY, f64::min);
        worst = worst.max(apart);
    }
    let t = (1.0 - worst / 3f64.to_radians()).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}
