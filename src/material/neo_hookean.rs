//! Neo-Hookean with an isochoric shear term and a quadratic `(J - 1)^2` volume penalty.

use super::{
    Lame, Lane, LaneMat3, Lanes, Mat3, Material, MaterialError, Real, Vec3, cofactor,
    frobenius_squared, invariant_first_piola, invariants, math, principal_invariants,
};

/// The isochoric neo-Hookean model (`docs/math.md` section 2): with `I_C = tr(F^T F)`,
/// `J = det F` and bulk modulus `K = lambda + 2 mu / 3`,
/// `W = mu/2 (J^(-2/3) I_C - 3) + K/2 (J - 1)^2` and
/// `P = mu J^(-2/3) F - (mu/3) J^(-5/3) I_C cof(F) + K (J - 1) cof(F)`.
///
/// # At and beyond `J = 0`
/// The shear term is a barrier: `W >= mu (J^(-2/3) - 3/2)` when two stretches are 1, so the
/// energy and the stress grow without bound as `J -> 0`, and an element pushed through `J = 0`
/// cannot come back. Precisely:
/// * `J = 0` (a flat element): `W = +inf` (NaN if `F = 0`) and `P` has non-finite entries (inf
///   or NaN). Nothing panics; the NaN propagates so a stepper can detect it. Use the clamped
///   principal path ([`Material::first_piola_principal_clamped`]) or [`StableNeoHookean`] when
///   elements may flatten.
/// * `J < 0`: `J^(-2/3)` is taken as the real cube root, `(J^2)^(-1/3) > 0`, so `W` and `P` are
///   finite and `P` is still the gradient of `W` (the mirror image of the `J > 0` branch of the
///   shear term). Its barrier then holds the element on the inverted side: the failure mode
///   the stability tests show, rather than a NaN.
///
/// # Rounding at small strain
/// The isochoric term `J^(-2/3) I_C - 3` is a difference of terms of order one, so the energy
/// carries an absolute rounding error of order `eps mu` however small the strain `e` (a relative
/// error of `eps / e^2`, far above 1 in f32 below `e ~ 3e-4`). The stress is not affected. An
/// f32 line search ([`relax_step`](super::super::step::relax_step)) on such a state compares
/// energies that rounding dominates; [`StableNeoHookean`] and [`StVK`](super::StVK) form their
/// energies without this cancellation.
///
/// ```
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::material::{Material, NeoHookean};
///
/// let nh = NeoHookean::from_lame(2.0e6, 1.0e6)?;
/// let flattened = |t: f32| Mat3::from_diagonal(Vec3::new(1.0, 1.0, t));
/// // The barrier: squashing 100x harder costs far more energy.
/// assert!(nh.energy_density(flattened(1e-3)) > 10.0 * nh.energy_density(flattened(1e-1)));
/// // A flat element has infinite energy and a non-finite stress, without panicking.
/// assert_eq!(nh.energy_density(flattened(0.0)), f32::INFINITY);
/// assert!(!nh.first_piola(flattened(0.0)).is_finite());
/// # Ok::<(), softfem::MaterialError>(())
/// ```
///
/// [`StableNeoHookean`]: super::StableNeoHookean
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeoHookean {
    lame: Lame,
    /// `K = lambda + 2 mu / 3` (Pa).
    bulk_modulus: Real,
}

impl NeoHookean {
    /// The model with the given (already validated) Lamé parameters.
    #[inline]
    #[must_use]
    pub const fn new(lame: Lame) -> NeoHookean {
        NeoHookean {
            lame,
            bulk_modulus: lame.bulk_modulus(),
        }
    }

    /// `W(I_C, J)`.
    #[inline(always)]
    fn energy<L: Lane>(&self, ic: L, j: L) -> L {
        self.energy_with(ic, j, j_pow_minus_two_thirds(j))
    }

    /// [`energy`](Self::energy) given `j23 = J^(-2/3)`.
    #[inline(always)]
    fn energy_with<L: Lane>(&self, ic: L, j: L, j23: L) -> L {
        let one = L::splat(1.0);
        let shear = L::splat(0.5 * self.lame.mu()) * (j23 * ic - L::splat(3.0));
        shear + L::splat(0.5 * self.bulk_modulus) * (j - one) * (j - one)
    }

    /// `(2 dW/dI_C, dW/dJ) = (mu J^(-2/3), -(mu/3) J^(-5/3) I_C + K (J - 1))`.
    #[inline(always)]
    fn stress_coefficients<L: Lane>(&self, ic: L, j: L) -> (L, L) {
        self.stress_coefficients_with(ic, j, j_pow_minus_two_thirds(j))
    }

    /// [`stress_coefficients`](Self::stress_coefficients) given `j23 = J^(-2/3)`.
    #[inline(always)]
    fn stress_coefficients_with<L: Lane>(&self, ic: L, j: L, j23: L) -> (L, L) {
        let shear = L::splat(self.lame.mu()) * j23;
        // Grouped as (I_C / 3) / J so that the two shear terms of P cancel exactly at F = I.
        (
            shear,
            L::splat(self.bulk_modulus) * (j - L::splat(1.0)) - shear * (ic / L::splat(3.0)) / j,
        )
    }

    /// `(W_II, W_IJ, W_JJ) = (0, -(mu/3) J^(-5/3), (5 mu / 9) J^(-8/3) I_C + K)`, the second
    /// derivatives of `W(I_C, J)` with the real cube root (`docs/math.md` section 6); not
    /// finite at `J = 0`.
    #[inline(always)]
    fn hessian_coefficients<L: Lane>(&self, ic: L, j: L) -> (L, L, L) {
        let j23 = j_pow_minus_two_thirds(j);
        let mu = self.lame.mu();
        (
            L::splat(0.0),
            L::splat(-(mu / 3.0)) * j23 / j,
            L::splat(5.0 * mu / 9.0) * ic * j23 / (j * j) + L::splat(self.bulk_modulus),
        )
    }

    /// `(W, P)` with one cofactor matrix and one cube root, for one value or a group of lanes.
    #[inline(always)]
    fn energy_and_stress<L: Lane>(&self, f: LaneMat3<L>) -> (L, LaneMat3<L>) {
        let cof = cofactor(f);
        let (ic, j) = (frobenius_squared(f), f.c0.dot(cof.c0));
        let j23 = j_pow_minus_two_thirds(j);
        let (a, b) = self.stress_coefficients_with(ic, j, j23);
        (self.energy_with(ic, j, j23), f.scale(a) + cof.scale(b))
    }
}

lame_constructors!(NeoHookean);

/// `J^(-2/3)` through the real cube root: defined and positive for `J < 0`, `+inf` at `J = 0`.
#[inline(always)]
fn j_pow_minus_two_thirds<L: Lane>(j: L) -> L {
    let cube_root = j.map(math::cbrt);
    L::splat(1.0) / (cube_root * cube_root)
}

impl Material for NeoHookean {
    #[inline]
    fn energy_density(&self, f: Mat3) -> Real {
        let (ic, j) = invariants(LaneMat3::from(f));
        self.energy(ic, j)
    }

    #[inline(always)]
    fn energy_density_wide<L: Lane>(&self, f: LaneMat3<L>) -> L {
        let (ic, j) = invariants(f);
        self.energy(ic, j)
    }

    #[inline]
    fn principal_energy(&self, s: Vec3) -> Real {
        let (ic, j) = principal_invariants(s);
        self.energy(ic, j)
    }

    invariant_stress_methods!();
    invariant_hessian_methods!();
}
