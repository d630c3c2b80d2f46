//! The table file format, field by field.
//!
//! ```text
//! table   := header payload
//! header  := 256 bytes, little-endian, at offset 0 (layout below)
//! payload := the rkyv archive of the version's `TableData`, root object at the very end
//! ```
//!
//! | offset | size | field |
//! |-------:|-----:|-------|
//! | 0   | 8  | magic `b"ADWITBL\0"` |
//! | 8   | 2  | endianness mark `0xFEFF` (reads `0xFFFE` on a big-endian misreading) |
//! | 10  | 2  | format version: 4 for a table that records its evidence (bytes 200-243) or merged samples (bytes 244-247), else 2 ([`v2`]), or 3 ([`v3`]) for a table with a posture term; version 1 ([`v1`]) is still read. The payload of a version-4 table is [`v3`]'s when it has a posture term (content flag bit 4), else [`v2`]'s |
//! | 12  | 4  | header length in bytes (256) |
//! | 16  | 4  | rkyv format flags: bit 0 little-endian, bit 1 aligned primitives, bits 8-15 pointer width in bytes |
//! | 20  | 4  | content flags: bit 0 orientation errors, bit 1 configurations, bit 2 sample joint values (v2: stored only for a joint screen), bit 3 kinematic model (a hybrid table), bit 4 posture term (version 3, a hybrid table) |
//! | 24  | 8  | payload length in bytes (file length − 256) |
//! | 32  | 8  | payload checksum, XXH3-64 of the payload |
//! | 40  | 8  | source hash, XXH3-64 of the canonical sample values the table was built from |
//! | 48  | 4  | k, the neighbour count |
//! | 52  | 4  | consistency screen (40): 0 off, 1 on |
//! | 56  | 8  | ε, the neighbourhood radius, mm |
//! | 64  | 8  | ω1 |
//! | 72  | 8  | ω2 |
//! | 80  | 8  | r, the power |
//! | 88  | 8  | \[λ\], 1/mm |
//! | 96  | 8  | \[ζ\], 1/mm² |
//! | 104 | 8  | cell edge length, mm |
//! | 112 | 24 | grid origin (minimum corner) x, y, z, mm, base frame |
//! | 136 | 12 | grid size in cells along x, y, z |
//! | 148 | 4  | sample count |
//! | 152 | 8  | joint-space radius, rad: a sample is admissible only if every joint value is within it of the target's, when the target's joint values are given; 0 = off |
//! | 160 | 4  | v2: the robot's joint count, when the table holds joint values or a model; 0 otherwise (v1: reserved, zero; v1 robots have 6) |
//! | 164 | 4  | v2: the number of node sets of the served tier; 0 for a table served by its exact tier alone (v1: reserved, zero) |
//! | 168 | 4  | v2: folds of the cross-validation that chose the method's parameters (`tablec build --tune`) or the served field (by default); 0 when both were given |
//! | 172 | 4  | v2: what the served tier's nodes hold ([`ServedField`]): 0 the method's own values at the nodes, 1 kriging with a nugget of the samples' errors (`tablec build --served-field kriging`), 2 that kriging with a part that turns with the tool's approach axis (`--served-field kriging-tool-axis`; hybrid tables; 4 vectors per node) |
//! | 176 | 8  | v2: that cross-validation's mean position residual, mm (0 when not tuned) |
//! | 184 | 8  | v2: the same cross-validation's mean position residual of the served tier with the chosen served field, mm (0 when not tuned or without a served tier) |
//! | 192 | 8  | v3: the same cross-validation's mean position residual of the served tier with the posture term, mm (0 when not cross-validated; v2: reserved, zero) |
//! | 200 | 12 | v4: the samples' mean tool approach axis, a unit vector, base frame, 3 × `f32` ([`ApproachCone`]; zero when not recorded) |
//! | 212 | 4  | v4: the largest angle of a sample's approach axis from that mean, rad, `f32` |
//! | 216 | 12 | v4: the table's measured point in the flange frame, translation, mm, 3 × `f32` ([`PointInFlange`]; zero when not recorded) |
//! | 228 | 12 | v4: the same point's frame in the flange frame, rotation vector, rad, 3 × `f32` |
//! | 240 | 4  | v4: evidence flags: bit 0 the approach cone is recorded, bit 1 the point in the flange is |
//! | 244 | 4  | v4: the samples' merge voxel, mm, `f32` ([`Header::merge_voxel_mm`]): the edge of the voxels within which the measured samples (of one configuration) were averaged into the table's samples; 0 when every measured sample is a sample of the table (v2, v3: 200-247 reserved, zero) |
//! | 248 | 8  | header checksum, XXH3-64 of bytes 0..248 |
//!
//! The payload starts at offset 256, a multiple of 64: in a memory map (page-aligned) the
//! archive, and a version-2 table's cell records that open it, start on a cache line. The
//! payloads: [`v2::TableData`] (what a query reads, and nothing else), [`v3::TableData`]
//! (the same and a posture term, written only when the table has one: a table without is
//! version 2, byte for byte), [`v5::TableData`] (the same, a posture term or none, and the
//! model's joint record: every hybrid table, version 6) and the older [`v1::TableData`].

use rkyv::{Archive, Deserialize, Serialize};

pub mod v1;
pub mod v2;
pub mod v3;
pub mod v5;

pub use v1::{
    joint_rows, joint_rows_to_mdh, rows_of, transform_of, KinematicModel, ModelParams, JOINT_COUNT,
};

/// The file's first eight bytes.
pub const MAGIC: [u8; 8] = *b"ADWITBL\0";
/// Written as a little-endian `u16`; reading it back any other way gives `0xFFFE`.
pub const ENDIAN_MARK: u16 = 0xFEFF;
/// The newest format version this runtime writes: 6 for a hybrid table ([`encode_v6`]:
/// the joints the samples span bound its residual), else 4 for a table that records its
/// evidence ([`Header::evidence`]), else 3 for a table with a posture term, 2 for any other
/// ([`encode`], [`encode_v3`]). Version 5 (the joint record on a hybrid table whose model
/// has joint-space terms, the residual unbounded) is read, no longer written.
pub const FORMAT_VERSION: u16 = 6;
/// The oldest format version this runtime reads.
pub const OLDEST_SUPPORTED_VERSION: u16 = 1;
/// The header's length in bytes; the payload starts here.
pub const HEADER_LEN: usize = 256;
/// The payload's alignment requirement, bytes.
pub const PAYLOAD_ALIGN: usize = 16;

