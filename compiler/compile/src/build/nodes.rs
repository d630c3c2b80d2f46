//! The served field's nodes: the value every node of the grid holds, once per set of
//! samples a target configuration sees — the exact method's answer there, or a kriging of
//! the samples' errors (the build's module docs) — and how many cells they serve.

use adwi_runtime::format::{v2, Grid, SampleRecord};
use adwi_runtime::method::{self, MethodParams, CONFIG_UNKNOWN};
use adwi_runtime::model::PreparedModel;
use rayon::prelude::*;

use super::{BuildError, ServedField};
use crate::local_kriging::{KrigingField, LocalSettings};
use crate::nugget_kriging::GivenChoices;
use adwi_samples::SampleSet;

/// What the nodes hold: the method's answer, or the kriging of the samples' errors, fitted
/// with a part that turns with the tool's axis when given one unit axis per sample.
pub(super) enum NodeField {
    Method,
    /// The samples' tool axes (a hybrid table), and the hyperparameters when given.
    Kriging(Option<Vec<[f64; 3]>>, Option<Box<GivenChoices>>),
}

impl NodeField {
    /// The field `served` asks for. A kriging field is fitted with the tool's axes whenever
    /// there are some (`model` and the samples' joint values: a hybrid table), so that the
    /// likelihood decides whether it turns; `kriging-tool-axis` is an older name of
    /// `kriging`.
    pub(super) fn new(
        served: ServedField,
        given: Option<GivenChoices>,
        samples: &SampleSet,
        model: Option<&PreparedModel>,
    ) -> Result<NodeField, BuildError> {
        Ok(match served {
            ServedField::Method => NodeField::Method,
            ServedField::Kriging | ServedField::KrigingToolAxis => match (model, &samples.joints) {
                (Some(model), Some(_)) => {
                    NodeField::Kriging(Some(tool_axes(samples, model)?), given.map(Box::new))
                }
                _ => NodeField::Kriging(None, given.map(Box::new)),
            },
        })
    }
}

/// The hyperparameters a kriging served field of `samples` would choose by likelihood
/// (turning with the tool when `model` gives the samples' axes), searched as a build
/// searches them and nothing predicted: what a served-field choice reuses in its folds.
/// `samples` are those the nodes are fitted to (a hybrid table's residuals).
pub(super) fn kriging_choices(
    samples: &SampleSet,
    model: Option<&PreparedModel>,
) -> Result<Option<GivenChoices>, BuildError> {
    let axes = match (model, &samples.joints) {
        (Some(model), Some(_)) => Some(tool_axes(samples, model)?),
        _ => None,
    };
    let records = samples.records();
    let all: Vec<usize> = (0..records.len()).collect();
    let orientation = samples.rotation_error_rad.is_some();
    let (inputs, values) = kriging_rows(&records, &all, orientation);
    let choices = crate::local_kriging::search_choices(
        &inputs,
        axes.as_deref(),
        &values,
        LocalSettings::default(),
    )
    .map_err(BuildError::Kriging)?;
    Ok(GivenChoices::new(&choices))
}

/// The kriging's inputs (the samples' actual positions, where the method places them) and
/// values (position errors, and orientation errors when stored) of `samples` of `records`.
fn kriging_rows(
    records: &[SampleRecord],
    samples: &[usize],
    orientation: bool,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let inputs: Vec<Vec<f64>> = samples
        .iter()
        .map(|&i| records[i].actual_mm.to_vec())
        .collect();
    let values: Vec<Vec<f64>> = samples
        .iter()
        .map(|&i| {
            let r = &records[i];
            let mut row = r.error_mm.to_vec();
            if orientation {
                row.extend_from_slice(&r.rotation_error_rad);
            }
            row
        })
        .collect();
    (inputs, values)
}

