//! Hyperelastic material models: strain energy density and first Piola–Kirchhoff stress
//! (`docs/math.md` section 2).
//!
//! # Conventions
//! * `f` is the deformation gradient `F = Ds Dm^-1` (dimensionless), `J = det F`,
//!   `I_C = tr(F^T F)`, `cof(F) = det(F) F^-T`.
//! * [`Material::energy_density`] is the strain energy `W` per unit **rest** volume, in
//!   J/m^3 = Pa; [`Material::first_piola`] is `P = dW/dF` in Pa (force per unit rest area). A
//!   tetrahedron of rest volume `V` stores `V W` and receives the forces `-V P Dm^-T`.
//! * The principal forms take the signed singular values `s` of `F` from
//!   [`svd3`] (dimensionless stretches, `s.z < 0` exactly when the element is
//!   inverted) and return `W(s)` and `dW/ds`. By isotropy `P = U diag(dW/ds) V^T`, which the
//!   provided methods of [`Material`] compute.
//! * Every model is built from validated [`Lame`] parameters (Pa) and linearises to the same
//!   small-strain elasticity `P = lambda tr(eps) I + 2 mu eps`, so swapping models never changes
//!   how stiff a scene is at small strain. Every model has `W(I) = 0` and `P(I) = 0`.
//!
//! # Which model a scene needs
//! | model | inverted element (`J <= 0`) | strong compression | cost |
//! |---|---|---|---|
//! | [`StVK`] | reflections are stress-free equilibria: an inverted element stays inverted | softens: the uniaxial nominal stress peaks at stretch `1/sqrt(3)`, then collapses | cheapest |
//! | [`NeoHookean`] (isochoric, `(J-1)^2` volume term) | barrier at `J = 0`: energy and stress blow up, and an element pushed through cannot come back | stiffens without bound | a cube root |
//! | [`StableNeoHookean`] | smooth through `J = 0`, restoring force on inverted elements | stiffens, finite everywhere | a `ln` |
//!
//! Small deformations (a few percent): any. Large deformations with implicit (energy-based)
//! stepping or relaxation, or anything that can invert: [`StableNeoHookean`]. Explicit stepping
//! of [`StVK`] or [`NeoHookean`] through inversion: the clamped principal path
//! [`Material::first_piola_principal_clamped`] (Irving, Teran, Fedkiw 2004).
//!
//! ```
//! use softfem::glam::{Mat3, Vec3};
//! use softfem::material::{Material, StableNeoHookean};
//!
//! let rubber = StableNeoHookean::from_young_poisson(1.0e6, 0.45)?;
//! // Squash an element by 10% along z.
//! let f = Mat3::from_diagonal(Vec3::new(1.0, 1.0, 0.9));
//! let p = rubber.first_piola(f);
//! assert!(p.z_axis.z < 0.0); // compressive
//! assert!(rubber.energy_density(f) > 0.0);
//! // The principal path (through the SVD) gives the same stress.
//! assert!(rubber.first_piola_principal(f).abs_diff_eq(p, 1e-4 * p.z_axis.z.abs()));
//! # Ok::<(), softfem::MaterialError>(())
//! ```

use core::fmt::Debug;

use super::lanes::{
    Lane, LaneMat3, LaneSvd3, LaneVec3, Lanes, map_lane_corners, map_lane_matrices, map_lanes,
};
use super::math;
use super::svd::{Svd3, svd3};
use super::types::{Mat3, Real, Vec3};
use crate::error::MaterialError;

/// The constructors and parameter accessors every model shares. A model `$model` provides
/// `fn new(lame: Lame) -> $model` and keeps its parameters in a field `lame: Lame`.
macro_rules! lame_constructors {
    ($model:ident) => {
        impl $model {
            #[doc = concat!("The [`", stringify!($model), "`] model with Lamé parameters `lambda` \
                and `mu` (both Pa).")]
            ///
            /// # Errors
            /// As [`Lame::new`]: `lambda` not finite, `mu` not finite and positive, or the bulk
            /// modulus `lambda + 2 mu / 3` not finite and positive.
            #[inline]
            pub fn from_lame(lambda: Real, mu: Real) -> Result<Self, MaterialError> {
                Lame::new(lambda, mu).map(Self::new)
            }

            #[doc = concat!("The [`", stringify!($model), "`] model with Young's modulus `e` \
                (Pa) and Poisson ratio `nu` (dimensionless).")]
            ///
            /// # Errors
            /// As [`Lame::from_young_poisson`]: `e` not finite and positive, or `nu` outside
            /// `(-1, 1/2)`.
            ///
            /// ```
            #[doc = concat!("use softfem::material::", stringify!($model), " as Model;")]
            ///
            /// let steel = Model::from_young_poisson(200e9, 0.3)?;
            /// assert!((steel.mu() - 200e9 / 2.6).abs() < 1e-6 * steel.mu());
            /// // nu = 1/2 is incompressible: not representable with a finite lambda.
            /// assert!(Model::from_young_poisson(1e6, 0.5).is_err());
            /// # Ok::<(), softfem::MaterialError>(())
            /// ```
            #[inline]
            pub fn from_young_poisson(e: Real, nu: Real) -> Result<Self, MaterialError> {
                Lame::from_young_poisson(e, nu).map(Self::new)
            }

            /// The first Lamé parameter `lambda` (Pa) this model linearises to.
            #[inline]
            #[must_use]
            pub fn lambda(&self) -> Real {
                self.lame.lambda()
            }

            /// The shear modulus `mu` (Pa) this model linearises to.
            #[inline]
            #[must_use]
            pub fn mu(&self) -> Real {
                self.lame.mu()
            }

            /// The validated Lamé parameters of this model.
            #[inline]
            #[must_use]
            pub fn lame(&self) -> Lame {
                self.lame
            }
        }
    };
}