/// The rkyv format this runtime was compiled with, read off the archived types themselves so
/// that a build with other rkyv features (through feature unification, say) writes and
/// expects different flags: bit 0 little-endian, bit 1 aligned, bits 8-15 pointer width.
pub const RKYV_FLAGS: u32 = {
    // SAFETY: `Archived<u32>` is a plain 4-byte integer in the archive's byte order.
    let one: [u8; 4] = unsafe { core::mem::transmute(rkyv::Archived::<u32>::from_native(1)) };
    let little_endian = (one[0] == 1) as u32;
    let aligned = (core::mem::align_of::<rkyv::Archived<u64>>() == 8) as u32;
    let pointer_width = core::mem::size_of::<rkyv::Archived<usize>>() as u32;
    little_endian | (aligned << 1) | (pointer_width << 8)
};

/// Content flag: samples carry orientation errors.
pub const CONTENT_ORIENTATION: u32 = 1 << 0;
/// Content flag: samples carry inverse-kinematics configurations.
pub const CONTENT_CONFIG: u32 = 1 << 1;
/// Content flag: samples carry joint angles.
pub const CONTENT_JOINTS: u32 = 1 << 2;
/// Content flag: the table carries a calibrated kinematic model (a hybrid table).
pub const CONTENT_MODEL: u32 = 1 << 3;
/// Content flag: the table carries a posture term ([`crate::posture`], version 3, exactly
/// then).
pub const CONTENT_POSTURE: u32 = 1 << 4;
/// Content flag: the payload holds the joint record ([`v5::TableData`]): the calibrated
/// model's joint-space terms ([`crate::joint_terms`]) and the angles the samples span,
/// per joint. Version 5 and 6, exactly then (version 5: a model with terms; version 6:
/// every hybrid table, its terms zero when it has none).
pub const CONTENT_JOINT_TERMS: u32 = 1 << 5;
/// Every content flag this format version defines; a table naming others is refused.
pub const CONTENT_KNOWN: u32 = CONTENT_ORIENTATION
    | CONTENT_CONFIG
    | CONTENT_JOINTS
    | CONTENT_MODEL
    | CONTENT_POSTURE
    | CONTENT_JOINT_TERMS;

/// The decoded header: identification, integrity fields and the build parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Header {
    /// The file's format version.
    pub version: u16,
    /// rkyv format flags of the writer.
    pub rkyv_flags: u32,
    /// What the samples carry ([`CONTENT_ORIENTATION`], ...).
    pub content_flags: u32,
    /// The payload's length, bytes.
    pub payload_len: u64,
    /// XXH3-64 of the payload.
    pub payload_checksum: u64,
    /// XXH3-64 of the canonical sample values.
    pub source_hash: u64,
    /// The method's parameters.
    pub method: crate::method::MethodParams,
    /// The cell grid.
    pub grid: Grid,
    /// The number of samples.
    pub sample_count: u32,
    /// The joint-space admissibility radius, rad, or 0 when off: with the target's joint
    /// angles known ([`crate::Table::query_with_joints`]), a sample is admissible only if
    /// `max_i |q_sample,i − q_target,i|` is at most this. Needs [`CONTENT_JOINTS`].
    pub joint_radius_rad: f64,
    /// The robot's joint count when the table holds joint values or a model (version 1:
    /// 6 then), else 0.
    pub joint_count: u32,
    /// The served tier's node sets (version 2; 0: the exact tier alone answers).
    pub node_set_count: u32,
    /// How the method's parameters were chosen (version 2), when by cross-validation.
    pub tuning: Option<Tuning>,
    /// What the served tier's nodes hold (version 2; [`ServedField::Method`] before).
    pub served_field: ServedField,
    /// What the samples span beyond their positions (version 4; empty before): the
    /// queries' [`crate::Evidence`] flag is checked against it.
    pub evidence: EvidenceRecord,
    /// The edge of the voxels within which the measured samples were averaged into the
    /// table's samples, mm (version 4, header bytes 244-247, an `f32`); `None` when the
    /// table holds every measured sample. A build merges only samples too many for the
    /// table's size bound (a tracked path's thousands a second): both tiers then answer
    /// from the voxel averages, and [`Header::sample_count`] counts those.
    pub merge_voxel_mm: Option<f64>,
}

/// How far beyond the samples' approach axes a target's may turn before its answer is
/// flagged ([`crate::Evidence::ORIENTATION`]), rad: 3°. A residual learnt at one
/// orientation holds for small changes of it; at the shipped KR150-2 data's 45° it is off
/// by several times its own scatter.
pub const ORIENTATION_MARGIN_RAD: f64 = 3.0 * std::f64::consts::PI / 180.0;

/// How far a named TCP may lie from the table's measured point before a table without a
/// model flags its answer ([`crate::Evidence::TCP`]), mm: a rotation error of a
/// milliradian then moves it by a micrometre.
pub const TCP_MARGIN_MM: f64 = 1.0;

/// What a table's samples span beyond their positions (format version 4, header bytes
/// 200-247): the orientations the tool had, and where the measured point is on the
/// flange. Each part is recorded when the compiler knew it (orientation columns or a
/// robot's joint values for the first, a robot file for the second).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EvidenceRecord {
    /// The cone of the samples' tool approach axes.
    pub approach: Option<ApproachCone>,
    /// The measured point's frame in the flange frame.
    pub point_in_flange: Option<PointInFlange>,
}

impl EvidenceRecord {
    /// Whether nothing is recorded (a table written before version 4, or without either).
    pub fn is_empty(&self) -> bool {
        self.approach.is_none() && self.point_in_flange.is_none()
    }
}

/// The samples' tool approach axes (the z axis of the tool's frame, base frame) as a cone:
/// its mean direction and the largest angle of a sample's axis from it. Stored as `f32`:
/// an envelope needs no more.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ApproachCone {
    /// The mean axis, a unit vector, base frame.
    pub axis: [f64; 3],
    /// The largest angle of a sample's axis from `axis`, rad, in `[0, π]`.
    pub spread_rad: f64,
    /// `cos(spread + margin)`, or −2 when that reaches π (every axis holds): computed once,
    /// so that a query compares a dot product and takes no cosine.
    cos_limit: f64,
}

impl ApproachCone {
    /// The cone of `axes` (unit vectors): their normalised mean and the largest angle
    /// from it, rounded to what the header stores. `None` for no axes; a mean of zero
    /// length (axes in every direction) gives a cone of half-angle π, which holds any
    /// axis.
    pub fn of(axes: impl IntoIterator<Item = [f64; 3]>) -> Option<ApproachCone> {
        let axes: Vec<[f64; 3]> = axes.into_iter().collect();
        if axes.is_empty() || axes.iter().flatten().any(|v| !v.is_finite()) {
            return None;
        }
        let mut sum = [0.0; 3];
        for a in &axes {
            for (s, v) in sum.iter_mut().zip(a) {
                *s += v;
            }
        }
        let norm = crate::method::norm_mm(sum);
        let mean = if norm > 1e-9 * axes.len() as f64 {
            sum.map(|v| v / norm)
        } else {
            [0.0, 0.0, 1.0]
        };
        // As stored, so that the compiler's cone and the runtime's are the same one.
        let mean = unit_f32(mean);
        let spread_rad = if norm > 1e-9 * axes.len() as f64 {
            axes.iter()
                .map(|a| angle_between_rad(mean, *a))
                .fold(0.0, f64::max)
        } else {
            std::f64::consts::PI
        };
        // Rounded up, never down: a sample's own axis stays inside.
        let stored = spread_rad as f32;
        let stored = if (stored as f64) < spread_rad {
            f32::from_bits(stored.to_bits() + 1)
        } else {
            stored
        };
        Some(ApproachCone::new(
            mean,
            (stored as f64).min(std::f64::consts::PI),
        ))
    }