/// The unit approach (z) axis of the nominal TCP at each sample's joint values: what a
/// served field turning with the tool combines its terms with (the runtime computes the
/// same at the query's joint values).
fn tool_axes(samples: &SampleSet, model: &PreparedModel) -> Result<Vec<[f64; 3]>, BuildError> {
    let Some(joints) = &samples.joints else {
        return Err(BuildError::MissingJoints);
    };
    joints
        .rows()
        .map(|q| model.approach_axis(q).ok_or(BuildError::ToolAxis))
        .collect()
}

/// The served tier's node values: the exact method at every node of the grid, per set;
/// `stride` vectors per node (the layout of [`v2::TableData::node_errors_mm`]).
pub(super) struct NodeValues {
    /// What the nodes hold: the method's answer, a kriging of position, or one that turns
    /// with the tool (stride 4) when the likelihood gave some component a turning part.
    pub(super) served_field: ServedField,
    pub(super) sets: Vec<v2::NodeSet>,
    /// The first kriging fit's hyperparameters (empty for the method's values).
    pub(super) kriging_choices: Vec<crate::nugget_kriging::GpChoice>,
    stride: usize,
    pub(super) position_mm: Vec<[f64; 3]>,
    pub(super) orientation_rad: Vec<[f64; 3]>,
}

/// One node's vectors: position and orientation, `[f, h_x, h_y, h_z]` (only `f` used at
/// stride 1).
type NodeTerms = ([[f64; 3]; 4], [[f64; 3]; 4]);

