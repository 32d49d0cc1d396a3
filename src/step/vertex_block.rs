//! The per-element work of a Vertex Block Descent update: the elastic force on one corner and
//! that corner's SPD-projected 3x3 Hessian block, from one SVD, without assembling the 9x9
//! stress derivative.
//!
//! With `F = U diag(s) V^T` the projected derivative is `sum_m lambda_m+ vec(Q_m) vec(Q_m)^T`
//! over the nine modes of Smith, de Goes and Kim ("Analytic eigensystems for isotropic
//! distortion energies", ACM TOG 2019; `docs/math.md` section 6): the scaling modes
//! `Q_i = u_i v_i^T` coupled by the principal Hessian `S = d^2 W / ds^2` (projected as a whole),
//! and per pair `(i, j)` the flip `(u_i v_j^T + u_j v_i^T) / sqrt 2` and the twist
//! `(u_i v_j^T - u_j v_i^T) / sqrt 2`. Corner `a` with shape gradient `g` sees `dF = dx g^T`,
//! so its block is `V sum_m lambda_m+ (Q_m g)(Q_m g)^T`, and with `h = V^T g`,
//! `Q_i g = u_i h_i` and `(u_i v_j^T +- u_j v_i^T) g = u_i h_j +- u_j h_i`. In the frame of `U`
//! the block is therefore `V U M U^T` with
//! `M = S+ o (h h^T)` plus, per pair, `(f + t) / 2 h_j^2` at `(i, i)`, `(f + t) / 2 h_i^2` at
//! `(j, j)` and `(f - t) / 2 h_i h_j` at `(i, j)` and `(j, i)` (`f`, `t` the clamped flip and
//! twist eigenvalues): some 60 operations on top of the SVD instead of the 9x9's 800. The same
//! block as [`TetHessian::vertex_block`](super::super::element::TetHessian::vertex_block) to
//! rounding (checked by the tests below).

use super::super::element::TetRest;
use super::super::material::Material;
use super::super::svd::{Svd3, svd3};
use super::super::types::{Mat3, Real, Vec3};

/// The pairs `(i, j)` of the flip and twist modes, in the order of
/// [`Material::principal_pair_eigenvalues`].
const PAIRS: [(usize, usize); 3] = [(1, 2), (0, 2), (0, 1)];

/// The gradient `g_a` (m^-1) of corner `a`'s shape function: row `a - 1` of `Dm^-1` for
/// `a = 1, 2, 3`, minus their sum for `a = 0` (zero out of range).
#[inline(always)]
pub(super) fn shape_gradient(rest: &TetRest, corner: usize) -> Vec3 {
    let rows = [rest.dm_inv.row(0), rest.dm_inv.row(1), rest.dm_inv.row(2)];
    match corner.checked_sub(1) {
        Some(k) => rows.get(k).copied().unwrap_or(Vec3::ZERO),
        None => -(rows.iter().copied().sum::<Vec3>()),
    }
}

/// `max(x, 0)`, NaN kept.
#[inline(always)]
fn clamp_negative(x: Real) -> Real {
    if x < 0.0 { 0.0 } else { x }
}

/// The positive semi-definite part of the symmetric `s`: `s` itself when every principal minor
/// is non-negative, else `(s + |s|) / 2` with `|s| = B diag(sigma) B^T` from the SVD
/// `s = A diag(sigma) B^T` (for a symmetric matrix the right singular vectors are its
/// eigenvectors and the singular values the moduli of its eigenvalues). NaN fails the test
/// and propagates.
fn positive_part(s: Mat3) -> Mat3 {
    let (a, b, c) = (s.x_axis.x, s.y_axis.y, s.z_axis.z);
    let (ab, ac, bc) = (s.y_axis.x, s.z_axis.x, s.z_axis.y);
    let psd = a >= 0.0
        && b >= 0.0
        && c >= 0.0
        && a * b - ab * ab >= 0.0
        && a * c - ac * ac >= 0.0
        && b * c - bc * bc >= 0.0
        && s.determinant() >= 0.0;
    if psd {
        return s;
    }
    let svd = svd3(s);
    let modulus = svd.v * Mat3::from_diagonal(svd.sigma.abs()) * svd.v.transpose();
    let half = (s + modulus) * 0.5;
    (half + half.transpose()) * 0.5
}