/// The lane forms of [`Material::first_piola_from_svd`] and
/// [`Material::first_piola_clamped_from_svd`] for a model that keeps those two provided
/// methods and gives [`Material::principal_stress_wide`]: the same operations on every lane, so
/// the principal-path force kernels form stresses a group at a time with the bits of one
/// element at a time.
macro_rules! principal_wide_methods {
    () => {
        #[inline(always)]
        fn first_piola_from_svd_wide<L: super::Lane>(
            &self,
            svd: &super::LaneSvd3<L>,
        ) -> super::LaneMat3<L> {
            super::diagonal_product(svd, self.principal_stress_wide(svd.sigma))
        }

        #[inline(always)]
        fn first_piola_clamped_from_svd_wide<L: super::Lane>(
            &self,
            svd: &super::LaneSvd3<L>,
            threshold: super::Real,
        ) -> super::LaneMat3<L> {
            let clamped = super::clamp_stretches(svd.sigma, threshold);
            super::diagonal_product(svd, self.principal_stress_wide(clamped))
        }
    };
}

/// The methods of [`Material`] that a model written as `W(I_C, J)` forms the same way, from its
/// own `stress_coefficients(I_C, J)` (`(2 dW/dI_C, dW/dJ)`, generic over [`Lane`]) and
/// `energy_and_stress(F)` (generic over [`Lane`]): the direct stress, the fused energy and
/// stress, both for one value and for a group of lanes, and the principal stress.
macro_rules! invariant_stress_methods {
    () => {
        #[inline]
        fn first_piola(&self, f: Mat3) -> Mat3 {
            invariant_first_piola(LaneMat3::from(f), |ic, j| self.stress_coefficients(ic, j)).into()
        }

        #[inline]
        fn energy_and_first_piola(&self, f: Mat3) -> (Real, Mat3) {
            let (energy, stress) = self.energy_and_stress(LaneMat3::from(f));
            (energy, stress.into())
        }

        #[inline]
        fn first_piola_lanes(&self, f: LaneMat3<Lanes>) -> LaneMat3<Lanes> {
            invariant_first_piola(f, |ic, j| self.stress_coefficients(ic, j))
        }

        #[inline]
        fn energy_and_first_piola_lanes(&self, f: LaneMat3<Lanes>) -> (Lanes, LaneMat3<Lanes>) {
            self.energy_and_stress(f)
        }

        #[inline]
        fn principal_stress(&self, s: Vec3) -> Vec3 {
            self.principal_stress_wide(super::LaneVec3::from(s)).into()
        }

        // `dW/ds = a s + b (s_y s_z, s_z s_x, s_x s_y)` from `dI_C/ds = 2 s` and
        // `dJ/ds = (s_y s_z, s_z s_x, s_x s_y)`, with `(a, b)` of `W(I_C, J)` at
        // `(I_C, J) = (|s|^2, s_x s_y s_z)`. Written out without a closure, as
        // `first_piola_wide`.
        #[inline(always)]
        fn principal_stress_wide<L: super::Lane>(
            &self,
            s: super::LaneVec3<L>,
        ) -> super::LaneVec3<L> {
            let (ic, j) = (s.dot(s), s.x * s.y * s.z);
            let (a, b) = self.stress_coefficients(ic, j);
            let products = super::LaneVec3::new(s.y * s.z, s.z * s.x, s.x * s.y);
            s.scale(a) + products.scale(b)
        }

        principal_wide_methods!();

        // Written out without the closures of `invariant_first_piola` (the same operations):
        // a closure is not `inline(always)`, and one left out of line runs without the wide
        // registers of the SIMD function that calls this (measured 4x slower with AVX2).
        #[inline(always)]
        fn first_piola_wide<L: Lane>(&self, f: LaneMat3<L>) -> LaneMat3<L> {
            let cof = cofactor(f);
            let j = f.c0.dot(cof.c0);
            let (a, b) = self.stress_coefficients(frobenius_squared(f), j);
            f.scale(a) + cof.scale(b)
        }

        #[inline(always)]
        fn energy_and_first_piola_wide<L: Lane>(&self, f: LaneMat3<L>) -> (L, LaneMat3<L>) {
            self.energy_and_stress(f)
        }
    };
}

