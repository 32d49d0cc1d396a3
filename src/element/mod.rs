//! Per-element kinematics and forces (`docs/math.md` section 1): rest data, deformation gradient,
//! nodal forces and energy of one tetrahedron or triangle.
//!
//! # Conventions
//! * Positions are in metres. `Dm` (rest) and `Ds` (deformed) hold the edge vectors
//!   `X1-X0, X2-X0[, X3-X0]` as columns; the deformation gradient is `F = Ds Dm^-1`
//!   (dimensionless).
//! * A tetrahedron of rest volume `V` (m^3) with first Piola–Kirchhoff stress `P` (Pa) receives the
//!   nodal forces `[f1 f2 f3] = -V P Dm^-T`, `f0 = -(f1 + f2 + f3)` (N), and stores the energy
//!   `V W(F)` (J). Triangles do the same with the area `A` and 2-column matrices.
//! * A tetrahedron is positively oriented when `det Dm > 0`, i.e. `X3` lies on the side of the
//!   triangle `X0 X1 X2` its counter-clockwise normal points to. 2D triangles are positive when
//!   counter-clockwise. [`fix_orientation`] reorders a negative tetrahedron.
//! * Rest data is validated once ([`TetRest::new`], [`TriRest::new`], [`TriRest::membrane`]):
//!   after that, every function here is branch-free straight-line arithmetic that never panics;
//!   NaN or infinite deformed positions give NaN or infinite results.
//!
//! ```
//! use softfem::element::TetRest;
//! use softfem::glam::{Mat3, Vec3};
//! use softfem::material::{Material, StableNeoHookean};
//!
//! let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
//! let tet = TetRest::new(rest)?;
//! assert!((tet.volume - 1.0 / 6.0).abs() < 1e-7);
//! // Stretch by 10% along x.
//! let stretch = Mat3::from_diagonal(Vec3::new(1.1, 1.0, 1.0));
//! let deformed = rest.map(|x| stretch * x);
//! assert!(tet.deformation_gradient(deformed).abs_diff_eq(stretch, 1e-6));
//! let rubber = StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap();
//! let forces = tet.elastic_forces(&rubber, deformed);
//! // The stretched vertex is pulled back, and the forces balance.
//! assert!(forces[1].x < 0.0);
//! assert!(forces.iter().sum::<Vec3>().length() < 1e-2);
//! # Ok::<(), softfem::ElementError>(())
//! ```

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

use super::types::{Real, Vec2, Vec3};
use crate::error::ElementError;

mod hessian;
mod tet;
mod triangle;
mod triangle_hessian;

pub(crate) use hessian::ENTRIES as HESSIAN_ENTRIES;
pub use hessian::{TetHessian, tet_vertex_force_and_block};
pub use tet::{TetRest, fix_orientation};
pub use triangle::{TriRest, TriangleStVK};
pub use triangle_hessian::{MembraneHessian, SymmetricMatrix, TriHessian};

/// The smallest accepted rest volume of a tetrahedron relative to the cube of its longest edge
/// (and rest area of a triangle relative to the square of its longest edge):
/// `64 * Real::EPSILON`, about `7.6e-6` in f32 and `1.4e-14` in f64.
///
/// Why this value: the volume `det(Dm)/6` is a sum of six products of three edge components, each
/// bounded by `L^3` (`L` the longest edge), so its rounding error is a few `eps L^3`. Above
/// `64 eps L^3` the computed volume has the right sign and is accurate to a few percent; below
/// it, it is mostly rounding, and so are `Dm^-1` and every force. (A regular tetrahedron has
/// `V = 0.118 L^3`; anything near this bound is a sliver whose stiffness would also force a
/// tiny explicit time step.) Positions far from the origin relative to the element size lose
/// digits in `X_i - X_0` before this test: keep coordinates local to the body.
pub const DEGENERACY_RATIO: Real = 64.0 * Real::EPSILON;

/// Classifies a signed rest measure (volume or area) against `scale` (longest edge cubed or
/// squared): degenerate if it is not finite or `|measure| <= DEGENERACY_RATIO * scale`
/// (including an overflowed `scale`), inverted if negative.
fn check_measure(measure: Real, scale: Real) -> Result<(), ElementError> {
    // A comparison with NaN is false, so a NaN measure or scale lands in the degenerate branch.
    let resolved = measure.is_finite() && measure.abs() > DEGENERACY_RATIO * scale;
    if !resolved {
        Err(ElementError::Degenerate)
    } else if measure < 0.0 {
        Err(ElementError::Inverted)
    } else {
        Ok(())
    }
}

mod sealed {
    /// Implemented by `Vec2` and `Vec3` only; carries the per-vertex lane arithmetic of the
    /// steppers (`lanes/point.rs`).
    pub trait Sealed: super::super::lanes::point::Grouped {}
    impl Sealed for super::Vec2 {}
    impl Sealed for super::Vec3 {}
}

/// The position types the crate is written once for: `Vec2` (2D solids) and `Vec3` (solids and
/// membranes); a triangle's columns, a mesh's positions and forces, a stepper's state. Sealed.
pub trait Vector:
    Copy
    + Default
    + Debug
    + PartialEq
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Real, Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + Send
    + Sync
    + sealed::Sealed
{
    /// The zero vector.
    const ZERO: Self;
    /// The dot product.
    fn dot(self, other: Self) -> Real;
    /// Whether every coordinate is finite.
    fn is_finite(self) -> bool;
}

impl Vector for Vec2 {
    const ZERO: Self = Vec2::ZERO;
    #[inline(always)]
    fn dot(self, other: Self) -> Real {
        Vec2::dot(self, other)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        Vec2::is_finite(self)
    }
}

impl Vector for Vec3 {
    const ZERO: Self = Vec3::ZERO;
    #[inline(always)]
    fn dot(self, other: Self) -> Real {
        Vec3::dot(self, other)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        Vec3::is_finite(self)
    }
}
