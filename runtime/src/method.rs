//! Approximation-degree weighted average interpolation, written once.
//!
//! Every caller computes through this module: the runtime's table queries, the compiler's
//! brute-force reference over all samples, and the base weights the compiler stores per
//! cell. Nothing here allocates or panics; selections live in fixed-size arrays of at most
//! [`MAX_NEIGHBOURS`] entries.
//!
//! # Definitions
//!
//! For a target's nominal position `p` and a sample's actual position `s` (nominal plus
//! measured error), both vectors from the robot base origin (mm, base frame):
//!
//! - distance `|s − p|`, angle φ between `s` and `p`, area `S = ½ |s × p|`;
//! - `λ = sin φ / |s − p|` and `ζ = 1 / S`;
//! - weights `q_i = ω1 · λ_i^r / Σ λ_j^r + ω2 · ζ_i^r / Σ ζ_j^r` and the prediction
//!   `d_p = Σ q_i d_i`, the same weights for position and orientation errors.
//!
//! # Degenerate cases
//!
//! - **Coincident sample** (`s == p` exactly): `λ = 1`, `ζ = ∞` as the method defines. If any
//!   selected neighbour coincides with the target, the prediction is the mean of the
//!   coincident samples' errors (weight `1/n` each, zero for the others): the measured
//!   error at the target is the answer.
//! - **Collinear sample** (`s ≠ p` on the line through the origin and `p`, φ = 0): the
//!   method gives `λ = 0`, `S = 0` and `ζ = ∞`. A point that is not the target must not
//!   take all the weight, so the area is floored: `S ≥ ½ · h_min · max(|p|, |s|)` with
//!   `h_min =` [`MIN_PERPENDICULAR_OFFSET_MM`] (1 µm), i.e. an offset from the line smaller
//!   than the tracker can resolve counts as 1 µm. The floor only acts below 1 µm, so
//!   ordinary samples keep the paper's exact values.
//! - **Target at the origin** (`|p| = 0`): φ is undefined; `sin φ` is taken as 0, so `λ = 0`
//!   and `S` takes the floor above.
//! - **All λ zero** (every neighbour collinear, `r > 0`): `Σ λ^r = 0` carries no
//!   information; the share ω1 then follows the ζ distribution, so `q_i = ζ_i^r / Σ ζ_j^r`.
//!
//! # Admissibility
//!
//! A sample may stand in for the target when (docs/method.md §5):
//! (31) `λ ≥ [λ]`, (32) `ζ ≥ [ζ]`, (33) `|s − p| ≤ ε`, (34) `sin φ ≥ [λ] · ε`, its
//! configuration matches the target's when both are known, and the target itself satisfies
//! (37) `|p|² ≤ 2 / ([ζ] [λ] ε)`. A coincident sample is always admissible. Of the
//! admissible samples the `k` nearest are used, ties broken by sample order. Finally the
//! consistency screen (40) `max_i |d_p − d_i| ≤ ε / m`, when enabled, drops the neighbour
//! whose error disagrees most with the prediction and recomputes, until it holds; dropped
//! neighbours are not replaced by farther ones.

use crate::kinematics::cross;
use std::mem::MaybeUninit;

/// The largest neighbour count `k` a table may use; selections are fixed-size arrays.
pub const MAX_NEIGHBOURS: usize = 16;

/// Perpendicular offsets below this (mm) from the line through the origin and the target
/// count as this much when computing the triangle area `S` (see the module docs).
pub const MIN_PERPENDICULAR_OFFSET_MM: f64 = 1e-3;

/// Sample configuration value meaning "unknown": matches any target configuration.
pub const CONFIG_UNKNOWN: u8 = u8::MAX;

/// The method's parameters: weights, power, thresholds, radius, neighbour count.
///
/// Generic over the radius's type so that one definition serves a table (`f64`, the
/// default) and a build request whose ε may still be derived from the samples
/// (`Option<f64>`); [`MethodParams::with_radius`] turns one into the other.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MethodParams<Radius = f64> {
    /// ε: the neighbourhood radius, mm (33), also the consistency bound of (40).
    pub radius_mm: Radius,
    /// k: at most this many neighbours, nearest first (1 ..= [`MAX_NEIGHBOURS`]).
    pub max_neighbours: u32,
    /// ω1: the share of the weight given by λ.
    pub w1: f64,
    /// ω2: the share of the weight given by ζ (ω1 + ω2 = 1).
    pub w2: f64,
    /// r: the power applied to λ and ζ, 0 ≤ r ≤ 2.
    pub power: f64,
    /// \[λ\]: the lower bound on λ, 1/mm (31, 34, 37).
    pub lambda_min_per_mm: f64,
    /// \[ζ\]: the lower bound on ζ, 1/mm² (32, 37).
    pub zeta_min_per_mm2: f64,
    /// Whether the consistency screen (40) is applied.
    pub consistency_screen: bool,
}

impl<Radius> MethodParams<Radius> {
    /// The paper's parameters (ω1 = 0.87, ω2 = 0.13, r = 1, k = 8, \[λ\] = \[ζ\] = 0, screen on)
    /// with the given radius: the one place they are written.
    pub const fn paper(radius_mm: Radius) -> MethodParams<Radius> {
        MethodParams {
            radius_mm,
            max_neighbours: 8,
            w1: 0.87,
            w2: 0.13,
            power: 1.0,
            lambda_min_per_mm: 0.0,
            zeta_min_per_mm2: 0.0,
            consistency_screen: true,
        }
    }

