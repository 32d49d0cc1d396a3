//! The per-vertex Newton system of a Vertex Block Descent update: the shape gradient of a
//! corner, and the SPD factor of a vertex's accumulated 3x3 block.
//!
//! Per element and corner the sweep takes the force `-V P g` and the exact diagonal block
//! `V K(g)` of [`Material::corner_stress_and_stiffness`]: closed forms in the invariants
//! (no SVD, some 60 operations on top of the stress). The exact blocks are summed per vertex
//! with the inertia `m / h^2 I`, and only that sum is made positive definite (the approach of
//! Chen et al., "Vertex Block Descent", TOG 2024, which use the local Hessian as is and guard
//! its definiteness): [`VertexFactor::new`] factors it by `L D L^T` (Cholesky without square
//! roots) where it is positive definite, which it is for
//! [`StableNeoHookean`](super::super::super::super::material::StableNeoHookean) always (every
//! element term is, see below) and for the other models unless elements are strongly compressed
//! with little inertia; otherwise it factors `m / h^2 I + (sum_e V_e K_e)+`, the positive
//! semi-definite part of the elastic sum from its eigen-decomposition (one 3x3 symmetric SVD for
//! that vertex, not one per element), with the Levenberg–Marquardt shift of [`Ldlt::regularised`]
//! where even that is singular. Either way the factored matrix `H` is symmetric positive definite,
//! so `d = -H^-1 grad` satisfies `grad . d = -grad^T H^-1 grad < 0`: a descent direction of the
//! vertex's local energy, and with the line search every accepted update lowers `Phi`.
//!
//! Why the exact block is mostly definite already: for `W(I_C, J)` the block is
//! `2 W_I |g|^2 I + [p q] [[4 W_II, 2 W_IJ], [2 W_IJ, W_JJ]] [p q]^T` (`p = F g`,
//! `q = cof(F) g`), the indefinite `W_J d^2 J / dF^2` part of the full Hessian vanishing on one
//! corner. Stable neo-Hookean has `W_I > 0`, `W_II > 0`, `W_IJ = 0`, `W_JJ > 0`: every element
//! term is positive definite. Neo-Hookean's `W_IJ < 0` and StVK's `g^T S g < 0` under
//! compression can make a term indefinite; the inertia and the other elements usually
//! outweigh it.

use super::super::super::super::element::TetRest;
use super::super::super::super::lanes::{Lane, LaneVec3};
use super::super::super::super::svd::svd3;
use super::super::super::super::types::{Mat3, Real, Vec3};

/// The gradient `g_a` (m^-1) of corner `a`'s shape function: row `a - 1` of `Dm^-1` for
/// `a = 1, 2, 3`, minus their sum for `a = 0` (zero out of range).
#[inline(always)]
pub(crate) fn shape_gradient(rest: &TetRest, corner: usize) -> Vec3 {
    // A match on the corner, not an index into an array of rows: the array would go through
    // the stack, and loading a row written there a moment ago stalls the sweep's gather.
    let m = &rest.dm_inv;
    let (r0, r1, r2) = (m.row(0), m.row(1), m.row(2));
    match corner {
        0 => -(r0 + r1 + r2),
        1 => r0,
        2 => r1,
        3 => r2,
        _ => Vec3::ZERO,
    }
}

/// The positive semi-definite part of the symmetric `s`: `(s + |s|) / 2` with
/// `|s| = B diag(sigma) B^T` from the SVD `s = A diag(sigma) B^T` (for a symmetric matrix the
/// right singular vectors are its eigenvectors and the singular values the moduli of its
/// eigenvalues). NaN propagates.
fn positive_part(s: Mat3) -> Mat3 {
    let svd = svd3(s);
    let modulus = svd.v * Mat3::from_diagonal(svd.sigma.abs()) * svd.v.transpose();
    let half = (s + modulus) * 0.5;
    (half + half.transpose()) * 0.5
}

/// A pivot of the `L D L^T` factorisation must exceed this times the block's trace.
pub(crate) const PIVOT_FLOOR: Real = 64.0 * Real::EPSILON;

/// `sqrt(eps)`: the relative Levenberg–Marquardt shift of [`Ldlt::regularised`].
const SHIFT: Real = 1.0 / (1u64 << (Real::MANTISSA_DIGITS / 2)) as Real;