    /// The cone of mean `axis` (a unit vector) and half-angle `spread_rad`.
    pub fn new(axis: [f64; 3], spread_rad: f64) -> ApproachCone {
        let limit = spread_rad + ORIENTATION_MARGIN_RAD;
        let cos_limit = if limit >= std::f64::consts::PI {
            -2.0
        } else {
            crate::trig::sin_cos(limit).1
        };
        ApproachCone {
            axis,
            spread_rad,
            cos_limit,
        }
    }

    /// Whether `axis` (a unit vector, base frame) is within the cone widened by
    /// [`ORIENTATION_MARGIN_RAD`]. Compares cosines: no inverse trigonometry on a query.
    #[inline]
    pub fn holds(&self, axis: [f64; 3]) -> bool {
        let cos = self.axis[0] * axis[0] + self.axis[1] * axis[1] + self.axis[2] * axis[2];
        // Written so that NaN fails the test.
        cos >= self.cos_limit
    }
}

/// Where the table's measured point is on the flange: its frame's translation and
/// rotation in the flange frame, as the robot file's tool gives it. Stored as `f32`
/// (translation to about 1e-5 mm at 200 mm).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PointInFlange {
    /// The point, mm, flange frame.
    pub translation_mm: [f64; 3],
    /// Its frame's rotation in the flange frame, rotation vector, rad.
    pub rotation_rad: [f64; 3],
}

impl PointInFlange {
    /// The point as the header stores it (each value rounded to `f32`).
    pub fn stored(translation_mm: [f64; 3], rotation_rad: [f64; 3]) -> PointInFlange {
        PointInFlange {
            translation_mm: translation_mm.map(|v| v as f32 as f64),
            rotation_rad: rotation_rad.map(|v| v as f32 as f64),
        }
    }
}

impl PointInFlange {
    /// The lever from this point to a TCP at `tcp_mm` (flange frame), in the point's own
    /// frame: `M⁻¹ · t`.
    #[inline]
    pub fn lever_of(&self, tcp_mm: [f64; 3]) -> [f64; 3] {
        let r = crate::kinematics::rotation_from_vector(self.rotation_rad);
        let d = [0, 1, 2].map(|i| tcp_mm[i] - self.translation_mm[i]);
        // Rᵀ · d.
        [0, 1, 2].map(|j| r[0][j] * d[0] + r[1][j] * d[1] + r[2][j] * d[2])
    }
}

/// `v` normalised after rounding to `f32`, as the header stores a unit vector (the stored
/// value read back normalises to itself).
fn unit_f32(v: [f64; 3]) -> [f64; 3] {
    v.map(|x| x as f32 as f64)
}

/// The angle between two vectors, rad, by `atan2(|a × b|, a · b)`: accurate at small
/// angles, where `acos` of a dot product is not.
fn angle_between_rad(a: [f64; 3], b: [f64; 3]) -> f64 {
    let cross = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    crate::method::norm_mm(cross).atan2(dot)
}

/// Evidence flag: the approach cone is recorded (header bytes 200-215).
const EVIDENCE_APPROACH: u32 = 1 << 0;
/// Evidence flag: the point in the flange is recorded (header bytes 216-239).
const EVIDENCE_POINT: u32 = 1 << 1;

/// What a table's served tier blends between: the values at the grid's nodes.
///
/// The exact tier always answers the method itself; the served field either tabulates
/// that answer at the nodes, or a smoother estimate of the same errors. Both are blended
/// trilinearly at query time, so the choice costs a query nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u32)]
pub enum ServedField {
    /// The method's own answer at every node: the served field is the exact tier's,
    /// tabulated.
    #[default]
    Method = 0,
    /// Kriging with a nugget of the samples' errors (a hybrid table's: the residuals its
    /// model leaves) in Cartesian distance, at every corner of a cell whose candidate list
    /// is not empty (so the served field answers wherever the exact tier can): it smooths
    /// the measurement noise the method interpolates. The exact tier still answers the
    /// method.
    Kriging = 1,
    /// Kriging with a nugget as [`ServedField::Kriging`], whose covariance also lets the
    /// errors turn with the tool: `E(p, a) = f(p) + a_x h_x(p) + a_y h_y(p) + a_z h_z(p)`,
    /// with `a` the unit approach (z) axis of the nominal TCP at the query's joint values,
    /// base frame. Residuals that depend on the tool's orientation and not only on where it
    /// is (an offset tool, a target seen from another side) are then predicted, still in
    /// constant time: each node holds the four vectors `f, h_x, h_y, h_z` (the layout of
    /// [`crate::format::v2::TableData::node_errors_mm`]), blended trilinearly, and the
    /// query combines them with `a`. Hybrid tables only: the axis comes from their nominal
    /// chain.
    KrigingToolAxis = 2,
}

impl ServedField {
    /// Every kind, in header order.
    pub const ALL: [ServedField; 3] = [
        ServedField::Method,
        ServedField::Kriging,
        ServedField::KrigingToolAxis,
    ];

    /// The kind `tablec` and the bindings call `name` ([`ServedField::name`]).
    pub fn from_name(name: &str) -> Option<ServedField> {
        ServedField::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Vectors stored per node and component group: 1, or 4 for
    /// [`ServedField::KrigingToolAxis`] (`f, h_x, h_y, h_z`).
    pub fn node_stride(self) -> usize {
        match self {
            ServedField::Method | ServedField::Kriging => 1,
            ServedField::KrigingToolAxis => 4,
        }
    }
}

impl ServedField {
    /// The name `tablec` uses for it: `method`, `kriging` or `kriging-tool-axis`.
    pub fn name(self) -> &'static str {
        match self {
            ServedField::Method => "method",
            ServedField::Kriging => "kriging",
            ServedField::KrigingToolAxis => "kriging-tool-axis",
        }
    }
}

/// The cross-validation that chose a table's parameters (`tablec build --tune`) or its
/// served field (by default, `--served-field auto`), recorded
/// so that `inspect` can say how the table came to be and how well it is expected to do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tuning {
    /// Number of folds.
    pub folds: u32,
    /// Mean position residual over the held-out folds with the chosen parameters, mm
    /// (the exact tier's: the method the table computes).
    pub cv_mean_mm: f64,
    /// The served tier's mean over the same folds with the chosen served field, mm, when
    /// the table has one: what queries by the served field are expected to leave.
    pub served_cv_mean_mm: Option<f64>,
    /// The served tier's mean over the same folds with the posture term added, mm, when
    /// it was cross-validated (version 3: a table that has the term).
    pub posture_cv_mean_mm: Option<f64>,
}