    /// The same parameters with another radius.
    pub fn with_radius<Other>(self, radius_mm: Other) -> MethodParams<Other> {
        MethodParams {
            radius_mm,
            max_neighbours: self.max_neighbours,
            w1: self.w1,
            w2: self.w2,
            power: self.power,
            lambda_min_per_mm: self.lambda_min_per_mm,
            zeta_min_per_mm2: self.zeta_min_per_mm2,
            consistency_screen: self.consistency_screen,
        }
    }
}

impl MethodParams {
    /// Checks the parameters' ranges; `Err` names the first one out of range.
    pub fn validate(&self) -> Result<(), &'static str> {
        let finite_nonneg = |x: f64| x.is_finite() && x >= 0.0;
        if !(self.radius_mm.is_finite() && self.radius_mm > 0.0) {
            return Err("radius must be finite and positive");
        }
        if self.max_neighbours == 0 || self.max_neighbours as usize > MAX_NEIGHBOURS {
            return Err("neighbour count k must be between 1 and 16");
        }
        if !(finite_nonneg(self.w1) && finite_nonneg(self.w2)) {
            return Err("weights w1, w2 must be finite and non-negative");
        }
        if (self.w1 + self.w2 - 1.0).abs() > 1e-9 {
            return Err("weights w1 + w2 must equal 1");
        }
        if !(finite_nonneg(self.power) && self.power <= 2.0) {
            return Err("power r must be between 0 and 2");
        }
        if !(finite_nonneg(self.lambda_min_per_mm) && finite_nonneg(self.zeta_min_per_mm2)) {
            return Err("thresholds lambda-min, zeta-min must be finite and non-negative");
        }
        Ok(())
    }

    /// Whether λ or ζ thresholds are active, i.e. admissibility depends on more than the
    /// distance and the configuration.
    pub fn has_degree_thresholds(&self) -> bool {
        self.lambda_min_per_mm > 0.0 || self.zeta_min_per_mm2 > 0.0
    }

    /// Condition (37): whether any sample can be admissible for a target at `target_mm`.
    pub fn target_in_range(&self, target_mm: [f64; 3]) -> bool {
        let product = self.zeta_min_per_mm2 * self.lambda_min_per_mm * self.radius_mm;
        product <= 0.0 || norm_squared(target_mm) <= 2.0 / product
    }

    /// Conditions (31)-(34) for one sample's approximation degree.
    pub fn degree_admissible(&self, degree: &Degree) -> bool {
        if degree.coincident {
            return true;
        }
        degree.distance_squared_mm2 <= self.radius_mm * self.radius_mm
            && degree.lambda_per_mm >= self.lambda_min_per_mm
            && degree.zeta_per_mm2 >= self.zeta_min_per_mm2
            && degree.sin_phi >= self.lambda_min_per_mm * self.radius_mm
    }
}

/// How close a sample's actual position is to a target position, by the method's measures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Degree {
    /// `|s − p|²`, mm²: the key neighbours are ranked and screened by (33) with, so that
    /// no square root stands between a candidate and its rejection.
    pub distance_squared_mm2: f64,
    /// `|s − p|`, mm.
    pub distance_mm: f64,
    /// `sin φ`, φ the angle between `s` and `p` seen from the base origin.
    pub sin_phi: f64,
    /// `S = ½ |s × p|`, mm², before the collinearity floor.
    pub area_mm2: f64,
    /// λ, 1/mm.
    pub lambda_per_mm: f64,
    /// ζ, 1/mm² (infinite only for a coincident sample).
    pub zeta_per_mm2: f64,
    /// `s == p` exactly.
    pub coincident: bool,
}

/// `|a − b|`, mm. The one distance every selection uses, so that all callers order
/// neighbours identically.
#[inline]
pub fn distance_mm(a: [f64; 3], b: [f64; 3]) -> f64 {
    distance_squared_mm2(a, b).sqrt()
}

/// `|a|`, mm, as every caller computes it (the table stores it per sample, so the bits
/// must agree).
#[inline]
pub fn norm_mm(a: [f64; 3]) -> f64 {
    norm_squared(a).sqrt()
}

/// `|a − b|²`, mm²: the ranking key of neighbours (nearest first, ties by sample index)
/// and the quantity (33) bounds, as `|a − b|² ≤ ε²`.
#[inline]
pub fn distance_squared_mm2(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm_squared(sub(a, b))
}

/// The approximation degree of a sample at actual position `actual_mm` for a target at
/// nominal position `target_mm` (both mm, base frame). Finite for every finite input.
#[inline]
pub fn approximation_degree(target_mm: [f64; 3], actual_mm: [f64; 3]) -> Degree {
    degree_from_parts(
        target_mm,
        norm_mm(target_mm),
        actual_mm,
        norm_mm(actual_mm),
        distance_squared_mm2(actual_mm, target_mm),
    )
}

/// [`approximation_degree`] with `|target|`, `|actual|` and the squared distance already
/// computed by the caller, by the same expressions (so with the same bits).
#[inline]
fn degree_from_parts(
    target_mm: [f64; 3],
    target_norm: f64,
    actual_mm: [f64; 3],
    actual_norm: f64,
    distance_squared_mm2: f64,
) -> Degree {
    let distance_mm = distance_squared_mm2.sqrt();
    if distance_mm == 0.0 {
        return Degree {
            distance_squared_mm2,
            distance_mm,
            sin_phi: 0.0,
            area_mm2: 0.0,
            lambda_per_mm: 1.0,
            zeta_per_mm2: f64::INFINITY,
            coincident: true,
        };
    }
    let cross_norm = norm_squared(cross(actual_mm, target_mm)).sqrt();
    let norms = target_norm * actual_norm;
    let area_mm2 = 0.5 * cross_norm;
    let area_floor_mm2 = 0.5 * MIN_PERPENDICULAR_OFFSET_MM * target_norm.max(actual_norm);
    let area_used_mm2 = area_mm2.max(area_floor_mm2);
    // λ = sin φ / |s − p| with sin φ = |s × p| / (|s| |p|) clamped to 1 against rounding,
    // and ζ = 1 / S: both from one division, as the query path needs λ and ζ but not sin φ.
    let (sin_phi, lambda_per_mm, zeta_per_mm2) = if norms > 0.0 {
        let clamped = cross_norm.min(norms);
        let denominator = norms * distance_mm;
        let reciprocal = 1.0 / (denominator * area_used_mm2);
        (
            clamped / norms,
            clamped * area_used_mm2 * reciprocal,
            denominator * reciprocal,
        )
    } else {
        (0.0, 0.0, 1.0 / area_used_mm2)
    };
    Degree {
        distance_squared_mm2,
        distance_mm,
        sin_phi,
        area_mm2,
        lambda_per_mm,
        zeta_per_mm2,
        coincident: false,
    }
}

