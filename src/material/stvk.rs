//! Saint Venant–Kirchhoff: linear elasticity written in the Green strain.

use super::{Lame, Lane, LaneMat3, LaneVec3, Lanes, Mat3, Material, MaterialError, Real, Vec3};

/// Saint Venant–Kirchhoff (`docs/math.md` section 2): with the Green strain `G = (F^T F - I) / 2`,
/// `W = lambda/2 (tr G)^2 + mu tr(G^2)` and `P = F (2 mu G + lambda tr(G) I)`.
///
/// Rotation-invariant and the cheapest model, but only sound for moderate strains:
/// * every reflection (`F^T F = I` with `det F = -1`) has `W = 0` and `P = 0`, so an inverted
///   element is at equilibrium and stays inverted;
/// * it softens in compression: under uniaxial strain `F = diag(s, 1, 1)` the nominal stress
///   `P_xx = (lambda + 2 mu) s (s^2 - 1) / 2` is largest in magnitude at `s = 1/sqrt(3)` and
///   returns to zero at `s = 0`, so a hard push flattens the element.
///
/// Finite for every `F` with `max |F_ij|` up to [`deformation_limit`](Material::deformation_limit),
/// `((Real::MAX / 2^24) / (256 (|lambda| + mu)))^(1/4)` rounded down to a power of two (its
/// energy grows like `|F|^4`): `5.2e5` in f32 and `1.4e73` in f64 for `E = 1 MPa`, `nu = 0.3`. Beyond it (`F = 1e20 I` in f32) the values
/// overflow, and the mesh kernels refuse such deformations with an error.
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

impl StVK {
    /// `W(F)`, written once for one value or a group of lanes. With the Green strain
    /// `G = (F^T F - I) / 2`, whose entries are the dot products of the columns of `F` (formed
    /// as glam's `(F^T F - I) * 0.5` forms them): `W = lambda/2 (tr G)^2 + mu |G|^2`, where
    /// `tr(G^2) = |G|^2` because `G` is symmetric.
    #[inline(always)]
    fn energy<L: Lane>(&self, f: LaneMat3<L>) -> L {
        let (a, b, c) = (f.c0, f.c1, f.c2);
        let (one, half) = (L::splat(1.0), L::splat(0.5));
        let (g00, g11, g22) = (
            (a.dot(a) - one) * half,
            (b.dot(b) - one) * half,
            (c.dot(c) - one) * half,
        );
        let (g01, g02, g12) = (a.dot(b) * half, a.dot(c) * half, b.dot(c) * half);
        let trace = g00 + g11 + g22;
        // |G|^2 column by column: (G00, G10, G20), (G01, G11, G21), (G02, G12, G22).
        let squared_norm = (g00 * g00 + g01 * g01 + g02 * g02)
            + (g01 * g01 + g11 * g11 + g12 * g12)
            + (g02 * g02 + g12 * g12 + g22 * g22);
        L::splat(0.5 * self.lame.lambda()) * trace * trace + L::splat(self.lame.mu()) * squared_norm
    }

    /// `P(F)`, written once for one value or a group of lanes: `P = F S` with
    /// `S = 2 mu G + lambda tr(G) I`. `F^T F` and `S` are symmetric, so only their six distinct
    /// entries are formed (the force kernel's hot path measured 4 % faster this way than with
    /// full 3x3 products).
    #[inline(always)]
    fn stress<L: Lane>(&self, f: LaneMat3<L>) -> LaneMat3<L> {
        let (a, b, c) = (f.c0, f.c1, f.c2);
        let one = L::splat(1.0);
        // 2 G: the diagonal, then the off-diagonal entries.
        let (g00, g11, g22) = (a.dot(a) - one, b.dot(b) - one, c.dot(c) - one);
        let (c01, c02, c12) = (a.dot(b), a.dot(c), b.dot(c));
        let mu = L::splat(self.lame.mu());
        let volumetric = L::splat(0.5 * self.lame.lambda()) * (g00 + g11 + g22);
        let (s00, s11, s22) = (
            mu * g00 + volumetric,
            mu * g11 + volumetric,
            mu * g22 + volumetric,
        );
        let (s01, s02, s12) = (mu * c01, mu * c02, mu * c12);
        LaneMat3 {
            c0: a.scale(s00) + b.scale(s01) + c.scale(s02),
            c1: a.scale(s01) + b.scale(s11) + c.scale(s12),
            c2: a.scale(s02) + b.scale(s12) + c.scale(s22),
        }
    }
}