/// The second-derivative methods of [`Material`] for a model written as `W(I_C, J)`, from its
/// `stress_coefficients(I_C, J)` and `hessian_coefficients(I_C, J)`
/// (`(W_II, W_IJ, W_JJ)`, scalar): the principal Hessian, the closed-form twist and flip
/// eigenvalues and the direct stress differential (`material/hessian.rs`).
macro_rules! invariant_hessian_methods {
    () => {
        #[inline]
        fn principal_hessian(&self, s: Vec3) -> Mat3 {
            let (ic, j) = super::principal_invariants(s);
            super::hessian::invariant_principal_hessian(
                s,
                self.stress_coefficients(ic, j),
                self.hessian_coefficients(ic, j),
            )
        }

        #[inline]
        fn principal_pair_eigenvalues(&self, s: Vec3) -> [Vec3; 2] {
            let (ic, j) = super::principal_invariants(s);
            super::hessian::invariant_pair_eigenvalues(s, self.stress_coefficients(ic, j))
        }

        #[inline]
        fn first_piola_differential(&self, f: Mat3, df: Mat3) -> Mat3 {
            let (ic, j) = super::invariants(super::LaneMat3::from(f));
            super::hessian::invariant_first_piola_differential(
                f,
                df,
                self.stress_coefficients(ic, j),
                self.hessian_coefficients(ic, j),
            )
        }

        #[inline]
        fn corner_stress_and_stiffness(&self, f: Mat3, g: Vec3) -> (Vec3, Mat3) {
            let (stress, stiffness) = self.corner_stress_and_stiffness_wide(
                super::LaneMat3::from(f),
                super::LaneVec3::from(g),
            );
            (stress.into(), stiffness.into())
        }

        // Written out without closures (the same operations for one value and for lanes), as
        // `first_piola_wide`: a closure left out of line would run without the wide registers.
        #[inline(always)]
        fn corner_stress_and_stiffness_wide<L: super::Lane>(
            &self,
            f: super::LaneMat3<L>,
            g: super::LaneVec3<L>,
        ) -> (super::LaneVec3<L>, super::LaneMat3<L>) {
            let cof = super::cofactor(f);
            let (ic, j) = (super::frobenius_squared(f), f.c0.dot(cof.c0));
            super::invariant_corner_stress_and_stiffness(
                (f, cof, g),
                self.stress_coefficients(ic, j),
                self.hessian_coefficients(ic, j),
            )
        }
    };
}

pub(crate) mod hessian;
mod lame;
mod neo_hookean;
mod stable_neo_hookean;
mod stvk;

pub use hessian::StressDerivative;
pub use lame::Lame;
pub use neo_hookean::NeoHookean;
pub use stable_neo_hookean::StableNeoHookean;
pub use stvk::StVK;

/// An isotropic hyperelastic material: a strain energy density and its derivatives, in two
/// equivalent forms (direct in `F`, and principal in the signed singular values of `F`).
///
/// Implementors provide the four required methods; the principal-path stresses are provided.
/// All methods are pure functions of their arguments, never panic, and propagate NaN and
/// infinity from their input instead of hiding them.
pub trait Material: Copy + Debug {
    /// The strain energy density `W(F)` (J/m^3 = Pa, per unit rest volume) at deformation
    /// gradient `f` (dimensionless).
    #[must_use]
    fn energy_density(&self, f: Mat3) -> Real;

    /// The first Piola–Kirchhoff stress `P = dW/dF` (Pa) at deformation gradient `f`, computed
    /// directly from `f` (no SVD).
    #[must_use]
    fn first_piola(&self, f: Mat3) -> Mat3;

    /// The largest entry `max |F_ij|` (dimensionless) of a deformation gradient up to which this
    /// model's energy density and stresses (direct, principal and clamped) are guaranteed finite
    /// in this precision, with room for the element-level products: below it they stay under
    /// `Real::MAX / 2^24` in magnitude (see [`deformation_limit_for`]). The mesh kernels refuse
    /// an element whose `max(1, max |F_ij|)` exceeds it (so a limit below 1 refuses every
    /// deformation, `F = 0` included) with
    /// [`MeshError::DeformationRange`](crate::MeshError::DeformationRange) instead of returning
    /// infinite or NaN forces. The provided method returns infinity: no limit is known, and a
    /// custom model's own overflow is not detected.
    #[inline]
    #[must_use]
    fn deformation_limit(&self) -> Real {
        Real::INFINITY
    }

    /// `(energy_density(f), first_piola(f))` in one call, bit for bit: the per-element work
    /// of the energy-based steppers (a line search needs both at every trial point). The
    /// models here override it to compute the invariants, `cof(F)` and any cube root or
    /// logarithm they share only once.
    #[inline]
    #[must_use]
    fn energy_and_first_piola(&self, f: Mat3) -> (Real, Mat3) {
        (self.energy_density(f), self.first_piola(f))
    }

