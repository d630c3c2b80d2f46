//! Repeated poses: rows that command one pose become one sample, the mean of their measured
//! errors, and the spread of those errors about their mean is reported — the repeatability
//! of the robot and the measuring instrument together.

use nalgebra::Rotation3;
use rayon::iter::{IntoParallelIterator, ParallelIterator};
use rustc_hash::FxHashMap;

use super::{Joints, SampleSet};

/// Two rows command the same pose when their nominal positions (mm), the entries of their
/// nominal rotation matrices (≈ rad), their joint values (rad; mm for prismatic joints)
/// round to the same multiples of this, and their configurations are equal.
///
/// Rounding rather than comparing differences makes "the same pose" an equivalence, found
/// by hashing in one pass: values written with different digits for one number (a
/// controller's `0.30000000000000004` for `0.3`) are the same, values a nanometre or a
/// nanoradian apart are not. (Two values within 1e-15 of each other that straddle a
/// rounding boundary stay two samples: harmless, as several samples may share a nominal
/// position.)
pub const REPEAT_RESOLUTION: f64 = 1e-9;

/// The spread of the measured errors of repeated poses: how far each repeat's error lies
/// from the mean of its pose's repeats.
#[derive(Clone, Debug, PartialEq)]
pub struct RepeatReport {
    /// Poses given on more than one row; each became one sample.
    pub poses: usize,
    /// The rows of those poses, all together.
    pub rows: usize,
    /// The most rows of one pose.
    pub max_rows_per_pose: usize,
    /// The largest distance of a repeat's position error from its pose's mean, mm.
    pub position_max_mm: f64,
    /// The RMS of those distances over every row of a repeated pose, mm.
    pub position_rms_mm: f64,
    /// The largest angle between a repeat's orientation error and its pose's mean (the norm
    /// of the difference of their rotation vectors), mrad, when the samples have
    /// orientation errors.
    pub orientation_max_mrad: Option<f64>,
    /// The RMS of those angles, mrad.
    pub orientation_rms_mrad: Option<f64>,
}

/// Rows from which the digests are computed on the thread pool: fewer take less time than
/// waking it.
const PARALLEL_ROWS: usize = 1 << 14;

/// A sample set's values before repeated poses are folded.
pub(crate) struct Parts {
    pub nominal_mm: Vec<[f64; 3]>,
    pub error_mm: Vec<[f64; 3]>,
    pub nominal_rotation: Option<Vec<Rotation3<f64>>>,
    pub rotation_error_rad: Option<Vec<[f64; 3]>>,
    pub joints: Option<Joints>,
    pub config: Option<Vec<u8>>,
    pub lines: Vec<u64>,
}

impl Parts {
    /// Row `i`'s pose, rounded ([`REPEAT_RESOLUTION`]), into `key`.
    fn pose_key(&self, i: usize, key: &mut Vec<u64>) {
        // +0.0 folds −0.0 into 0.0, so both spellings of zero are the same value.
        let round = |v: f64| ((v / REPEAT_RESOLUTION).round() + 0.0).to_bits();
        key.clear();
        key.extend(self.nominal_mm[i].map(round));
        if let Some(r) = &self.nominal_rotation {
            key.extend(r[i].matrix().iter().map(|&v| round(v)));
        }
        if let Some(j) = &self.joints {
            key.extend(j.row(i).iter().map(|&v| round(v)));
        }
        if let Some(c) = &self.config {
            key.push(u64::from(c[i]));
        }
    }

    /// Row `i`'s orientation error (a rotation vector, rad), zero without orientations.
    fn rotation(&self, i: usize) -> [f64; 3] {
        self.rotation_error_rad.as_ref().map_or([0.0; 3], |r| r[i])
    }
}

/// Running sums of one repeated pose.
struct Group {
    rows: usize,
    error_mm: [f64; 3],
    rotation_rad: [f64; 3],
}

