//! Merging samples too many for a table's size bound: the measured samples averaged within
//! small voxels, so that a tracked path's thousands of samples a second (each a fraction of
//! a millimetre from the last) become one sample per voxel it passes through.
//!
//! The table's size grows with its samples (each holds its position, errors and its place
//! in the candidate lists), while what the method answers depends on the samples near a
//! target, not on how many repeat the same few micrometres. Averaging samples of one
//! configuration that share a voxel much smaller than the sample spacing keeps the field
//! they describe and smooths their measurement noise; the voxel's edge is recorded in the
//! table's header ([`adwi_runtime::format::Header::merge_voxel_mm`]).
//!
//! The voxels are aligned to the samples' nominal bounding box; samples are grouped by
//! configuration and voxel, averaged in their source order (so the same samples give the
//! same averages to the bit, at any thread count), and the merged samples are in the order
//! of each voxel's first sample.

use adwi_samples::SampleSet;
use rayon::iter::{IndexedParallelIterator, ParallelIterator};
use rayon::slice::ParallelSliceMut;

/// The voxel edges a build tries, as fractions of the derivation spacing
/// ([`super::plan::derivation_spacing_mm`]), finest first: a tracked path sampled at 1 kHz
/// has hundreds of samples per spacing, which the finest voxels already merge; samples a
/// spacing apart (a lattice, a random cloud) merge only at the coarsest, and are never
/// merged beyond a quarter of the spacing, where averaging would move the field.
///
/// Each is twice the last, and the voxels share one origin, so each voxel is whole voxels of
/// the finer ones: a coarser voxel never leaves more samples.
pub const MERGE_FRACTIONS: [f64; 5] = [1.0 / 64.0, 1.0 / 32.0, 1.0 / 16.0, 1.0 / 8.0, 1.0 / 4.0];

/// A merge of the samples, as planned: the voxel edge and the count it leaves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleMerge {
    /// The voxels' edge, mm (a value an `f32` holds exactly, as the header records it).
    pub voxel_mm: f64,
    /// The samples measured.
    pub measured: usize,
    /// The samples the table holds: one per voxel and configuration.
    pub merged: usize,
}

/// Where each sample falls: its voxel, its configuration and, with joint values, the cell
/// of each joint in steps of `voxel_mm` over the samples' reach (rad; mm for a prismatic
/// joint, which then merges only nearly equal values). Samples at one position in other arm
/// poses (a pose measured in several orientations) are not one sample: their joint values
/// and errors do not average into any pose the arm takes. A joint turned by less than the
/// step moves the point by at most about a voxel, so a tracked path still merges.
///
/// Each sample's key (configuration, voxel, joint cells) is computed once: a sort of a
/// million samples then compares integers instead of dividing and flooring in every
/// comparison.
struct Voxels {
    /// Integers per key: the configuration, three voxel indices, one cell per joint.
    stride: usize,
    keys: Vec<i64>,
    /// A hash of each key: the sort compares these, and keys only where they are equal.
    hashes: Vec<u64>,
}

impl Voxels {
    fn new(samples: &SampleSet, voxel_mm: f64) -> Option<Voxels> {
        let (lo_mm, _) = samples.nominal_bounds_mm()?;
        // The same reach for every voxel, so that the joint cells of a voxel twice as large
        // are exactly twice as large and the merges nest ([`MERGE_FRACTIONS`]).
        let reach_mm = samples
            .nominal_mm
            .iter()
            .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
            .fold(0.0, f64::max);
        // Samples all at the base's origin: one joint cell.
        let joint_step = if reach_mm > 0.0 {
            voxel_mm / reach_mm
        } else {
            f64::INFINITY
        };
        let joints = samples.joints.as_ref();
        let stride = 4 + joints.map_or(0, |j| j.count());
        let mut keys = vec![0; samples.len() * stride];
        let hashes = (keys.par_chunks_exact_mut(stride).enumerate())
            .map(|(i, key)| {
                let p = samples.nominal_mm[i];
                key[0] = i64::from(samples.config.as_ref().map_or(0, |c| c[i]));
                // Finite samples within the workspace bound: the quotient fits an i64.
                for a in 0..3 {
                    key[1 + a] = ((p[a] - lo_mm[a]) / voxel_mm).floor() as i64;
                }
                if let Some(joints) = joints {
                    for (k, &q) in key[4..].iter_mut().zip(joints.row(i)) {
                        *k = (q / joint_step).floor() as i64;
                    }
                }
                hash_key(key)
            })
            .collect();
        Some(Voxels {
            stride,
            keys,
            hashes,
        })
    }

