//! Meshes, bodies and time loops, written once against `super::api` (`softfem` or
//! `softfem::f64`) and compiled per precision by `single.rs` and `double.rs`, the way the crate
//! compiles its own numeric modules. Positions leave this module as `f64` triples so that runs
//! in the two precisions can be compared.

// Each precision's charts use part of this module (the f64 instantiation computes references,
// the f32 one runs most scenes), so what one instantiation leaves unused would warn.
#![allow(dead_code)]
// `f64::from` widens in the f32 instantiation and is the identity in the f64 one.
#![allow(clippy::useless_conversion)]

use std::time::Instant;

use nalgebra::DMatrix;
use softfem::StepError;

use super::api::element::TetRest;
use super::api::generate::{BoxSplit, box_counts, fill_box};
use super::api::mesh::TetMesh;
use super::api::step::{
    ElasticEnergy, ElasticModel, ExplicitScratch, ExplicitSettings, RelaxScratch, RelaxSettings,
    Scene, explicit_step, relax_step, scratch_len,
};
use super::api::types::{Real, Vec3};
use crate::measure::{Run, StepOutcome};

/// A box of tetrahedra from `softfem::generate::fill_box`.
#[derive(Clone, Debug)]
pub struct BoxMesh {
    /// Rest positions (m).
    pub rest: Vec<Vec3>,
    /// Positively oriented tetrahedra.
    pub tets: Vec<[u32; 4]>,
}

impl BoxMesh {
    /// The box `[0, size]` (m) in `cells` cubes split by `split`.
    pub fn new(size: Vec3, cells: [usize; 3], split: BoxSplit) -> Result<BoxMesh, String> {
        let [nx, ny, nz] = cells;
        let (vertices, tets) = box_counts(nx, ny, nz, split).map_err(|e| e.to_string())?;
        let mut mesh = BoxMesh {
            rest: vec![Vec3::ZERO; vertices],
            tets: vec![[0; 4]; tets],
        };
        fill_box(
            Vec3::ZERO,
            size,
            nx,
            ny,
            nz,
            split,
            &mut mesh.rest,
            &mut mesh.tets,
        )
        .map_err(|e| e.to_string())?;
        Ok(mesh)
    }

    /// The validated mesh, its rest data kept in `rest_data`.
    pub fn mesh<'a>(&'a self, rest_data: &'a mut Vec<TetRest>) -> Result<TetMesh<'a>, String> {
        rest_data.clear();
        rest_data.resize(self.tets.len(), TetRest::default());
        TetMesh::new(&self.rest, &self.tets, rest_data).map_err(|e| e.to_string())
    }

    /// One flag per vertex: whether its rest position satisfies `select`.
    pub fn flags(&self, select: impl Fn(Vec3) -> bool) -> Vec<bool> {
        self.rest.iter().map(|&x| select(x)).collect()
    }
}

/// The lumped masses (kg) of `mesh` at `density` (kg/m^3).
pub fn masses(mesh: &TetMesh<'_>, density: Real) -> Result<Vec<Real>, String> {
    let mut masses = vec![0.0; mesh.vertex_count()];
    mesh.lumped_masses(density, &mut masses)
        .map_err(|e| e.to_string())?;
    Ok(masses)
}

/// The smallest element volume ratio (current / rest) and the ratio of the total volumes.
pub fn volume_ratios(mesh: &TetMesh<'_>, x: &[Vec3]) -> (f64, f64) {
    let (mut smallest, mut current, mut rest) = (f64::INFINITY, 0.0, 0.0);
    for (tet, data) in mesh.tets().iter().zip(mesh.rest()) {
        let [x0, x1, x2, x3] = tet.map(|i| x[i as usize]);
        let volume = f64::from((x1 - x0).cross(x2 - x0).dot(x3 - x0)) / 6.0;
        smallest = smallest.min(volume / f64::from(data.volume));
        current += volume;
        rest += f64::from(data.volume);
    }
    (smallest, current / rest)
}

/// Positions as f64 triples.
pub fn to_f64(x: &[Vec3]) -> Vec<[f64; 3]> {
    x.iter().map(|p| p.to_array().map(f64::from)).collect()
}

/// Advances `(x, v)` by steps of `dt` (s) until `duration` (s), with `step` doing one step in
/// place, and records the positions at `sample_times` (ascending, s). Stops at the first error,
/// which `softfem::step` reports with the state restored.
pub fn run(
    x: &mut [Vec3],
    v: &mut [Vec3],
    dt: f64,
    duration: f64,
    sample_times: &[f64],
    mut step: impl FnMut(&mut [Vec3], &mut [Vec3]) -> Result<StepOutcome, StepError>,
) -> Run {
    let started = Instant::now();
    let mut result = Run::default();
    let mut pending = sample_times.iter().copied().peekable();
    while pending.next_if(|&t| t <= 0.0).is_some() {
        result.samples.push(to_f64(x));
    }
    let mut previous = x.to_vec();
    let steps = (duration / dt - 1e-9).ceil().max(0.0) as u64;
    for k in 0..steps {
        previous.copy_from_slice(x);
        match step(x, v) {
            Ok(outcome) => {
                result.iterations += u64::from(outcome.iterations);
                result.unconverged += u64::from(!outcome.converged);
            }
            Err(error) => {
                result.failure = Some((k as f64 * dt, error));
                break;
            }
        }
        result.steps += 1;
        let (t0, t1) = (k as f64 * dt, (k + 1) as f64 * dt);
        while let Some(t) = pending.next_if(|&t| t <= t1 + 1e-12 * t1) {
            let w = ((t - t0) / dt).clamp(0.0, 1.0);
            result.samples.push(
                previous
                    .iter()
                    .zip(x.iter())
                    .map(|(a, b)| {
                        let (a, b) = (a.to_array(), b.to_array());
                        std::array::from_fn(|i| {
                            f64::from(a[i]) + w * (f64::from(b[i]) - f64::from(a[i]))
                        })
                    })
                    .collect(),
            );
        }
    }
    result.wall = started.elapsed();
    result
}