/// The samples of `parts`, each repeated pose folded into its first row with the mean of
/// the repeats' errors (position errors, and rotation vectors).
pub(crate) fn fold(parts: Parts) -> SampleSet {
    let Some(pose_of) = first_rows_of_poses(&parts) else {
        return SampleSet {
            nominal_mm: parts.nominal_mm,
            error_mm: parts.error_mm,
            nominal_rotation: parts.nominal_rotation,
            rotation_error_rad: parts.rotation_error_rad,
            joints: parts.joints,
            config: parts.config,
            lines: parts.lines,
            repeats: None,
        };
    };
    let means = Means::of(&parts, &pose_of);
    let report = means.spread(&parts, &pose_of);

    // The first row of each pose, with its pose's mean errors.
    let keep: Vec<usize> = (0..pose_of.len())
        .filter(|&i| pose_of[i] as usize == i)
        .collect();
    let mean = |i: usize| means.of_pose(i as u32);
    SampleSet {
        nominal_mm: keep.iter().map(|&i| parts.nominal_mm[i]).collect(),
        error_mm: keep
            .iter()
            .map(|&i| mean(i).map_or(parts.error_mm[i], |g| g.error_mm))
            .collect(),
        nominal_rotation: parts
            .nominal_rotation
            .as_ref()
            .map(|r| keep.iter().map(|&i| r[i]).collect()),
        rotation_error_rad: parts.rotation_error_rad.as_ref().map(|r| {
            keep.iter()
                .map(|&i| mean(i).map_or(r[i], |g| g.rotation_rad))
                .collect()
        }),
        joints: parts.joints.as_ref().map(|j| j.subset(&keep)),
        config: parts
            .config
            .as_ref()
            .map(|c| keep.iter().map(|&i| c[i]).collect()),
        lines: keep.iter().map(|&i| parts.lines[i]).collect(),
        repeats: Some(report),
    }
}

/// For each row, the first row that commands its pose; `None` when every pose is given once.
fn first_rows_of_poses(parts: &Parts) -> Option<Vec<u32>> {
    let n = parts.nominal_mm.len();
    // Rows by a 64-bit digest of their rounded pose; rows whose digests collide but whose
    // poses differ are chained in `collisions`.
    let mut first: FxHashMap<u64, u32> = FxHashMap::default();
    first.reserve(n);
    let mut collisions: FxHashMap<u32, u32> = FxHashMap::default();
    let mut pose_of: Vec<u32> = Vec::with_capacity(n);
    // The digests, each row's alone: on the thread pool for many rows.
    let digest = |(key, bytes): &mut (Vec<u64>, Vec<u8>), i: usize| {
        parts.pose_key(i, key);
        bytes.clear();
        key.iter()
            .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
        xxhash_rust::xxh3::xxh3_64(bytes)
    };
    let digests: Vec<u64> = if n >= PARALLEL_ROWS {
        (0..n)
            .into_par_iter()
            .map_init(|| (Vec::new(), Vec::new()), digest)
            .collect()
    } else {
        let mut buffers = (Vec::new(), Vec::new());
        (0..n).map(|i| digest(&mut buffers, i)).collect()
    };
    let (mut key, mut other) = (Vec::new(), Vec::new());
    let mut repeated = false;
    for (i, &digest) in digests.iter().enumerate() {
        let mut pose = i as u32;
        match first.get(&digest) {
            None => {
                first.insert(digest, i as u32);
            }
            Some(&head) => {
                parts.pose_key(i, &mut key);
                let mut j = head;
                loop {
                    parts.pose_key(j as usize, &mut other);
                    if other == key {
                        pose = j;
                        repeated = true;
                        break;
                    }
                    match collisions.get(&j) {
                        Some(&next) => j = next,
                        None => {
                            collisions.insert(j, i as u32);
                            break;
                        }
                    }
                }
            }
        }
        pose_of.push(pose);
    }
    repeated.then_some(pose_of)
}

/// The mean errors of each repeated pose, in first-row order.
struct Means {
    /// A repeated pose's first row → its index in `groups`.
    group_of: FxHashMap<u32, usize>,
    groups: Vec<Group>,
}