/// One neighbour: its sample index and approximation degree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Neighbour {
    /// The sample's index in the sample database (its order in the source file).
    pub sample: u32,
    /// Its approximation degree for the target.
    pub degree: Degree,
}

/// A placeholder for unused slots of fixed-size arrays; never read.
const EMPTY_NEIGHBOUR: Neighbour = Neighbour {
    sample: 0,
    degree: Degree {
        distance_squared_mm2: 0.0,
        distance_mm: 0.0,
        sin_phi: 0.0,
        area_mm2: 0.0,
        lambda_per_mm: 0.0,
        zeta_per_mm2: 0.0,
        coincident: false,
    },
};

/// Up to `N` values of a fixed-size array, of which the first `len` are set: the query
/// path's scratch space, which is never zeroed (a query writes what it reads).
#[derive(Clone, Copy)]
struct Slots<T: Copy, const N: usize> {
    len: usize,
    items: [MaybeUninit<T>; N],
}

impl<T: Copy, const N: usize> Slots<T, N> {
    #[inline]
    fn new() -> Self {
        Slots {
            len: 0,
            items: [MaybeUninit::uninit(); N],
        }
    }

    /// The first `len` of `items` (at most `N`), the rest unset.
    #[inline]
    fn filled(items: [T; N], len: usize) -> Self {
        Slots {
            len: len.min(N),
            items: items.map(MaybeUninit::new),
        }
    }

    /// Appends `value`; ignored when full.
    #[inline]
    fn push(&mut self, value: T) {
        if let Some(slot) = self.items.get_mut(self.len) {
            slot.write(value);
            self.len += 1;
        }
    }

    /// Sets item `i` of the set ones, or the next one (`i == len`, growing by one); other
    /// indices are ignored.
    #[inline]
    fn set(&mut self, i: usize, value: T) {
        if i <= self.len {
            if let Some(slot) = self.items.get_mut(i) {
                slot.write(value);
                self.len = self.len.max(i + 1);
            }
        }
    }

    #[inline]
    fn as_slice(&self) -> &[T] {
        // SAFETY: the first `len` items were written (`push` and `set` only ever extend
        // the set prefix by one), and `len <= N`.
        unsafe { initialised(&self.items, self.len) }
    }
}

impl<T: Copy + std::fmt::Debug, const N: usize> std::fmt::Debug for Slots<T, N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.as_slice()).finish()
    }
}

/// The `k` nearest admissible samples, nearest first, ties broken by the smaller sample
/// index: offering candidates in any order gives the same result. Only keys are kept
/// (sample index and squared distance, 12 bytes a slot), so that ranking candidates moves
/// little memory; degrees are computed for the survivors only.
#[derive(Clone, Copy, Debug)]
pub struct Selection {
    capacity: usize,
    samples: Slots<u32, MAX_NEIGHBOURS>,
    keys_mm2: Slots<f64, MAX_NEIGHBOURS>,
}

impl Selection {
    /// An empty selection keeping at most `k` neighbours (clamped to 1 ..= `MAX_NEIGHBOURS`).
    #[inline]
    pub fn new(k: u32) -> Selection {
        Selection {
            capacity: (k as usize).clamp(1, MAX_NEIGHBOURS),
            samples: Slots::new(),
            keys_mm2: Slots::new(),
        }
    }

    /// Whether a candidate at squared distance `key_mm2` with index `sample` would enter
    /// the selection.
    #[inline]
    pub fn would_accept(&self, sample: u32, key_mm2: f64) -> bool {
        let len = self.len();
        len < self.capacity || self.precedes(sample, key_mm2, len - 1)
    }

    #[inline]
    fn precedes(&self, sample: u32, key_mm2: f64, slot: usize) -> bool {
        let d = self.keys_mm2.as_slice()[slot];
        key_mm2 < d || (key_mm2 == d && sample < self.samples.as_slice()[slot])
    }

    /// Offers a candidate; it is kept if it is among the `k` nearest seen so far.
    #[inline]
    pub fn offer(&mut self, sample: u32, key_mm2: f64) {
        if !self.would_accept(sample, key_mm2) {
            return;
        }
        // The slot it takes: after the last that precedes it; the ones behind move back
        // (the farthest drops off when full).
        let len = self.len();
        let mut i = len.min(self.capacity - 1);
        while i > 0 && self.precedes(sample, key_mm2, i - 1) {
            i -= 1;
        }
        let last = len.min(self.capacity - 1);
        let mut j = last;
        while j > i {
            let (s, k) = (
                self.samples.as_slice()[j - 1],
                self.keys_mm2.as_slice()[j - 1],
            );
            self.samples.set(j, s);
            self.keys_mm2.set(j, k);
            j -= 1;
        }
        self.samples.set(i, sample);
        self.keys_mm2.set(i, key_mm2);
    }