/// A regular grid of cubic cells over an axis-aligned box of the base frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// The minimum corner, mm, base frame.
    pub origin_mm: [f64; 3],
    /// The cells' edge length, mm.
    pub cell_mm: f64,
    /// The number of cells along x, y, z.
    pub dims: [u32; 3],
}

impl Grid {
    /// The number of cells, or `None` on overflow.
    pub fn cell_count(&self) -> Option<usize> {
        let [x, y, z] = self.dims.map(|d| d as usize);
        x.checked_mul(y)?.checked_mul(z)
    }

    /// The maximum corner, mm, base frame.
    pub fn max_mm(&self) -> [f64; 3] {
        let mut out = self.origin_mm;
        for (axis, o) in out.iter_mut().enumerate() {
            *o += self.dims[axis] as f64 * self.cell_mm;
        }
        out
    }

    /// The cell holding `position_mm`, or `None` outside the grid or for a non-finite
    /// position. Cells are half-open `[lo, hi)`, except that the grid's maximum faces
    /// belong to the last cells.
    #[inline]
    pub fn cell_of(&self, position_mm: [f64; 3]) -> Option<usize> {
        let mut index = [0usize; 3];
        for axis in 0..3 {
            let u = (position_mm[axis] - self.origin_mm[axis]) / self.cell_mm;
            // Written so that NaN fails the test.
            if !(u >= 0.0 && u <= self.dims[axis] as f64) {
                return None;
            }
            index[axis] = (u as usize).min((self.dims[axis] as usize).saturating_sub(1));
        }
        Some(self.linear_index(index))
    }

    /// The linear index of cell `(ix, iy, iz)`: x fastest.
    #[inline]
    pub fn linear_index(&self, [ix, iy, iz]: [usize; 3]) -> usize {
        ix + self.dims[0] as usize * (iy + self.dims[1] as usize * iz)
    }

    /// The cell `(ix, iy, iz)` of a linear index.
    pub fn cell_coords(&self, linear: usize) -> [usize; 3] {
        let nx = self.dims[0] as usize;
        let ny = self.dims[1] as usize;
        [linear % nx, (linear / nx) % ny, linear / (nx * ny)]
    }

    /// The box of cell `(ix, iy, iz)`: minimum and maximum corners, mm.
    pub fn cell_box(&self, [ix, iy, iz]: [usize; 3]) -> ([f64; 3], [f64; 3]) {
        let lo = [
            self.origin_mm[0] + ix as f64 * self.cell_mm,
            self.origin_mm[1] + iy as f64 * self.cell_mm,
            self.origin_mm[2] + iz as f64 * self.cell_mm,
        ];
        (lo, lo.map(|v| v + self.cell_mm))
    }
}

/// One sample as the runtime needs it. Positions mm, base frame.
#[derive(Archive, Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[rkyv(derive(Debug))]
pub struct SampleRecord {
    /// Actual position = nominal + measured error, mm: what the approximation degree uses.
    pub actual_mm: [f64; 3],
    /// Nominal (commanded) position, mm.
    pub nominal_mm: [f64; 3],
    /// Measured position error, actual − nominal, mm.
    pub error_mm: [f64; 3],
    /// Measured orientation error, rotation vector of `R_actual · R_nominalᵀ`, rad; zero
    /// when the table has no orientation (see the content flags).
    pub rotation_error_rad: [f64; 3],
    /// Inverse-kinematics configuration, or [`crate::method::CONFIG_UNKNOWN`].
    pub config: u8,
}

impl SampleRecord {
    /// The sample's measured errors, as the method weighs them.
    pub fn measured_error(&self) -> crate::method::SampleError {
        crate::method::SampleError {
            position_mm: self.error_mm,
            orientation_rad: self.rotation_error_rad,
        }
    }
}

fn put<const N: usize>(buf: &mut [u8; HEADER_LEN], offset: usize, bytes: [u8; N]) {
    buf[offset..offset + N].copy_from_slice(&bytes);
}

impl Header {
    /// Whether a query turns a named TCP's lever by a rotation error its samples measured:
    /// a hybrid table (its answer's rotation turns the lever) of samples with orientation. Positions
    /// at one point do not determine that rotation (docs/runtime.md, "Another TCP"), and a
    /// position-only table has nothing to turn the lever with.
    pub fn turns_measured_lever(&self) -> bool {
        self.content_flags & CONTENT_MODEL != 0 && self.content_flags & CONTENT_ORIENTATION != 0
    }

    /// Whether a query naming the TCP `tcp_mm` (flange frame; `None`: the table's own
    /// point) is within the samples' evidence: its point recorded, and the lever turned by
    /// a measured rotation ([`Header::turns_measured_lever`]) or the TCP within
    /// [`TCP_MARGIN_MM`] of the point.
    pub fn tcp_within_evidence(&self, tcp_mm: Option<[f64; 3]>) -> bool {
        let Some(tcp) = tcp_mm else {
            return true;
        };
        let Some(point) = self.evidence.point_in_flange else {
            return false;
        };
        self.turns_measured_lever()
            || crate::method::distance_mm(tcp, point.translation_mm) <= TCP_MARGIN_MM
    }

    /// Whether the payload holds a posture term ([`v3::TableData`]): version 3, or version
    /// 4 with [`CONTENT_POSTURE`].
    pub fn has_posture(&self) -> bool {
        self.version >= 3 && self.content_flags & CONTENT_POSTURE != 0
    }

    /// Whether the payload is version 5's ([`v5::TableData`]): a model with joint-space
    /// terms (version 5), or any hybrid table's model and the joints its samples span
    /// (version 6).
    pub fn has_joint_terms(&self) -> bool {
        self.version >= 5 && self.content_flags & CONTENT_JOINT_TERMS != 0
    }

    /// Whether the joint record's ranges bound the residual (version 6): beyond the angles
    /// the samples span, a hybrid table's residual fades to zero
    /// ([`crate::joint_terms::RESIDUAL_FADE_RAD`]) and the model answers alone.
    pub fn bounds_residual_by_joints(&self) -> bool {
        self.version >= 6 && self.has_joint_terms()
    }

    /// Whether the header records what only version 4 (and 5) can hold: evidence
    /// ([`Header::evidence`]) or merged samples ([`Header::merge_voxel_mm`]).
    pub fn records_version_4(&self) -> bool {
        !self.evidence.is_empty() || self.merge_voxel_mm.is_some()
    }