/// [`run`] with explicit symplectic Euler (`scene.dt` per step).
#[allow(clippy::too_many_arguments)]
pub fn run_explicit<F: ElasticModel<Vector = Vec3>>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, Vec3>,
    settings: &ExplicitSettings,
    x: &mut [Vec3],
    v: &mut [Vec3],
    duration: f64,
    sample_times: &[f64],
) -> Run {
    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(x.len())];
    let mut scratch = ExplicitScratch::new(&mut buffer);
    run(x, v, f64::from(scene.dt), duration, sample_times, |x, v| {
        explicit_step(model, masses, pinned, scene, settings, x, v, &mut scratch).map(|_| {
            StepOutcome {
                iterations: 0,
                converged: true,
            }
        })
    })
}

/// [`run`] with implicit Euler steps solved by the relaxation (`scene.dt` per step).
#[allow(clippy::too_many_arguments)]
pub fn run_relax<F: ElasticEnergy<Vector = Vec3>>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, Vec3>,
    settings: &RelaxSettings,
    x: &mut [Vec3],
    v: &mut [Vec3],
    duration: f64,
    sample_times: &[f64],
) -> Run {
    let n = x.len();
    let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
    run(x, v, f64::from(scene.dt), duration, sample_times, |x, v| {
        relax_step(model, masses, pinned, scene, settings, x, v, &mut scratch).map(|report| {
            StepOutcome {
                iterations: report.iterations,
                converged: report.converged,
            }
        })
    })
}

/// The stiffness matrix `K = -df/dx` (N/m, `3n x 3n`, symmetrised) of `model` at `x`, by
/// central differences of its forces with step `step` (m).
pub fn stiffness_matrix<F: ElasticModel<Vector = Vec3>>(
    model: &F,
    x: &[Vec3],
    step: Real,
) -> Result<DMatrix<f64>, String> {
    let n = x.len();
    let mut k = DMatrix::<f64>::zeros(3 * n, 3 * n);
    let (mut plus, mut minus) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    let mut shifted = x.to_vec();
    for column in 0..3 * n {
        for (sign, forces) in [(1.0, &mut plus), (-1.0, &mut minus)] {
            shifted.copy_from_slice(x);
            shifted[column / 3][column % 3] += sign * step;
            forces.fill(Vec3::ZERO);
            model
                .add_forces(&shifted, forces)
                .map_err(|e| e.to_string())?;
        }
        for row in 0..3 * n {
            let df = f64::from(plus[row / 3][row % 3]) - f64::from(minus[row / 3][row % 3]);
            k[(row, column)] = -df / (2.0 * f64::from(step));
        }
    }
    Ok((&k + k.transpose()) * 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_sample_by_interpolation_and_stop_at_errors() {
        let mut x = vec![Vec3::ZERO];
        let mut v = vec![Vec3::X];
        // Constant velocity 1 m/s, steps of 0.1 s: the sample at 0.25 s lies between steps.
        let run = run(&mut x, &mut v, 0.1, 0.5, &[0.0, 0.25, 0.5], |x, v| {
            x[0] += v[0] * 0.1;
            Ok(StepOutcome {
                iterations: 2,
                converged: true,
            })
        });
        assert_eq!(run.steps, 5);
        assert_eq!(run.iterations, 10);
        let xs: Vec<f64> = run.samples.iter().map(|s| s[0][0]).collect();
        assert_eq!(xs.len(), 3);
        assert!(
            (xs[1] - 0.25).abs() < 1e-6 && (xs[2] - 0.5).abs() < 1e-6,
            "{xs:?}"
        );

        let mut calls = 0;
        let failed = super::run(&mut x, &mut v, 0.1, 1.0, &[1.0], |_, _| {
            calls += 1;
            if calls == 3 {
                Err(StepError::EnergyBlowUp)
            } else {
                Ok(StepOutcome::default())
            }
        });
        assert_eq!(failed.steps, 2);
        assert!(failed.samples.is_empty());
        assert!(
            matches!(failed.failure, Some((t, StepError::EnergyBlowUp)) if (t - 0.2).abs() < 1e-9)
        );
    }

    #[test]
    fn volume_ratios_of_a_stretched_box() {
        let boxed = BoxMesh::new(Vec3::ONE, [1, 1, 1], BoxSplit::Kuhn6).unwrap();
        let mut rest_data = Vec::new();
        let mesh = boxed.mesh(&mut rest_data).unwrap();
        let stretched: Vec<Vec3> = boxed
            .rest
            .iter()
            .map(|&p| p * Vec3::new(2.0, 1.0, 1.0))
            .collect();
        let (smallest, total) = volume_ratios(&mesh, &stretched);
        assert!((smallest - 2.0).abs() < 1e-6 && (total - 2.0).abs() < 1e-6);
    }
}
