//! The explicit stability bound: per-element stiffness bounds against lumped masses. The
//! derivation and what it guarantees are in the `step` module documentation.

use super::super::super::element::TriangleStVK;
use super::super::super::element::{TetRest, TriRest};
use super::super::super::lanes::each_lane;
use super::super::super::material::Material;
use super::super::super::math::{self, BATCH_SVD};
use super::super::super::mesh::TetMesh;
use super::super::super::svd::{svd3, svd3_lanes};
use super::super::super::types::{Mat2, Mat3, Real, Vec2, Vec3};
use super::super::model::ElasticModel;
use super::super::state::check_length;
use crate::error::{MeshError, StepBuffer, StepError};

/// Step of the central differences in [`linearised_moduli`] (dimensionless strain).
const MODULUS_STRAIN: Real = 1.0e-3;

/// Relative enlargement of the measured moduli, covering the central differences' error
/// (`O(strain^2)` from the nonlinearity, `O(eps / strain)` from rounding: about `1e-4` in f32).
const MODULUS_MARGIN: Real = 1.001;

/// The small-strain Lamé parameters `(lambda, mu)` (Pa) of `material`, measured by central
/// differences of [`Material::first_piola`] about the identity (strain `1e-3`): `lambda + 2 mu`
/// from a uniaxial stretch, `mu` from a simple shear. Exact (to rounding and `1e-6` relative)
/// for every model here, which all linearise to linear elasticity; works for any `Material`.
///
/// ```
/// use softfem::material::StableNeoHookean;
/// use softfem::step::explicit::linearised_moduli;
///
/// let rubber = StableNeoHookean::from_lame(4.0e5, 1.0e5)?;
/// let (lambda, mu) = linearised_moduli(&rubber);
/// assert!((lambda - 4.0e5).abs() < 1e2 && (mu - 1.0e5).abs() < 1e1);
/// # Ok::<(), softfem::MaterialError>(())
/// ```
#[must_use]
pub fn linearised_moduli<M: Material>(material: &M) -> (Real, Real) {
    let h = MODULUS_STRAIN;
    let stretch = |s: Real| {
        material
            .first_piola(Mat3::from_diagonal(Vec3::new(1.0 + s, 1.0, 1.0)))
            .x_axis
            .x
    };
    let shear = |s: Real| {
        material
            .first_piola(Mat3::from_cols(Vec3::X, Vec3::new(s, 1.0, 0.0), Vec3::Z))
            .y_axis
            .x
    };
    let p_wave = (stretch(h) - stretch(-h)) / (2.0 * h);
    let mu = (shear(h) - shear(-h)) / (2.0 * h);
    (p_wave - 2.0 * mu, mu)
}

/// `c_max`, the largest eigenvalue of the small-strain elasticity tensor (Pa) in `dimension`
/// 2 or 3, from the P-wave modulus and the shear modulus, with the safety margin.
fn largest_modulus(p_wave: Real, mu: Real, dimension: Real) -> Real {
    let lambda = p_wave - 2.0 * mu;
    let bulk_mode = dimension * lambda + 2.0 * mu;
    MODULUS_MARGIN * bulk_mode.max(2.0 * mu)
}

/// Visits every tetrahedron with its stiffness bound `V c_max lambda_max(G G^T)` (N/m).
pub(crate) fn tet_stiffness<M: Material>(
    mesh: &TetMesh<'_>,
    material: &M,
    mut visit: impl FnMut(&[u32], Real, Real),
) {
    let (lambda, mu) = linearised_moduli(material);
    let c_max = largest_modulus(lambda + 2.0 * mu, mu, 3.0);
    // `G G^T` is symmetric positive semi-definite: its largest singular value is its largest
    // eigenvalue. Where SIMD makes it faster, the SVDs run LANES elements at a time
    // (bit-identical to `svd3`).
    let (groups, tail) = mesh.groups_and_tail(BATCH_SVD);
    for (tets, rests) in groups {
        let svds = svd3_lanes(&each_lane(*rests, gradient_products));
        for ((corners, rest), svd) in tets.iter().zip(rests).zip(&svds) {
            visit(corners, rest.volume * c_max * svd.sigma.x, rest.volume);
        }
    }
    for (corners, rest) in tail {
        let largest = svd3(gradient_products(*rest)).sigma.x;
        visit(corners, rest.volume * c_max * largest, rest.volume);
    }
}