impl NodeValues {
    /// Evaluates every node for targets of unknown configuration, then for each
    /// configuration the samples carry (a set equal to an earlier one shares its nodes):
    /// the method's answer where it has one, or the kriging `field` asks for at every
    /// corner of a cell where the exact tier can answer. With `computed` (a flag per node
    /// of a set, [`serving_nodes`]), the nodes it leaves out are missing; the others hold
    /// what they hold in the full set, to the bit.
    pub(super) fn compute(
        records: &[SampleRecord],
        params: &MethodParams,
        grid: &Grid,
        lists: &[Vec<u32>],
        samples: &SampleSet,
        field: &NodeField,
        computed: Option<&[bool]>,
    ) -> Result<NodeValues, BuildError> {
        let mut configs: Vec<u8> = samples.config.clone().unwrap_or_default();
        configs.sort_unstable();
        configs.dedup();
        let [nx, ny, nz] = grid.dims.map(|d| d as usize + 1);
        let per_set = nx * ny * nz;
        // Kriging nodes are computed with their four terms, and reduced to `f` at the end
        // when no fit turns.
        let stride = match field {
            NodeField::Method => 1,
            NodeField::Kriging(..) => 4,
        };
        let mut out = NodeValues {
            served_field: match field {
                NodeField::Method => ServedField::Method,
                NodeField::Kriging(..) => ServedField::KrigingToolAxis,
            },
            sets: Vec::new(),
            kriging_choices: Vec::new(),
            stride,
            position_mm: Vec::new(),
            orientation_rad: Vec::new(),
        };
        let missing = [[v2::NO_NODE_VALUE; 3]; 4];
        let computed = |node: usize| computed.is_none_or(|c| c[node]);
        // Kriging fits, by the samples they were fitted to (one per distinct subset).
        let mut fits: Vec<(Vec<usize>, NodeKriging)> = Vec::new();
        let wanted = std::iter::once(None).chain(configs.into_iter().map(Some));
        for config in wanted {
            let node_position = |node: usize| {
                let ijk = [node % nx, node / nx % ny, node / (nx * ny)];
                (ijk, grid_node_mm(grid, ijk))
            };
            // Written flat, `stride` vectors a node: the method's one, straight from its
            // nodes (a node's four vectors and their copy were 8 times the memory, touched
            // fresh for every table an evaluation builds).
            let (position, orientation): (Vec<[f64; 3]>, Vec<[f64; 3]>) = match field {
                NodeField::Method => (0..per_set)
                    .into_par_iter()
                    .map(|node| {
                        if !computed(node) {
                            return (missing[0], missing[0]);
                        }
                        let (p, r) =
                            node_value(records, params, grid, lists, node_position(node).0, config);
                        if adwi_runtime::served::is_missing(&p) {
                            (missing[0], missing[0])
                        } else {
                            (p, r)
                        }
                    })
                    .unzip(),
                NodeField::Kriging(axes, given) => {
                    // The samples a target of this configuration may use (method::select).
                    let seen: Vec<usize> = (0..records.len())
                        .filter(|&i| method::config_matches(records[i].config, config))
                        .collect();
                    let fitted = match fits.iter().position(|(s, _)| *s == seen) {
                        Some(i) => i,
                        None => {
                            let orientation = samples.rotation_error_rad.is_some();
                            let fit = NodeKriging::fit(
                                records,
                                &seen,
                                axes.as_deref(),
                                given.as_deref().copied(),
                                orientation,
                            )?;
                            fits.push((seen.clone(), fit));
                            fits.len() - 1
                        }
                    };
                    let kriging = &fits[fitted].1;
                    if out.kriging_choices.is_empty() {
                        out.kriging_choices = kriging.field.choices();
                    }
                    let usable =
                        |s: &u32| method::config_matches(records[*s as usize].config, config);
                    let reached = |node: usize| {
                        node_cells(grid, node).any(|cell| lists[cell].iter().any(usable))
                    };
                    let terms = kriging
                        .field
                        .lattice_terms(
                            [nx, ny, nz],
                            grid.cell_mm,
                            &|ijk| grid_node_mm(grid, ijk),
                            &reached,
                            &computed,
                            &|terms| kriging.node_terms(terms),
                        )
                        .map_err(BuildError::Kriging)?;
                    let none: NodeTerms = (missing, missing);
                    let flat = |which: fn(&NodeTerms) -> &[[f64; 3]; 4]| -> Vec<[f64; 3]> {
                        terms
                            .iter()
                            .flat_map(|t| which(t.as_ref().unwrap_or(&none))[..stride].iter())
                            .copied()
                            .collect()
                    };
                    (flat(|t| &t.0), flat(|t| &t.1))
                }
            };
            let first_node = (0..out.sets.len())
                .map(|s| out.sets[s].first_node as usize)
                .find(|&first| {
                    let at = first * stride;
                    position
                        .iter()
                        .zip(&out.position_mm[at..])
                        .all(|(a, b)| same_bits(a, b))
                        && orientation
                            .iter()
                            .zip(&out.orientation_rad[at..])
                            .all(|(a, b)| same_bits(a, b))
                })
                .unwrap_or_else(|| {
                    let first = out.position_mm.len() / stride;
                    out.position_mm.extend(position);
                    out.orientation_rad.extend(orientation);
                    first
                });
            out.sets.push(v2::NodeSet {
                config: config.unwrap_or(CONFIG_UNKNOWN),
                first_node: first_node as u32,
            });
        }
        if matches!(field, NodeField::Kriging(..)) && !fits.iter().any(|(_, f)| f.field.turns()) {
            // No part turns with the tool (no axes, or the likelihood gave it no weight):
            // every `h` is 0, and a node is its `f`.
            out.served_field = ServedField::Kriging;
            out.stride = 1;
            out.position_mm = out.position_mm.iter().step_by(4).copied().collect();
            out.orientation_rad = out.orientation_rad.iter().step_by(4).copied().collect();
        }
        Ok(out)
    }

    /// The number of cells of the first set whose 8 nodes all have values.
    pub(super) fn served_cells(&self, grid: &Grid) -> usize {
        let [nx, ny, _] = grid.dims.map(|d| d as usize + 1);
        let has = |i: usize| !adwi_runtime::served::is_missing(&self.position_mm[i * self.stride]);
        (0..grid.cell_count().unwrap_or(0))
            .filter(|&cell| {
                let [i, j, k] = grid.cell_coords(cell);
                let base = i + nx * (j + ny * k);
                [
                    0,
                    1,
                    nx,
                    nx + 1,
                    nx * ny,
                    nx * ny + 1,
                    nx * ny + nx,
                    nx * ny + nx + 1,
                ]
                .iter()
                .all(|&c| has(base + c))
            })
            .count()
    }
}