    /// The header's 256 bytes, with its checksum.
    pub fn to_bytes(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        put(&mut b, 0, MAGIC);
        put(&mut b, 8, ENDIAN_MARK.to_le_bytes());
        put(&mut b, 10, self.version.to_le_bytes());
        put(&mut b, 12, (HEADER_LEN as u32).to_le_bytes());
        put(&mut b, 16, self.rkyv_flags.to_le_bytes());
        put(&mut b, 20, self.content_flags.to_le_bytes());
        put(&mut b, 24, self.payload_len.to_le_bytes());
        put(&mut b, 32, self.payload_checksum.to_le_bytes());
        put(&mut b, 40, self.source_hash.to_le_bytes());
        let m = &self.method;
        put(&mut b, 48, m.max_neighbours.to_le_bytes());
        put(&mut b, 52, u32::from(m.consistency_screen).to_le_bytes());
        put(&mut b, 56, m.radius_mm.to_le_bytes());
        put(&mut b, 64, m.w1.to_le_bytes());
        put(&mut b, 72, m.w2.to_le_bytes());
        put(&mut b, 80, m.power.to_le_bytes());
        put(&mut b, 88, m.lambda_min_per_mm.to_le_bytes());
        put(&mut b, 96, m.zeta_min_per_mm2.to_le_bytes());
        put(&mut b, 104, self.grid.cell_mm.to_le_bytes());
        for axis in 0..3 {
            put(
                &mut b,
                112 + 8 * axis,
                self.grid.origin_mm[axis].to_le_bytes(),
            );
            put(&mut b, 136 + 4 * axis, self.grid.dims[axis].to_le_bytes());
        }
        put(&mut b, 148, self.sample_count.to_le_bytes());
        put(&mut b, 152, self.joint_radius_rad.to_le_bytes());
        if self.version >= 2 {
            put(&mut b, 160, self.joint_count.to_le_bytes());
            put(&mut b, 164, self.node_set_count.to_le_bytes());
            if let Some(t) = self.tuning {
                put(&mut b, 168, t.folds.to_le_bytes());
                put(&mut b, 176, t.cv_mean_mm.to_le_bytes());
                put(
                    &mut b,
                    184,
                    t.served_cv_mean_mm.unwrap_or(0.0).to_le_bytes(),
                );
                if self.version >= 3 {
                    put(
                        &mut b,
                        192,
                        t.posture_cv_mean_mm.unwrap_or(0.0).to_le_bytes(),
                    );
                }
            }
            put(&mut b, 172, (self.served_field as u32).to_le_bytes());
        }
        if self.version >= 4 {
            let mut flags = 0;
            let f32s = |b: &mut [u8; HEADER_LEN], offset: usize, v: [f64; 3]| {
                for (i, x) in v.iter().enumerate() {
                    put(b, offset + 4 * i, (*x as f32).to_le_bytes());
                }
            };
            if let Some(cone) = self.evidence.approach {
                f32s(&mut b, 200, cone.axis);
                put(&mut b, 212, (cone.spread_rad as f32).to_le_bytes());
                flags |= EVIDENCE_APPROACH;
            }
            if let Some(point) = self.evidence.point_in_flange {
                f32s(&mut b, 216, point.translation_mm);
                f32s(&mut b, 228, point.rotation_rad);
                flags |= EVIDENCE_POINT;
            }
            put(&mut b, 240, flags.to_le_bytes());
            let voxel_mm = self.merge_voxel_mm.unwrap_or(0.0) as f32;
            put(&mut b, 244, voxel_mm.to_le_bytes());
        }
        let checksum = xxhash_rust::xxh3::xxh3_64(&b[..248]);
        put(&mut b, 248, checksum.to_le_bytes());
        b
    }