/// The square-root-free Cholesky factorisation `H = L D L^T` of a symmetric 3x3 matrix (`L`
/// unit lower triangular, `D` diagonal; Golub and Van Loan, "Matrix Computations", 4th ed.,
/// section 4.1.2), kept as the three sub-diagonal entries of `L` and the reciprocals of the
/// pivots `D`.
///
/// The pivots are those of the Cholesky factorisation squared (`d_k = l_kk^2`), so the
/// definiteness test "every pivot above the floor" is the same; the factor costs three
/// divisions (one per pivot, one after the other) and no square root, and a solve is
/// multiplications only, where the Cholesky factor took three square roots and two divisions,
/// and six divisions per solve.
pub(crate) struct Ldlt {
    l10: Real,
    l20: Real,
    l21: Real,
    /// `1 / d_0`, `1 / d_1`, `1 / d_2`.
    inverse_pivots: Vec3,
}

impl Ldlt {
    /// The factor of `h` (its lower triangle is read), if every pivot exceeds `floor`.
    #[inline]
    fn new(h: &Mat3, floor: Real) -> Option<Ldlt> {
        let (a00, a10, a20) = (h.x_axis.x, h.x_axis.y, h.x_axis.z);
        let (a11, a21, a22) = (h.y_axis.y, h.y_axis.z, h.z_axis.z);
        let pivot = |d: Real| (d > floor).then(|| 1.0 / d);
        let i0 = pivot(a00)?;
        let (l10, l20) = (a10 * i0, a20 * i0);
        let i1 = pivot(a11 - l10 * a10)?;
        // `d_1 l_21`, the (2, 1) entry of the first elimination step.
        let e21 = a21 - l20 * a10;
        let l21 = e21 * i1;
        let i2 = pivot(a22 - l20 * a20 - l21 * e21)?;
        Some(Ldlt {
            l10,
            l20,
            l21,
            inverse_pivots: Vec3::new(i0, i1, i2),
        })
    }

    /// The factor of `h`, or of `h + sqrt(eps) tr(h) / 3 I` if `h` has a pivot at or below
    /// `64 eps tr(h)`; `None` if that fails too, or `tr(h)` is not finite and positive.
    #[inline]
    pub(crate) fn regularised(h: &Mat3) -> Option<Ldlt> {
        let trace = h.x_axis.x + h.y_axis.y + h.z_axis.z;
        if !(trace > 0.0 && trace.is_finite()) {
            return None;
        }
        let floor = PIVOT_FLOOR * trace;
        Ldlt::new(h, floor).or_else(|| {
            let shift = Mat3::from_diagonal(Vec3::splat(SHIFT * trace / 3.0));
            Ldlt::new(&(*h + shift), floor)
        })
    }

    /// `H^-1 r`: forward substitution with `L`, the pivots, back substitution with `L^T`.
    #[inline]
    pub(crate) fn solve(&self, r: Vec3) -> Vec3 {
        let z1 = r.y - self.l10 * r.x;
        let z2 = r.z - self.l20 * r.x - self.l21 * z1;
        let y = Vec3::new(r.x, z1, z2) * self.inverse_pivots;
        let x2 = y.z;
        let x1 = y.y - self.l21 * x2;
        let x0 = y.x - self.l10 * x1 - self.l20 * x2;
        Vec3::new(x0, x1, x2)
    }
}

/// [`Ldlt`] of one symmetric matrix per lane: the operations of [`Ldlt::new`] in its order, so
/// every lane that factors holds the bits of the one-matrix factor (the vertex updates of a
/// sweep's lane group, `step/descent/vbd/lanes.rs`). A lane whose pivot is at or below the floor is
/// flagged, its values meaningless (all three divisions run in every lane).
pub(crate) struct LaneLdlt<L> {
    l10: L,
    l20: L,
    l21: L,
    /// `1 / d_0`, `1 / d_1`, `1 / d_2`.
    inverse_pivots: LaneVec3<L>,
}

impl<L: Lane> LaneLdlt<L> {
    /// The factor of the matrices whose lower triangles are
    /// `[a00, a10, a20, a11, a21, a22]`, and 1 in the lanes where every pivot exceeds `floor`
    /// (where [`Ldlt::new`] gives `Some`), 0 in the others.
    #[inline(always)]
    pub(crate) fn new([a00, a10, a20, a11, a21, a22]: [L; 6], floor: L) -> (Self, L) {
        let (one, zero) = (L::splat(1.0), L::splat(0.0));
        let i0 = one / a00;
        let (l10, l20) = (a10 * i0, a20 * i0);
        let d1 = a11 - l10 * a10;
        let i1 = one / d1;
        let e21 = a21 - l20 * a10;
        let l21 = e21 * i1;
        let d2 = a22 - l20 * a20 - l21 * e21;
        let i2 = one / d2;
        let factored = L::select(a00.gt(floor), one, zero);
        let factored = L::select(d1.gt(floor), factored, zero);
        let factored = L::select(d2.gt(floor), factored, zero);
        let factor = LaneLdlt {
            l10,
            l20,
            l21,
            inverse_pivots: LaneVec3::new(i0, i1, i2),
        };
        (factor, factored)
    }