    /// [`first_piola`](Material::first_piola) of the [`LANES`](super::lanes::LANES)
    /// deformation gradients held in `f` (structure of arrays), lane by lane bit for bit. The
    /// provided method calls `first_piola` once per lane; the models here compute every lane at
    /// once, which the force kernels use where [`Lanes`] are SIMD registers.
    #[inline]
    #[must_use]
    fn first_piola_lanes(&self, f: LaneMat3<Lanes>) -> LaneMat3<Lanes> {
        LaneMat3::from_matrices(&f.to_matrices().map(|f| self.first_piola(f)))
    }

    /// [`energy_and_first_piola`](Material::energy_and_first_piola) of every lane of `f`, bit
    /// for bit; see [`first_piola_lanes`](Material::first_piola_lanes).
    #[inline]
    #[must_use]
    fn energy_and_first_piola_lanes(&self, f: LaneMat3<Lanes>) -> (Lanes, LaneMat3<Lanes>) {
        let both = f.to_matrices().map(|f| self.energy_and_first_piola(f));
        (
            Lanes::from_array(both.map(|(energy, _)| energy)),
            LaneMat3::from_matrices(&both.map(|(_, stress)| stress)),
        )
    }

    /// [`energy_density`](Material::energy_density) of every lane of `f`, for a group of any
    /// [`Lane`] type (the mesh kernels run groups of 4, 8, 16 or 32, see
    /// [`simd`](crate::simd)), lane by lane bit for bit. The provided method calls
    /// `energy_density` once per lane; the models here compute every lane at once.
    #[inline(always)]
    #[must_use]
    fn energy_density_wide<L: Lane>(&self, f: LaneMat3<L>) -> L {
        map_lane_matrices(f, |f| (self.energy_density(f), Mat3::ZERO)).0
    }

    /// [`first_piola`](Material::first_piola) of every lane of `f`, bit for bit; see
    /// [`energy_density_wide`](Material::energy_density_wide).
    #[inline(always)]
    #[must_use]
    fn first_piola_wide<L: Lane>(&self, f: LaneMat3<L>) -> LaneMat3<L> {
        map_lane_matrices(f, |f| (0.0, self.first_piola(f))).1
    }

    /// [`energy_and_first_piola`](Material::energy_and_first_piola) of every lane of `f`, bit
    /// for bit; see [`energy_density_wide`](Material::energy_density_wide).
    #[inline(always)]
    #[must_use]
    fn energy_and_first_piola_wide<L: Lane>(&self, f: LaneMat3<L>) -> (L, LaneMat3<L>) {
        map_lane_matrices(f, |f| self.energy_and_first_piola(f))
    }

    /// The strain energy density `W` (J/m^3) as a function of the signed singular values `s` of
    /// `F` (dimensionless, as returned by [`svd3`]: `s.z < 0` for an inverted element).
    /// Equals [`energy_density`](Material::energy_density) of any `F` with these singular values.
    #[must_use]
    fn principal_energy(&self, s: Vec3) -> Real;

    /// The principal stresses `dW/ds` (Pa): the gradient of
    /// [`principal_energy`](Material::principal_energy) with respect to the signed singular
    /// values `s`.
    #[must_use]
    fn principal_stress(&self, s: Vec3) -> Vec3;

    /// The first Piola–Kirchhoff stress (Pa) by the principal path, `P = U diag(dW/ds) V^T` with
    /// `F = U diag(s) V^T` from [`svd3`]. Agrees with [`first_piola`](Material::first_piola) to
    /// rounding wherever the model is defined.
    #[inline]
    #[must_use]
    fn first_piola_principal(&self, f: Mat3) -> Mat3 {
        self.first_piola_from_svd(&svd3(f))
    }

    /// The principal-path stress `U diag(dW/ds) V^T` (Pa) from an SVD the caller already has,
    /// so that a kernel which needs the SVD anyway does not compute it twice.
    #[inline]
    #[must_use]
    fn first_piola_from_svd(&self, svd: &Svd3) -> Mat3 {
        svd.u.mul_diagonal_scale(self.principal_stress(svd.sigma)) * svd.v.transpose()
    }

    /// **Not the gradient of any energy: for explicit time stepping only.** The inversion-robust
    /// stress (Pa) of Irving, Teran and Fedkiw, "Invertible finite elements for robust
    /// simulation of large deformation" (SCA 2004): `U diag(dW/ds(s')) V^T` with the stretches
    /// clamped from below, `s'_i = max(s_i, threshold)`.
    ///
    /// An inverted or nearly flat element is thereby given the stress of a mildly compressed,
    /// uninverted one, which pushes it back towards `J > 0` even for models whose own stress
    /// traps it ([`StVK`]) or is not finite ([`NeoHookean`] at `J = 0`). `threshold` is a
    /// dimensionless stretch, typically `0.2..0.5`; it must be positive for the result to be
    /// finite with [`NeoHookean`]. Elements with every stretch at or above `threshold` get
    /// exactly [`first_piola_principal`](Material::first_piola_principal).
    ///
    /// Because the clamped stress is not `dW/dF` for any `W`, the forces it produces are not
    /// conservative: energy-based solvers (implicit Euler as minimisation, relaxation, line
    /// searches) must not use it, and energy is not conserved by it. NaN stretches propagate.
    #[inline]
    #[must_use]
    fn first_piola_principal_clamped(&self, f: Mat3, threshold: Real) -> Mat3 {
        self.first_piola_clamped_from_svd(&svd3(f), threshold)
    }