/// Kriging with a nugget of some samples' errors, in Cartesian distance of their actual
/// positions (where the method places them): position, and orientation when stored;
/// turning with the tool's axis when given the samples' axes. Dense or local
/// ([`crate::local_kriging`]) as the sample count says.
struct NodeKriging {
    field: KrigingField,
    orientation: bool,
}

impl NodeKriging {
    fn fit(
        records: &[SampleRecord],
        samples: &[usize],
        axes: Option<&[[f64; 3]]>,
        given: Option<GivenChoices>,
        orientation: bool,
    ) -> Result<NodeKriging, BuildError> {
        let (inputs, values) = kriging_rows(records, samples, orientation);
        let axes: Option<Vec<[f64; 3]>> = axes.map(|a| samples.iter().map(|&i| a[i]).collect());
        let settings = LocalSettings::default();
        let field = match given {
            Some(given) => KrigingField::with_choices(
                &inputs,
                axes.as_deref(),
                &values,
                given.as_slice(),
                settings,
            ),
            None => KrigingField::fit(&inputs, axes.as_deref(), &values, settings),
        }
        .map_err(BuildError::Kriging)?;
        Ok(NodeKriging { field, orientation })
    }

    /// A node's vectors from the field's terms there, `[f, h_x, h_y, h_z]` per component
    /// (`f` alone when it does not turn); orientation zero when not stored (as the
    /// method's).
    fn node_terms(&self, t: &[[f64; 4]]) -> NodeTerms {
        let vectors = |c: usize| [0, 1, 2, 3].map(|k| [t[c][k], t[c + 1][k], t[c + 2][k]]);
        let rotation = if self.orientation {
            vectors(3)
        } else {
            [[0.0; 3]; 4]
        };
        (vectors(0), rotation)
    }
}

/// Per node of a set (x fastest over `dims + 1` per axis), whether it is a corner of the
/// cell the runtime blends for a target at one of `positions`, mm: the cell of the grid
/// box's point nearest the target (`adwi_runtime::served`; the target's own cell inside
/// the box), found by the same arithmetic. Non-finite positions need none.
pub(super) fn serving_nodes(grid: &Grid, positions: &[[f64; 3]]) -> Vec<bool> {
    let [nx, ny, nz] = grid.dims.map(|d| d as usize + 1);
    let mut out = vec![false; nx * ny * nz];
    for p in positions.iter().filter(|p| p.iter().all(|v| v.is_finite())) {
        let mut cell = [0usize; 3];
        for axis in 0..3 {
            let u = (p[axis] - grid.origin_mm[axis]) / grid.cell_mm;
            let cells = grid.dims[axis] as usize;
            cell[axis] = (u.clamp(0.0, cells as f64) as usize).min(cells.saturating_sub(1));
        }
        for corner in 0..8 {
            let [i, j, k] = [0, 1, 2].map(|a| cell[a] + (corner >> a & 1));
            out[i + nx * (j + ny * k)] = true;
        }
    }
    out
}

/// The cells (linear indices) node `node` of a set (x fastest over `dims + 1` per axis) is
/// a corner of ([`adjacent_cells`]).
pub(super) fn node_cells(grid: &Grid, node: usize) -> impl Iterator<Item = usize> + '_ {
    let [nx, ny, _] = grid.dims.map(|d| d as usize + 1);
    adjacent_cells(grid, [node % nx, node / nx % ny, node / (nx * ny)])
}