impl Material for StVK {
    #[inline]
    fn deformation_limit(&self) -> Real {
        super::deformation_limit_for(self.lame.lambda().abs() + self.lame.mu(), 4)
    }

    #[inline]
    fn energy_density(&self, f: Mat3) -> Real {
        self.energy(LaneMat3::from(f))
    }

    #[inline]
    fn first_piola(&self, f: Mat3) -> Mat3 {
        self.stress(LaneMat3::from(f)).into()
    }

    #[inline]
    fn energy_and_first_piola(&self, f: Mat3) -> (Real, Mat3) {
        let f = LaneMat3::from(f);
        (self.energy(f), self.stress(f).into())
    }

    #[inline]
    fn first_piola_lanes(&self, f: LaneMat3<Lanes>) -> LaneMat3<Lanes> {
        self.stress(f)
    }

    #[inline]
    fn energy_and_first_piola_lanes(&self, f: LaneMat3<Lanes>) -> (Lanes, LaneMat3<Lanes>) {
        (self.energy(f), self.stress(f))
    }

    #[inline(always)]
    fn energy_density_wide<L: Lane>(&self, f: LaneMat3<L>) -> L {
        self.energy(f)
    }

    #[inline(always)]
    fn first_piola_wide<L: Lane>(&self, f: LaneMat3<L>) -> LaneMat3<L> {
        self.stress(f)
    }

    #[inline(always)]
    fn energy_and_first_piola_wide<L: Lane>(&self, f: LaneMat3<L>) -> (L, LaneMat3<L>) {
        (self.energy(f), self.stress(f))
    }

    #[inline]
    fn principal_energy(&self, s: Vec3) -> Real {
        let g = (s * s - Vec3::ONE) * 0.5;
        let trace = g.element_sum();
        0.5 * self.lame.lambda() * trace * trace + self.lame.mu() * g.length_squared()
    }

    #[inline]
    fn principal_stress(&self, s: Vec3) -> Vec3 {
        self.principal_stress_wide(LaneVec3::from(s)).into()
    }

    /// `dW/ds = s (lambda tr(G) + 2 mu g)` with `g = (s^2 - 1) / 2` per axis (the operations
    /// of glam's `Vec3` in their order, so one value and a group give the same bits).
    #[inline(always)]
    fn principal_stress_wide<L: Lane>(&self, s: LaneVec3<L>) -> LaneVec3<L> {
        let (one, half) = (L::splat(1.0), L::splat(0.5));
        let g = LaneVec3::new(
            (s.x * s.x - one) * half,
            (s.y * s.y - one) * half,
            (s.z * s.z - one) * half,
        );
        let volumetric = L::splat(self.lame.lambda()) * (g.x + g.y + g.z);
        let shear = L::splat(2.0 * self.lame.mu());
        LaneVec3::new(
            s.x * (volumetric + g.x * shear),
            s.y * (volumetric + g.y * shear),
            s.z * (volumetric + g.z * shear),
        )
    }

    principal_wide_methods!();

    /// `H = diag(c + 3 mu s_i^2) + lambda s s^T` with `c = lambda tr(G) - mu`, from
    /// `psi_i = c s_i + mu s_i^3`.
    #[inline]
    fn principal_hessian(&self, s: Vec3) -> Mat3 {
        let (lambda, mu) = (self.lame.lambda(), self.lame.mu());
        let c = lambda * ((s * s - Vec3::ONE) * 0.5).element_sum() - mu;
        let diagonal = Mat3::from_diagonal(Vec3::splat(c) + s * s * (3.0 * mu));
        diagonal + Mat3::from_cols(s * (lambda * s.x), s * (lambda * s.y), s * (lambda * s.z))
    }

    /// From `psi_i = c s_i + mu s_i^3`: flip `c + mu (s_i^2 + s_i s_j + s_j^2)`, twist
    /// `c + mu (s_i^2 - s_i s_j + s_j^2)`, polynomials exact at repeated stretches.
    #[inline]
    fn principal_pair_eigenvalues(&self, s: Vec3) -> [Vec3; 2] {
        let (lambda, mu) = (self.lame.lambda(), self.lame.mu());
        let c = lambda * ((s * s - Vec3::ONE) * 0.5).element_sum() - mu;
        // Pair k is the other two axes (i, j).
        let (si, sj) = (Vec3::new(s.y, s.x, s.x), Vec3::new(s.z, s.z, s.y));
        let squares = si * si + sj * sj;
        let product = si * sj;
        [
            Vec3::splat(c) + (squares + product) * mu,
            Vec3::splat(c) + (squares - product) * mu,
        ]
    }

