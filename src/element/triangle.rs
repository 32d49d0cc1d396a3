//! Linear triangles: 2D solids (positions in the plane) and membranes (positions in space),
//! with the Saint Venant–Kirchhoff model (`docs/math.md` section 1).
//!
//! The kinematics are written once over the column type (`Vec2` or `Vec3`): a 2D solid's `F`
//! is 2x2, a membrane's is 3x2 (two `Vec3` columns), and both give the same 2x2 Green strain.

use super::super::material::StVK;
use super::super::math;
use super::super::types::{Mat2, Real, Vec2, Vec3};
use super::{Vector, check_measure};
use crate::error::ElementError;

/// The precomputed rest data of a triangle, for a 2D solid ([`TriRest::new`]) or a membrane in
/// 3D ([`TriRest::membrane`]).
///
/// `Default` (zero) exists only to size buffers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TriRest {
    /// `Dm^-1` (m^-1), the inverse of the 2x2 rest edge matrix `Dm = [X1-X0, X2-X0]` (for a
    /// membrane, expressed in an orthonormal frame of the triangle's own plane whose first axis
    /// is `X1-X0`).
    pub dm_inv: Mat2,
    /// The rest area `A = det(Dm) / 2` (m^2), positive.
    pub area: Real,
}

impl TriRest {
    /// The rest data of a 2D triangle with rest positions `x` (m), counter-clockwise.
    ///
    /// # Errors
    /// [`ElementError::NonFiniteRestPosition`] if a coordinate is NaN or infinite;
    /// [`ElementError::Inverted`] if clockwise (`det Dm < 0`); [`ElementError::Degenerate`] if
    /// `|A| <= DEGENERACY_RATIO * L^2` with `L` the longest edge (see
    /// [`DEGENERACY_RATIO`](super::DEGENERACY_RATIO)).
    pub fn new(x: [Vec2; 3]) -> Result<TriRest, ElementError> {
        if !x.iter().all(|p| p.is_finite()) {
            return Err(ElementError::NonFiniteRestPosition);
        }
        let [x0, x1, x2] = x;
        let dm = Mat2::from_cols(x1 - x0, x2 - x0);
        Self::from_edge_matrix(dm, dm.determinant() / 2.0, longest_squared([x0, x1, x2]))
    }

    /// The rest data of a membrane triangle with rest positions `x` (m) in space. The rest
    /// shape is measured in the triangle's own plane, so a membrane has no orientation at rest
    /// and is never inverted (its normal is `(X1-X0) x (X2-X0)`).
    ///
    /// # Errors
    /// [`ElementError::NonFiniteRestPosition`] if a coordinate is NaN or infinite;
    /// [`ElementError::Degenerate`] if `A <= DEGENERACY_RATIO * L^2` (collinear or coincident
    /// vertices).
    pub fn membrane(x: [Vec3; 3]) -> Result<TriRest, ElementError> {
        if !x.iter().all(|p| p.is_finite()) {
            return Err(ElementError::NonFiniteRestPosition);
        }
        let [x0, x1, x2] = x;
        let (e1, e2) = (x1 - x0, x2 - x0);
        let normal = e1.cross(e2);
        let normal_length = math::sqrt(normal.length_squared());
        let e1_length = math::sqrt(e1.length_squared());
        // The in-plane frame: t along e1, b = n x t, so e2 has a positive b component and
        // det Dm = |e1| (e2 . b) = |n| > 0.
        let t = e1 / e1_length;
        let b = normal.cross(e1) / (normal_length * e1_length);
        let dm = Mat2::from_cols(Vec2::new(e1_length, 0.0), Vec2::new(e2.dot(t), e2.dot(b)));
        let longest = longest_squared([x0, x1, x2]);
        // The area from |n| rather than det Dm: it does not depend on the frame's rounding.
        Self::from_edge_matrix(dm, normal_length / 2.0, longest)
    }

    fn from_edge_matrix(dm: Mat2, area: Real, longest_squared: Real) -> Result<Self, ElementError> {
        check_measure(area, longest_squared)?;
        let dm_inv = dm.inverse();
        if !dm_inv.is_finite() {
            return Err(ElementError::Degenerate);
        }
        Ok(TriRest { dm_inv, area })
    }

    /// The deformation gradient `F = Ds Dm^-1` (2x2, dimensionless) of a 2D triangle at
    /// deformed positions `x` (m).
    #[inline]
    #[must_use]
    pub fn deformation_gradient(&self, x: [Vec2; 3]) -> Mat2 {
        let [c0, c1] = self.gradient(x);
        Mat2::from_cols(c0, c1)
    }