    /// The selected sample indices, nearest first.
    pub fn samples(&self) -> &[u32] {
        self.samples.as_slice()
    }

    /// Their squared distances to the target, mm².
    pub fn keys_mm2(&self) -> &[f64] {
        self.keys_mm2.as_slice()
    }

    /// The number of selected neighbours.
    pub fn len(&self) -> usize {
        self.samples.len
    }

    /// Whether no neighbour is selected.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Whether a sample of configuration `sample_config` may serve a target whose
/// configuration is `target_config` (unknown on either side matches anything).
#[inline]
pub fn config_matches(sample_config: u8, target_config: Option<u8>) -> bool {
    match target_config {
        Some(c) => sample_config == CONFIG_UNKNOWN || sample_config == c,
        None => true,
    }
}

/// Selects the `k` nearest admissible samples among `candidates` for a target.
///
/// `sample(i)` gives sample `i`'s actual position (mm) and configuration, or `None` to
/// skip it. Candidates may come in any order. Without λ or ζ thresholds admissibility is a
/// matter of distance and configuration, and only distances are computed here.
#[inline]
pub fn select(
    params: &MethodParams,
    target_mm: [f64; 3],
    target_config: Option<u8>,
    candidates: impl IntoIterator<Item = u32>,
    sample: impl Fn(u32) -> Option<([f64; 3], u8)>,
) -> Selection {
    let thresholds = params.has_degree_thresholds();
    let mut selection = Selection::new(params.max_neighbours);
    if !params.target_in_range(target_mm) {
        return selection;
    }
    let radius_squared = params.radius_mm * params.radius_mm;
    for index in candidates {
        let Some((actual_mm, config)) = sample(index) else {
            continue;
        };
        let key = distance_squared_mm2(actual_mm, target_mm);
        // Written as `within` so that a NaN distance is rejected too.
        let within = key <= radius_squared;
        if !within || !config_matches(config, target_config) || !selection.would_accept(index, key)
        {
            continue;
        }
        if !thresholds || params.degree_admissible(&approximation_degree(target_mm, actual_mm)) {
            selection.offer(index, key);
        }
    }
    selection
}

/// [`select`] for a table's exact tier, with the same result to the bit: the `k` nearest
/// admissible samples among `candidates`, ties by the smaller index.
///
/// `actual_of(i)` gives sample `i`'s actual position (mm), or `None` to skip it;
/// `admissible(i)` the rest of its admissibility (configuration, joint screen), asked only
/// of a candidate within ε that would enter the selection. Without λ or ζ thresholds (a
/// table's usual method) a candidate costs a distance and one comparison with the `k`-th
/// key kept, not a call to [`Selection::offer`]; the few that enter are placed by
/// insertion, as `offer` places them. With thresholds this is [`select`] itself.
#[inline]
pub fn select_nearest(
    params: &MethodParams,
    target_mm: [f64; 3],
    candidates: impl IntoIterator<Item = u32>,
    actual_of: impl Fn(u32) -> Option<[f64; 3]>,
    admissible: impl Fn(u32) -> bool,
) -> Selection {
    if params.has_degree_thresholds() {
        return select(params, target_mm, None, candidates, |i| {
            if admissible(i) {
                actual_of(i).map(|a| (a, CONFIG_UNKNOWN))
            } else {
                None
            }
        });
    }
    let empty = Selection::new(params.max_neighbours);
    if !params.target_in_range(target_mm) {
        return empty;
    }
    let capacity = empty.capacity;
    let radius_squared = params.radius_mm * params.radius_mm;
    // The kept keys and indices, nearest first; `len` of them set. Locals, not `Slots`,
    // so that they live in registers and the stack without length bookkeeping.
    let mut keys_mm2 = [0.0f64; MAX_NEIGHBOURS];
    let mut samples = [0u32; MAX_NEIGHBOURS];
    let mut len = 0usize;
    // The last slot a newcomer may take: the farthest kept drops off once `k` are kept.
    let last_slot = (capacity - 1).min(MAX_NEIGHBOURS - 1);
    // The `k`-th key kept and its sample, read only once `k` are kept.
    let (mut bound, mut bound_sample) = (0.0, 0);
    for index in candidates {
        let Some(actual_mm) = actual_of(index) else {
            continue;
        };
        let key = distance_squared_mm2(actual_mm, target_mm);
        // Written as `within` so that a NaN distance is rejected too.
        let within = key <= radius_squared;
        if !within {
            continue;
        }
        // Once `k` are kept, a candidate must precede the `k`-th (`would_accept`).
        if len == capacity && !(key < bound || (key == bound && index < bound_sample)) {
            continue;
        }
        if !admissible(index) {
            continue;
        }
        let mut slot = len.min(last_slot);
        while slot > 0 {
            let (d, s) = (keys_mm2[slot - 1], samples[slot - 1]);
            if !(key < d || (key == d && index < s)) {
                break;
            }
            keys_mm2[slot] = d;
            samples[slot] = s;
            slot -= 1;
        }
        keys_mm2[slot] = key;
        samples[slot] = index;
        len = (len + 1).min(capacity);
        (bound, bound_sample) = (keys_mm2[last_slot], samples[last_slot]);
    }
    Selection {
        capacity,
        samples: Slots::filled(samples, len),
        keys_mm2: Slots::filled(keys_mm2, len),
    }
}

/// The weights of selected neighbours, in selection order; `Σ q_i = 1` when non-empty.
#[derive(Clone, Copy, Debug)]
pub struct Weights {
    q: Slots<f64, MAX_NEIGHBOURS>,
}

impl Weights {
    /// The weights, in the order of the neighbours they were computed for.
    pub fn as_slice(&self) -> &[f64] {
        self.q.as_slice()
    }
}

/// The neighbours a prediction used, nearest first.
#[derive(Clone, Copy, Debug)]
pub struct Neighbours {
    len: usize,
    items: [Neighbour; MAX_NEIGHBOURS],
}

impl Neighbours {
    /// The neighbours, nearest first.
    pub fn as_slice(&self) -> &[Neighbour] {
        &self.items[..self.len]
    }

