//! An estimate of the highest natural frequency of a body, for a tighter explicit time step than
//! the proven bound of [`stable_time_step`](super::super::stable_time_step).
//!
//! Symplectic Euler is stable for `dt < 2 / omega_max`, `omega_max^2` the largest eigenvalue of
//! `M^-1 H` (`docs/math.md` section 4). The proven bound majorises `omega_max` element by element,
//! which is safe but loose: on the Kuhn boxes of [`generate`](crate::generate) it allows only
//! about 0.6 of the true limit (measured in `tests/steppers/frequency.rs`: 0.632 on one cube, 0.599
//! on a 3x2x2 bar pinned at one end). Here `omega_max^2` is computed by power iteration on `M^-1 H`
//! (pinned degrees of freedom removed) with the projected Hessian `H` at the given positions,
//! through [`ElasticHessian`] products (`docs/math.md` section 6): `v <- M^-1 H v / |M^-1 H v|_M`,
//! `omega^2 = v.Hv / v.Mv` (the Rayleigh quotient in the mass inner product, where `M^-1 H` is
//! symmetric). The Rayleigh quotient never exceeds the largest eigenvalue and converges to it from
//! below, so the step it implies is **not** a guarantee: use [`FrequencyEstimate::time_step`],
//! which applies [`FrequencyEstimate::MARGIN`], and keep the stepper's blow-up detection on. At
//! rest the projected Hessian is the exact one (it is positive semi-definite there), so the
//! estimate is the linearised system's.

use super::super::super::element::TetHessian;
use super::super::super::math;
use super::super::super::types::{Real, Vec3};
use super::super::model::ElasticHessian;
use super::super::scratch_len;
use super::super::state::{check_length, pinned_flags};
use crate::error::{StepBuffer, StepError};

/// The fraction of the estimated limit `2 / omega_max` that [`FrequencyEstimate::time_step`]
/// takes: `0.8`. See [`FrequencyEstimate::MARGIN`] for what it covers and why it is not 0.9.
pub(crate) const FREQUENCY_MARGIN: Real = 0.8;

/// What [`estimate_max_frequency`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrequencyEstimate {
    /// The estimated highest angular frequency `omega_max` (rad/s), a lower bound on the true
    /// one that converges to it.
    pub omega_max: Real,
    /// Power iterations done.
    pub iterations: u32,
    /// The relative change of `omega_max^2` in the last iteration (the convergence measure).
    pub change: Real,
}

impl FrequencyEstimate {
    /// The margin [`time_step`](Self::time_step) leaves below the estimated limit: 0.8.
    ///
    /// **It covers the power iteration's shortfall**, which is far smaller: on a free
    /// 3x3x3 Kuhn box (edge 0.05 m, E = 1e5 Pa, nu = 0.3) the doc example's `(200, 1e-6)`
    /// stops at 0.99998 of the converged `omega_max`. **And it covers a body that moves away
    /// from the state the estimate was taken at, where 0.9 did not.** Measured (`margin_report` in
    /// `tests/steppers/frequency.rs`, run with `cargo test --release --all-features --test
    /// steppers -- frequency:: --ignored --nocapture`): that box, StVK and stable neo-Hookean,
    /// rest positions moved by a uniform 1 % of the edge per coordinate (16 seeds), released
    /// without velocity or gravity. The perturbed state's `omega_max` is 0.999 to 1.018 of the
    /// rest one, yet at 0.9 the step blows up within 200 steps for 16 of 16 seeds (StVK) and 5
    /// of 16 (stable neo-Hookean) with the estimate taken at rest, 15 or 16 of 16 and 2 of 16
    /// with the estimate taken at the perturbed state; forced on past the detector, every such
    /// run diverges to infinity within 3000 steps, so these are real instabilities the detector
    /// caught (the state is restored; [`StepError::EnergyBlowUp`]). The states the motion
    /// visits stay within 1.05 of the rest `omega_max`: the instability is the nonlinear
    /// coupling of the modes near the limit, which no linearised frequency shows. Margins 0.8,
    /// 0.7, 0.6 and 0.5 never blew up (200 steps, every seed, both estimates, both precisions;
    /// 0.8 also over 3000 steps for 4 seeds). The measurement is one 64-vertex box, so keep the
    /// blow-up detection on; [`time_step_with_margin`](Self::time_step_with_margin) takes
    /// another margin.
    pub const MARGIN: Real = FREQUENCY_MARGIN;

    /// The explicit step `MARGIN * 2 / omega_max` (s); infinite if `omega_max` is 0
    /// (nothing free, or no stiffness). See [`MARGIN`](Self::MARGIN) for what the margin
    /// covers, measured.
    #[inline]
    #[must_use]
    pub fn time_step(&self) -> Real {
        self.time_step_with_margin(FREQUENCY_MARGIN)
    }

    /// The explicit step `margin * 2 / omega_max` (s), for a margin of your choosing.
    #[inline]
    #[must_use]
    pub fn time_step_with_margin(&self, margin: Real) -> Real {
        margin * 2.0 / self.omega_max
    }
}

