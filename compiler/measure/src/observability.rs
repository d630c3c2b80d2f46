//! The classical observability indices of a set of poses for a kinematic identification,
//! from the singular values `σ₁ ≥ … ≥ σ_L` of its identification Jacobian `J` (the
//! position rows of the `m` poses stacked, `3m × L`), the parameters in millimetres and
//! milliradians so that a millimetre of length and a milliradian of angle weigh alike:
//!
//! - `O1 = (σ₁ σ₂ ⋯ σ_L)^(1/L) / √m` (Borm and Menq 1991): the volume of the parameters'
//!   confidence ellipsoid, per pose (D-optimality);
//! - `O2 = σ_L / σ₁` (Driels and Pathre 1990): the inverse condition number;
//! - `O3 = σ_L` (Nahvi, Hollerbach and Hayward 1994): the worst-determined direction
//!   (E-optimality);
//! - `O4 = σ_L² / σ₁` (Nahvi and Hollerbach 1996), their noise amplification index;
//! - `O5 = 1 / (1/σ₁ + ⋯ + 1/σ_L)` (Sun and Hollerbach 2008; A-optimality).
//!
//! Larger is better for every one. Beside them, the **noise amplification**
//! `√(tr((JᵀJ)⁻¹) / L)`: the RMS standard deviation of the identified parameters (mm and
//! mrad) per millimetre of noise on one measured coordinate, what a parameter error
//! comes to if the model holds. docs/measure.md has the references in full.

use adwi_identify::calibrate::Parameter;
use nalgebra::DMatrix;

/// The indices of one set of poses (module docs).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Observability {
    /// Borm and Menq's O1, mm per mm (or mrad).
    pub o1: f64,
    /// Driels and Pathre's O2, the inverse condition number (no unit).
    pub o2: f64,
    /// Nahvi, Hollerbach and Hayward's O3, the smallest singular value.
    pub o3: f64,
    /// Nahvi and Hollerbach's O4, the noise amplification index.
    pub o4: f64,
    /// Sun and Hollerbach's O5.
    pub o5: f64,
    /// RMS parameter standard deviation per unit of measurement noise: `√(tr((JᵀJ)⁻¹)/L)`.
    pub noise_amplification: f64,
}

/// The factor that turns a parameter's Jacobian column (mm per mm, mm per rad) into mm
/// per mm or per mrad: angles are weighed in milliradians.
pub fn per_display_unit(parameter: Parameter) -> f64 {
    if parameter.is_length() || parameter.is_compliance() {
        1.0
    } else {
        1e-3
    }
}

/// The indices of the stacked Jacobian `j` (`3m × L`, in mm and mrad) of `poses` poses;
/// `None` when it has no column, no pose, or a singular value that is zero or not finite
/// (a parameter the poses do not determine).
pub fn observability(j: &DMatrix<f64>, poses: usize) -> Option<Observability> {
    let l = j.ncols();
    if l == 0 || poses == 0 || j.nrows() < l {
        return None;
    }
    let mut sigma: Vec<f64> = j
        .clone()
        .svd(false, false)
        .singular_values
        .iter()
        .copied()
        .collect();
    sigma.sort_by(|a, b| b.total_cmp(a));
    let (first, last) = (sigma[0], sigma[l - 1]);
    if !(last > 0.0 && sigma.iter().all(|s| s.is_finite())) {
        return None;
    }
    let log_mean = sigma.iter().map(|s| s.ln()).sum::<f64>() / l as f64;
    let inverse_sum: f64 = sigma.iter().map(|s| 1.0 / s).sum();
    let inverse_square_sum: f64 = sigma.iter().map(|s| 1.0 / (s * s)).sum();
    let o = Observability {
        o1: log_mean.exp() / (poses as f64).sqrt(),
        o2: last / first,
        o3: last,
        o4: last * last / first,
        o5: 1.0 / inverse_sum,
        noise_amplification: (inverse_square_sum / l as f64).sqrt(),
    };
    let all = [o.o1, o.o2, o.o3, o.o4, o.o5, o.noise_amplification];
    all.iter().all(|v| v.is_finite()).then_some(o)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Jacobian with known singular values, 4, 2 and 1, over two poses: each index is
    /// its formula worked by hand.
    #[test]
    fn the_indices_are_their_formulas_on_known_singular_values() {
        // Orthogonal columns of norms 4, 2, 1 in six rows (two poses).
        let mut j = DMatrix::zeros(6, 3);
        j[(0, 0)] = 4.0;
        j[(4, 1)] = 2.0;
        j[(2, 2)] = 1.0;
        let o = observability(&j, 2).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(close(o.o1, 2.0 / 2f64.sqrt()), "{}", o.o1); // (4·2·1)^(1/3) = 2
        assert!(close(o.o2, 0.25));
        assert!(close(o.o3, 1.0));
        assert!(close(o.o4, 0.25));
        assert!(close(o.o5, 1.0 / 1.75)); // 1/4 + 1/2 + 1
                                          // (1/16 + 1/4 + 1) / 3 = 21/48
        assert!(close(o.noise_amplification, (21.0f64 / 48.0).sqrt()));
    }

    /// A parameter the poses do not determine gives no indices, not infinities.
    #[test]
    fn an_undetermined_parameter_gives_no_indices() {
        let mut j = DMatrix::zeros(6, 2);
        j[(0, 0)] = 1.0;
        assert_eq!(observability(&j, 2), None);
        assert_eq!(observability(&DMatrix::zeros(6, 0), 2), None);
        assert_eq!(observability(&DMatrix::zeros(2, 3), 1), None);
    }
}