/// `G G^T = sum_a grad N_a grad N_a^T` over the four corners' shape-function gradients.
#[inline]
fn gradient_products(rest: TetRest) -> Mat3 {
    let g = rest.dm_inv.transpose(); // columns: grad N_1, grad N_2, grad N_3
    let g0 = -(g.x_axis + g.y_axis + g.z_axis);
    g * g.transpose() + Mat3::from_cols(g0 * g0.x, g0 * g0.y, g0 * g0.z)
}

/// Visits every triangle (2D or membrane, both measured in their rest plane) with its
/// stiffness bound `A c_max lambda_max(G G^T)`.
pub(crate) fn triangle_stiffness(
    tris: &[[u32; 3]],
    rest: &[TriRest],
    material: &TriangleStVK,
    mut visit: impl FnMut(&[u32], Real, Real),
) {
    let h = MODULUS_STRAIN;
    let stretch = |s: Real| {
        material
            .first_piola(Mat2::from_diagonal(Vec2::new(1.0 + s, 1.0)))
            .x_axis
            .x
    };
    let shear = |s: Real| {
        material
            .first_piola(Mat2::from_cols(Vec2::X, Vec2::new(s, 1.0)))
            .y_axis
            .x
    };
    let p_wave = (stretch(h) - stretch(-h)) / (2.0 * h);
    let mu = (shear(h) - shear(-h)) / (2.0 * h);
    let c_max = largest_modulus(p_wave, mu, 2.0);
    for (corners, rest) in tris.iter().zip(rest) {
        let g = rest.dm_inv.transpose();
        let g0 = -(g.x_axis + g.y_axis);
        let ggt = g * g.transpose() + Mat2::from_cols(g0 * g0.x, g0 * g0.y);
        let (a, b, d) = (ggt.x_axis.x, ggt.y_axis.x, ggt.y_axis.y);
        let half_difference = 0.5 * (a - d);
        let largest = 0.5 * (a + d) + math::sqrt(half_difference * half_difference + b * b);
        visit(corners, rest.area * c_max * largest, rest.area);
    }
}

