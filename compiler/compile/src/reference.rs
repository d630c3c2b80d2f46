//! The brute-force reference: every sample examined for every target, in the most obvious
//! way, through the same method functions as the runtime. The compiled table must give the
//! same answer for every target inside its grid; the property tests hold it to that.

use adwi_runtime::format::SampleRecord;
use adwi_runtime::method::joints_within;
use adwi_runtime::method::{
    self, approximation_degree, config_matches, MethodParams, Neighbour, Prediction,
};
use adwi_runtime::Target;

use adwi_samples::Joints;

/// The admissible samples for `target`, the `k` nearest, nearest first, ties broken by
/// sample order: filter all samples, sort, truncate.
pub fn neighbours(
    records: &[SampleRecord],
    params: &MethodParams,
    target: &Target,
) -> Vec<Neighbour> {
    neighbours_screened(records, params, target, None)
}

/// The joint-space admissibility screen of a query with known joint angles: sample `i`
/// is admissible only if `joints_within(samples.row(i), target_rad, radius_rad)`.
#[derive(Clone, Copy, Debug)]
pub struct JointScreen<'a> {
    /// Every sample's joint values, rad, in sample order.
    pub samples: &'a Joints,
    /// The target's joint values, rad.
    pub target_rad: &'a [f64],
    /// The radius, rad.
    pub radius_rad: f64,
}

impl JointScreen<'_> {
    /// Whether sample `index` passes the screen.
    pub fn admits(&self, index: usize) -> bool {
        index < self.samples.len()
            && joints_within(self.samples.row(index), self.target_rad, self.radius_rad)
    }
}

/// As [`neighbours`], with the joint-space screen applied when given.
pub fn neighbours_screened(
    records: &[SampleRecord],
    params: &MethodParams,
    target: &Target,
    screen: Option<&JointScreen>,
) -> Vec<Neighbour> {
    neighbours_ranked(records, params, target, screen, |n| {
        n.degree.distance_squared_mm2
    })
}

/// The admissible samples for `target` (with the joint-space screen when given), the `k`
/// first by `rank` (smallest first, ties by sample order): filter all samples, sort,
/// truncate. [`neighbours_screened`] ranks by Cartesian distance, as the method does;
/// other rankings (the nearest in joint space, say) keep its admissibility exactly.
pub fn neighbours_ranked(
    records: &[SampleRecord],
    params: &MethodParams,
    target: &Target,
    screen: Option<&JointScreen>,
    rank: impl Fn(&Neighbour) -> f64,
) -> Vec<Neighbour> {
    let p = target.position_mm;
    if !params.target_in_range(p) {
        return Vec::new();
    }
    let mut admissible: Vec<(f64, Neighbour)> = records
        .iter()
        .enumerate()
        .filter(|(_, s)| config_matches(s.config, target.config))
        .filter(|(i, _)| screen.is_none_or(|screen| screen.admits(*i)))
        .map(|(i, s)| Neighbour {
            sample: i as u32,
            degree: approximation_degree(p, s.actual_mm),
        })
        .filter(|n| params.degree_admissible(&n.degree))
        .map(|n| (rank(&n), n))
        .collect();
    admissible.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.sample.cmp(&b.1.sample)));
    admissible.truncate(params.max_neighbours as usize);
    admissible.into_iter().map(|(_, n)| n).collect()
}

/// The reference prediction at `target`, or `None` when no sample is admissible (or the
/// target is not finite).
pub fn predict(
    records: &[SampleRecord],
    params: &MethodParams,
    target: &Target,
) -> Option<Prediction> {
    predict_screened(records, params, target, None)
}

/// As [`predict`], with the joint-space screen applied when given.
pub fn predict_screened(
    records: &[SampleRecord],
    params: &MethodParams,
    target: &Target,
    screen: Option<&JointScreen>,
) -> Option<Prediction> {
    if !target.position_mm.iter().all(|v| v.is_finite()) {
        return None;
    }
    let selected = neighbours_screened(records, params, target, screen);
    method::predict(params, &selected, |i| records[i as usize].measured_error())
}