    /// The number of neighbours.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

#[inline]
fn pow_r(x: f64, r: f64) -> f64 {
    if r == 1.0 {
        x
    } else if r == 0.0 {
        1.0
    } else if r == 2.0 {
        x * x
    } else {
        x.powf(r)
    }
}

/// What the weights and the prediction need of up to [`MAX_NEIGHBOURS`] neighbours, side
/// by side: λ, ζ, which coincide with the target, and their errors (orientation errors only
/// when the prediction includes them: a position-only table does no orientation work).
struct Gathered {
    // The counts first and together, the arrays after them never written before use:
    // with a count inside each array's own `Slots`, the compiler merged the zero stores
    // into one memset over the whole struct, arrays included, on every query.
    len: usize,
    orientation_len: usize,
    coincident: u32,
    lambda: [MaybeUninit<f64>; MAX_NEIGHBOURS],
    zeta: [MaybeUninit<f64>; MAX_NEIGHBOURS],
    position_mm: [MaybeUninit<[f64; 3]>; MAX_NEIGHBOURS],
    orientation_rad: [MaybeUninit<[f64; 3]>; MAX_NEIGHBOURS],
}

impl Gathered {
    #[inline]
    fn new() -> Gathered {
        Gathered {
            len: 0,
            orientation_len: 0,
            coincident: 0,
            lambda: [MaybeUninit::uninit(); MAX_NEIGHBOURS],
            zeta: [MaybeUninit::uninit(); MAX_NEIGHBOURS],
            position_mm: [MaybeUninit::uninit(); MAX_NEIGHBOURS],
            orientation_rad: [MaybeUninit::uninit(); MAX_NEIGHBOURS],
        }
    }

    #[inline]
    fn len(&self) -> usize {
        self.len
    }

    #[inline]
    fn push(&mut self, degree: &Degree, error: &SampleError, orientation: bool) {
        let i = self.len;
        if i < MAX_NEIGHBOURS {
            self.lambda[i].write(degree.lambda_per_mm);
            self.zeta[i].write(degree.zeta_per_mm2);
            self.coincident |= u32::from(degree.coincident) << i;
            self.position_mm[i].write(error.position_mm);
            if orientation && self.orientation_len == i {
                self.orientation_rad[i].write(error.orientation_rad);
                self.orientation_len += 1;
            }
            self.len += 1;
        }
    }

    #[inline]
    fn lambda(&self) -> &[f64] {
        // SAFETY: `push` writes items 0..len of `lambda`, `zeta` and `position_mm`, and
        // 0..orientation_len of `orientation_rad`, in order; both counts are at most
        // MAX_NEIGHBOURS.
        unsafe { initialised(&self.lambda, self.len) }
    }

    #[inline]
    fn zeta(&self) -> &[f64] {
        // SAFETY: as in `lambda`.
        unsafe { initialised(&self.zeta, self.len) }
    }

    #[inline]
    fn positions(&self) -> &[[f64; 3]] {
        // SAFETY: as in `lambda`.
        unsafe { initialised(&self.position_mm, self.len) }
    }