    fn key(&self, i: u32) -> &[i64] {
        let i = i as usize;
        &self.keys[i * self.stride..(i + 1) * self.stride]
    }

    /// Each sample's key hash and index.
    fn hashed(&self) -> Vec<(u64, u32)> {
        (self.hashes.iter().enumerate())
            .map(|(i, &h)| (h, i as u32))
            .collect()
    }

    /// The sample indices sorted so that those merged together are adjacent, each group in
    /// source order: by key hash, key, then index (a total order, so the same at any run).
    fn sorted(&self) -> Vec<u32> {
        let mut order = self.hashed();
        order.par_sort_unstable_by(|&(h, i), &(g, j)| {
            h.cmp(&g)
                .then_with(|| self.key(i).cmp(self.key(j)))
                .then(i.cmp(&j))
        });
        order.into_iter().map(|(_, i)| i).collect()
    }

    /// Whether samples `i` and `j` are merged together.
    fn together(&self, i: u32, j: u32) -> bool {
        self.key(i) == self.key(j)
    }

    /// The groups of `order` ([`Voxels::sorted`]) as ranges of it, ordered by first member
    /// (each group's first entry, its lowest index).
    fn groups(&self, order: &[u32]) -> Vec<std::ops::Range<usize>> {
        let mut groups = Vec::new();
        let mut start = 0;
        for j in 1..=order.len() {
            if j == order.len() || !self.together(order[j - 1], order[j]) {
                groups.push(start..j);
                start = j;
            }
        }
        groups.sort_unstable_by_key(|g| order[g.start]);
        groups
    }
}

/// A hash of a voxel key (64-bit multiply-xorshift mixing of each integer): fixed, so the
/// same samples sort the same on every machine.
fn hash_key(key: &[i64]) -> u64 {
    key.iter().fold(0x9e37_79b9_7f4a_7c15, |h, &k| {
        let x = (h ^ k as u64).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x ^ (x >> 31)
    })
}

/// How many samples a merge in voxels of `voxel_mm` leaves (one per voxel, configuration
/// and joint cells), without merging.
pub fn merged_count(samples: &SampleSet, voxel_mm: f64) -> usize {
    let Some(voxels) = Voxels::new(samples, voxel_mm) else {
        return 0;
    };
    // Sorted by hash alone (integers compared, not keys); a run of one hash is one voxel
    // unless its keys differ, which a run then sorts by key to count.
    let mut order = voxels.hashed();
    order.par_sort_unstable();
    order
        .chunk_by(|a, b| a.0 == b.0)
        .map(|run| {
            let first = voxels.key(run[0].1);
            if run.iter().all(|&(_, i)| voxels.key(i) == first) {
                return 1;
            }
            let mut keys: Vec<&[i64]> = run.iter().map(|&(_, i)| voxels.key(i)).collect();
            keys.sort_unstable();
            keys.dedup();
            keys.len()
        })
        .sum()
}

fn count_sorted(voxels: &Voxels, order: &[u32]) -> usize {
    order
        .windows(2)
        .filter(|w| !voxels.together(w[0], w[1]))
        .count()
        + usize::from(!order.is_empty())
}

/// A merge in voxels of `voxel_mm`, planned once: the count it leaves known before the
/// samples are averaged, which [`Merging::merge`] then does from the same sort.
pub(super) struct Merging<'a> {
    samples: &'a SampleSet,
    voxels: Option<(Voxels, Vec<u32>)>,
}