/// The cells (linear indices) node `ijk` is a corner of: up to 8, fewer on the grid's faces.
fn adjacent_cells(grid: &Grid, ijk: [usize; 3]) -> impl Iterator<Item = usize> + '_ {
    let range = move |a: usize| ijk[a].saturating_sub(1)..=ijk[a].min(grid.dims[a] as usize - 1);
    range(2).flat_map(move |k| {
        range(1).flat_map(move |j| range(0).map(move |i| grid.linear_index([i, j, k])))
    })
}

/// The position of node `ijk`, mm.
fn grid_node_mm(grid: &Grid, [i, j, k]: [usize; 3]) -> [f64; 3] {
    [
        grid.origin_mm[0] + i as f64 * grid.cell_mm,
        grid.origin_mm[1] + j as f64 * grid.cell_mm,
        grid.origin_mm[2] + k as f64 * grid.cell_mm,
    ]
}

fn same_bits(a: &[f64; 3], b: &[f64; 3]) -> bool {
    (0..3).all(|i| a[i].to_bits() == b[i].to_bits())
}

/// The exact method at node `ijk` for a target of `config`: through the candidate list of
/// a cell the node is a corner of (a list serves every point of its closed cell), so that
/// the value is the brute-force reference's. Missing ([`v2::NO_NODE_VALUE`]) where no
/// sample is admissible.
fn node_value(
    records: &[SampleRecord],
    params: &MethodParams,
    grid: &Grid,
    lists: &[Vec<u32>],
    [i, j, k]: [usize; 3],
    config: Option<u8>,
) -> ([f64; 3], [f64; 3]) {
    let position = grid_node_mm(grid, [i, j, k]);
    let last = grid.dims.map(|d| d as usize - 1);
    let cell = grid.linear_index([i.min(last[0]), j.min(last[1]), k.min(last[2])]);
    let selection = method::select(params, position, config, lists[cell].iter().copied(), |s| {
        let r = &records[s as usize];
        Some((r.actual_mm, r.config))
    });
    let sample = |s: u32| {
        let r = &records[s as usize];
        (
            r.actual_mm,
            method::norm_mm(r.actual_mm),
            r.measured_error(),
        )
    };
    match method::estimate(params, position, &selection, true, sample) {
        Some(e) => (e.position_error_mm, e.orientation_error_rad),
        None => ([v2::NO_NODE_VALUE; 3], [v2::NO_NODE_VALUE; 3]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::fixtures::{build, noisy_lattice, samples};
    use crate::build::BuildOptions;

    #[test]
    fn a_kriging_served_field_holds_the_kriging_wherever_the_exact_tier_can_answer() {
        use adwi_runtime::Status;
        let s = noisy_lattice();
        let options = |served_field| BuildOptions {
            served_field,
            ..BuildOptions::default()
        };
        let method =
            adwi_runtime::Table::from_vec(build(&s, options(ServedField::Method)).unwrap())
                .unwrap();
        let kriging = build(&s, options(ServedField::Kriging)).unwrap();
        assert_eq!(kriging, build(&s, options(ServedField::Kriging)).unwrap());
        let kriging = adwi_runtime::Table::from_vec(kriging).unwrap();
        assert_eq!(kriging.header().served_field, ServedField::Kriging);
        assert_eq!(method.header().served_field, ServedField::Method);
        // The reference: the same fit, evaluated directly.
        let records = s.records();
        let inputs: Vec<Vec<f64>> = records.iter().map(|r| r.actual_mm.to_vec()).collect();
        let values: Vec<Vec<f64>> = records.iter().map(|r| r.error_mm.to_vec()).collect();
        let gp = crate::nugget_kriging::ResidualGp::fit_cartesian(&inputs, &values).unwrap();
        let grid = kriging.header().grid;
        let (mut nodes, mut compared, mut smoother) = (0, 0, 0);
        for i in 0..=grid.dims[0] {
            for j in 0..=grid.dims[1] {
                for k in 0..=grid.dims[2] {
                    let at = grid_node_mm(&grid, [i as usize, j as usize, k as usize]);
                    let (m, g) = (method.query(at), kriging.query(at));
                    // The exact tier is the method's in both.
                    assert_eq!(
                        method.exact().query(at).position_error_mm,
                        kriging.exact().query(at).position_error_mm
                    );
                    if m.status == Status::Ok {
                        assert_eq!(g.status, Status::Ok, "the kriging covers less at {at:?}");
                    }
                    if g.status != Status::Ok {
                        continue;
                    }
                    nodes += 1;
                    let want = gp.predict(&at).unwrap();
                    for (got, want) in g.position_error_mm.iter().zip(&want) {
                        assert!((got - want).abs() < 1e-9, "{at:?}");
                    }
                    if m.status != Status::Ok {
                        continue;
                    }
                    // Against the noise-free field, the kriging is the closer one mostly.
                    compared += 1;
                    let truth = [0, 1, 2].map(|a| ((at[a] - 1200.0) / 300.0).sin() * 0.3);
                    let off = |v: [f64; 3]| (0..3).map(|a| (v[a] - truth[a]).abs()).sum::<f64>();
                    if off(g.position_error_mm) < off(m.position_error_mm) {
                        smoother += 1;
                    }
                }
            }
        }
        assert!(compared > 100, "{compared} nodes served by both");
        assert!(nodes > compared, "the kriging serves no fringe node");
        assert!(
            2 * smoother > compared,
            "kriging closer at {smoother} of {compared} nodes"
        );
        // Coverage, against a brute-force reference: a cell is served exactly when each of
        // its 8 corners is a corner of some cell with a sample within ε of its box, and
        // wherever the exact tier answers, the served field does.
        let radius_mm = kriging.method().radius_mm;
        let reached = |cell: [usize; 3]| {
            let (lo, hi) = grid.cell_box(cell);
            records.iter().any(|r| {
                let gap: f64 = (0..3)
                    .map(|a| {
                        (lo[a] - r.actual_mm[a])
                            .max(r.actual_mm[a] - hi[a])
                            .max(0.0)
                    })
                    .map(|d| d * d)
                    .sum();
                gap.sqrt() <= radius_mm
            })
        };
        let dims = grid.dims.map(|d| d as usize);
        let node_reached = |n: [usize; 3]| {
            let around = |a: usize| n[a].saturating_sub(1)..=n[a].min(dims[a] - 1);
            around(0).any(|i| around(1).any(|j| around(2).any(|k| reached([i, j, k]))))
        };
        let mut served = 0;
        for cell in 0..grid.cell_count().unwrap() {
            let c = grid.cell_coords(cell);
            let (lo, _) = grid.cell_box(c);
            let corners_reached =
                (0..8).all(|corner| node_reached([0, 1, 2].map(|a| c[a] + (corner >> a & 1))));
            // Points inside the cell, its centre among them.
            for t in [[0.5; 3], [0.1, 0.9, 0.3], [0.95, 0.05, 0.7]] {
                let at = [0, 1, 2].map(|a| lo[a] + t[a] * grid.cell_mm);
                let answer = kriging.query(at);
                assert_eq!(answer.status == Status::Ok, corners_reached, "at {at:?}");
                if kriging.exact().query(at).status == Status::Ok {
                    assert_eq!(
                        answer.status,
                        Status::Ok,
                        "the exact tier answers at {at:?}"
                    );
                }
            }
            served += usize::from(corners_reached);
        }
        assert!(
            served < grid.cell_count().unwrap(),
            "no cell is left unserved"
        );
    }

    /// Whether two answers are the same to the bit.
    fn same_answer(a: &adwi_runtime::Correction, b: &adwi_runtime::Correction) -> bool {
        a.status == b.status
            && same_bits(&a.position_error_mm, &b.position_error_mm)
            && same_bits(&a.orientation_error_rad, &b.orientation_error_rad)
            && a.residual == b.residual
    }

    #[test]
    fn a_table_serving_some_positions_answers_there_as_the_full_table() {
        use crate::build::{compile_serving, Queried};
        use adwi_runtime::{Status, Table};
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let s = noisy_lattice();
        // Inside the grid, on a node, outside it, and not finite.
        let mut positions: Vec<[f64; 3]> = (0..40)
            .map(|_| [0, 1, 2].map(|_| rng.gen_range(700.0..1700.0)))
            .collect();
        positions.extend([[1200.0, 1300.0, 1000.0], [f64::NAN, 0.0, 0.0]]);
        for served_field in [ServedField::Method, ServedField::Kriging] {
            let options = BuildOptions {
                served_field,
                ..BuildOptions::default()
            };
            let table = |nodes| {
                Table::from_vec(compile_serving(&s, &options, nodes, &|_| {}).unwrap().0).unwrap()
            };
            let (full, some) = (
                table(Queried::Anywhere),
                table(Queried::At {
                    served: &positions,
                    exact: &[],
                }),
            );
            let mut answered = 0;
            for p in &positions {
                let (a, b) = (full.query(*p), some.query(*p));
                assert!(
                    same_answer(&a, &b),
                    "{served_field:?} at {p:?}: {a:?} vs {b:?}"
                );
                answered += usize::from(a.status == Status::Ok);
            }
            assert!(answered > 10, "{answered} answered");
            // Queried by the exact tier there alone: no node, the lists of those cells.
            let exact = table(Queried::At {
                served: &[],
                exact: &positions,
            });
            for p in &positions {
                let target = adwi_runtime::Target::at(*p);
                let (a, b) = (
                    full.exact().query_target(&target),
                    exact.exact().query_target(&target),
                );
                assert!(same_answer(&a, &b), "exact at {p:?}: {a:?} vs {b:?}");
            }
            let unlisted = (0..200)
                .map(|_| adwi_runtime::Target::at([0, 1, 2].map(|_| rng.gen_range(1000.0..1400.0))))
                .filter(|t| {
                    exact.exact().query_target(t).status != full.exact().query_target(t).status
                })
                .count();
            assert!(
                unlisted > 0,
                "{served_field:?}: the exact-only table lists every cell"
            );
            // Elsewhere, the partial table serves less.
            let unserved = (0..200)
                .map(|_| [0, 1, 2].map(|_| rng.gen_range(1000.0..1400.0)))
                .filter(|p| some.query(*p).status != full.query(*p).status)
                .count();
            assert!(
                unserved > 0,
                "{served_field:?}: the partial table serves everywhere"
            );
        }
    }

    #[test]
    fn a_hybrid_table_serving_some_targets_answers_them_as_the_full_table() {
        // Targets beyond the grid box too, where the residual fades out from the nearest
        // cell of the grid.
        use crate::build::{plan, Queried};
        use adwi_runtime::chain::Chain;
        use adwi_runtime::kinematics::{MdhJoint, Transform};
        use adwi_runtime::{Table, Target};
        use rand::{Rng, SeedableRng};
        use std::f64::consts::FRAC_PI_2;
        let joint = |a_mm, d_mm, alpha_rad| MdhJoint {
            a_mm,
            d_mm,
            alpha_rad,
            ..MdhJoint::default()
        };
        let joints = [
            joint(0.0, 400.0, 0.0),
            joint(50.0, 0.0, -FRAC_PI_2),
            joint(500.0, 0.0, 0.0),
            joint(50.0, 450.0, -FRAC_PI_2),
            joint(0.0, 0.0, FRAC_PI_2),
            joint(0.0, 100.0, -FRAC_PI_2),
        ];
        let nominal =
            Chain::from_mdh(Transform::IDENTITY, &joints, Transform::IDENTITY, None).unwrap();
        let shifted = Transform {
            translation_mm: [0.3, -0.2, 0.1],
            ..Transform::IDENTITY
        };
        let calibrated = Chain::from_mdh(shifted, &joints, Transform::IDENTITY, None).unwrap();
        let model = PreparedModel::new(nominal, calibrated).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let mut pose = || -> (Vec<f64>, [f64; 3]) {
            let q: Vec<f64> = (0..6).map(|_| rng.gen_range(-0.6..0.6)).collect();
            let at = model.at(&q).unwrap().nominal_tcp_mm;
            (q, at)
        };
        let mut csv = String::from("x,y,z,dx,dy,dz,j1,j2,j3,j4,j5,j6\n");
        for _ in 0..150 {
            let (q, p) = pose();
            let e = [0, 1, 2].map(|a| 0.3 + 0.2 * (p[a] / 200.0).sin() + 0.01 * q[a]);
            // The samples' joint columns are in degrees.
            let q: Vec<String> = q.iter().map(|v| v.to_degrees().to_string()).collect();
            csv += &format!(
                "{},{},{},{},{},{},{}\n",
                p[0],
                p[1],
                p[2],
                e[0],
                e[1],
                e[2],
                q.join(",")
            );
        }
        let s = adwi_samples::parse_samples(
            "s.csv".as_ref(),
            csv.as_bytes(),
            &adwi_samples::ColumnMap::default(),
        )
        .unwrap();
        let targets: Vec<(Vec<f64>, [f64; 3])> = (0..60).map(|_| pose()).collect();
        let positions: Vec<[f64; 3]> = targets.iter().map(|t| t.1).collect();
        // The grid box a fifth narrower than the samples' on every side.
        let (lo, hi) = s.nominal_bounds_mm().unwrap();
        let inset = [0, 1, 2].map(|a| 0.2 * (hi[a] - lo[a]));
        let bounds = (
            [0, 1, 2].map(|a| lo[a] + inset[a]),
            [0, 1, 2].map(|a| hi[a] - inset[a]),
        );
        for served_field in [ServedField::Method, ServedField::Kriging] {
            let options = BuildOptions {
                served_field,
                bounds_mm: Some(bounds),
                ..BuildOptions::default()
            };
            let plan = plan(&s, &options).unwrap();
            let table = |nodes| {
                let built = crate::hybrid::compile_serving(&s, &model, &plan, nodes, &|_| {});
                Table::from_vec(built.unwrap().bytes).unwrap()
            };
            let (full, some) = (
                table(Queried::Anywhere),
                table(Queried::At {
                    served: &positions,
                    exact: &[],
                }),
            );
            let mut faded = 0;
            for (q, p) in &targets {
                let target = Target::at(*p);
                let (a, b) = (
                    full.query_with_joints(&target, q),
                    some.query_with_joints(&target, q),
                );
                assert!(
                    same_answer(&a, &b),
                    "{served_field:?} at {p:?}: {a:?} vs {b:?}"
                );
                faded += usize::from(a.residual == adwi_runtime::Residual::Faded);
            }
            assert!(faded > 0, "{served_field:?}: no target beyond the grid box");
            // Queried by the exact tier there alone: no node, the lists of those cells.
            let exact = table(Queried::At {
                served: &[],
                exact: &positions,
            });
            let mut listed = 0;
            for (q, p) in &targets {
                let target = Target::at(*p);
                let (a, b) = (
                    full.exact().query_with_joints(&target, q),
                    exact.exact().query_with_joints(&target, q),
                );
                assert!(same_answer(&a, &b), "exact at {p:?}: {a:?} vs {b:?}");
                listed += usize::from(a.neighbours > 0);
            }
            // Most targets lie beyond the grid box, where the exact tier has no cell.
            assert!(
                listed >= 5,
                "{served_field:?}: {listed} answered from a list"
            );
        }
    }

    #[test]
    fn a_kriging_served_field_needs_a_served_tier() {
        let s = samples("");
        let options = BuildOptions {
            served_field: ServedField::Kriging,
            joint_radius_deg: Some(10.0),
            ..BuildOptions::default()
        };
        assert!(matches!(
            build(&s, options),
            Err(BuildError::KrigingWithoutServedTier)
        ));
    }
}