    #[inline]
    fn orientations(&self) -> &[[f64; 3]] {
        // SAFETY: as in `lambda`.
        unsafe { initialised(&self.orientation_rad, self.orientation_len) }
    }
}

/// The first `len` items of `items`.
///
/// # Safety
///
/// `len <= N`, and items `0..len` were written.
#[inline]
unsafe fn initialised<T, const N: usize>(items: &[MaybeUninit<T>; N], len: usize) -> &[T] {
    debug_assert!(len <= N);
    // SAFETY: by the caller's contract; `MaybeUninit<T>` has `T`'s layout.
    unsafe { std::slice::from_raw_parts(items.as_ptr().cast::<T>(), len) }
}

/// The weights `q_i` of docs/method.md §4 for the given neighbours (see the module docs for the
/// coincident and all-collinear cases).
pub fn weights(params: &MethodParams, neighbours: &[Neighbour]) -> Weights {
    let mut degrees = Gathered::new();
    let no_error = SampleError::default();
    neighbours
        .iter()
        .for_each(|n| degrees.push(&n.degree, &no_error, false));
    let mut out = Weights { q: Slots::new() };
    weights_of_active(params, &degrees, all_active(degrees.len()), &mut out.q);
    out
}

/// A mask with the first `len` neighbours active.
#[inline]
fn all_active(len: usize) -> u32 {
    if len >= 32 {
        u32::MAX
    } else {
        (1u32 << len) - 1
    }
}

/// The weights of the neighbours whose bit is set in `active` (bit `i` for neighbour
/// `i`), written to `q[i]`; inactive neighbours get 0. Sums run in neighbour order, so
/// every caller gets the same bits.
#[inline]
fn weights_of_active(
    params: &MethodParams,
    degrees: &Gathered,
    active: u32,
    q: &mut Slots<f64, MAX_NEIGHBOURS>,
) {
    let n = degrees.len();
    let is_active = |i: usize| active & (1 << i) != 0;
    let coincident = degrees.coincident & active;
    if coincident != 0 {
        let share = 1.0 / coincident.count_ones() as f64;
        for i in 0..n {
            q.set(
                i,
                if coincident & (1 << i) != 0 {
                    share
                } else {
                    0.0
                },
            );
        }
        return;
    }
    let r = params.power;
    let (lambda, zeta) = (degrees.lambda(), degrees.zeta());
    let mut lambda_r = Slots::<f64, MAX_NEIGHBOURS>::new();
    let mut zeta_r = Slots::<f64, MAX_NEIGHBOURS>::new();
    let mut lambda_sum = 0.0;
    let mut zeta_sum = 0.0;
    for i in 0..n {
        let (l, z) = if is_active(i) {
            (pow_r(lambda[i], r), pow_r(zeta[i], r))
        } else {
            (0.0, 0.0)
        };
        lambda_r.push(l);
        zeta_r.push(z);
        lambda_sum += l;
        zeta_sum += z;
    }
    // q_i = ω1 λ_i^r / Σλ^r + ω2 ζ_i^r / Σζ^r, with the two quotients' divisors folded
    // into one factor each.
    let (lambda_factor, zeta_factor) = if lambda_sum > 0.0 {
        (params.w1 / lambda_sum, params.w2 / zeta_sum)
    } else {
        (0.0, 1.0 / zeta_sum)
    };
    let (lambda_r, zeta_r) = (lambda_r.as_slice(), zeta_r.as_slice());
    for i in 0..n {
        let weight = if is_active(i) {
            lambda_factor * lambda_r[i] + zeta_factor * zeta_r[i]
        } else {
            0.0
        };
        q.set(i, weight);
    }
}

/// A sample's measured errors: position (mm) and orientation (rotation vector, rad), both
/// in the base frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SampleError {
    /// Actual − nominal position, mm.
    pub position_mm: [f64; 3],
    /// Rotation vector of `R_actual · R_nominalᵀ`, rad (zero when not measured).
    pub orientation_rad: [f64; 3],
}

/// A prediction with the neighbours and weights that produced it.
#[derive(Clone, Copy, Debug)]
pub struct Prediction {
    /// Predicted position error, mm, base frame.
    pub position_error_mm: [f64; 3],
    /// Predicted orientation error (rotation vector), rad, base frame.
    pub orientation_error_rad: [f64; 3],
    /// The neighbours used, nearest first (after the consistency screen).
    pub neighbours: Neighbours,
    /// Their weights, in the same order.
    pub weights: Weights,
}

/// A prediction alone: what a controller needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Predicted position error, mm, base frame.
    pub position_error_mm: [f64; 3],
    /// Predicted orientation error (rotation vector), rad, base frame.
    pub orientation_error_rad: [f64; 3],
    /// The number of neighbours weighted.
    pub neighbours: u32,
}

/// The weighting and the consistency screen (40) over gathered neighbours (nearest
/// first); the survivors are marked in the returned mask and their weights are in `q`.
#[inline]
fn weigh(
    params: &MethodParams,
    g: &Gathered,
    q: &mut Slots<f64, MAX_NEIGHBOURS>,
) -> Option<(Estimate, u32)> {
    let n = g.len();
    let mut active = all_active(n);
    let positions = g.positions();
    let orientations = g.orientations();
    loop {
        let count = active.count_ones();
        if count == 0 {
            return None;
        }
        weights_of_active(params, g, active, q);
        let weights = q.as_slice();
        let mut position = [0.0; 3];
        for i in 0..n {
            if active & (1 << i) != 0 {
                for axis in 0..3 {
                    position[axis] += weights[i] * positions[i][axis];
                }
            }
        }
        if params.consistency_screen {
            // Compared squared: the same order as the distances, without square roots.
            let bound_mm = params.radius_mm / count as f64;
            let bound_squared = bound_mm * bound_mm;
            let mut worst: Option<(usize, f64)> = None;
            for (i, p) in positions.iter().enumerate() {
                if active & (1 << i) == 0 {
                    continue;
                }
                let gap_squared = norm_squared(sub(position, *p));
                // `>=` so that among equal gaps the farther neighbour is dropped first.
                if gap_squared > bound_squared && worst.is_none_or(|(_, w)| gap_squared >= w) {
                    worst = Some((i, gap_squared));
                }
            }
            if let Some((i, _)) = worst {
                active &= !(1 << i);
                continue;
            }
        }
        // Orientation errors take the same weights, summed only when gathered.
        let mut orientation = [0.0; 3];
        for (i, o) in orientations.iter().enumerate() {
            if active & (1 << i) != 0 {
                for axis in 0..3 {
                    orientation[axis] += weights[i] * o[axis];
                }
            }
        }
        let estimate = Estimate {
            position_error_mm: position,
            orientation_error_rad: orientation,
            neighbours: count,
        };
        return Some((estimate, active));
    }
}

/// The prediction from a selection: computes the selected samples' degrees, weights their
/// errors and applies the consistency screen (40). The runtime's query path.
///
/// `sample(i)` returns a selected sample's actual position (mm), its norm ([`norm_mm`],
/// stored by tables) and its errors; it is called once for each index the selection holds.
/// Orientation errors are weighed only when `orientation` (the estimate's is zero
/// otherwise). Returns `None` when the selection is empty or nothing survives the screen.
#[inline]
pub fn estimate(
    params: &MethodParams,
    target_mm: [f64; 3],
    selection: &Selection,
    orientation: bool,
    sample: impl Fn(u32) -> ([f64; 3], f64, SampleError),
) -> Option<Estimate> {
    let target_norm = norm_mm(target_mm);
    let mut g = Gathered::new();
    for (&i, &key) in selection.samples().iter().zip(selection.keys_mm2()) {
        let (actual_mm, actual_norm, error) = sample(i);
        let degree = degree_from_parts(target_mm, target_norm, actual_mm, actual_norm, key);
        g.push(&degree, &error, orientation);
    }
    let mut q = Slots::new();
    weigh(params, &g, &mut q).map(|(e, _)| e)
}

