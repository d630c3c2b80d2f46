//! Inverse distance weighting (Zhou, Liao, Tian 2013): the baseline the paper compares
//! itself against.
//!
//! The prediction at a query `x` is the weighted mean of the values of the `k` samples
//! nearest to `x` (optionally only those within a radius), with weights `1 / d_i^p` where
//! `d_i` is the distance from `x` to sample `i`. Unlike the approximation degree, the weights
//! see only distance, not direction.

use super::neighbours::{KdTree, Neighbour};
use super::{validate_query, validate_samples, Baseline, BaselineError, NotCovered, PredictError};

/// Parameters of inverse distance weighting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdwParams {
    /// The distance exponent `p` in the weights `1 / d^p`; larger values favour the
    /// nearest samples more strongly. Must be finite and positive; 2 is the common choice.
    pub power: f64,
    /// How many nearest samples take part (`k`); at least 1. The paper uses 8 neighbours.
    pub neighbours: usize,
    /// Only samples within this distance (mm) take part; `None` for no limit. A query with
    /// no sample inside the radius is reported as not covered instead of reaching for far
    /// samples.
    pub radius_mm: Option<f64>,
}

impl Default for IdwParams {
    /// `p = 2`, the 8 nearest samples, no radius limit.
    fn default() -> Self {
        Self {
            power: 2.0,
            neighbours: 8,
            radius_mm: None,
        }
    }
}

impl IdwParams {
    fn validate(&self) -> Result<(), BaselineError> {
        if !(self.power.is_finite() && self.power > 0.0) {
            return Err(BaselineError::InvalidParameter {
                name: "power",
                reason: format!("must be finite and positive, got {}", self.power),
            });
        }
        if self.neighbours == 0 {
            return Err(BaselineError::InvalidParameter {
                name: "neighbours",
                reason: "must be at least 1".into(),
            });
        }
        if let Some(r) = self.radius_mm {
            if !(r.is_finite() && r > 0.0) {
                return Err(BaselineError::InvalidParameter {
                    name: "radius_mm",
                    reason: format!("must be finite and positive, got {r}"),
                });
            }
        }
        Ok(())
    }
}

/// An inverse-distance-weighting interpolator over a set of samples.
///
/// Exact at sample points: a query at a sample's position returns that sample's value (the
/// mean value if several samples share the position), rather than dividing by zero.
#[derive(Debug, Clone)]
pub struct Idw {
    /// The samples' positions, for their nearest neighbours.
    tree: KdTree,
    values: Vec<[f64; 3]>,
    params: IdwParams,
}

impl Idw {
    /// Builds the interpolator from sample nominal positions (mm, base frame) and their
    /// values (any unit; position errors in mm or orientation errors in rad).
    ///
    /// # Errors
    ///
    /// [`BaselineError`] for empty, mismatched or non-finite samples, or invalid parameters.
    pub fn new(
        positions_mm: &[[f64; 3]],
        values: &[[f64; 3]],
        params: IdwParams,
    ) -> Result<Self, BaselineError> {
        validate_samples(positions_mm, values)?;
        params.validate()?;
        Ok(Self {
            tree: KdTree::new(positions_mm),
            values: values.to_vec(),
            params,
        })
    }

    /// The parameters this interpolator was built with.
    pub fn params(&self) -> &IdwParams {
        &self.params
    }

    /// The weighted mean of the nearest samples' values at `query_position_mm`.
    ///
    /// # Errors
    ///
    /// [`PredictError::NonFiniteQuery`], or [`NotCovered::NoSampleWithinRadius`] when a
    /// radius is set and no sample lies within it.
    pub fn predict(&self, query_position_mm: [f64; 3]) -> Result<[f64; 3], PredictError> {
        validate_query(query_position_mm)?;
        let radius_squared = self.params.radius_mm.map(|r| r * r);
        // One buffer per thread: held-out points are predicted side by side, none allocates.
        thread_local! {
            static NEIGHBOURS: std::cell::RefCell<Vec<Neighbour>> =
                const { std::cell::RefCell::new(Vec::new()) };
        }
        NEIGHBOURS.with_borrow_mut(|neighbours| {
            self.tree.k_nearest_into(
                query_position_mm,
                self.params.neighbours,
                radius_squared,
                neighbours,
            );
            self.weighted_mean(neighbours)
        })
    }

    /// The inverse-distance-weighted mean of `neighbours` (nearest first).
    fn weighted_mean(&self, neighbours: &[Neighbour]) -> Result<[f64; 3], PredictError> {
        let Some(nearest) = neighbours.first() else {
            return Err(PredictError::NotCovered(NotCovered::NoSampleWithinRadius {
                radius_mm: self.params.radius_mm.unwrap_or(f64::INFINITY),
            }));
        };

        let mut sum = [0.0; 3];
        let mut weight_sum = 0.0;
        if nearest.distance_squared_mm2 == 0.0 {
            // The query is a sample: its value is the answer. Coincident samples share the
            // weight equally. Only coincident ones can be at distance 0, and they come first.
            for n in neighbours
                .iter()
                .take_while(|n| n.distance_squared_mm2 == 0.0)
            {
                add_scaled(&mut sum, &self.values[n.index], 1.0);
                weight_sum += 1.0;
            }
        } else {
            // Weights (d_min / d_i)^p are proportional to 1 / d_i^p but lie in (0, 1], so
            // they neither overflow for tiny distances nor underflow for large ones.
            let half_power = 0.5 * self.params.power;
            for n in neighbours {
                let w = (nearest.distance_squared_mm2 / n.distance_squared_mm2).powf(half_power);
                add_scaled(&mut sum, &self.values[n.index], w);
                weight_sum += w;
            }
        }
        Ok(sum.map(|s| s / weight_sum))
    }
}

