//! Polar decomposition `a = rotation * stretch` from the rotation-variant SVD.
//!
//! With `a = u diag(sigma) v^T` from [`svd3`], the rotation is `u v^T` (always a
//! proper rotation, `det = +1`) and the stretch is the symmetric `v diag(sigma) v^T`. For an
//! inverted `a` (`det a < 0`) the stretch has one negative eigenvalue instead of the rotation
//! becoming a reflection: the convention co-rotational and principal-stretch elasticity needs.

use super::svd::{Svd3, svd3};
use super::types::Mat3;

/// The right polar decomposition `a = rotation * stretch`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Polar3 {
    /// A proper rotation (`rotation^T rotation = I`, `det = +1`).
    pub rotation: Mat3,
    /// The symmetric right stretch `v diag(sigma) v^T`; indefinite when `det a < 0`.
    pub stretch: Mat3,
}

impl Polar3 {
    /// The polar decomposition carried by an existing SVD (no further factorisation).
    #[inline]
    #[must_use]
    pub fn from_svd(svd: &Svd3) -> Polar3 {
        let v_t = svd.v.transpose();
        Polar3 {
            rotation: svd.u * v_t,
            stretch: svd.v * Mat3::from_diagonal(svd.sigma) * v_t,
        }
    }
}

/// The right polar decomposition of `a` (via [`svd3`]).
///
/// Never panics. A non-finite `a` gives a NaN stretch and the identity rotation; the zero matrix
/// gives the identity rotation and a zero stretch.
///
/// ```
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::polar::polar3;
///
/// // A 90-degree turn about z after stretching x by 3.
/// let rotation = Mat3::from_rotation_z(core::f32::consts::FRAC_PI_2);
/// let stretch = Mat3::from_diagonal(Vec3::new(3.0, 1.0, 1.0));
/// let polar = polar3(rotation * stretch);
/// assert!(polar.rotation.abs_diff_eq(rotation, 1e-6));
/// assert!(polar.stretch.abs_diff_eq(stretch, 1e-5));
/// ```
#[inline]
#[must_use]
pub fn polar3(a: Mat3) -> Polar3 {
    Polar3::from_svd(&svd3(a))
}