/// The neighbours of a selection with their degrees, for [`predict`].
pub fn neighbours(
    target_mm: [f64; 3],
    selection: &Selection,
    actual_of: impl Fn(u32) -> [f64; 3],
) -> Neighbours {
    let mut out = Neighbours {
        len: selection.len(),
        items: [EMPTY_NEIGHBOUR; MAX_NEIGHBOURS],
    };
    for (slot, &i) in out.items.iter_mut().zip(selection.samples()) {
        *slot = Neighbour {
            sample: i,
            degree: approximation_degree(target_mm, actual_of(i)),
        };
    }
    out
}

/// As [`estimate`], from neighbours given with their degrees (nearest first, at most
/// [`MAX_NEIGHBOURS`]), returning the neighbours that survived the screen and their
/// weights too. The brute-force reference and explanations use it.
pub fn predict(
    params: &MethodParams,
    neighbours: &[Neighbour],
    error_of: impl Fn(u32) -> SampleError,
) -> Option<Prediction> {
    let neighbours = &neighbours[..neighbours.len().min(MAX_NEIGHBOURS)];
    let mut g = Gathered::new();
    for n in neighbours {
        g.push(&n.degree, &error_of(n.sample), true);
    }
    let mut q = Slots::new();
    let (estimate, active) = weigh(params, &g, &mut q)?;
    let mut prediction = Prediction {
        position_error_mm: estimate.position_error_mm,
        orientation_error_rad: estimate.orientation_error_rad,
        neighbours: Neighbours {
            len: 0,
            items: [EMPTY_NEIGHBOUR; MAX_NEIGHBOURS],
        },
        weights: Weights { q: Slots::new() },
    };
    for (i, (n, &weight)) in neighbours.iter().zip(q.as_slice()).enumerate() {
        if active & (1 << i) != 0 {
            let out = &mut prediction.neighbours;
            out.items[out.len] = *n;
            out.len += 1;
            prediction.weights.q.push(weight);
        }
    }
    Some(prediction)
}

#[inline]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn norm_squared(a: [f64; 3]) -> f64 {
    a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
}