    /// [`first_piola_principal_clamped`](Material::first_piola_principal_clamped) from an SVD
    /// the caller already has. **Not the gradient of any energy: for explicit time stepping
    /// only.**
    #[inline]
    #[must_use]
    fn first_piola_clamped_from_svd(&self, svd: &Svd3, threshold: Real) -> Mat3 {
        // `select` rather than `max`: `Real::max` would replace a NaN stretch by the threshold
        // and hide a non-finite deformation behind a finite stress.
        let clamp = |s: Real| math::select(s < threshold, threshold, s);
        let clamped = Vec3::new(clamp(svd.sigma.x), clamp(svd.sigma.y), clamp(svd.sigma.z));
        svd.u.mul_diagonal_scale(self.principal_stress(clamped)) * svd.v.transpose()
    }

    /// [`principal_stress`](Material::principal_stress) of every lane of `s`, bit for bit; see
    /// [`energy_density_wide`](Material::energy_density_wide).
    #[inline(always)]
    #[must_use]
    fn principal_stress_wide<L: Lane>(&self, s: LaneVec3<L>) -> LaneVec3<L> {
        let each = |_, s| (self.principal_stress(s), Mat3::ZERO);
        map_lane_corners(LaneMat3::identity(), s, each).0
    }

    /// [`first_piola_from_svd`](Material::first_piola_from_svd) of the SVD in every lane of
    /// `svd`, bit for bit: the principal force kernels' stresses, a group at a time. The
    /// provided method calls `first_piola_from_svd` once per lane (so it agrees with an
    /// overridden one); the models here compute every lane at once.
    #[inline(always)]
    #[must_use]
    fn first_piola_from_svd_wide<L: Lane>(&self, svd: &LaneSvd3<L>) -> LaneMat3<L> {
        map_lanes(|lane| (0.0, self.first_piola_from_svd(&svd.lane(lane)))).1
    }

    /// [`first_piola_clamped_from_svd`](Material::first_piola_clamped_from_svd) of the SVD in
    /// every lane of `svd`, bit for bit; see
    /// [`first_piola_from_svd_wide`](Material::first_piola_from_svd_wide). **Not the gradient
    /// of any energy: for explicit time stepping only.**
    #[inline(always)]
    #[must_use]
    fn first_piola_clamped_from_svd_wide<L: Lane>(
        &self,
        svd: &LaneSvd3<L>,
        threshold: Real,
    ) -> LaneMat3<L> {
        map_lanes(|lane| {
            let stress = self.first_piola_clamped_from_svd(&svd.lane(lane), threshold);
            (0.0, stress)
        })
        .1
    }

    /// The principal Hessian `d^2 W / ds^2` (Pa), a symmetric 3x3 matrix, at the signed singular
    /// values `s`: the derivative of [`principal_stress`](Material::principal_stress).
    ///
    /// The models here give it in closed form. The provided method takes central differences of
    /// `principal_stress` (step `eps^(1/3) max(1, |s|)`, symmetrised), accurate to about
    /// `eps^(2/3)` relative: override it with the exact form where one is known.
    #[inline]
    #[must_use]
    fn principal_hessian(&self, s: Vec3) -> Mat3 {
        hessian::difference_principal_hessian(|s| self.principal_stress(s), s)
    }

    /// The eigenvalues `[flip, twist]` (Pa) of the pair modes of `d^2 W / dF^2` at the signed
    /// singular values `s`: component `k` belongs to the pair of the other two axes `(i, j)`,
    /// flip `(psi_i - psi_j) / (s_i - s_j)` and twist `(psi_i + psi_j) / (s_i + s_j)` with
    /// `psi = dW/ds` (see `docs/math.md` section 6 and [`StressDerivative`]).
    ///
    /// The models here give them in closed form, exact at repeated and opposite stretches. The
    /// provided method forms the quotients and takes their limits `(H_ii + H_jj)/2 -+ H_ij` (of
    /// [`principal_hessian`](Material::principal_hessian)) where a denominator is below
    /// `sqrt(eps) max(1, |s|)`.
    #[inline]
    #[must_use]
    fn principal_pair_eigenvalues(&self, s: Vec3) -> [Vec3; 2] {
        hessian::quotient_pair_eigenvalues(self.principal_stress(s), self.principal_hessian(s), s)
    }

    /// The exact (unprojected) derivative of the stress in the direction `df`:
    /// `dP = (dP/dF) : dF` (Pa) at `f`, the action of the symmetric 9x9 `d^2 W / dF^2`.
    ///
    /// The models here differentiate their direct stress (no SVD). The provided method uses
    /// the principal-frame eigensystem ([`stress_derivative`](Material::stress_derivative)).
    #[inline]
    #[must_use]
    fn first_piola_differential(&self, f: Mat3, df: Mat3) -> Mat3 {
        self.stress_derivative(f).apply(df)
    }