    /// The deformation gradient `F = Ds Dm^-1` (3x2, dimensionless, as its two columns) of a
    /// membrane at deformed positions `x` (m).
    #[inline]
    #[must_use]
    pub fn membrane_deformation_gradient(&self, x: [Vec3; 3]) -> [Vec3; 2] {
        self.gradient(x)
    }

    /// The nodal forces of a 2D triangle with first Piola–Kirchhoff stress `p` (2x2):
    /// `[f1 f2] = -A P Dm^-T`, `f0 = -(f1 + f2)`. Units: `A P` is N/m when `p` is in Pa (force
    /// per unit thickness); see [`TriangleStVK`].
    #[inline]
    #[must_use]
    pub fn nodal_forces(&self, p: Mat2) -> [Vec2; 3] {
        self.forces([p.x_axis, p.y_axis])
    }

    /// The nodal forces of a membrane with first Piola–Kirchhoff stress `p` (3x2, as its two
    /// columns): `[f1 f2] = -A P Dm^-T`, `f0 = -(f1 + f2)`.
    #[inline]
    #[must_use]
    pub fn membrane_nodal_forces(&self, p: [Vec3; 2]) -> [Vec3; 3] {
        self.forces(p)
    }

    /// The elastic nodal forces of a 2D triangle at deformed positions `x` (m).
    #[inline]
    #[must_use]
    pub fn elastic_forces(&self, material: &TriangleStVK, x: [Vec2; 3]) -> [Vec2; 3] {
        self.forces(material.piola(self.gradient(x)))
    }

    /// The elastic nodal forces of a membrane at deformed positions `x` (m).
    #[inline]
    #[must_use]
    pub fn membrane_elastic_forces(&self, material: &TriangleStVK, x: [Vec3; 3]) -> [Vec3; 3] {
        self.forces(material.piola(self.gradient(x)))
    }

    /// The elastic energy `A W(F)` of a 2D triangle at deformed positions `x` (m).
    #[inline]
    #[must_use]
    pub fn elastic_energy(&self, material: &TriangleStVK, x: [Vec2; 3]) -> Real {
        self.area * material.energy(self.gradient(x))
    }

    /// The elastic energy `A W(F)` of a membrane at deformed positions `x` (m).
    #[inline]
    #[must_use]
    pub fn membrane_elastic_energy(&self, material: &TriangleStVK, x: [Vec3; 3]) -> Real {
        self.area * material.energy(self.gradient(x))
    }

    /// `F = Ds Dm^-1` as columns: column `j` is `sum_k (x_{k+1} - x0) (Dm^-1)_{kj}`.
    #[inline(always)]
    pub(crate) fn gradient<V: Vector>(&self, [x0, x1, x2]: [V; 3]) -> [V; 2] {
        let (d1, d2) = (x1 - x0, x2 - x0);
        let m = self.dm_inv;
        [
            d1 * m.x_axis.x + d2 * m.x_axis.y,
            d1 * m.y_axis.x + d2 * m.y_axis.y,
        ]
    }

    /// `[f1 f2] = -A P Dm^-T`: `f_{j+1} = -A sum_k P_k (Dm^-1)_{jk}`.
    #[inline(always)]
    pub(crate) fn forces<V: Vector>(&self, [p0, p1]: [V; 2]) -> [V; 3] {
        let m = self.dm_inv;
        let f1 = (p0 * m.x_axis.x + p1 * m.y_axis.x) * -self.area;
        let f2 = (p0 * m.x_axis.y + p1 * m.y_axis.y) * -self.area;
        [-(f1 + f2), f1, f2]
    }
}

/// The square of the longest edge of a triangle.
fn longest_squared<V: Vector>([x0, x1, x2]: [V; 3]) -> Real {
    [x1 - x0, x2 - x0, x2 - x1]
        .iter()
        .map(|e| e.dot(*e))
        .fold(0.0, Real::max)
}