    /// `dP = dF S + F dS` with `dS = 2 mu dG + lambda tr(dG) I`, `dG = (dF^T F + F^T dF) / 2`.
    #[inline]
    fn first_piola_differential(&self, f: Mat3, df: Mat3) -> Mat3 {
        let (lambda, mu) = (self.lame.lambda(), self.lame.mu());
        let green = (f.transpose() * f - Mat3::IDENTITY) * 0.5;
        let d_green = (df.transpose() * f + f.transpose() * df) * 0.5;
        let trace = |m: Mat3| m.x_axis.x + m.y_axis.y + m.z_axis.z;
        let stress = green * (2.0 * mu) + Mat3::from_diagonal(Vec3::splat(lambda * trace(green)));
        let d_stress =
            d_green * (2.0 * mu) + Mat3::from_diagonal(Vec3::splat(lambda * trace(d_green)));
        df * stress + f * d_stress
    }

    /// With `p = F g`: `P g = F S g`, `S g = mu (F^T p - g) + lambda / 2 (I_C - 3) g`, and
    /// `K = (g^T S g) I + mu |g|^2 F F^T + (lambda + mu) p p^T` from `dP = dF S + F dS` at
    /// `dF = u g^T`, where `g^T S g = mu (|p|^2 - |g|^2) + lambda / 2 (I_C - 3) |g|^2`
    /// (`2 G = F^T F - I`).
    #[inline]
    fn corner_stress_and_stiffness(&self, f: Mat3, g: Vec3) -> (Vec3, Mat3) {
        let (stress, stiffness) =
            self.corner_stress_and_stiffness_wide(LaneMat3::from(f), LaneVec3::from(g));
        (stress.into(), stiffness.into())
    }

    /// [`corner_stress_and_stiffness`](Material::corner_stress_and_stiffness) for one value or
    /// a group of lanes (the same operations).
    #[inline(always)]
    fn corner_stress_and_stiffness_wide<L: Lane>(
        &self,
        f: LaneMat3<L>,
        g: LaneVec3<L>,
    ) -> (LaneVec3<L>, LaneMat3<L>) {
        let (lambda, mu) = (self.lame.lambda(), self.lame.mu());
        let (a, b, c) = (f.c0, f.c1, f.c2);
        let one = L::splat(1.0);
        let p = f.mul_vec(g);
        let g2 = g.dot(g);
        let volumetric =
            L::splat(0.5 * lambda) * ((a.dot(a) - one) + (b.dot(b) - one) + (c.dot(c) - one));
        let mu_lanes = L::splat(mu);
        let s_g = (f.transpose().mul_vec(p) - g).scale(mu_lanes) + g.scale(volumetric);
        let diagonal = mu_lanes * (p.dot(p) - g2) + volumetric * g2;
        let (shear, volume) = (mu_lanes * g2, L::splat(lambda + mu));
        // K_xy = mu |g|^2 (F F^T)_xy + (lambda + mu) p_x p_y, (F F^T)_xy = a_x a_y + b_x b_y
        // + c_x c_y.
        let entry = |(ax, bx, cx, px): (L, L, L, L), (ay, by, cy, py): (L, L, L, L)| {
            shear * (ax * ay + bx * by + cx * cy) + volume * px * py
        };
        let (ex, ey, ez) = (
            (a.x, b.x, c.x, p.x),
            (a.y, b.y, c.y, p.y),
            (a.z, b.z, c.z, p.z),
        );
        let (dx, dy, dz) = (
            entry(ex, ex) + diagonal,
            entry(ey, ey) + diagonal,
            entry(ez, ez) + diagonal,
        );
        let (o01, o02, o12) = (entry(ex, ey), entry(ex, ez), entry(ey, ez));
        let k = LaneMat3 {
            c0: LaneVec3::new(dx, o01, o02),
            c1: LaneVec3::new(o01, dy, o12),
            c2: LaneVec3::new(o02, o12, dz),
        };
        (f.mul_vec(s_g), k)
    }
}
