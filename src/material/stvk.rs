//! Saint Venant–Kirchhoff: linear elasticity written in the Green strain.

use super::{Lame, Mat3, Material, MaterialError, Real, Vec3, frobenius_squared};

/// Saint Venant–Kirchhoff (`SPEC.md` section 2): with the Green strain `G = (F^T F - I) / 2`,
/// `W = lambda/2 (tr G)^2 + mu tr(G^2)` and `P = F (2 mu G + lambda tr(G) I)`.
///
/// Rotation-invariant and the cheapest model, but only sound for moderate strains:
/// * every reflection (`F^T F = I` with `det F = -1`) has `W = 0` and `P = 0`, so an inverted
///   element is at equilibrium and stays inverted;
/// * it softens in compression: under uniaxial strain `F = diag(s, 1, 1)` the nominal stress
///   `P_xx = (lambda + 2 mu) s (s^2 - 1) / 2` is largest in magnitude at `s = 1/sqrt(3)` and
///   returns to zero at `s = 0`, so a hard push flattens the element.
///
/// Defined (finite) for every finite `F`.
///
/// ```
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::material::{Material, StVK};
///
/// let stvk = StVK::from_lame(2.0e6, 1.0e6)?;
/// // A mirror image is stress-free: the inverted equilibrium.
/// let mirrored = Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0));
/// assert_eq!(stvk.energy_density(mirrored), 0.0);
/// assert_eq!(stvk.first_piola(mirrored), Mat3::ZERO);
/// # Ok::<(), softfem::MaterialError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StVK {
    lame: Lame,
}

impl StVK {
    /// The model with the given (already validated) Lamé parameters.
    #[inline]
    #[must_use]
    pub const fn new(lame: Lame) -> StVK {
        StVK { lame }
    }
}

lame_constructors!(StVK);

/// The Green strain `(F^T F - I) / 2` (dimensionless, symmetric).
#[inline(always)]
fn green_strain(f: Mat3) -> Mat3 {
    (f.transpose() * f - Mat3::IDENTITY) * 0.5
}

impl Material for StVK {
    #[inline]
    fn energy_density(&self, f: Mat3) -> Real {
        let g = green_strain(f);
        let trace = g.diagonal().element_sum();
        // tr(G^2) is the squared Frobenius norm because G is symmetric.
        0.5 * self.lame.lambda() * trace * trace + self.lame.mu() * frobenius_squared(g)
    }

    #[inline]
    fn first_piola(&self, f: Mat3) -> Mat3 {
        // P = F S with S = 2 mu G + lambda tr(G) I and G = (F^T F - I) / 2. F^T F and S are
        // symmetric, so only their six distinct entries are formed: the force kernel's hot path
        // measured 4 % faster this way than with full 3x3 products.
        let (a, b, c) = (f.x_axis, f.y_axis, f.z_axis);
        // 2 G: the diagonal, then the off-diagonal entries.
        let (g00, g11, g22) = (a.dot(a) - 1.0, b.dot(b) - 1.0, c.dot(c) - 1.0);
        let (c01, c02, c12) = (a.dot(b), a.dot(c), b.dot(c));
        let mu = self.lame.mu();
        let volumetric = 0.5 * self.lame.lambda() * (g00 + g11 + g22);
        let (s00, s11, s22) = (
            mu * g00 + volumetric,
            mu * g11 + volumetric,
            mu * g22 + volumetric,
        );
        let (s01, s02, s12) = (mu * c01, mu * c02, mu * c12);
        Mat3::from_cols(
            a * s00 + b * s01 + c * s02,
            a * s01 + b * s11 + c * s12,
            a * s02 + b * s12 + c * s22,
        )
    }

    #[inline]
    fn principal_energy(&self, s: Vec3) -> Real {
        let g = (s * s - Vec3::ONE) * 0.5;
        let trace = g.element_sum();
        0.5 * self.lame.lambda() * trace * trace + self.lame.mu() * g.length_squared()
    }

    #[inline]
    fn principal_stress(&self, s: Vec3) -> Vec3 {
        let g = (s * s - Vec3::ONE) * 0.5;
        let trace = g.element_sum();
        s * (Vec3::splat(self.lame.lambda() * trace) + g * (2.0 * self.lame.mu()))
    }
}