impl Means {
    fn of(parts: &Parts, pose_of: &[u32]) -> Means {
        let mut group_of: FxHashMap<u32, usize> = FxHashMap::default();
        let mut groups: Vec<Group> = Vec::new();
        for (i, &pose) in pose_of.iter().enumerate() {
            if pose as usize == i {
                continue;
            }
            let g = *group_of.entry(pose).or_insert_with(|| {
                let p = pose as usize;
                groups.push(Group {
                    rows: 1,
                    error_mm: parts.error_mm[p],
                    rotation_rad: parts.rotation(p),
                });
                groups.len() - 1
            });
            let group = &mut groups[g];
            group.rows += 1;
            let (e, r) = (parts.error_mm[i], parts.rotation(i));
            for a in 0..3 {
                group.error_mm[a] += e[a];
                group.rotation_rad[a] += r[a];
            }
        }
        for g in &mut groups {
            let k = g.rows as f64;
            g.error_mm = g.error_mm.map(|v| v / k);
            g.rotation_rad = g.rotation_rad.map(|v| v / k);
        }
        Means { group_of, groups }
    }

    /// The mean of the pose whose first row is `pose`, if it is repeated.
    fn of_pose(&self, pose: u32) -> Option<&Group> {
        self.group_of.get(&pose).map(|&g| &self.groups[g])
    }