    /// Decodes a header, checking in order: length, magic, endianness mark, version range,
    /// header length, header checksum, rkyv format flags, reserved bytes zero. Parameter
    /// ranges are checked later, with the payload ([`crate::Table`], [`check_plausible`]).
    pub fn from_bytes(bytes: &[u8]) -> Result<Header, crate::OpenError> {
        use crate::OpenError;
        let Some(b) = bytes.get(..HEADER_LEN) else {
            return Err(OpenError::Truncated {
                len: bytes.len() as u64,
                needed: HEADER_LEN as u64,
            });
        };
        let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]);
        let u32_at = |o: usize| u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
        let u64_at = |o: usize| {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[o..o + 8]);
            u64::from_le_bytes(a)
        };
        let f64_at = |o: usize| f64::from_bits(u64_at(o));
        if b[..8] != MAGIC {
            return Err(OpenError::BadMagic);
        }
        let mark = u16_at(8);
        if mark != ENDIAN_MARK {
            return Err(OpenError::Endianness { mark });
        }
        let version = u16_at(10);
        if !(OLDEST_SUPPORTED_VERSION..=FORMAT_VERSION).contains(&version) {
            return Err(OpenError::UnsupportedVersion {
                found: version,
                oldest: OLDEST_SUPPORTED_VERSION,
                newest: FORMAT_VERSION,
            });
        }
        let header_len = u32_at(12);
        if header_len as usize != HEADER_LEN {
            return Err(OpenError::Corrupt {
                what: "header length is not 256",
            });
        }
        let stored = u64_at(248);
        let computed = xxhash_rust::xxh3::xxh3_64(&b[..248]);
        if stored != computed {
            return Err(OpenError::HeaderChecksum { stored, computed });
        }
        let rkyv_flags = u32_at(16);
        if rkyv_flags != RKYV_FLAGS {
            return Err(OpenError::RkyvFormat {
                found: rkyv_flags,
                expected: RKYV_FLAGS,
            });
        }
        let reserved: [std::ops::Range<usize>; 2] = if version >= 4 {
            [248..248, 248..248]
        } else if version >= 3 {
            [200..248, 248..248]
        } else if version >= 2 {
            [192..248, 248..248]
        } else {
            [160..248, 248..248]
        };
        if reserved
            .iter()
            .any(|r| b[r.clone()].iter().any(|&byte| byte != 0))
        {
            return Err(OpenError::Corrupt {
                what: "reserved header bytes are not zero",
            });
        }
        let consistency = u32_at(52);
        if consistency > 1 {
            return Err(OpenError::Corrupt {
                what: "consistency screen flag is neither 0 nor 1",
            });
        }
        let joint_radius_rad = f64_at(152);
        // Written so that NaN fails the test.
        if !(joint_radius_rad >= 0.0 && joint_radius_rad.is_finite()) {
            return Err(OpenError::Corrupt {
                what: "joint radius is negative or not finite",
            });
        }
        // The posture term came with version 3, and version 3 is a table with one.
        let posture = u32_at(20) & CONTENT_POSTURE != 0;
        if (posture && version < 3) || (version == 3 && !posture) {
            return Err(OpenError::Corrupt {
                what: "a posture term is stored in a version-3 table, or a version-4 one",
            });
        }
        // The joint record came with version 5, and versions 5 and 6 are tables with it.
        let terms = u32_at(20) & CONTENT_JOINT_TERMS != 0;
        if terms != (version >= 5) {
            return Err(OpenError::Corrupt {
                what: "the joint record is stored in a version-5 or 6 table, and only there",
            });
        }
        if terms && u32_at(20) & CONTENT_MODEL == 0 {
            return Err(OpenError::Corrupt {
                what: "joint-space terms without a kinematic model",
            });
        }
        if posture && u32_at(20) & CONTENT_MODEL == 0 {
            return Err(OpenError::Corrupt {
                what: "a posture term without a kinematic model",
            });
        }
        let served_field = match (version, u32_at(172)) {
            (1, _) | (_, 0) => ServedField::Method,
            (_, 1) => ServedField::Kriging,
            (_, 2) => ServedField::KrigingToolAxis,
            _ => {
                return Err(OpenError::Corrupt {
                    what: "the served field's kind is none of 0 (method), 1 (kriging), 2 (kriging-tool-axis)",
                })
            }
        };
        if served_field != ServedField::Method && u32_at(164) == 0 {
            return Err(OpenError::Corrupt {
                what: "a kriging served field without node sets",
            });
        }
        // Its approach axis comes from the nominal chain.
        if served_field == ServedField::KrigingToolAxis && u32_at(20) & CONTENT_MODEL == 0 {
            return Err(OpenError::Corrupt {
                what: "a tool-axis served field without a kinematic model",
            });
        }
        let tuning = if version >= 2 && u32_at(168) > 0 {
            let cv_mean_mm = f64_at(176);
            // Written so that NaN fails the test.
            if !(0.0..=MAX_COORDINATE_MM).contains(&cv_mean_mm) {
                return Err(OpenError::Corrupt {
                    what:
                        "the tuning's cross-validated mean is negative, implausible or not finite",
                });
            }
            let served = f64_at(184);
            // Written so that NaN fails the test; 0 is "not scored".
            if !(0.0..=MAX_COORDINATE_MM).contains(&served) {
                return Err(OpenError::Corrupt {
                    what: "the tuning's served cross-validated mean is negative, implausible or not finite",
                });
            }
            let posture = if version >= 3 { f64_at(192) } else { 0.0 };
            // Written so that NaN fails the test; 0 is "not scored".
            if !(0.0..=MAX_COORDINATE_MM).contains(&posture) {
                return Err(OpenError::Corrupt {
                    what: "the tuning's posture cross-validated mean is negative, implausible or not finite",
                });
            }
            Some(Tuning {
                folds: u32_at(168),
                cv_mean_mm,
                served_cv_mean_mm: (served > 0.0).then_some(served),
                posture_cv_mean_mm: (posture > 0.0).then_some(posture),
            })
        } else {
            let posture_bits = if version >= 3 { u64_at(192) } else { 0 };
            if version >= 2
                && (f64_at(176).to_bits() != 0 || f64_at(184).to_bits() != 0 || posture_bits != 0)
            {
                return Err(OpenError::Corrupt {
                    what: "a cross-validated mean without folds",
                });
            }
            None
        };
        let f32_at = |o: usize| f32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]) as f64;
        let f32s_at = |o: usize| [f32_at(o), f32_at(o + 4), f32_at(o + 8)];
        let evidence = if version >= 4 {
            evidence_of(
                u32_at(240),
                f32s_at(200),
                f32_at(212),
                f32s_at(216),
                f32s_at(228),
            )?
        } else {
            EvidenceRecord::default()
        };
        let merge_voxel_mm = if version >= 4 {
            merge_voxel_of(f32_at(244))?
        } else {
            None
        };
        Ok(Header {
            version,
            rkyv_flags,
            content_flags: u32_at(20),
            payload_len: u64_at(24),
            payload_checksum: u64_at(32),
            source_hash: u64_at(40),
            method: crate::method::MethodParams {
                radius_mm: f64_at(56),
                max_neighbours: u32_at(48),
                w1: f64_at(64),
                w2: f64_at(72),
                power: f64_at(80),
                lambda_min_per_mm: f64_at(88),
                zeta_min_per_mm2: f64_at(96),
                consistency_screen: consistency == 1,
            },
            grid: Grid {
                origin_mm: [f64_at(112), f64_at(120), f64_at(128)],
                cell_mm: f64_at(104),
                dims: [u32_at(136), u32_at(140), u32_at(144)],
            },
            sample_count: u32_at(148),
            joint_radius_rad,
            joint_count: if version >= 2 {
                u32_at(160)
            } else if u32_at(20) & (CONTENT_JOINTS | CONTENT_MODEL) != 0 {
                JOINT_COUNT as u32
            } else {
                0
            },
            node_set_count: if version >= 2 { u32_at(164) } else { 0 },
            tuning,
            served_field,
            evidence,
            merge_voxel_mm,
        })
    }
}

/// The smallest merge voxel a table records, mm: a nanometre, far below any tracker's
/// resolution, so that a smaller one is damage.
pub const MIN_MERGE_VOXEL_MM: f64 = 1e-6;

/// A version-4 header's merge voxel (bytes 244-247): 0 for none, else finite, within
/// [`MIN_MERGE_VOXEL_MM`] and [`MAX_COORDINATE_MM`].
fn merge_voxel_of(voxel_mm: f64) -> Result<Option<f64>, crate::OpenError> {
    if voxel_mm.to_bits() == 0 {
        return Ok(None);
    }
    // Written so that NaN fails the test.
    if !(MIN_MERGE_VOXEL_MM..=MAX_COORDINATE_MM).contains(&voxel_mm) {
        return Err(crate::OpenError::Corrupt {
            what: "the merge voxel is neither 0 nor within 1e-6 to 1e6 mm",
        });
    }
    Ok(Some(voxel_mm))
}