impl<'a> Merging<'a> {
    pub(super) fn new(samples: &'a SampleSet, voxel_mm: f64) -> Merging<'a> {
        let voxels = Voxels::new(samples, voxel_mm).map(|v| {
            let order = v.sorted();
            (v, order)
        });
        Merging { samples, voxels }
    }

    /// The samples the merge leaves ([`merged_count`]).
    pub(super) fn count(&self) -> usize {
        self.voxels
            .as_ref()
            .map_or(0, |(voxels, order)| count_sorted(voxels, order))
    }

    /// The merged samples ([`merge`]).
    pub(super) fn merge(self) -> SampleSet {
        match self.voxels {
            Some((voxels, order)) => merge_sorted(self.samples, &voxels, &order),
            None => self.samples.clone(),
        }
    }
}

/// `samples` merged in voxels of `voxel_mm`: per voxel, configuration and joint cells one
/// sample, the mean of its members' nominal positions, position and orientation errors and
/// joint values; its nominal orientation, source line and configuration are its first
/// member's.
pub fn merge(samples: &SampleSet, voxel_mm: f64) -> SampleSet {
    Merging::new(samples, voxel_mm).merge()
}

fn merge_sorted(samples: &SampleSet, voxels: &Voxels, order: &[u32]) -> SampleSet {
    // The groups, each a run of `order` (its members in source order), ordered by first
    // member.
    let groups = voxels.groups(order);
    let firsts: Vec<usize> = groups.iter().map(|g| order[g.start] as usize).collect();
    let mut merged = samples.subset(&firsts);
    drop(firsts);
    let mean3 = |values: &[[f64; 3]], group: &[u32]| {
        let mut sum = [0.0; 3];
        for &i in group {
            for (s, v) in sum.iter_mut().zip(values[i as usize]) {
                *s += v;
            }
        }
        sum.map(|s| s / group.len() as f64)
    };
    for (out, range) in groups.iter().enumerate() {
        let group = &order[range.clone()];
        if group.len() == 1 {
            continue;
        }
        merged.nominal_mm[out] = mean3(&samples.nominal_mm, group);
        merged.error_mm[out] = mean3(&samples.error_mm, group);
        if let (Some(into), Some(from)) = (
            merged.rotation_error_rad.as_mut(),
            samples.rotation_error_rad.as_ref(),
        ) {
            into[out] = mean3(from, group);
        }
    }
    if let Some(from) = samples.joints.as_ref() {
        let mut joints = adwi_samples::Joints::new(from.count());
        let mut mean = vec![0.0; from.count()];
        for range in &groups {
            let group = &order[range.clone()];
            mean.fill(0.0);
            for &i in group {
                for (s, v) in mean.iter_mut().zip(from.row(i as usize)) {
                    *s += v;
                }
            }
            for s in mean.iter_mut() {
                *s /= group.len() as f64;
            }
            joints.push(&mean);
        }
        merged.joints = Some(joints);
    }
    merged
}

#[cfg(test)]
mod tests {
    use super::*;
    use adwi_samples::{parse_samples, ColumnMap};

