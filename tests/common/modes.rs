//! The small-vibration modes of a body about a state, for the stepper tests
//! (`tests/steppers/stability.rs`, `tests/steppers/step.rs`): the stiffness matrix by central
//! differences of the force kernel, the eigenvalues of `M^-1/2 K M^-1/2` by nalgebra in f64.

use nalgebra::{DMatrix, SymmetricEigen};

/// The eigenvalues (ascending, 1/s^2) of `M^-1/2 K M^-1/2` for a stiffness matrix given as
/// dense rows in f64 (symmetrised here) and lumped masses.
pub fn frequencies_squared(k: &DMatrix<f64>, masses: &[f64]) -> Vec<f64> {
    let n = k.nrows();
    let scaled = DMatrix::from_fn(n, n, |i, j| {
        0.5 * (k[(i, j)] + k[(j, i)]) / (masses[i / 3] * masses[j / 3]).sqrt()
    });
    let mut values: Vec<f64> = SymmetricEigen::new(scaled)
        .eigenvalues
        .iter()
        .copied()
        .collect();
    values.sort_by(f64::total_cmp);
    values
}

/// Expands, inside a test module of one precision (with `Vec3`, `Real` and `ElasticModel` of
/// that precision in scope), to `squared_frequencies(body, x, masses, step)`: the squared
/// angular frequencies (ascending, 1/s^2) of `body` about positions `x`, with `K` from central
/// differences of step `step` (m).
macro_rules! squared_frequencies {
    () => {
        fn squared_frequencies(
            body: &impl ElasticModel<Vector = Vec3>,
            x: &[Vec3],
            masses: &[Real],
            step: Real,
        ) -> Vec<f64> {
            let n = x.len();
            let mut k = nalgebra::DMatrix::<f64>::zeros(3 * n, 3 * n);
            for col in 0..3 * n {
                let mut forces = [vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]];
                for (sign, f) in [1.0, -1.0].into_iter().zip(forces.iter_mut()) {
                    let mut x = x.to_vec();
                    x[col / 3][col % 3] += sign * step;
                    body.add_forces(&x, f).unwrap();
                }
                for row in 0..3 * n {
                    let df = forces[0][row / 3][row % 3] - forces[1][row / 3][row % 3];
                    k[(row, col)] = -(df as f64) / (2.0 * step as f64);
                }
            }
            let masses: Vec<f64> = masses.iter().map(|&m| m as f64).collect();
            crate::common::modes::frequencies_squared(&k, &masses)
        }
    };
}
pub(crate) use squared_frequencies;