    /// The spread of the repeats about their means.
    fn spread(&self, parts: &Parts, pose_of: &[u32]) -> RepeatReport {
        let distance = |a: [f64; 3], b: [f64; 3]| {
            let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        };
        let (mut position_max, mut position_sq, mut rotation_max, mut rotation_sq) =
            (0.0f64, 0.0, 0.0f64, 0.0);
        let mut rows = 0usize;
        for (i, &pose) in pose_of.iter().enumerate() {
            if let Some(g) = self.of_pose(pose) {
                let d = distance(parts.error_mm[i], g.error_mm);
                let r = distance(parts.rotation(i), g.rotation_rad);
                position_max = position_max.max(d);
                position_sq += d * d;
                rotation_max = rotation_max.max(r);
                rotation_sq += r * r;
                rows += 1;
            }
        }
        let orientation = parts.rotation_error_rad.is_some();
        RepeatReport {
            poses: self.groups.len(),
            rows,
            max_rows_per_pose: self.groups.iter().map(|g| g.rows).max().unwrap_or(0),
            position_max_mm: position_max,
            position_rms_mm: (position_sq / rows as f64).sqrt(),
            orientation_max_mrad: orientation.then_some(rotation_max * 1e3),
            orientation_rms_mrad: orientation.then(|| (rotation_sq / rows as f64).sqrt() * 1e3),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use approx::assert_abs_diff_eq;

    use super::super::{parse_samples, parse_samples_with, ColumnMap, ReadOptions, SampleSet};

    fn samples(text: &str) -> SampleSet {
        parse_samples(Path::new("s.csv"), text.as_bytes(), &ColumnMap::default()).unwrap()
    }

    #[test]
    fn several_poses_at_one_position_are_separate_samples() {
        // Orientation, joints or configuration differ: four samples at one position.
        let s = samples(
            "x,y,z,dx,dy,dz,a,b,c,j1,config\n\
             1,2,3,0.1,0,0,0,90,0,10,1\n\
             1,2,3,0.2,0,0,0,90,45,10,1\n\
             1,2,3,0.3,0,0,0,90,0,20,1\n\
             1,2,3,0.4,0,0,0,90,0,10,2\n",
        );
        assert_eq!(s.len(), 4);
        assert_eq!(
            s.error_mm.iter().map(|e| e[0]).collect::<Vec<_>>(),
            [0.1, 0.2, 0.3, 0.4]
        );
        assert!(s.repeats.is_none());
    }

    #[test]
    fn repeated_poses_are_averaged_and_their_spread_reported() {
        let s = samples(
            "x,y,z,dx,dy,dz,rx,ry,rz,a,b,c\n\
             1,2,3,0.1,0,0,0.001,0,0,0,90,0\n\
             4,5,6,0,0,1,0,0,0,0,90,0\n\
             # the first pose again, twice\n\
             1,2,3,0.2,0,0,0.002,0,0,0,90,0\n\
             7,8,9,5,5,5,0,0,0,0,90,0\n\
             1,2,3,0.3,0,0,0.003,0,0,0,90,0\n\
             4,5,6,0,0,-1,0,0,0,0,90,0\n",
        );
        assert_eq!(
            s.nominal_mm,
            vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]
        );
        assert_eq!(s.lines, vec![2, 3, 6]);
        assert_abs_diff_eq!(s.error_mm[0][0], 0.2, epsilon = 1e-15);
        assert_eq!(s.error_mm[1], [0.0; 3]);
        assert_eq!(s.error_mm[2], [5.0; 3]);
        let r = s.rotation_error_rad.as_ref().unwrap();
        assert_abs_diff_eq!(r[0][0], 0.002, epsilon = 1e-15);
        let report = s.repeats.unwrap();
        assert_eq!(
            (report.poses, report.rows, report.max_rows_per_pose),
            (2, 5, 3)
        );
        // Deviations from the means: 0.1, 0, 0.1 mm and 1, 1 mm.
        assert_abs_diff_eq!(report.position_max_mm, 1.0, epsilon = 1e-12);
        let rms = ((0.01 + 0.0 + 0.01 + 1.0 + 1.0) / 5.0f64).sqrt();
        assert_abs_diff_eq!(report.position_rms_mm, rms, epsilon = 1e-12);
        // 1, 0, 1 mrad and 0, 0.
        assert_abs_diff_eq!(report.orientation_max_mrad.unwrap(), 1.0, epsilon = 1e-9);
        let rms = (2.0 / 5.0f64).sqrt();
        assert_abs_diff_eq!(report.orientation_rms_mrad.unwrap(), rms, epsilon = 1e-9);
    }

    #[test]
    fn a_position_only_file_averages_repeated_positions() {
        let s = samples("x,y,z,dx,dy,dz\n1,2,3,0.5,0,0\n1,2,3.0,1.5,0,0\n");
        assert_eq!(s.len(), 1);
        assert_eq!(s.error_mm[0], [1.0, 0.0, 0.0]);
        let report = s.repeats.unwrap();
        assert_eq!(report.orientation_max_mrad, None);
        assert_abs_diff_eq!(report.position_max_mm, 0.5, epsilon = 1e-15);
    }

    #[test]
    fn repeats_are_the_same_pose_to_the_resolution() {
        let metres = ReadOptions {
            length_unit: crate::LengthUnit::Metre,
            ..ReadOptions::default()
        };
        let read = |text: &str| {
            parse_samples_with(
                Path::new("s.csv"),
                text.as_bytes(),
                &ColumnMap::default(),
                &metres,
            )
            .unwrap()
        };
        // One number written two ways, and both zeros: one pose.
        let s = read("x,y,z,dx,dy,dz,j1\n0.30000000000000004,-0,1,0,0,0,0\n0.3,0,1,0,0,0,-0\n");
        assert_eq!(s.len(), 1);
        // A nanometre apart, in position or in a joint (1e-9 m is 1e-6 mm): two poses.
        let s = read("x,y,z,dx,dy,dz\n0.3,0,1,0,0,0\n0.300000001,0,1,0,0,0\n");
        assert_eq!(s.len(), 2);
        let s = samples("x,y,z,dx,dy,dz,j1\n1,2,3,0,0,0,0\n1,2,3,0,0,0,1e-6\n");
        assert_eq!(s.len(), 2);
    }

    #[test]
    fn the_spacing_counts_samples_at_one_position_once() {
        let mut text = String::from("x,y,z,dx,dy,dz,a,b,c\n");
        for i in 0..10 {
            for c in [0, 90, 180] {
                text += &format!("{},0,0,0,0,0,0,0,{c}\n", 100 * i);
            }
        }
        let s = samples(&text);
        assert_eq!(s.len(), 30);
        assert_eq!(s.spacing_mm(), Some(100.0));
        // Every sample at one position: no spacing.
        let s = samples("x,y,z,dx,dy,dz,a,b,c\n1,2,3,0,0,0,0,0,0\n1,2,3,0,0,0,0,0,90\n");
        assert_eq!(s.spacing_mm(), None);
    }
}