/// The elastic force (N) on `corner` of the tetrahedron `rest` with deformation gradient `f`
/// (whose SVD is `svd`) and that corner's SPD-projected Hessian block (N/m): see the
/// [module documentation](self). The force is `-V P g_a` with the direct stress
/// [`Material::first_piola`].
#[inline]
pub(super) fn force_and_projected_block<M: Material>(
    material: &M,
    rest: &TetRest,
    f: Mat3,
    svd: &Svd3,
    corner: usize,
) -> (Vec3, Mat3) {
    let g = shape_gradient(rest, corner);
    let force = material.first_piola(f) * g * -rest.volume;
    let h = svd.v.transpose() * g;
    let scaling = positive_part(material.principal_hessian(svd.sigma));
    let [flip, twist] = material.principal_pair_eigenvalues(svd.sigma);
    let outer = Mat3::from_cols(h * h.x, h * h.y, h * h.z);
    let mut m = [
        (scaling.x_axis * outer.x_axis).to_array(),
        (scaling.y_axis * outer.y_axis).to_array(),
        (scaling.z_axis * outer.z_axis).to_array(),
    ];
    let hs = h.to_array();
    let (flips, twists) = (flip.to_array(), twist.to_array());
    for (k, &(i, j)) in PAIRS.iter().enumerate() {
        let f = clamp_negative(flips.get(k).copied().unwrap_or(0.0));
        let t = clamp_negative(twists.get(k).copied().unwrap_or(0.0));
        let (hi, hj) = (
            hs.get(i).copied().unwrap_or(0.0),
            hs.get(j).copied().unwrap_or(0.0),
        );
        let (sum, difference) = (0.5 * (f + t), 0.5 * (f - t));
        let mut add = |column: usize, row: usize, value: Real| {
            if let Some(entry) = m.get_mut(column).and_then(|c| c.get_mut(row)) {
                *entry += value;
            }
        };
        add(i, i, sum * hj * hj);
        add(j, j, sum * hi * hi);
        add(j, i, difference * hi * hj);
        add(i, j, difference * hi * hj);
    }
    let principal = Mat3::from_cols_array_2d(&m);
    let block = svd.u * principal * svd.u.transpose() * rest.volume;
    (force, (block + block.transpose()) * 0.5)
}

#[cfg(test)]
mod tests {
    use super::super::super::element::{TetRest, tet_vertex_force_and_block};
    use super::super::super::material::{Material, NeoHookean, StVK, StableNeoHookean};
    use super::super::super::svd::svd3;
    use super::super::super::types::{Mat3, Real, Vec3};
    use super::force_and_projected_block;

    /// The contraction equals the element block of the 9x9 assembly for every model, at rest,
    /// stretched, compressed (indefinite principal Hessian), sheared, and inverted, to a few
    /// hundred eps of the block's scale; the forces are the same bits.
    #[test]
    fn contraction_equals_the_assembled_block() {
        let rest_positions = [
            Vec3::ZERO,
            Vec3::new(1.0, 0.1, 0.0),
            Vec3::new(0.2, 0.9, 0.1),
            Vec3::new(0.1, 0.2, 1.1),
        ];
        let rest = TetRest::new(rest_positions).unwrap();
        let gradients = [
            Mat3::IDENTITY,
            Mat3::from_diagonal(Vec3::new(1.3, 0.9, 1.05)),
            Mat3::from_diagonal(Vec3::new(0.5, 0.6, 0.7)),
            Mat3::from_cols(
                Vec3::new(1.0, 0.4, -0.1),
                Vec3::new(0.3, 0.8, 0.2),
                Vec3::new(-0.2, 0.1, 1.2),
            ),
            Mat3::from_diagonal(Vec3::new(1.1, 0.9, -0.3)),
            Mat3::from_diagonal(Vec3::new(1.0, 1.0, 1.0 + 1e-3)),
        ];
        fn check<M: Material>(material: &M, rest: &TetRest, positions: [Vec3; 4], f: Mat3) {
            let x = positions.map(|p| f * p);
            let fx = rest.deformation_gradient(x);
            for corner in 0..4 {
                let (force, block) = tet_vertex_force_and_block(material, rest, x, corner);
                let (mine, my_block) =
                    force_and_projected_block(material, rest, fx, &svd3(fx), corner);
                let scale = block
                    .abs()
                    .to_cols_array()
                    .iter()
                    .fold(0.0 as Real, |a, &b| a.max(b));
                let error = (my_block - block)
                    .abs()
                    .to_cols_array()
                    .iter()
                    .fold(0.0 as Real, |a, &b| a.max(b));
                assert!(
                    error <= 512.0 * Real::EPSILON * scale,
                    "{f} corner {corner}: {my_block} vs {block}"
                );
                let force_error = (mine - force).length();
                assert!(
                    force_error <= 64.0 * Real::EPSILON * force.length().max(1.0),
                    "{mine} vs {force}"
                );
            }
        }
        for f in gradients {
            check(
                &StVK::from_young_poisson(1e6, 0.3).unwrap(),
                &rest,
                rest_positions,
                f,
            );
            check(
                &StableNeoHookean::from_young_poisson(1e6, 0.45).unwrap(),
                &rest,
                rest_positions,
                f,
            );
            if f.determinant() > 0.0 {
                check(
                    &NeoHookean::from_young_poisson(1e6, 0.3).unwrap(),
                    &rest,
                    rest_positions,
                    f,
                );
            }
        }
    }
}
