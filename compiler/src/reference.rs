//! The brute-force reference: every sample examined for every target, in the most obvious
//! way, through the same method functions as the runtime. The compiled table must give the
//! same answer for every target inside its grid; the property tests hold it to that.

use adwi_runtime::format::SampleRecord;
use adwi_runtime::method::{
    self, approximation_degree, config_matches, MethodParams, Neighbour, Prediction, SampleError,
};
use adwi_runtime::Target;

/// The admissible samples for `target`, the `k` nearest, nearest first, ties broken by
/// sample order: filter all samples, sort, truncate.
pub fn neighbours(
    records: &[SampleRecord],
    params: &MethodParams,
    target: &Target,
) -> Vec<Neighbour> {
    let p = target.position_mm;
    if !params.target_in_range(p) {
        return Vec::new();
    }
    let mut admissible: Vec<Neighbour> = records
        .iter()
        .enumerate()
        .filter(|(_, s)| config_matches(s.config, target.config))
        .map(|(i, s)| Neighbour {
            sample: i as u32,
            degree: approximation_degree(p, s.actual_mm),
        })
        .filter(|n| params.degree_admissible(&n.degree))
        .collect();
    admissible.sort_by(|a, b| {
        a.degree
            .distance_mm
            .total_cmp(&b.degree.distance_mm)
            .then(a.sample.cmp(&b.sample))
    });
    admissible.truncate(params.max_neighbours as usize);
    admissible
}

/// The reference prediction at `target`, or `None` when no sample is admissible (or the
/// target is not finite).
pub fn predict(
    records: &[SampleRecord],
    params: &MethodParams,
    target: &Target,
) -> Option<Prediction> {
    if !target.position_mm.iter().all(|v| v.is_finite()) {
        return None;
    }
    let selected = neighbours(records, params, target);
    method::predict(params, &selected, |i| {
        let s = &records[i as usize];
        SampleError {
            position_mm: s.error_mm,
            orientation_rad: s.rotation_error_rad,
        }
    })
}
