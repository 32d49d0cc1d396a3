//! Validated Lamé parameters, the two numbers every model here is built from.

use super::{MaterialError, Real};

/// The Lamé parameters `(lambda, mu)` of an isotropic solid, in pascals, checked to describe a
/// stable material: `mu > 0`, bulk modulus `K = lambda + 2 mu / 3 > 0`, both finite.
///
/// Every model in this module linearises to isotropic linear elasticity with exactly these
/// parameters (`docs/math.md` section 2), so the same `Lame` gives the same small-strain behaviour
/// whichever model it builds.
///
/// ```
/// use softfem::material::Lame;
///
/// // Rubber-like: E = 1 MPa, nu = 0.45.
/// let lame = Lame::from_young_poisson(1.0e6, 0.45)?;
/// assert!((lame.mu() - 1.0e6 / 2.9).abs() < 1.0);
/// assert!((lame.lambda() - 0.45e6 / (1.45 * 0.1)).abs() < 10.0);
/// # Ok::<(), softfem::MaterialError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lame {
    lambda: Real,
    mu: Real,
}

impl Lame {
    /// Lamé parameters `lambda` and `mu` (both Pa).
    ///
    /// # Errors
    /// [`MaterialError::Lambda`] if `lambda` is not finite, [`MaterialError::Mu`] if `mu` is not
    /// finite and positive, [`MaterialError::BulkModulus`] if `K = lambda + 2 mu / 3` is not
    /// finite and positive. A negative `lambda` is valid as long as `K > 0` (auxetic materials,
    /// Poisson ratio below zero).
    #[inline]
    pub const fn new(lambda: Real, mu: Real) -> Result<Lame, MaterialError> {
        if !lambda.is_finite() {
            return Err(MaterialError::Lambda);
        }
        if !(mu > 0.0 && mu.is_finite()) {
            return Err(MaterialError::Mu);
        }
        let bulk = lambda + 2.0 * mu / 3.0;
        if !(bulk > 0.0 && bulk.is_finite()) {
            return Err(MaterialError::BulkModulus);
        }
        Ok(Lame { lambda, mu })
    }

    /// Lamé parameters from Young's modulus `e` (Pa) and Poisson ratio `nu` (dimensionless):
    /// `lambda = e nu / ((1 + nu)(1 - 2 nu))`, `mu = e / (2 (1 + nu))`.
    ///
    /// # Errors
    /// [`MaterialError::YoungModulus`] if `e` is not finite and positive,
    /// [`MaterialError::PoissonRatio`] if `nu` is not strictly between `-1` and `1/2`; then any
    /// error of [`Lame::new`], which can still occur when `nu` is so close to a bound that the
    /// converted values overflow or lose the sign of `K` to rounding.
    #[inline]
    pub const fn from_young_poisson(e: Real, nu: Real) -> Result<Lame, MaterialError> {
        if !(e > 0.0 && e.is_finite()) {
            return Err(MaterialError::YoungModulus);
        }
        if !(nu > -1.0 && nu < 0.5) {
            return Err(MaterialError::PoissonRatio);
        }
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let mu = e / (2.0 * (1.0 + nu));
        Lame::new(lambda, mu)
    }

    /// The first Lamé parameter `lambda` (Pa).
    #[inline]
    #[must_use]
    pub const fn lambda(&self) -> Real {
        self.lambda
    }

    /// The shear modulus `mu` (Pa), the second Lamé parameter.
    #[inline]
    #[must_use]
    pub const fn mu(&self) -> Real {
        self.mu
    }

    /// The bulk modulus `K = lambda + 2 mu / 3` (Pa), always positive.
    #[inline]
    #[must_use]
    pub const fn bulk_modulus(&self) -> Real {
        self.lambda + 2.0 * self.mu / 3.0
    }
}