/// A version-4 header's evidence fields, checked: known flags only, a unit axis and a
/// spread within `[0, π]`, a point within the plausible range and a rotation of at most a
/// turn, and every field that its flag does not announce zero.
fn evidence_of(
    flags: u32,
    axis: [f64; 3],
    spread_rad: f64,
    translation_mm: [f64; 3],
    rotation_rad: [f64; 3],
) -> Result<EvidenceRecord, crate::OpenError> {
    use crate::OpenError;
    let corrupt = |what| Err(OpenError::Corrupt { what });
    if flags & !(EVIDENCE_APPROACH | EVIDENCE_POINT) != 0 {
        return corrupt("the evidence flags name an unknown part");
    }
    let zero = |v: &[f64]| v.iter().all(|x| x.to_bits() == 0);
    let approach = if flags & EVIDENCE_APPROACH != 0 {
        let norm = crate::method::norm_mm(axis);
        // Written so that NaN fails the test.
        if !((norm - 1.0).abs() <= 1e-5
            && (0.0..=std::f64::consts::PI + 1e-6).contains(&spread_rad))
        {
            return corrupt("the evidence's approach axis is not a unit vector, or its spread is not within [0, π]");
        }
        Some(ApproachCone::new(
            axis,
            spread_rad.min(std::f64::consts::PI),
        ))
    } else if !zero(&axis) || !zero(&[spread_rad]) {
        return corrupt("the evidence's approach fields are not zero though not recorded");
    } else {
        None
    };
    let point_in_flange = if flags & EVIDENCE_POINT != 0 {
        let turn = crate::method::norm_mm(rotation_rad);
        let plausible = translation_mm.iter().all(|v| v.abs() <= MAX_COORDINATE_MM);
        // Written so that NaN fails the test.
        if !(plausible && turn <= std::f64::consts::TAU) {
            return corrupt("the evidence's point in the flange is implausible or not finite");
        }
        Some(PointInFlange {
            translation_mm,
            rotation_rad,
        })
    } else if !zero(&translation_mm) || !zero(&rotation_rad) {
        return corrupt("the evidence's point fields are not zero though not recorded");
    } else {
        None
    };
    Ok(EvidenceRecord {
        approach,
        point_in_flange,
    })
}

/// Serialises a version-2 table: the header (with its checksums and lengths filled in from
/// the payload) followed by the rkyv archive of `data`. The compiler's way to write a
/// table without a posture term. A header that records evidence ([`Header::evidence`])
/// or merged samples ([`Header::merge_voxel_mm`]) makes it a version-4 table with the
/// same payload.
///
/// `header.payload_len`, `payload_checksum`, `version` and `rkyv_flags` are overwritten.
pub fn encode(header: Header, data: &v2::TableData) -> Result<Vec<u8>, rkyv::rancor::Error> {
    let version = if header.records_version_4() { 4 } else { 2 };
    with_header(header, version, data, data.archived_len_hint())
}

/// Serialises a version-3 table (a table with a posture term) as [`encode`] a version-2
/// one; the header's [`CONTENT_POSTURE`] flag is set. A header that records evidence or
/// merged samples makes it a version-4 table with the same payload.
pub fn encode_v3(mut header: Header, data: &v3::TableData) -> Result<Vec<u8>, rkyv::rancor::Error> {
    header.content_flags |= CONTENT_POSTURE;
    let version = if header.records_version_4() { 4 } else { 3 };
    with_header(header, version, data, data.base.archived_len_hint())
}

/// Serialises a version-6 table (a hybrid table: its model's joint-space terms, zero when
/// it has none, and the angles its samples span, which bound its residual) as [`encode`] a
/// version-2 one; the header's [`CONTENT_JOINT_TERMS`] flag is set, and
/// [`CONTENT_POSTURE`] when `posture_term` (else `data.posture` is not read).
pub fn encode_v6(
    mut header: Header,
    data: &v5::TableData,
    posture_term: bool,
) -> Result<Vec<u8>, rkyv::rancor::Error> {
    header.content_flags |= CONTENT_JOINT_TERMS;
    if posture_term {
        header.content_flags |= CONTENT_POSTURE;
    } else {
        header.content_flags &= !CONTENT_POSTURE;
    }
    with_header(header, 6, data, data.base.archived_len_hint())
}

/// The table file of `data` at `version`: the header, with its lengths and checksums,
/// then the payload. The payload is serialised where the file holds it, after the
/// header's room, rather than copied there (a table is tens of megabytes): its bytes are
/// those it has alone, since [`HEADER_LEN`] is a multiple of every alignment the archive
/// pads to and its pointers are relative.
fn with_header<T>(
    mut header: Header,
    version: u16,
    data: &T,
    payload_len_hint: usize,
) -> Result<Vec<u8>, rkyv::rancor::Error>
where
    T: for<'a> rkyv::Serialize<
        rkyv::api::high::HighSerializer<
            Vec<u8>,
            rkyv::ser::allocator::ArenaHandle<'a>,
            rkyv::rancor::Error,
        >,
    >,
{
    const _: () = assert!(HEADER_LEN % PAYLOAD_ALIGN == 0 && HEADER_LEN >= 64);
    // Room for the whole file at once where the hint allows it (a hint too large to
    // reserve is no error: the buffer then grows as it is written).
    let mut room = Vec::new();
    let _ = room.try_reserve_exact(HEADER_LEN.saturating_add(payload_len_hint));
    room.resize(HEADER_LEN, 0u8);
    let mut out = rkyv::api::high::to_bytes_in(data, room)?;
    let payload = &out[HEADER_LEN..];
    header.version = version;
    header.rkyv_flags = RKYV_FLAGS;
    header.payload_len = payload.len() as u64;
    header.payload_checksum = xxhash_rust::xxh3::xxh3_64(payload);
    out[..HEADER_LEN].copy_from_slice(&header.to_bytes());
    Ok(out)
}

/// The largest plausible distance of a grid corner or a sample from the robot's base, mm,
/// per coordinate. No robot workspace reaches a kilometre, so a larger value is damage or
/// a unit error; bounding it also keeps every product the method forms (distances
/// squared, cross products, areas) far from overflow.
pub const MAX_COORDINATE_MM: f64 = 1e6;

/// The largest plausible joint-space radius, rad: 4π (720°) is the widest difference
/// between two angles of a joint turning ±360°, so a wider screen screens nothing.
pub const MAX_JOINT_RADIUS_RAD: f64 = 4.0 * std::f64::consts::PI;

/// The largest plausible magnitude of a rotation entry of a kinematic model's tool or
/// base transform: rotation matrices have entries in `[-1, 1]`, up to rounding.
pub const MAX_ROTATION_ENTRY: f64 = 1.0 + 1e-6;

/// A build parameter, grid field or stored value outside the range any real table
/// respects, though the table's checksums may be intact: the runtime refuses to open it
/// and the compiler to write it ([`check_plausible`], [`check_model_plausible`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Implausible {
    /// The field, with its unit.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// What it must be, relative to `limit`.
    pub rule: &'static str,
    /// The bound it crosses.
    pub limit: f64,
}

impl std::fmt::Display for Implausible {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} is {}, but must be {}{}",
            self.field,
            Number(self.value),
            self.rule,
            Number(self.limit)
        )
    }
}

impl std::error::Error for Implausible {}

/// A number as people read it: plain in the usual range, in exponent form outside it (the
/// plain form of 1e300 has 301 digits).
struct Number(f64);

impl std::fmt::Display for Number {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = self.0;
        if v == 0.0 || (1e-4..1e9).contains(&v.abs()) {
            write!(f, "{v}")
        } else {
            write!(f, "{v:e}")
        }
    }
}

/// The smallest box holding `points`: minimum and maximum corners, or `None` for no
/// points.
pub fn bounding_box(points: impl IntoIterator<Item = [f64; 3]>) -> Option<([f64; 3], [f64; 3])> {
    points.into_iter().fold(None, |acc, p| {
        let (lo, hi) = acc.unwrap_or((p, p));
        Some((
            [0, 1, 2].map(|a| lo[a].min(p[a])),
            [0, 1, 2].map(|a| hi[a].max(p[a])),
        ))
    })
}