/// A time step (s) below the critical step of explicit symplectic Euler for `model` with the
/// caller's lumped `masses` (kg) and `pinned` flags (empty or one per vertex): the vertex bound
/// `min_i 2 sqrt(m_i / k_i)` over free vertices, `k_i` the sum of the stiffness bounds of the
/// elements around vertex `i` (see the [module documentation](super::super) for the derivation and
/// what it guarantees: the linearised system at rest). `stiffness` is scratch space, one entry
/// per vertex, left holding `k_i` (N/m). Infinite if no free vertex has stiffness.
///
/// ```
/// use softfem::element::TetRest;
/// use softfem::generate::{BoxSplit, fill_box};
/// use softfem::glam::Vec3;
/// use softfem::material::StVK;
/// use softfem::mesh::TetMesh;
/// use softfem::step::explicit::element_stable_time_step;
/// use softfem::step::{TetElastic, stable_time_step};
///
/// let (mut rest, mut tets) = ([Vec3::ZERO; 12], [[0u32; 4]; 12]);
/// fill_box(Vec3::ZERO, Vec3::new(0.2, 0.1, 0.1), 2, 1, 1, BoxSplit::Kuhn6, &mut rest, &mut tets)?;
/// let mut rest_data = [TetRest::default(); 12];
/// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
/// let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e6, 0.3)?);
/// let mut masses = [0.0; 12];
/// mesh.lumped_masses(1000.0, &mut masses)?;
/// let mut stiffness = [0.0; 12];
/// let dt = stable_time_step(&body, &masses, &[], &mut stiffness)?;
/// // c_d = sqrt((lambda + 2 mu) / rho) = 37 m/s across 0.1 m cells: a fraction of a ms.
/// assert!(dt > 1e-4 && dt < 2e-3);
/// assert!(dt >= element_stable_time_step(&body, 1000.0)?);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`StepError::LengthMismatch`] if `masses`, `stiffness` or a non-empty `pinned` does not have
/// one entry per vertex; [`StepError::Mass`] for the first mass that is not a finite normal
/// positive number; [`StepError::Stiffness`] for the first free vertex whose bound `k_i` is
/// NaN, negative or infinite, or whose `k_i / m_i` overflows (the material is too stiff for
/// this precision, or a custom model reports a NaN bound).
pub fn stable_time_step<F: ElasticModel>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    stiffness: &mut [Real],
) -> Result<Real, StepError> {
    let n = model.vertex_count();
    check_length(StepBuffer::Masses, n, masses.len())?;
    if !pinned.is_empty() {
        check_length(StepBuffer::Pinned, n, pinned.len())?;
    }
    check_length(StepBuffer::ScalarScratch, n, stiffness.len())?;
    if let Some(vertex) = masses
        .iter()
        .position(|&m| !super::super::state::mass_in_range(m))
    {
        return Err(StepError::Mass { vertex });
    }
    vertex_stiffness(model, stiffness);
    let mut worst: Real = 0.0; // max k_i / m_i
    for (vertex, ((&k, &m), pinned)) in stiffness
        .iter()
        .zip(masses)
        .zip(super::super::state::pinned_flags(pinned))
        .enumerate()
    {
        // A NaN or infinite bound (a custom model's NaN, a modulus near `Real::MAX` whose
        // element bound overflows, or `k / m` overflowing) has no step to give: `Ok(0)` or,
        // with NaN ignored by `max`, `Ok(inf)` would be a wrong answer.
        if pinned {
            continue;
        }
        let ratio = k / m;
        if !(k >= 0.0 && ratio.is_finite()) {
            return Err(StepError::Stiffness { vertex });
        }
        worst = worst.max(ratio);
    }
    Ok(if worst > 0.0 {
        2.0 / math::sqrt(worst)
    } else {
        Real::INFINITY
    })
}

/// Writes `k_i` (N/m), the sum of the stiffness bounds of the elements around each vertex, into
/// `stiffness` (one entry per vertex, length checked by the caller).
pub(crate) fn vertex_stiffness<F: ElasticModel>(model: &F, stiffness: &mut [Real]) {
    stiffness.fill(0.0);
    model.for_each_element_stiffness(|corners, k, _| {
        for &i in corners {
            if let Some(slot) = stiffness.get_mut(i as usize) {
                *slot += k;
            }
        }
    });
}

/// the per-element bound `min_e 2 / omega_e` (s), each element against its own lumped share
/// `density * measure / N` of mass (`density` in kg/m^3, or kg/m^2 for membranes): needs no
/// scratch, and is never larger than [`stable_time_step`] with lumped masses. Infinite for a
/// mesh without elements.
///
/// # Errors
/// [`StepError::Mesh`]`(`[`MeshError::Density`]`)` if `density` is not finite and positive;
/// [`StepError::Stiffness`] naming the first corner of the first element whose bound is NaN or
/// infinite or gives no positive step.
pub fn element_stable_time_step<F: ElasticModel>(
    model: &F,
    density: Real,
) -> Result<Real, StepError> {
    if !(density > 0.0 && density.is_finite()) {
        return Err(StepError::Mesh(MeshError::Density));
    }
    let mut smallest = Real::INFINITY;
    let mut unusable = None;
    model.for_each_element_stiffness(|corners, k, measure| {
        let corner_count = corners.len() as Real;
        let step = 2.0 * math::sqrt(density * measure / (corner_count * k));
        // NaN (ignored by `min`) or zero from a bound that is NaN or overflows.
        if unusable.is_none() && !(step > 0.0 && k.is_finite()) {
            unusable = Some(corners.first().map_or(0, |&i| i as usize));
        }
        smallest = smallest.min(step);
    });
    match unusable {
        Some(vertex) => Err(StepError::Stiffness { vertex }),
        None => Ok(smallest),
    }
}