    /// The exact stress derivative `dP/dF` (Pa) at `f` as a symmetric 9x9 matrix, assembled from
    /// the analytic eigensystem in the principal frame of [`svd3`]`(f)` without projection (it
    /// may be indefinite). Agrees with
    /// [`first_piola_differential`](Material::first_piola_differential) to rounding.
    #[inline]
    #[must_use]
    fn stress_derivative(&self, f: Mat3) -> StressDerivative {
        let svd = svd3(f);
        hessian::principal_frame_derivative(
            &svd,
            self.principal_hessian(svd.sigma),
            self.principal_pair_eigenvalues(svd.sigma),
            false,
        )
    }

    /// The stress derivative `dP/dF` (Pa) at `f` projected onto the symmetric positive
    /// semi-definite matrices: every eigenvalue of the analytic eigensystem (Smith, de Goes,
    /// Kim, "Analytic Eigensystems for Isotropic Distortion Energies", ACM TOG 2019; scaling
    /// modes from the 3x3 principal Hessian, twist and flip modes in closed form) clamped at
    /// zero (`docs/math.md` section 6). Where the exact derivative is already SPD this is it.
    /// The Hessian that Newton's method and Vertex Block Descent need to always descend.
    ///
    /// Finite for every finite `f` where the model is (not [`NeoHookean`] at `J = 0`); NaN
    /// input gives NaN entries, never a panic.
    #[inline]
    #[must_use]
    fn projected_stress_derivative(&self, f: Mat3) -> StressDerivative {
        self.projected_stress_derivative_from_svd(&svd3(f))
    }

    /// The stress on one corner, `P g` (Pa/m), and the same-corner stiffness
    /// `K(g) = sum_(a,b) g_a g_b (d^2 W / dF^2)[(., a), (., b)]` (Pa/m^2), the symmetric 3x3
    /// with `K(g) u = dP(u g^T) g`, at deformation gradient `f` for the shape-function gradient
    /// `g` (m^-1): a tetrahedron of rest volume `V` has the force `-V P g` on that corner and
    /// the exact (unprojected, possibly indefinite) diagonal Hessian block `V K(g)` there. What
    /// Vertex Block Descent needs per element and corner (`docs/math.md` section 7).
    ///
    /// The models here give both in closed form without an SVD: for `W(I_C, J)`, with
    /// `p = F g` and `q = cof(F) g`, `P g = 2 W_I p + W_J q` and `K = 2 W_I |g|^2 I +
    /// 4 W_II p p^T + 2 W_IJ (p q^T + q p^T) + W_JJ q q^T` (the `W_J d^2 J / dF^2` term vanishes
    /// on one corner: `d cof(F)[u g^T] g` is a sum of `g_a g_b (u x F_c + F_c x u)` = 0); for
    /// [`StVK`], `K = (g^T S g) I + mu |g|^2 F F^T + (lambda + mu) p p^T`. The provided method
    /// takes [`first_piola`](Material::first_piola) and three
    /// [`first_piola_differential`](Material::first_piola_differential)s.
    #[inline]
    #[must_use]
    fn corner_stress_and_stiffness(&self, f: Mat3, g: Vec3) -> (Vec3, Mat3) {
        let column = |u: Vec3| {
            let df = Mat3::from_cols(u * g.x, u * g.y, u * g.z);
            self.first_piola_differential(f, df) * g
        };
        let k = Mat3::from_cols(column(Vec3::X), column(Vec3::Y), column(Vec3::Z));
        (self.first_piola(f) * g, (k + k.transpose()) * 0.5)
    }

    /// [`corner_stress_and_stiffness`](Material::corner_stress_and_stiffness) of every lane of
    /// `f` and `g`, bit for bit: what the Vertex Block Descent sweep evaluates for several
    /// vertices of one colour at once. The models here write one kernel for one value and for
    /// lanes; the provided method takes the lanes one at a time.
    #[inline(always)]
    #[must_use]
    fn corner_stress_and_stiffness_wide<L: Lane>(
        &self,
        f: LaneMat3<L>,
        g: LaneVec3<L>,
    ) -> (LaneVec3<L>, LaneMat3<L>) {
        map_lane_corners(f, g, |f, g| self.corner_stress_and_stiffness(f, g))
    }

    /// [`projected_stress_derivative`](Material::projected_stress_derivative) from an SVD the
    /// caller already has.
    #[inline]
    #[must_use]
    fn projected_stress_derivative_from_svd(&self, svd: &Svd3) -> StressDerivative {
        hessian::principal_frame_derivative(
            svd,
            self.principal_hessian(svd.sigma),
            self.principal_pair_eigenvalues(svd.sigma),
            true,
        )
    }
}