    /// `H^-1 r` per lane, as [`Ldlt::solve`].
    #[inline(always)]
    pub(crate) fn solve(&self, r: LaneVec3<L>) -> LaneVec3<L> {
        let z1 = r.y - self.l10 * r.x;
        let z2 = r.z - self.l20 * r.x - self.l21 * z1;
        let p = self.inverse_pivots;
        let (y0, y1, y2) = (r.x * p.x, z1 * p.y, z2 * p.z);
        let x2 = y2;
        let x1 = y1 - self.l21 * x2;
        let x0 = y0 - self.l10 * x1 - self.l20 * x2;
        LaneVec3::new(x0, x1, x2)
    }
}

/// The SPD system of one vertex update, see the [module documentation](self).
pub(crate) struct VertexFactor {
    /// The factor of the matrix solved with.
    pub(crate) factor: Ldlt,
    /// Whether the elastic sum had to be replaced by its positive part.
    pub(crate) projected: bool,
}

impl VertexFactor {
    /// The factor of `inertia I + elastic` where that is positive definite (pivots above
    /// `64 eps` of the trace), else of `inertia I + elastic+` (regularised where singular);
    /// `None` where even that fails (a vertex in no element without inertia, or NaN).
    #[inline]
    pub(crate) fn new(inertia: Real, elastic: &Mat3) -> Option<VertexFactor> {
        let diagonal = Mat3::from_diagonal(Vec3::splat(inertia));
        let exact = *elastic + diagonal;
        let trace = exact.x_axis.x + exact.y_axis.y + exact.z_axis.z;
        if let Some(factor) = Ldlt::new(&exact, PIVOT_FLOOR * trace)
            && trace.is_finite()
        {
            return Some(VertexFactor {
                factor,
                projected: false,
            });
        }
        let factor = Ldlt::regularised(&(positive_part(*elastic) + diagonal))?;
        Some(VertexFactor {
            factor,
            projected: true,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::super::super::element::{TetRest, tet_vertex_force_and_block};
    use super::super::super::super::super::material::{
        Material, NeoHookean, StVK, StableNeoHookean,
    };
    use super::super::super::super::super::math;
    use super::super::super::super::super::types::{Mat3, Real, Vec3};
    use super::{PIVOT_FLOOR, SHIFT, VertexFactor, shape_gradient};

    /// The largest entry's modulus.
    fn largest(m: Mat3) -> Real {
        m.abs().to_cols_array().iter().fold(0.0, |a, &b| a.max(b))
    }

    /// A deterministic stream in `[-1, 1)` (xorshift64*).
    struct Stream(u64);
    impl Stream {
        fn next(&mut self) -> Real {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let bits = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11;
            (bits as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) as Real
        }
        fn vector(&mut self) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next())
        }
    }

    /// Calls `$check(material, f, g)` at every one of the [`gradients`] `f`, with `g` the next
    /// vector of `$stream` times `$scale`, for StVK and stable neo-Hookean, and for neo-Hookean
    /// where `det F > 0.2` (away from its singularity at `det F = 0`). A macro: `$check` is
    /// generic over the material.
    macro_rules! check_materials {
        ($check:ident, $stream:expr, $scale:expr) => {
            let mut stream = $stream;
            for f in gradients() {
                let g = stream.vector() * $scale;
                $check(&StVK::from_young_poisson(1e6, 0.3).unwrap(), f, g);
                $check(
                    &StableNeoHookean::from_young_poisson(1e6, 0.45).unwrap(),
                    f,
                    g,
                );
                if f.determinant() > 0.2 {
                    $check(&NeoHookean::from_young_poisson(1e6, 0.3).unwrap(), f, g);
                }
            }
        };
    }

    /// Deformation gradients: `I + 0.4 R` for random `R`, half of them with a column negated
    /// (inverted), and a few flat and strongly stretched ones.
    fn gradients() -> [Mat3; 42] {
        let mut stream = Stream(0x9e37_79b9_7f4a_7c15);
        core::array::from_fn(|k| match k {
            40 => Mat3::from_diagonal(Vec3::new(1.0, 1.0, 0.0)),
            41 => Mat3::from_diagonal(Vec3::new(3.0, 0.5, 0.8)),
            _ => {
                let r = Mat3::from_cols(stream.vector(), stream.vector(), stream.vector());
                let f = Mat3::IDENTITY + r * 0.4;
                if k % 2 == 0 {
                    f
                } else {
                    Mat3::from_cols(f.x_axis, f.y_axis, -f.z_axis)
                }
            }
        })
    }

    /// The closed-form `K(g)` equals central differences of the corner's stress contraction
    /// `P(F + t u g^T) g` in `t`, column by column, for every model and random `F` including
    /// inverted ones (neo-Hookean only at `J > 0.2`, away from its barrier). Step
    /// `eps^(1/3) / |g|`: truncation and rounding both `O(eps^(2/3))` relative to the stress
    /// scale, so the tolerance is `100 eps^(2/3)` of the largest stress derivative
    /// (`|K| |g|^-2` times the modulus scale).
    #[test]
    fn corner_stiffness_equals_central_differences_of_the_corner_force() {
        fn check<M: Material>(material: &M, f: Mat3, g: Vec3) {
            let (stress, k) = material.corner_stress_and_stiffness(f, g);
            let direct = material.first_piola(f);
            let scale = largest(direct) * g.length();
            assert!(
                (stress - direct * g).abs().max_element() <= 16.0 * Real::EPSILON * scale,
                "the corner stress is P g: {stress} vs {}",
                direct * g
            );
            let step = math::cbrt(Real::EPSILON) / g.length();
            let columns = [Vec3::X, Vec3::Y, Vec3::Z].map(|u| {
                let df = Mat3::from_cols(u * g.x, u * g.y, u * g.z) * step;
                (material.first_piola(f + df) * g - material.first_piola(f - df) * g) / (2.0 * step)
            });
            let difference = Mat3::from_cols(columns[0], columns[1], columns[2]);
            let scale = largest(k).max(largest(direct) * g.length_squared());
            let tolerance = 100.0 * math::cbrt(Real::EPSILON * Real::EPSILON) * scale;
            assert!(
                largest(k - difference) <= tolerance,
                "{material:?} F = {f}: {k} vs differences {difference}"
            );
            assert!(largest(k - k.transpose()) <= 8.0 * Real::EPSILON * largest(k));
        }
        check_materials!(check, Stream(17), 20.0);
    }

    /// The closed forms equal the provided method of [`Material`] (three stress
    /// differentials), to rounding of the largest term.
    #[test]
    fn corner_stiffness_equals_three_stress_differentials() {
        fn check<M: Material>(material: &M, f: Mat3, g: Vec3) {
            let (_, k) = material.corner_stress_and_stiffness(f, g);
            let column = |u: Vec3| {
                let df = Mat3::from_cols(u * g.x, u * g.y, u * g.z);
                material.first_piola_differential(f, df) * g
            };
            let provided = Mat3::from_cols(column(Vec3::X), column(Vec3::Y), column(Vec3::Z));
            let scale = largest(provided).max(largest(material.first_piola(f)) * g.dot(g));
            assert!(
                largest(k - provided) <= 256.0 * Real::EPSILON * scale,
                "{material:?} F = {f}: {k} vs {provided}"
            );
        }
        check_materials!(check, Stream(5), 1.0);
    }

    /// Where the element's exact 9x9 stress derivative is positive semi-definite already (its
    /// projection changes nothing), `V K(g)` is the projected element block of
    /// [`tet_vertex_force_and_block`], and the force is its force.
    #[test]
    fn exact_block_equals_the_projected_block_where_the_hessian_is_definite() {
        let rest_positions = [
            Vec3::ZERO,
            Vec3::new(1.0, 0.1, 0.0),
            Vec3::new(0.2, 0.9, 0.1),
            Vec3::new(0.1, 0.2, 1.1),
        ];
        let rest = TetRest::new(rest_positions).unwrap();
        let rotation = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 2.0).normalize(), 0.7);
        let gradients = [
            Mat3::IDENTITY,
            Mat3::from_diagonal(Vec3::new(1.3, 1.2, 1.1)),
            rotation * Mat3::from_diagonal(Vec3::new(1.25, 1.1, 1.05)),
            rotation * Mat3::from_diagonal(Vec3::new(1.02, 1.01, 1.03)),
        ];
        fn check<M: Material>(material: &M, rest: &TetRest, positions: [Vec3; 4], f: Mat3) -> bool {
            // Definite: projection leaves every entry of dP/dF as it is.
            let (exact, projected) = (
                material.stress_derivative(f),
                material.projected_stress_derivative(f),
            );
            let scale = (0..9)
                .flat_map(|i| (0..9).map(move |j| (i, j)))
                .fold(0.0 as Real, |a, (i, j)| a.max(exact.entry(i, j).abs()));
            let definite = (0..9).all(|i| {
                (0..9).all(|j| {
                    (exact.entry(i, j) - projected.entry(i, j)).abs()
                        <= 64.0 * Real::EPSILON * scale
                })
            });
            if !definite {
                return false;
            }
            let x = positions.map(|p| f * p);
            let fx = rest.deformation_gradient(x);
            for corner in 0..4 {
                let (force, block) = tet_vertex_force_and_block(material, rest, x, corner);
                let g = shape_gradient(rest, corner);
                let (stress, k) = material.corner_stress_and_stiffness(fx, g);
                let mine = k * rest.volume;
                assert!(
                    largest(mine - block) <= 512.0 * Real::EPSILON * largest(block),
                    "{f} corner {corner}: {mine} vs {block}"
                );
                // `P g` is formed as `a F g + b cof(F) g`, whose terms are of the size of the
                // block over `|g|` (`V mu |g|`) and cancel: rounding relative to that.
                let my_force = stress * -rest.volume;
                let term = largest(block) / g.length();
                assert!(
                    (my_force - force).length() <= 64.0 * Real::EPSILON * force.length().max(term),
                    "{my_force} vs {force}"
                );
            }
            true
        }
        let mut compared = 0;
        for f in gradients {
            compared += usize::from(check(
                &StVK::from_young_poisson(1e6, 0.3).unwrap(),
                &rest,
                rest_positions,
                f,
            ));
            compared += usize::from(check(
                &StableNeoHookean::from_young_poisson(1e6, 0.45).unwrap(),
                &rest,
                rest_positions,
                f,
            ));
            compared += usize::from(check(
                &NeoHookean::from_young_poisson(1e6, 0.3).unwrap(),
                &rest,
                rest_positions,
                f,
            ));
        }
        // Stretches above 1 are definite for all three models: most cases compare.
        assert!(compared >= 8, "only {compared} definite cases");
    }

    /// The `L D L^T` solve is backward stable on random symmetric positive definite blocks
    /// `B B^T + c I` (condition numbers up to about `1 / c`): the residual `|H x - r|` is
    /// within a few `eps |H| |x|` (Higham, "Accuracy and Stability of Numerical Algorithms",
    /// theorem 10.4, for Cholesky, whose pivots these are); and the factor refuses a matrix with
    /// a zero or negative pivot, which the regularised factor accepts shifted.
    #[test]
    fn ldlt_solves_to_rounding_and_refuses_singular_pivots() {
        use super::Ldlt;
        let mut stream = Stream(11);
        for k in 0..200 {
            let b = Mat3::from_cols(stream.vector(), stream.vector(), stream.vector());
            let c = [1.0, 1e-2, 1e-4][k % 3];
            let h = b * b.transpose() + Mat3::from_diagonal(Vec3::splat(c));
            let factor = Ldlt::regularised(&h).unwrap();
            let r = stream.vector();
            let x = factor.solve(r);
            assert!(
                (h * x - r).length() <= 32.0 * Real::EPSILON * largest(h) * x.length(),
                "{h} {r}: {x}"
            );
        }
        // A zero second pivot, and a negative one.
        for a11 in [1.0, 0.5] {
            let h = Mat3::from_cols(
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(1.0, a11, 0.0),
                Vec3::new(0.0, 0.0, 1.0),
            );
            assert!(Ldlt::new(&h, PIVOT_FLOOR).is_none());
        }
        let singular = Mat3::from_cols(
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        );
        let shifted = Ldlt::regularised(&singular).unwrap();
        // Trace 3: the shift is `sqrt(eps)`.
        let h = singular + Mat3::from_diagonal(Vec3::splat(SHIFT));
        let r = Vec3::new(1.0, -1.0, 2.0);
        let x = shifted.solve(r);
        assert!((h * x - r).length() <= 64.0 * Real::EPSILON * largest(h) * x.length());
    }

    /// The lane factor is the one-matrix factor, lane by lane: the same refusals and the same
    /// bits for every solve, over definite, indefinite and singular matrices.
    #[test]
    fn lane_factor_is_the_scalar_factor_in_every_lane() {
        use super::super::super::super::super::lanes::{LANES, Lane, LaneVec3, Lanes};
        use super::{LaneLdlt, Ldlt};
        let mut stream = Stream(23);
        let (mut factored, mut refused) = (0, 0);
        for k in 0..300 {
            let matrices: [Mat3; LANES] = core::array::from_fn(|j| {
                let b = Mat3::from_cols(stream.vector(), stream.vector(), stream.vector());
                // Definite, then indefinite (a negative diagonal shift), then singular.
                match (k + j) % 3 {
                    0 => b * b.transpose() + Mat3::from_diagonal(Vec3::splat(1e-2)),
                    1 => b * b.transpose() - Mat3::from_diagonal(Vec3::splat(0.3)),
                    _ => Mat3::from_cols(b.x_axis, b.x_axis, b.z_axis).transpose() * b,
                }
            });
            let r: [Vec3; LANES] = core::array::from_fn(|_| stream.vector());
            let entry = |f: fn(&Mat3) -> Real| Lanes::from_array(matrices.map(|h| f(&h)));
            let lower = [
                entry(|h| h.x_axis.x),
                entry(|h| h.x_axis.y),
                entry(|h| h.x_axis.z),
                entry(|h| h.y_axis.y),
                entry(|h| h.y_axis.z),
                entry(|h| h.z_axis.z),
            ];
            let floor = 1e-3;
            let (lanes, flags) = LaneLdlt::new(lower, Lanes::splat(floor));
            let solved = lanes.solve(LaneVec3::from_vectors(r)).to_vectors();
            for (j, h) in matrices.iter().enumerate() {
                match Ldlt::new(h, floor) {
                    Some(factor) => {
                        factored += 1;
                        assert_eq!(flags.to_array()[j], 1.0, "{h}");
                        let x = factor.solve(r[j]);
                        assert_eq!(
                            x.to_array().map(Real::to_bits),
                            solved[j].to_array().map(Real::to_bits),
                            "{h}"
                        );
                    }
                    None => {
                        refused += 1;
                        assert_eq!(flags.to_array()[j], 0.0, "{h}");
                    }
                }
            }
        }
        assert!(
            factored > 300 && refused > 300,
            "{factored} factored, {refused} refused"
        );
    }

    /// The vertex factor solves with the exact block where that is definite, and with a
    /// positive definite replacement (every solve a descent direction) where it is not.
    #[test]
    fn vertex_factor_is_exact_where_definite_and_descends_where_not() {
        let definite = Mat3::from_cols(
            Vec3::new(4.0, 1.0, 0.5),
            Vec3::new(1.0, 3.0, 0.2),
            Vec3::new(0.5, 0.2, 2.0),
        );
        let factor = VertexFactor::new(0.5, &definite).unwrap();
        assert!(!factor.projected);
        let r = Vec3::new(1.0, -2.0, 0.5);
        let h = definite + Mat3::from_diagonal(Vec3::splat(0.5));
        assert!((h * factor.factor.solve(r) - r).length() <= 64.0 * Real::EPSILON * 4.0);
        // Eigenvalues 3, -2, 1 (in a rotated frame) with inertia 1: indefinite.
        let rotation = Mat3::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize(), 0.4);
        let indefinite =
            rotation * Mat3::from_diagonal(Vec3::new(3.0, -2.0, 1.0)) * rotation.transpose();
        let factor = VertexFactor::new(1.0, &indefinite).unwrap();
        assert!(factor.projected);
        // The positive part plus inertia: eigenvalues 4, 1, 2.
        let expected =
            rotation * Mat3::from_diagonal(Vec3::new(4.0, 1.0, 2.0)) * rotation.transpose();
        let mut stream = Stream(3);
        for _ in 0..20 {
            let g = stream.vector();
            let d = factor.factor.solve(-g);
            assert!(g.dot(d) < 0.0);
            assert!((expected * d + g).length() <= 1e3 * Real::EPSILON * g.length());
        }
        assert!(VertexFactor::new(0.0, &Mat3::ZERO).is_none());
        assert!(VertexFactor::new(1.0, &Mat3::from_diagonal(Vec3::splat(Real::NAN))).is_none());
    }
}
