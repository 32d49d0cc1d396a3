//! Linear tetrahedra.

use super::super::material::Material;
use super::super::math;
use super::super::types::{Mat3, Real, Vec3};
use super::check_measure;
use crate::error::ElementError;

/// The precomputed rest data of a tetrahedron: everything the force kernel needs from the rest
/// shape.
///
/// Built and validated by [`TetRest::new`]; `Default` (zero) exists only to size buffers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TetRest {
    /// `Dm^-1` (m^-1), the inverse of the rest edge matrix `Dm = [X1-X0, X2-X0, X3-X0]`.
    pub dm_inv: Mat3,
    /// The rest volume `V = det(Dm) / 6` (m^3), positive.
    pub volume: Real,
}

impl TetRest {
    /// `Dm^-1 = 0` and zero volume, as `Default`: only a buffer's initial value, never the rest
    /// data of a valid element.
    pub const ZERO: TetRest = TetRest {
        dm_inv: Mat3::ZERO,
        volume: 0.0,
    };

    /// The rest data of the tetrahedron with rest positions `x` (m).
    ///
    /// # Errors
    /// [`ElementError::NonFiniteRestPosition`] if a coordinate is NaN or infinite;
    /// [`ElementError::Inverted`] if `det Dm < 0` (see [`fix_orientation`]);
    /// [`ElementError::Degenerate`] if `|V| <= DEGENERACY_RATIO * L^3` with `L` the longest
    /// edge (see [`DEGENERACY_RATIO`](super::DEGENERACY_RATIO)), or if `V` or `Dm^-1` is not
    /// representable.
    pub fn new(x: [Vec3; 4]) -> Result<TetRest, ElementError> {
        if !x.iter().all(|p| p.is_finite()) {
            return Err(ElementError::NonFiniteRestPosition);
        }
        let [x0, x1, x2, x3] = x;
        let dm = edge_matrix(x);
        let volume = dm.determinant() / 6.0;
        let longest_squared = [x1 - x0, x2 - x0, x3 - x0, x2 - x1, x3 - x1, x3 - x2]
            .iter()
            .map(|e| e.length_squared())
            .fold(0.0, Real::max);
        check_measure(volume, longest_squared * math::sqrt(longest_squared))?;
        let dm_inv = dm.inverse();
        if !dm_inv.is_finite() {
            return Err(ElementError::Degenerate);
        }
        Ok(TetRest { dm_inv, volume })
    }

    /// The deformation gradient `F = Ds Dm^-1` (dimensionless) at deformed positions `x` (m).
    #[inline]
    #[must_use]
    pub fn deformation_gradient(&self, x: [Vec3; 4]) -> Mat3 {
        edge_matrix(x) * self.dm_inv
    }

    /// The nodal forces (N) of first Piola–Kirchhoff stress `p` (Pa):
    /// `[f1 f2 f3] = -V P Dm^-T`, `f0 = -(f1 + f2 + f3)`. They sum to zero exactly (up to
    /// rounding) and, when `p` is the stress of an isotropic material at this element's `F`,
    /// exert no net torque.
    #[inline]
    #[must_use]
    pub fn nodal_forces(&self, p: Mat3) -> [Vec3; 4] {
        let h = (p * -self.volume) * self.dm_inv.transpose();
        [
            -(h.x_axis + h.y_axis + h.z_axis),
            h.x_axis,
            h.y_axis,
            h.z_axis,
        ]
    }

    /// The elastic nodal forces (N) of `material` at deformed positions `x` (m), through the
    /// direct stress [`Material::first_piola`].
    #[inline]
    #[must_use]
    pub fn elastic_forces<M: Material>(&self, material: &M, x: [Vec3; 4]) -> [Vec3; 4] {
        self.nodal_forces(material.first_piola(self.deformation_gradient(x)))
    }

    /// The elastic energy `V W(F)` (J) of `material` at deformed positions `x` (m).
    #[inline]
    #[must_use]
    pub fn elastic_energy<M: Material>(&self, material: &M, x: [Vec3; 4]) -> Real {
        self.volume * material.energy_density(self.deformation_gradient(x))
    }
}

/// `[x1-x0, x2-x0, x3-x0]` as columns.
#[inline(always)]
fn edge_matrix([x0, x1, x2, x3]: [Vec3; 4]) -> Mat3 {
    Mat3::from_cols(x1 - x0, x2 - x0, x3 - x0)
}

/// The tetrahedron `tet` (vertex indices) with its corners ordered so that its rest volume is
/// not negative: corners 1 and 2 are swapped when `det Dm < 0` for the rest positions `x` of
/// its corners (in the order of `tet`). Degenerate tetrahedra are returned unchanged (and are
/// still rejected by [`TetRest::new`]).
///
/// ```
/// use softfem::element::{TetRest, fix_orientation};
/// use softfem::glam::Vec3;
///
/// let x = [Vec3::ZERO, Vec3::Y, Vec3::X, Vec3::Z]; // left-handed: negative volume
/// assert!(TetRest::new(x).is_err());
/// assert_eq!(fix_orientation([7, 8, 9, 10], x), [7, 9, 8, 10]);
/// ```
#[inline]
#[must_use]
pub fn fix_orientation(tet: [u32; 4], x: [Vec3; 4]) -> [u32; 4] {
    let [a, b, c, d] = tet;
    if edge_matrix(x).determinant() < 0.0 {
        [a, c, b, d]
    } else {
        tet
    }
}