/// `(Real::MAX / 2^24 / (256 modulus))^(1 / power)` rounded down to a power of two: the
/// [`Material::deformation_limit`] of a model whose energy density and stress grow at most like
/// `modulus max(1, s)^power` with `s = max |F_ij|` (the constant 256 covers the sums of up to
/// nine products of entries in `I_C`, `det F`, `cof F` and the principal stretches, all bounded
/// by `3 s`). Rounding to a power of two keeps it exact, identical on every target and free of
/// roots (a software `cbrt` on a Cortex-M4F would cost more than the check it serves). `power`
/// is 2, 4 or 6 (taken as 6 otherwise). Below 1 for a modulus above about `Real::MAX / 2^32`
/// (8e28 Pa in f32, 4e298 Pa in f64): then even an undeformed element is refused, as such a
/// material leaves no headroom at any strain.
#[must_use]
pub fn deformation_limit_for(modulus: Real, power: u32) -> Real {
    let headroom = Real::MAX / 16_777_216.0;
    let x = headroom / (256.0 * modulus);
    if !(x > 0.0 && x.is_finite()) {
        return 0.0;
    }
    let root = match power {
        2 => 2,
        4 => 4,
        _ => 6,
    };
    // 2^floor(e / root) <= 2^(e / root) <= x^(1 / root), e = floor(log2 x).
    math::pow2(math::exponent(x).div_euclid(root))
}

// The helpers below are written once against `Lane`: instantiated with `Real` for the scalar
// methods of `Material` and with `Lanes` for its lane methods, so that lane `i` of a group is
// bit for bit what the scalar method gives for the same `F`. Their order of operations is that
// of the glam expressions they replace (`Vec3::dot`, `Vec3::cross`, `Mat3 * Mat3`).

/// `tr(a^T a)`, the squared Frobenius norm; `I_C` when `a = F`.
#[inline(always)]
fn frobenius_squared<L: Lane>(a: LaneMat3<L>) -> L {
    a.c0.dot(a.c0) + a.c1.dot(a.c1) + a.c2.dot(a.c2)
}

/// `cof(F) = det(F) F^-T` as cross products of the columns of `F`: no division, so it is exact
/// up to rounding for singular and inverted `F` too. `F^T cof(F) = det(F) I` column by column.
#[inline(always)]
fn cofactor<L: Lane>(f: LaneMat3<L>) -> LaneMat3<L> {
    LaneMat3 {
        c0: f.c1.cross(f.c2),
        c1: f.c2.cross(f.c0),
        c2: f.c0.cross(f.c1),
    }
}

/// `(I_C, J) = (tr(F^T F), det F)`, with `J = F_0 . cof(F)_0` (the triple product
/// `x . (y x z)` of the columns), exactly as [`invariant_first_piola`] forms it, so that a
/// model's energy and stress see the same `J` to the last bit.
#[inline(always)]
fn invariants<L: Lane>(f: LaneMat3<L>) -> (L, L) {
    (frobenius_squared(f), f.c0.dot(f.c1.cross(f.c2)))
}

/// `(I_C - 3, J - 1)` without cancellation, given `cof0 = F_1 x F_2`, the first column of
/// `cof(F)`. Forming `I_C` and `J` first and subtracting would leave an absolute error of a few
/// `eps`, which at a small strain `e` is a relative error of `eps / e` in every energy term of
/// order `e`. Instead, with `F_ii - 1` exact for `F_ii` in `[0.5, 2]` (Sterbenz):
/// `I_C - 3 = sum (F_ii - 1)(F_ii + 1) + sum_{i != j} F_ij^2`, and
/// `J - 1 = F_0 . cof0 - 1 = (cof0_x - 1) + (F_00 - 1, F_10, F_20) . cof0` with
/// `cof0_x - 1 = (F_11 - 1) + (F_22 - 1) + (F_11 - 1)(F_22 - 1) - F_21 F_12`.
#[inline(always)]
fn invariant_deviations<L: Lane>(f: LaneMat3<L>, cof0: LaneVec3<L>) -> (L, L) {
    let (a, b, c) = (f.c0, f.c1, f.c2);
    let one = L::splat(1.0);
    let (d0, d1, d2) = (a.x - one, b.y - one, c.z - one);
    let diagonal = d0 * (a.x + one) + d1 * (b.y + one) + d2 * (c.z + one);
    let off_diagonal = (a.y * a.y + a.z * a.z) + (b.x * b.x + b.z * b.z) + (c.x * c.x + c.y * c.y);
    let cof0_minus_1 = (d1 + d2) + (d1 * d2 - b.z * c.y);
    (
        diagonal + off_diagonal,
        cof0_minus_1 + LaneVec3::new(d0, a.y, a.z).dot(cof0),
    )
}

/// [`invariant_deviations`] from the signed singular values: with `d = s - 1`,
/// `I_C - 3 = 2 sum d + |d|^2` and `J - 1 = sum d + (d0 d1 + d0 d2 + d1 d2) + d0 d1 d2`.
#[inline(always)]
fn principal_invariant_deviations(s: Vec3) -> (Real, Real) {
    let d = s - Vec3::ONE;
    let trace = d.x + d.y + d.z;
    (
        2.0 * trace + d.length_squared(),
        trace + (d.x * d.y + d.x * d.z + d.y * d.z) + d.x * d.y * d.z,
    )
}