/// Saint Venant–Kirchhoff on triangles (`docs/math.md` section 1): with the 2x2 Green strain
/// `G = (F^T F - I)/2`, `W = lambda/2 tr(G)^2 + mu tr(G^2)`, `S = 2 mu G + lambda tr(G) I` and
/// `P = F S`, for 2D solids (`F` 2x2) and membranes (`F` 3x2).
///
/// The only model for triangles: the other models of [`material`](super::super::material) are
/// three-dimensional and out of scope here.
///
/// # Units
/// The Lamé parameters are taken as they are from [`StVK`]. With moduli in Pa, `W` is in
/// J/m^3 and a triangle's energy `A W` and forces are **per unit thickness** (J/m, N/m): this is
/// plane strain for a 2D solid. For a membrane (or a 2D sheet) of thickness `t`, either
/// multiply energies and forces by `t`, or build the [`StVK`] with `t lambda` and `t mu` (N/m) so
/// that energies come out in J and forces in N.
///
/// ```
/// use softfem::element::{TriRest, TriangleStVK};
/// use softfem::glam::Vec2;
/// use softfem::material::StVK;
///
/// let stvk = TriangleStVK::new(&StVK::from_lame(1.0e5, 1.0e5)?);
/// let rest = [Vec2::ZERO, Vec2::X, Vec2::Y];
/// let tri = TriRest::new(rest)?;
/// let stretched = rest.map(|x| x * Vec2::new(1.2, 1.0));
/// let f = tri.elastic_forces(&stvk, stretched);
/// assert!(f[1].x < 0.0 && tri.elastic_energy(&stvk, stretched) > 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleStVK {
    lambda: Real,
    mu: Real,
}

impl TriangleStVK {
    /// The triangle model with the Lamé parameters of `stvk`.
    #[inline]
    #[must_use]
    pub fn new(stvk: &StVK) -> TriangleStVK {
        TriangleStVK {
            lambda: stvk.lambda(),
            mu: stvk.mu(),
        }
    }

    /// The energy density `W` (J/m^3) of a 2D deformation gradient `f`.
    #[inline]
    #[must_use]
    pub fn energy_density(&self, f: Mat2) -> Real {
        self.energy([f.x_axis, f.y_axis])
    }

    /// The first Piola–Kirchhoff stress `P = F S` (Pa) of a 2D deformation gradient `f`.
    #[inline]
    #[must_use]
    pub fn first_piola(&self, f: Mat2) -> Mat2 {
        let [p0, p1] = self.piola([f.x_axis, f.y_axis]);
        Mat2::from_cols(p0, p1)
    }

    /// The energy density `W` (J/m^3) of a membrane deformation gradient `f` (3x2, columns).
    #[inline]
    #[must_use]
    pub fn membrane_energy_density(&self, f: [Vec3; 2]) -> Real {
        self.energy(f)
    }

    /// The first Piola–Kirchhoff stress `P = F S` (Pa, 3x2 as columns) of a membrane
    /// deformation gradient `f` (3x2, columns).
    #[inline]
    #[must_use]
    pub fn membrane_first_piola(&self, f: [Vec3; 2]) -> [Vec3; 2] {
        self.piola(f)
    }

    /// The Lamé parameters `(lambda, mu)` (Pa), for the second derivatives
    /// (`triangle_hessian.rs`).
    #[inline(always)]
    pub(crate) fn lame(&self) -> (Real, Real) {
        (self.lambda, self.mu)
    }

    /// The Green strain `(g00, g01, g11)` of `F^T F` built from the columns of `f`.
    #[inline(always)]
    fn green<V: Vector>([c0, c1]: [V; 2]) -> (Real, Real, Real) {
        (
            0.5 * (c0.dot(c0) - 1.0),
            0.5 * c0.dot(c1),
            0.5 * (c1.dot(c1) - 1.0),
        )
    }

    #[inline(always)]
    pub(crate) fn energy<V: Vector>(&self, f: [V; 2]) -> Real {
        let (g00, g01, g11) = Self::green(f);
        let trace = g00 + g11;
        0.5 * self.lambda * trace * trace + self.mu * (g00 * g00 + 2.0 * g01 * g01 + g11 * g11)
    }

    #[inline(always)]
    pub(crate) fn piola<V: Vector>(&self, f: [V; 2]) -> [V; 2] {
        let (g00, g01, g11) = Self::green(f);
        let volumetric = self.lambda * (g00 + g11);
        let two_mu = 2.0 * self.mu;
        let (s00, s01, s11) = (
            two_mu * g00 + volumetric,
            two_mu * g01,
            two_mu * g11 + volumetric,
        );
        let [c0, c1] = f;
        [c0 * s00 + c1 * s01, c0 * s01 + c1 * s11]
    }
}

impl From<&StVK> for TriangleStVK {
    #[inline]
    fn from(stvk: &StVK) -> TriangleStVK {
        TriangleStVK::new(stvk)
    }
}