/// Estimates the highest natural frequency of `model` linearised at `positions` (m, usually the
/// rest shape) with lumped `masses` (kg) and `pinned` vertices removed: at most
/// `max_iterations` power iterations, stopping once `omega^2` changes by at most `tolerance`
/// (relative) in one iteration. `hessians` ([`ElasticHessian::element_count`] entries) receives
/// the projected Hessian at `positions`; `vectors` is scratch of [`scratch_len::frequency`].
/// Deterministic: the start vector is a fixed pseudo-random pattern.
///
/// ```
/// use softfem::element::{TetHessian, TetRest};
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::explicit::estimate_max_frequency;
/// use softfem::step::scratch_len;
/// use softfem::step::{TetElastic, stable_time_step};
///
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z].map(|x| x * 0.1);
/// let tets = [[0, 1, 2, 3]];
/// let mut rest_data = [TetRest::default(); 1];
/// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
/// let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.3)?);
/// let mut masses = [0.0; 4];
/// mesh.lumped_masses(1000.0, &mut masses)?;
/// let (mut hessians, mut vectors) = ([TetHessian::default(); 1], [Vec3::ZERO; scratch_len::frequency(4)]);
/// let estimate = estimate_max_frequency(&body, &masses, &[], &rest, (200, 1e-6), &mut hessians, &mut vectors)?;
/// let proven = stable_time_step(&body, &masses, &[], &mut [0.0; 4])?;
/// assert!(estimate.time_step_with_margin(1.0) >= proven);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`StepError::LengthMismatch`] for a buffer of the wrong length, [`StepError::Mass`] for a
/// mass that is not finite and positive, and the Hessian kernels' errors (non-finite
/// positions) as [`StepError::Mesh`].
pub fn estimate_max_frequency<F: ElasticHessian>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    positions: &[Vec3],
    (max_iterations, tolerance): (u32, Real),
    hessians: &mut [TetHessian],
    vectors: &mut [Vec3],
) -> Result<FrequencyEstimate, StepError> {
    let n = model.vertex_count();
    check_length(StepBuffer::Masses, n, masses.len())?;
    if !pinned.is_empty() {
        check_length(StepBuffer::Pinned, n, pinned.len())?;
    }
    check_length(StepBuffer::Positions, n, positions.len())?;
    check_length(
        StepBuffer::Scratch,
        scratch_len::frequency(n),
        vectors.len(),
    )?;
    check_length(
        StepBuffer::HessianScratch,
        model.element_count(),
        hessians.len(),
    )?;
    if let Some(vertex) = masses.iter().position(|&m| !(m > 0.0 && m.is_finite())) {
        return Err(StepError::Mass { vertex });
    }
    model.projected_hessians(positions, hessians)?;
    let (v, product) = vectors.split_at_mut(n);
    // A fixed pseudo-random start (Knuth's MMIX linear congruential generator): no symmetry
    // of the mesh can make it orthogonal to the top mode.
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut draw = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 40) as Real) / ((1u64 << 24) as Real) - 0.5
    };
    for (x, pinned) in v.iter_mut().zip(pinned_flags(pinned)) {
        let random = Vec3::new(draw(), draw(), draw());
        *x = if pinned { Vec3::ZERO } else { random };
    }
    normalise(v, masses);
    let mut omega_squared: Real = 0.0;
    let mut change = Real::INFINITY;
    let mut iterations = 0;
    while iterations < max_iterations {
        product.fill(Vec3::ZERO);
        model.add_hessian_product(hessians, v, product)?;
        // v.Hv with |v|_M = 1: the Rayleigh quotient.
        let quotient: Real = v.iter().zip(&*product).map(|(a, b)| a.dot(*b)).sum();
        iterations += 1;
        change = (quotient - omega_squared).abs() / quotient.abs().max(Real::MIN_POSITIVE);
        omega_squared = quotient;
        // v <- M^-1 H v, pinned components removed, normalised in the mass norm.
        for (((x, &p), &m), pinned) in v
            .iter_mut()
            .zip(&*product)
            .zip(masses)
            .zip(pinned_flags(pinned))
        {
            *x = if pinned { Vec3::ZERO } else { p * (1.0 / m) };
        }
        if !normalise(v, masses) || change <= tolerance {
            break;
        }
    }
    Ok(FrequencyEstimate {
        omega_max: math::sqrt(omega_squared.max(0.0)),
        iterations,
        change,
    })
}

/// Scales `v` to unit mass norm `sqrt(sum m |v|^2)`; false (and `v` unchanged) if it is zero
/// or not finite.
fn normalise(v: &mut [Vec3], masses: &[Real]) -> bool {
    let norm_squared: Real = v.iter().zip(masses).map(|(x, &m)| m * x.dot(*x)).sum();
    if !(norm_squared > 0.0 && norm_squared.is_finite()) {
        return false;
    }
    let scale = 1.0 / math::sqrt(norm_squared);
    for x in v.iter_mut() {
        *x *= scale;
    }
    true
}