/// `(I_C, J) = (sum s_i^2, s0 s1 s2)` from the signed singular values.
#[inline(always)]
fn principal_invariants(s: Vec3) -> (Real, Real) {
    (s.length_squared(), s.x * s.y * s.z)
}

/// `P` of a model written as `W(I_C, J)`: `dI_C/dF = 2 F` and `dJ/dF = cof(F)` give
/// `P = a F + b cof(F)` with `(a, b) = (2 dW/dI_C, dW/dJ)` from `coefficients(I_C, J)`.
#[inline(always)]
fn invariant_first_piola<L: Lane>(
    f: LaneMat3<L>,
    coefficients: impl FnOnce(L, L) -> (L, L),
) -> LaneMat3<L> {
    first_piola_with_cofactor(f, cofactor(f), coefficients)
}

/// [`invariant_first_piola`] given `cof(F)`.
#[inline(always)]
fn first_piola_with_cofactor<L: Lane>(
    f: LaneMat3<L>,
    cof: LaneMat3<L>,
    coefficients: impl FnOnce(L, L) -> (L, L),
) -> LaneMat3<L> {
    let j = f.c0.dot(cof.c0);
    let (a, b) = coefficients(frobenius_squared(f), j);
    f.scale(a) + cof.scale(b)
}

/// [`Material::corner_stress_and_stiffness_wide`] of a model written as `W(I_C, J)`, given
/// `(F, cof(F), g)`, `(a, b) = (2 W_I, W_J)` and `(W_II, W_IJ, W_JJ)` at `F`: with `p = F g`,
/// `q = cof(F) g`, `P g = a p + b q` and
/// `K = a |g|^2 I + 4 W_II p p^T + 2 W_IJ (p q^T + q p^T) + W_JJ q q^T`, from
/// `dP = a dF + F da + cof(F) db + b d cof(F)` at `dF = u g^T` (`d cof(F)[u g^T] g = 0`). Six
/// entries of the symmetric `K` are formed, then mirrored.
#[inline(always)]
fn invariant_corner_stress_and_stiffness<L: Lane>(
    (f, cof, g): (LaneMat3<L>, LaneMat3<L>, LaneVec3<L>),
    (a, b): (L, L),
    (w_ii, w_ij, w_jj): (L, L, L),
) -> (LaneVec3<L>, LaneMat3<L>) {
    let (p, q) = (f.mul_vec(g), cof.mul_vec(g));
    let (pp, pq, qq) = (L::splat(4.0) * w_ii, L::splat(2.0) * w_ij, w_jj);
    // K = a |g|^2 I + p r^T + q s^T with r = pp p + pq q, s = pq p + qq q.
    let (r, s) = (p.scale(pp) + q.scale(pq), p.scale(pq) + q.scale(qq));
    let diagonal = a * g.dot(g);
    let k = symmetric(
        LaneVec3::new(
            p.x * r.x + q.x * s.x + diagonal,
            p.y * r.y + q.y * s.y + diagonal,
            p.z * r.z + q.z * s.z + diagonal,
        ),
        LaneVec3::new(
            p.x * r.y + q.x * s.y,
            p.x * r.z + q.x * s.z,
            p.y * r.z + q.y * s.z,
        ),
    );
    (p.scale(a) + q.scale(b), k)
}

/// The symmetric 3x3 with diagonal `d` and off-diagonal `(o.x, o.y, o.z)` at `(0, 1)`, `(0, 2)`,
/// `(1, 2)`.
#[inline(always)]
fn symmetric<L: Lane>(d: LaneVec3<L>, o: LaneVec3<L>) -> LaneMat3<L> {
    LaneMat3 {
        c0: LaneVec3::new(d.x, o.x, o.y),
        c1: LaneVec3::new(o.x, d.y, o.z),
        c2: LaneVec3::new(o.y, o.z, d.z),
    }
}

/// `U diag(psi) V^T` of the SVD in every lane (glam's `mul_diagonal_scale` and product, in
/// their order): the principal-path stress of [`principal_wide_methods`].
#[inline(always)]
fn diagonal_product<L: Lane>(svd: &LaneSvd3<L>, psi: LaneVec3<L>) -> LaneMat3<L> {
    let u = svd.u;
    let scaled = LaneMat3 {
        c0: u.c0.scale(psi.x),
        c1: u.c1.scale(psi.y),
        c2: u.c2.scale(psi.z),
    };
    scaled * svd.v.transpose()
}

/// The stretches `s` clamped from below at `threshold`, as
/// [`Material::first_piola_clamped_from_svd`] clamps them (a NaN stretch stays NaN).
#[inline(always)]
fn clamp_stretches<L: Lane>(s: LaneVec3<L>, threshold: Real) -> LaneVec3<L> {
    let t = L::splat(threshold);
    // `t > s` is `s < t`, false for NaN as in the scalar `select`.
    LaneVec3::new(
        L::select(t.gt(s.x), t, s.x),
        L::select(t.gt(s.y), t, s.y),
        L::select(t.gt(s.z), t, s.z),
    )
}