/// Checks one coordinate against [`MAX_COORDINATE_MM`]; `field` names it, with its unit.
pub fn check_coordinate(field: &'static str, value: f64) -> Result<(), Implausible> {
    // Written so that NaN fails the test.
    if value.abs() <= MAX_COORDINATE_MM {
        Ok(())
    } else {
        Err(Implausible {
            field,
            value,
            rule: "within ±",
            limit: MAX_COORDINATE_MM,
        })
    }
}

/// Checks a table's parameters and grid against each other and against the box holding
/// its samples' nominal and actual positions (`None` without samples): the ranges no real
/// table leaves, checked both by the runtime at open and by the compiler before it builds,
/// so that the compiler never writes what the runtime refuses.
///
/// Assumes [`MethodParams::validate`](crate::method::MethodParams::validate) passed, and
/// the samples are finite.
///
/// - Samples and grid within [`MAX_COORDINATE_MM`] of the base on every axis.
/// - The cell edge positive, and large enough to move every grid coordinate: the grid's
///   extent along each axis is then `dims × cell` (a few ulps aside), never lost to rounding.
/// - ε at most the diagonal of the box holding the grid and the samples: no distance
///   between a sample and a target in the grid exceeds it, so a larger ε admits nothing
///   more and can only be damage.
/// - The joint-space radius at most [`MAX_JOINT_RADIUS_RAD`].
pub fn check_plausible(
    method: &crate::method::MethodParams,
    grid: &Grid,
    joint_radius_rad: f64,
    samples_box_mm: Option<([f64; 3], [f64; 3])>,
) -> Result<(), Implausible> {
    let within_workspace = check_coordinate;
    if let Some((lo, hi)) = samples_box_mm {
        for v in lo.into_iter().chain(hi) {
            within_workspace("a sample coordinate (mm)", v)?;
        }
    }
    for v in grid.origin_mm {
        within_workspace("the grid origin (mm)", v)?;
    }
    if !(grid.cell_mm > 0.0 && grid.cell_mm.is_finite()) {
        return Err(Implausible {
            field: "the cell edge (mm)",
            value: grid.cell_mm,
            rule: "above ",
            limit: 0.0,
        });
    }
    let max = grid.max_mm();
    for (&origin, &corner) in grid.origin_mm.iter().zip(&max) {
        within_workspace("the grid's maximum corner (mm)", corner)?;
        let step = (origin + grid.cell_mm) - origin;
        if step <= 0.0 || step.is_nan() {
            return Err(Implausible {
                field: "the cell edge (mm)",
                value: grid.cell_mm,
                rule: "large enough to change the grid origin's coordinates, above ",
                limit: origin.abs() * f64::EPSILON,
            });
        }
    }
    let (lo, hi) = match samples_box_mm {
        Some((s_lo, s_hi)) => (
            [0, 1, 2].map(|a| s_lo[a].min(grid.origin_mm[a])),
            [0, 1, 2].map(|a| s_hi[a].max(max[a])),
        ),
        None => (grid.origin_mm, max),
    };
    let diagonal_mm = crate::method::distance_mm(lo, hi);
    if method.radius_mm > diagonal_mm || diagonal_mm.is_nan() {
        return Err(Implausible {
            field: "the radius ε (mm)",
            value: method.radius_mm,
            rule: "at most the diagonal of the box holding the grid and the samples, ",
            limit: diagonal_mm,
        });
    }
    if joint_radius_rad > MAX_JOINT_RADIUS_RAD || joint_radius_rad.is_nan() {
        return Err(Implausible {
            field: "the joint-space radius (rad)",
            value: joint_radius_rad,
            rule: "at most ",
            limit: MAX_JOINT_RADIUS_RAD,
        });
    }
    Ok(())
}

/// Checks a kinematic model's magnitudes: lengths and translations within
/// [`MAX_COORDINATE_MM`], rotation entries within [`MAX_ROTATION_ENTRY`], so that forward
/// kinematics stays finite for every finite joint angle. Assumes finite values.
pub fn check_model_plausible(model: &KinematicModel) -> Result<(), Implausible> {
    for params in [&model.nominal, &model.calibrated] {
        let lengths = params.joints.iter().flat_map(|j| [j[0], j[1]]);
        let translations = [&params.tool, &params.base]
            .into_iter()
            .flat_map(|t| [t[3], t[7], t[11]]);
        for v in lengths.chain(translations) {
            if v.abs() > MAX_COORDINATE_MM || v.is_nan() {
                return Err(Implausible {
                    field: "a kinematic model length (mm)",
                    value: v,
                    rule: "within ±",
                    limit: MAX_COORDINATE_MM,
                });
            }
        }
        let rotations = [&params.tool, &params.base]
            .into_iter()
            .flat_map(|t| [0, 1, 2, 4, 5, 6, 8, 9, 10].map(|i| t[i]));
        for v in rotations {
            if v.abs() > MAX_ROTATION_ENTRY || v.is_nan() {
                return Err(Implausible {
                    field: "a rotation entry of the model's tool or base",
                    value: v,
                    rule: "within ±",
                    limit: MAX_ROTATION_ENTRY,
                });
            }
        }
    }
    Ok(())
}

/// The largest plausible mass of a link or payload, kg.
pub const MAX_MASS_KG: f64 = 1e6;

/// Checks a chain's magnitudes, as [`check_model_plausible`] a version-1 model's: base,
/// tool and joint-origin translations within [`MAX_COORDINATE_MM`], masses within
/// [`MAX_MASS_KG`] and compliance centres of mass within the workspace bound. Assumes a
/// valid chain ([`crate::chain::Chain::new`]).
pub fn check_chain_plausible(chain: &crate::chain::Chain) -> Result<(), Implausible> {
    let translations = [chain.base.translation_mm, chain.tool.translation_mm]
        .into_iter()
        .chain(chain.joints().iter().map(|j| j.origin.translation_mm));
    for t in translations {
        for v in t {
            check_coordinate("a kinematic translation (mm)", v)?;
        }
    }
    if let Some(c) = &chain.compliance {
        let n = chain.joint_count();
        for &m in c.link_mass_kg[..n].iter().chain([&c.payload_kg]) {
            if m > MAX_MASS_KG || m.is_nan() {
                return Err(Implausible {
                    field: "a link or payload mass (kg)",
                    value: m,
                    rule: "at most ",
                    limit: MAX_MASS_KG,
                });
            }
        }
        for com in c.link_com_mm[..n].iter().chain([&c.payload_com_mm]) {
            for &v in com {
                check_coordinate("a centre of mass (mm)", v)?;
            }
        }
    }
    Ok(())
}