/// Whether every joint angle of `sample_rad` is within `radius_rad` of `target_rad`:
/// `max_i |q_sample,i − q_target,i| ≤ radius_rad` (joint vectors of unequal length fail). The one test of the joint-space screen,
/// shared by the runtime, the table builder and the brute-force reference. NaN fails.
#[inline]
pub fn joints_within(sample_rad: &[f64], target_rad: &[f64], radius_rad: f64) -> bool {
    sample_rad.len() == target_rad.len()
        && sample_rad
            .iter()
            .zip(target_rad)
            .all(|(s, t)| (s - t).abs() <= radius_rad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn neighbour(sample: u32, target: [f64; 3], actual: [f64; 3]) -> Neighbour {
        Neighbour {
            sample,
            degree: approximation_degree(target, actual),
        }
    }

    #[test]
    fn selection_keeps_k_nearest_with_ties_by_index_in_any_offer_order() {
        let target = [1000.0, 0.0, 0.0];
        let points: Vec<[f64; 3]> = vec![
            [1010.0, 0.0, 0.0],
            [990.0, 0.0, 0.0], // ties with 0 at 10 mm
            [1000.0, 5.0, 0.0],
            [1000.0, 0.0, 30.0],
            [1000.0, 0.0, -10.0], // ties with 0 and 1
        ];
        for order in [[0, 1, 2, 3, 4], [4, 3, 2, 1, 0], [2, 4, 0, 3, 1]] {
            let mut s = Selection::new(3);
            for i in order {
                s.offer(i, distance_squared_mm2(target, points[i as usize]));
            }
            let got: Vec<u32> = s.samples().to_vec();
            assert_eq!(got, vec![2, 0, 1]);
        }
    }

    use proptest::prelude::*;

    /// Sample positions on a coarse lattice around the target (so that equal distances,
    /// and so ties broken by index, are common), some of them not finite; a configuration
    /// for each; and a candidate list that may repeat or skip samples.
    fn scene() -> impl Strategy<Value = (Vec<([f64; 3], u8)>, Vec<u32>)> {
        let coordinate = prop_oneof![
            8 => (-6i32..=6).prop_map(|v| 1000.0 + 5.0 * f64::from(v)),
            1 => Just(f64::NAN),
            1 => Just(1000.0),
        ];
        let sample = (
            [coordinate.clone(), coordinate.clone(), coordinate],
            prop_oneof![Just(CONFIG_UNKNOWN), 0u8..3],
        );
        proptest::collection::vec(sample, 0..80).prop_flat_map(|samples| {
            // Indices up to a few past the end: absent samples are skipped.
            let count = samples.len() as u32 + 3;
            let list = proptest::collection::vec(0..count, 0..120);
            (Just(samples), list)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// The exact tier's selection keeps what the general one keeps, in the same
        /// order, for any k, radius, thresholds, configuration and candidate order.
        #[test]
        fn select_nearest_equals_select(
            (samples, list) in scene(),
            k in 1u32..=16,
            radius_mm in prop_oneof![Just(12.5), 1.0..40.0f64],
            thresholds in any::<bool>(),
            target_config in prop_oneof![Just(None), (0u8..3).prop_map(Some)],
            refused in any::<u64>(),
        ) {
            let target = [1000.0, 1000.0, 1000.0];
            let mut params = MethodParams::paper(radius_mm);
            params.max_neighbours = k;
            if thresholds {
                params.lambda_min_per_mm = 1e-5;
                params.zeta_min_per_mm2 = 1e-9;
            }
            // Some samples refused by the caller's own screen (the joint screen's place).
            let allowed = |i: u32| refused >> (i % 64) & 1 == 0;
            let reference = select(&params, target, target_config, list.iter().copied(), |i| {
                let &(actual, config) = samples.get(i as usize)?;
                allowed(i).then_some((actual, config))
            });
            let fast = select_nearest(
                &params,
                target,
                list.iter().copied(),
                |i| samples.get(i as usize).map(|s| s.0),
                |i| {
                    let config = samples.get(i as usize).map_or(CONFIG_UNKNOWN, |s| s.1);
                    config_matches(config, target_config) && allowed(i)
                },
            );
            prop_assert_eq!(fast.samples(), reference.samples());
            let bits = |s: &Selection| s.keys_mm2().iter().map(|k| k.to_bits()).collect::<Vec<_>>();
            prop_assert_eq!(bits(&fast), bits(&reference));
        }
    }

    #[test]
    fn coincident_sample_takes_all_weight() {
        let target = [1500.0, 200.0, 900.0];
        let p = MethodParams::paper(200.0);
        let ns = [
            neighbour(0, target, target),
            neighbour(1, target, [1510.0, 200.0, 900.0]),
        ];
        assert!(ns[0].degree.coincident);
        assert_eq!(weights(&p, &ns).as_slice(), &[1.0, 0.0]);
    }

    #[test]
    fn collinear_sample_gets_a_finite_floored_zeta() {
        let target = [1000.0, 0.0, 0.0];
        let on_line = approximation_degree(target, [1050.0, 0.0, 0.0]);
        assert_eq!(on_line.lambda_per_mm, 0.0);
        assert!(on_line.zeta_per_mm2.is_finite());
        let floored = 1.0 / (0.5 * 1e-3 * 1050.0);
        assert!((on_line.zeta_per_mm2 - floored).abs() <= 1e-15 * floored);
        let p = MethodParams::paper(200.0);
        let ns = [
            Neighbour {
                sample: 0,
                degree: on_line,
            },
            neighbour(1, target, [1000.0, 50.0, 0.0]),
        ];
        let w = weights(&p, &ns);
        assert!(w.as_slice().iter().all(|q| q.is_finite()));
        assert!((w.as_slice().iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn all_collinear_neighbours_fall_back_to_zeta() {
        let target = [1000.0, 0.0, 0.0];
        let ns = [
            neighbour(0, target, [1050.0, 0.0, 0.0]),
            neighbour(1, target, [900.0, 0.0, 0.0]),
        ];
        let w = weights(&MethodParams::paper(200.0), &ns);
        let z0 = ns[0].degree.zeta_per_mm2;
        let z1 = ns[1].degree.zeta_per_mm2;
        assert!((w.as_slice()[0] - z0 / (z0 + z1)).abs() < 1e-15);
        assert!((w.as_slice().iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn target_at_origin_is_finite() {
        let d = approximation_degree([0.0; 3], [10.0, 0.0, 0.0]);
        assert_eq!(d.lambda_per_mm, 0.0);
        assert!(d.zeta_per_mm2.is_finite() && d.zeta_per_mm2 > 0.0);
    }

    #[test]
    fn consistency_screen_drops_the_outlier() {
        let target = [1000.0, 0.0, 0.0];
        let mut p = MethodParams::paper(10.0);
        let s: Vec<Neighbour> = [[1001.0, 1.0, 0.0], [999.0, 1.0, 0.0], [1000.0, 2.0, 1.0]]
            .into_iter()
            .enumerate()
            .map(|(i, a)| neighbour(i as u32, target, a))
            .collect();
        // Errors 0, 0 and 20 mm: d_p is far from the third, beyond ε/m = 3.3 mm.
        let error_of = |i: u32| SampleError {
            position_mm: [if i == 2 { 20.0 } else { 0.0 }, 0.0, 0.0],
            orientation_rad: [0.0; 3],
        };
        let screened = predict(&p, &s, error_of).unwrap();
        assert_eq!(screened.neighbours.len(), 2);
        assert_eq!(screened.position_error_mm, [0.0; 3]);
        p.consistency_screen = false;
        let unscreened = predict(&p, &s, error_of).unwrap();
        assert_eq!(unscreened.neighbours.len(), 3);
        assert!(unscreened.position_error_mm[0] > 1.0);
    }

    #[test]
    fn thresholds_and_range() {
        let mut p = MethodParams::paper(100.0);
        p.lambda_min_per_mm = 1e-4;
        p.zeta_min_per_mm2 = 1e-5;
        // (37): |p|² ≤ 2 / (1e-5 · 1e-4 · 100) = 2e7, |p| ≤ 4472 mm.
        assert!(p.target_in_range([4000.0, 0.0, 0.0]));
        assert!(!p.target_in_range([4500.0, 0.0, 0.0]));
        let d = approximation_degree([1000.0, 0.0, 0.0], [1000.0, 50.0, 0.0]);
        assert!(p.degree_admissible(&d));
        let far = approximation_degree([1000.0, 0.0, 0.0], [1000.0, 150.0, 0.0]);
        assert!(!p.degree_admissible(&far));
    }

    #[test]
    fn joint_screen_is_a_max_norm_and_refuses_nan() {
        let target = [0.0, 0.5, -0.5, 1.0, 0.0, 0.0];
        let mut sample = target;
        sample[3] += 0.1;
        assert!(joints_within(&sample, &target, 0.1 + 1e-12));
        assert!(!joints_within(&sample, &target, 0.099));
        sample[0] = f64::NAN;
        assert!(!joints_within(&sample, &target, 10.0));
    }
}