    /// A path along x, `n` samples `step_mm` apart, errors varying along it.
    fn path(n: usize, step_mm: f64) -> SampleSet {
        let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz\n");
        for i in 0..n {
            let x = 1000.0 + step_mm * i as f64;
            csv += &format!(
                "{x},500,800,{},0.2,-0.1,0.001,0,{}\n",
                0.1 + 1e-3 * i as f64,
                1e-5 * i as f64
            );
        }
        parse_samples("p.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap()
    }

    #[test]
    fn a_merge_averages_each_voxel_in_source_order_and_counts_as_planned() {
        let s = path(100, 0.1);
        // Voxels of 1 mm: ten samples each (the path starts at a voxel's corner).
        assert_eq!(merged_count(&s, 1.0), 10);
        let m = merge(&s, 1.0);
        assert_eq!(m.len(), 10);
        let mean = |f: &dyn Fn(usize) -> f64| (0..10).map(f).sum::<f64>() / 10.0;
        assert_eq!(m.nominal_mm[3][0], mean(&|i| s.nominal_mm[30 + i][0]));
        assert_eq!(m.error_mm[3][0], mean(&|i| s.error_mm[30 + i][0]));
        let r = s.rotation_error_rad.as_ref().unwrap();
        assert_eq!(
            m.rotation_error_rad.as_ref().unwrap()[3][2],
            mean(&|i| r[30 + i][2])
        );
        assert_eq!(m.lines[3], s.lines[30]);
        // A voxel finer than the step keeps every sample as it was.
        assert_eq!(merge(&s, 0.05), s);
    }

    /// One position measured in two arm poses (joint values far apart) stays two samples;
    /// a path whose joints turn by a fraction of the voxel's angle still merges.
    #[test]
    fn samples_of_other_arm_poses_at_one_position_are_never_merged() {
        let mut csv = String::from("x,y,z,dx,dy,dz,j1,j2,j3,j4,j5,j6\n");
        for i in 0..4 {
            // Rows 0 and 2 in one pose, rows 1 and 3 with the wrist turned by 1° (joints in
            // degrees, read as radians).
            let wrist = if i % 2 == 0 { 0.0 } else { 1.0 };
            csv += &format!(
                "{},500,800,0.1,0.1,0.1,0.1,0.2,0.3,{wrist},0.5,0.6\n",
                1000.0 + 0.01 * f64::from(i)
            );
        }
        let s = parse_samples("a.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
        assert_eq!(merged_count(&s, 1.0), 2);
        let m = merge(&s, 1.0);
        assert_eq!(m.len(), 2);
        assert_eq!(m.joints.as_ref().unwrap().row(1)[3], 1f64.to_radians());
        assert_eq!(m.nominal_mm[1][0], (1000.01 + 1000.03) / 2.0);
        // A joint turning by 1e-6° a sample (well under a µm at this reach) merges in 1 mm
        // voxels.
        let mut csv = String::from("x,y,z,dx,dy,dz,j1,j2,j3,j4,j5,j6\n");
        for i in 0..10 {
            let q = 0.1 + 1e-6 * f64::from(i);
            csv += &format!(
                "{},500,800,0.1,0.1,0.1,{q},0.2,0.3,0.4,0.5,0.6\n",
                1000.0 + 0.001 * f64::from(i)
            );
        }
        let s = parse_samples("p.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
        assert_eq!(merged_count(&s, 1.0), merge(&s, 1.0).len());
        assert!(merged_count(&s, 1.0) <= 2, "{}", merged_count(&s, 1.0));
    }

    /// The merge as first written: each sample's key computed where needed, the groups
    /// gathered in a map, each averaged in source order.
    fn reference_merge(samples: &SampleSet, voxel_mm: f64) -> SampleSet {
        use std::collections::BTreeMap;
        let (lo, _) = samples.nominal_bounds_mm().unwrap();
        let reach = (samples.nominal_mm.iter())
            .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
            .fold(0.0, f64::max);
        let step = voxel_mm / reach;
        let mut groups: BTreeMap<(u8, Vec<i64>), Vec<usize>> = BTreeMap::new();
        for (i, p) in samples.nominal_mm.iter().enumerate() {
            let mut key: Vec<i64> = (0..3)
                .map(|a| ((p[a] - lo[a]) / voxel_mm).floor() as i64)
                .collect();
            if let Some(j) = &samples.joints {
                key.extend(j.row(i).iter().map(|q| (q / step).floor() as i64));
            }
            let config = samples.config.as_ref().map_or(0, |c| c[i]);
            groups.entry((config, key)).or_default().push(i);
        }
        let mut groups: Vec<Vec<usize>> = groups.into_values().collect();
        groups.sort_by_key(|g| g[0]);
        let mut out = samples.subset(&groups.iter().map(|g| g[0]).collect::<Vec<_>>());
        let mean = |v: &[[f64; 3]], g: &[usize]| {
            let mut s = [0.0; 3];
            for &i in g {
                (0..3).for_each(|a| s[a] += v[i][a]);
            }
            s.map(|x| x / g.len() as f64)
        };
        let mut joints = samples
            .joints
            .as_ref()
            .map(|j| adwi_samples::Joints::new(j.count()));
        for (k, g) in groups.iter().enumerate() {
            out.nominal_mm[k] = mean(&samples.nominal_mm, g);
            out.error_mm[k] = mean(&samples.error_mm, g);
            if let (Some(o), Some(r)) = (&mut out.rotation_error_rad, &samples.rotation_error_rad) {
                o[k] = mean(r, g);
            }
            if let (Some(into), Some(from)) = (&mut joints, &samples.joints) {
                let mut m = vec![0.0; from.count()];
                for &i in g {
                    m.iter_mut().zip(from.row(i)).for_each(|(s, v)| *s += v);
                }
                m.iter_mut().for_each(|s| *s /= g.len() as f64);
                into.push(&m);
            }
        }
        if joints.is_some() {
            out.joints = joints;
        }
        out
    }

    /// The merge (keys computed once, groups as runs of one sort) gives the reference's
    /// samples to the bit, and the count it plans, on random walks with and without
    /// joints and configurations, at every voxel a build tries.
    #[test]
    fn the_merge_is_the_reference_merge_to_the_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for case in 0..12 {
            let with_joints = case % 2 == 0;
            let with_config = case % 3 == 0;
            let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz");
            csv += if with_joints {
                ",j1,j2,j3,j4,j5,j6"
            } else {
                ""
            };
            csv += if with_config { ",config\n" } else { "\n" };
            let mut p = [1200.0, 300.0, 900.0];
            let mut q = [10.0, -40.0, 90.0, 5.0, -30.0, 0.0];
            for _ in 0..rng.gen_range(50..600) {
                p.iter_mut().for_each(|v| *v += rng.gen_range(-0.4..0.4));
                q.iter_mut().for_each(|v| *v += rng.gen_range(-0.01..0.01));
                csv += &format!(
                    "{},{},{},{},{},{},{},{},{}",
                    p[0],
                    p[1],
                    p[2],
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1e-3..1e-3),
                    rng.gen_range(-1e-3..1e-3),
                    rng.gen_range(-1e-3..1e-3)
                );
                if with_joints {
                    q.iter().for_each(|v| csv += &format!(",{v}"));
                }
                if with_config {
                    csv += &format!(",{}", rng.gen_range(0..2));
                }
                csv += "\n";
            }
            let s = parse_samples("w.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
            let mut finer = usize::MAX;
            for fraction in MERGE_FRACTIONS {
                let voxel_mm = 8.0 * fraction;
                let want = reference_merge(&s, voxel_mm);
                assert_eq!(merge(&s, voxel_mm), want, "case {case}, voxel {voxel_mm}");
                assert_eq!(merged_count(&s, voxel_mm), want.len());
                // The voxels nest: a coarser one never leaves more samples (the refusal
                // counts the coarsest alone).
                assert!(want.len() <= finer, "case {case}, voxel {voxel_mm}");
                finer = want.len();
            }
        }
    }

    #[test]
    fn samples_of_other_configurations_are_never_merged() {
        let mut csv = String::from("x,y,z,dx,dy,dz,config\n");
        for i in 0..6 {
            csv += &format!(
                "{},0,0,0.1,0.1,0.1,{}\n",
                1000.0 + 0.01 * f64::from(i),
                i % 2
            );
        }
        let s = parse_samples("c.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
        let m = merge(&s, 1.0);
        assert_eq!(merged_count(&s, 1.0), 2);
        assert_eq!(m.config, Some(vec![0, 1]));
        assert_eq!(m.nominal_mm[1][0], (1000.01 + 1000.03 + 1000.05) / 3.0);
    }
}
