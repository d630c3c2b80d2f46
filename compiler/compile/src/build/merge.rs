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

/// The voxel edges a build tries, as fractions of the derivation spacing
/// ([`super::plan::derivation_spacing_mm`]), finest first: a tracked path sampled at 1 kHz
/// has hundreds of samples per spacing, which the finest voxels already merge; samples a
/// spacing apart (a lattice, a random cloud) merge only at the coarsest, and are never
/// merged beyond a quarter of the spacing, where averaging would move the field.
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

/// Each sample's voxel and configuration, with its index: sorted, the samples of one voxel
/// are adjacent and in source order.
fn voxel_keys(samples: &SampleSet, voxel_mm: f64) -> Vec<([i64; 3], u8, u32)> {
    let Some((lo, _)) = samples.nominal_bounds_mm() else {
        return Vec::new();
    };
    let mut keys: Vec<([i64; 3], u8, u32)> = (0..samples.len())
        .map(|i| {
            let p = samples.nominal_mm[i];
            // Finite samples within the workspace bound: the quotient fits an i64.
            let key = [0, 1, 2].map(|a| ((p[a] - lo[a]) / voxel_mm).floor() as i64);
            let config = samples.config.as_ref().map_or(0, |c| c[i]);
            (key, config, i as u32)
        })
        .collect();
    keys.sort_unstable_by_key(|&(key, config, i)| (config, key, i));
    keys
}

/// How many samples a merge in voxels of `voxel_mm` leaves (one per voxel and
/// configuration), without merging.
pub fn merged_count(samples: &SampleSet, voxel_mm: f64) -> usize {
    let keys = voxel_keys(samples, voxel_mm);
    keys.windows(2)
        .filter(|w| (w[0].0, w[0].1) != (w[1].0, w[1].1))
        .count()
        + usize::from(!keys.is_empty())
}

/// `samples` merged in voxels of `voxel_mm`: per voxel and configuration one sample, the
/// mean of its members' nominal positions, position and orientation errors and joint
/// values; its nominal orientation, source line and configuration are its first member's.
pub fn merge(samples: &SampleSet, voxel_mm: f64) -> SampleSet {
    let keys = voxel_keys(samples, voxel_mm);
    // The groups, each its members' indices in source order, ordered by first member.
    let mut groups: Vec<Vec<u32>> = Vec::new();
    for (j, &(key, config, i)) in keys.iter().enumerate() {
        if j > 0 && (keys[j - 1].0, keys[j - 1].1) == (key, config) {
            groups.last_mut().expect("a group was opened").push(i);
        } else {
            groups.push(vec![i]);
        }
    }
    drop(keys);
    groups.sort_unstable_by_key(|g| g[0]);
    let firsts: Vec<usize> = groups.iter().map(|g| g[0] as usize).collect();
    let mut merged = samples.subset(&firsts);
    let mean3 = |values: &[[f64; 3]], group: &[u32]| {
        let mut sum = [0.0; 3];
        for &i in group {
            for (s, v) in sum.iter_mut().zip(values[i as usize]) {
                *s += v;
            }
        }
        sum.map(|s| s / group.len() as f64)
    };
    for (out, group) in groups.iter().enumerate() {
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
        for group in &groups {
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