impl Baseline for Idw {
    fn name(&self) -> &'static str {
        "idw"
    }

    fn predict(&self, query_position_mm: [f64; 3]) -> Result<[f64; 3], PredictError> {
        Idw::predict(self, query_position_mm)
    }
}

/// `sum += weight · value`, componentwise.
fn add_scaled(sum: &mut [f64; 3], value: &[f64; 3], weight: f64) {
    for (s, v) in sum.iter_mut().zip(value) {
        *s += weight * v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_samples(n: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let positions = (0..n)
            .map(|_| [(); 3].map(|_| rng.gen_range(0.0..1000.0)))
            .collect();
        let values = (0..n)
            .map(|_| [(); 3].map(|_| rng.gen_range(-2.0..2.0)))
            .collect();
        (positions, values)
    }

    #[test]
    fn reproduces_every_sample_at_its_position() {
        let (positions, values) = random_samples(300, 1);
        for power in [1.0, 2.0, 3.5] {
            let idw = Idw::new(
                &positions,
                &values,
                IdwParams {
                    power,
                    ..IdwParams::default()
                },
            )
            .unwrap();
            for (p, v) in positions.iter().zip(&values) {
                let got = idw.predict(*p).unwrap();
                for axis in 0..3 {
                    assert!((got[axis] - v[axis]).abs() <= 1e-9, "{got:?} vs {v:?}");
                }
            }
        }
    }

    #[test]
    fn midpoint_of_two_samples_is_their_mean() {
        let positions = [[100.0, 200.0, 300.0], [140.0, 170.0, 300.0]];
        let values = [[1.0, -2.0, 0.5], [3.0, 4.0, -0.5]];
        let idw = Idw::new(&positions, &values, IdwParams::default()).unwrap();
        let got = idw.predict([120.0, 185.0, 300.0]).unwrap();
        let want = [2.0, 1.0, 0.0];
        for axis in 0..3 {
            assert!((got[axis] - want[axis]).abs() <= 1e-12, "{got:?}");
        }
    }

    #[test]
    fn weights_follow_inverse_distance_power() {
        // Query at distance 1 from sample A and 3 from sample B, p = 2: weights 1 and 1/9.
        let positions = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0]];
        let values = [[10.0, 0.0, 0.0], [0.0, 10.0, 0.0]];
        let idw = Idw::new(&positions, &values, IdwParams::default()).unwrap();
        let got = idw.predict([1.0, 0.0, 0.0]).unwrap();
        let (wa, wb) = (1.0, 1.0 / 9.0);
        let want = [10.0 * wa / (wa + wb), 10.0 * wb / (wa + wb), 0.0];
        for axis in 0..3 {
            assert!((got[axis] - want[axis]).abs() <= 1e-12, "{got:?}");
        }
    }

    #[test]
    fn uses_only_the_k_nearest_and_respects_the_radius() {
        let positions = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [100.0, 0.0, 0.0]];
        let values = [[1.0; 3], [3.0; 3], [1000.0; 3]];
        let params = IdwParams {
            power: 1.0,
            neighbours: 2,
            radius_mm: Some(50.0),
        };
        let idw = Idw::new(&positions, &values, params).unwrap();
        // Midway between the first two; the far sample is excluded by k = 2.
        assert_eq!(idw.predict([5.0, 0.0, 0.0]).unwrap(), [2.0; 3]);
        // Near the far sample only: it is the single neighbour within 50 mm.
        assert_eq!(idw.predict([90.0, 0.0, 0.0]).unwrap(), [1000.0; 3]);
        assert_eq!(
            idw.predict([0.0, 500.0, 0.0]),
            Err(PredictError::NotCovered(NotCovered::NoSampleWithinRadius {
                radius_mm: 50.0
            }))
        );
    }

    #[test]
    fn coincident_samples_average_at_their_position() {
        let positions = [[1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [5.0, 5.0, 5.0]];
        let values = [[1.0; 3], [2.0; 3], [9.0; 3]];
        let idw = Idw::new(&positions, &values, IdwParams::default()).unwrap();
        assert_eq!(idw.predict([1.0, 2.0, 3.0]).unwrap(), [1.5; 3]);
    }

    #[test]
    fn rejects_invalid_parameters() {
        let bad = [
            IdwParams {
                power: 0.0,
                ..IdwParams::default()
            },
            IdwParams {
                neighbours: 0,
                ..IdwParams::default()
            },
            IdwParams {
                radius_mm: Some(-1.0),
                ..IdwParams::default()
            },
        ];
        for params in bad {
            assert!(matches!(
                Idw::new(&[[0.0; 3]], &[[0.0; 3]], params),
                Err(BaselineError::InvalidParameter { .. })
            ));
        }
    }
}
