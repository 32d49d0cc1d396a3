//! Errors of softfem's constructors, shared by both precisions.
//!
//! The types here carry no floating-point values, so one definition serves the `f32` API at the
//! crate root and the `f64` API under [`softfem::f64`](mod@crate::f64) (both re-export them).

use core::fmt;

/// An elastic material was given parameters for which it is not a stable solid.
///
/// Returned by the `from_lame` and `from_young_poisson` constructors of every model in
/// [`material`](crate::material). Each variant names the parameter at fault; the valid ranges are
/// those of isotropic linear elasticity: shear modulus `mu > 0` and bulk modulus
/// `K = lambda + 2 mu / 3 > 0`, or equivalently Young's modulus `E > 0` and Poisson ratio
/// `-1 < nu < 1/2`. Every parameter must also be finite.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum MaterialError {
    /// The first Lamé parameter `lambda` (Pa) is NaN or infinite.
    Lambda,
    /// The shear modulus `mu` (Pa) is NaN, infinite, zero or negative.
    Mu,
    /// The bulk modulus `K = lambda + 2 mu / 3` (Pa) is not positive (`lambda <= -2 mu / 3`), or
    /// not finite: the material would not resist compression.
    BulkModulus,
    /// Young's modulus `E` (Pa) is NaN, infinite, zero or negative.
    YoungModulus,
    /// The Poisson ratio `nu` (dimensionless) is NaN or outside the open interval `(-1, 1/2)`.
    PoissonRatio,
}

impl fmt::Display for MaterialError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            MaterialError::Lambda => "the Lame parameter lambda must be finite",
            MaterialError::Mu => "the shear modulus mu must be finite and positive",
            MaterialError::BulkModulus => {
                "the bulk modulus lambda + 2 mu / 3 must be finite and positive"
            }
            MaterialError::YoungModulus => "Young's modulus must be finite and positive",
            MaterialError::PoissonRatio => "the Poisson ratio must lie strictly between -1 and 1/2",
        })
    }
}

impl core::error::Error for MaterialError {}
