//! The element Hessian of a tetrahedron, `d^2 (V W) / dx^2` (12x12, N/m), matrix-free from the
//! projected stress derivative (`docs/math.md` section 6).
//!
//! # Conventions
//! With `G = [g_0 g_1 g_2 g_3]` the gradients of the shape functions (`g_a` for `a >= 1` is row
//! `a - 1` of `Dm^-1`, `g_0 = -(g_1 + g_2 + g_3)`), a displacement `v` of the corners changes
//! the deformation gradient by `dF = sum_a v_a g_a^T = [v1-v0, v2-v0, v3-v0] Dm^-1`. The
//! nodal forces are `f_a = -V P g_a` (the crate's `[f1 f2 f3] = -V P Dm^-T`), so the Hessian of
//! the element energy (the negative force Jacobian, `df = -H v`) is
//! `(H v)_a = V (dP/dF : dF) g_a`, and its 3x3 block of corners `a, b` is
//! `H_ab[r][s] = V sum_{c,d} g_a[c] g_b[d] (dP/dF)[(c, r), (d, s)]` (`vec` index
//! `3 * column + row`).
//!
//! With the projected `dP/dF` ([`Material::projected_stress_derivative`]) the 12x12 is
//! symmetric positive semi-definite: `v^T H v = V dF : D : dF >= 0`.

use super::super::lanes::Lane;
use super::super::material::{Material, StressDerivative};
use super::super::svd::svd3;
use super::super::types::{Mat3, Real, Vec3};
use super::TetRest;

/// Packed entries of [`TetHessian`]'s stiffness (the upper triangle of a symmetric 9x9).
pub(crate) const ENTRIES: usize = 45;

// The flat layout the grouped product relies on.
const _: () = assert!(core::mem::size_of::<TetHessian>() == ENTRIES * core::mem::size_of::<Real>());

/// The cached second-derivative data of one tetrahedron: its projected (SPD) stiffness on the
/// edge displacements, `K = V T^T (dP/dF) T` with `T` the map from `(v1 - v0, v2 - v0,
/// v3 - v0)` to `dF = [v1 - v0, v2 - v0, v3 - v0] Dm^-1` (N/m, symmetric 9x9). The 12x12
/// element Hessian is `K` on the edge displacements (rigid translations are its kernel), so
/// repeated Hessian products ([`product`](TetHessian::product)) are one 9x9 product without any
/// SVD or `Dm^-1` product, and diagonal blocks ([`vertex_block`](TetHessian::vertex_block))
/// are sub-blocks of `K`.
///
/// Size: 45 numbers (the upper triangle of the symmetric 9x9), **180 bytes per element in f32
/// and 360 bytes in f64**. `Default` (zero) exists to size buffers.
///
/// ```
/// use softfem::element::{TetHessian, TetRest};
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
///
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
/// let tet = TetRest::new(rest)?;
/// let rubber = StableNeoHookean::from_young_poisson(1.0e6, 0.45)?;
/// let squashed = rest.map(|x| x * Vec3::new(1.0, 1.0, 0.8));
/// let hessian = TetHessian::new(&rubber, &tet, squashed);
/// // Pushing the apex further down costs energy (positive curvature) ...
/// let push = [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, -Vec3::Z];
/// let hv = hessian.product(&tet, push);
/// assert!(hv[3].dot(-Vec3::Z) > 0.0);
/// // ... and a rigid translation costs nothing.
/// let shift = hessian.product(&tet, [Vec3::X; 4]);
/// assert!(shift.iter().all(|f| f.length() < 1e-2));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
// Transparent (as `StressDerivative`): `ENTRIES` numbers, no padding, so that a slice of
// them is a flat array of packed entries (the grouped product's gather, `mesh/hessian.rs`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(transparent)]
pub struct TetHessian {
    /// `K = V T^T (dP/dF) T` (N/m), in the packed storage of [`StressDerivative`], indexed
    /// `3 a + r` for component `r` of edge `a` (`v_{a+1} - v_0`).
    stiffness: StressDerivative,
}

impl TetHessian {
    /// All stiffness entries zero: only a buffer's initial value (as `Default`), never the
    /// Hessian of a valid element.
    pub const ZERO: TetHessian = TetHessian {
        stiffness: StressDerivative::ZERO,
    };

    /// The projected (SPD) Hessian data of `material` on the tetrahedron `rest` at deformed
    /// positions `corners` (m): one SVD of `F`.
    #[inline]
    #[must_use]
    pub fn new<M: Material>(material: &M, rest: &TetRest, corners: [Vec3; 4]) -> TetHessian {
        let f = rest.deformation_gradient(corners);
        Self::from_stress_derivative(&material.projected_stress_derivative(f), rest)
    }

    /// The exact (unprojected, possibly indefinite) Hessian data: for checks and for solvers
    /// that handle indefiniteness themselves.
    #[inline]
    #[must_use]
    pub fn exact<M: Material>(material: &M, rest: &TetRest, corners: [Vec3; 4]) -> TetHessian {
        let f = rest.deformation_gradient(corners);
        Self::from_stress_derivative(&material.stress_derivative(f), rest)
    }

    /// The Hessian data of a given stress derivative `derivative` (Pa) on `rest`.
    #[inline]
    #[must_use]
    pub fn from_stress_derivative(derivative: &StressDerivative, rest: &TetRest) -> TetHessian {
        TetHessian {
            stiffness: derivative.congruence(rest.dm_inv, rest.volume),
        }
    }

    /// The 12x12 element Hessian times the corner displacements `v` (m): `H v` (N). `rest`
    /// is the element's rest data; the cache already holds everything the product needs
    /// (`rest` is taken so that the signature does not change if it stops doing so).
    #[inline]
    #[must_use]
    pub fn product(&self, _rest: &TetRest, v: [Vec3; 4]) -> [Vec3; 4] {
        let [v0, v1, v2, v3] = v;
        let [h0, h1, h2, h3] = Self::lanes_product(
            |k| self.packed_entry(k),
            [v0.to_array(), v1.to_array(), v2.to_array(), v3.to_array()],
        );
        [
            Vec3::from_array(h0),
            Vec3::from_array(h1),
            Vec3::from_array(h2),
            Vec3::from_array(h3),
        ]
    }

    /// Packed entry `k` of `K` (the storage order of [`StressDerivative`]); 0 past the last.
    #[inline(always)]
    pub(crate) fn packed_entry(&self, k: usize) -> Real {
        self.stiffness.packed_entry(k)
    }

    /// [`product`](TetHessian::product) of any [`Lane`] type, coordinate by coordinate
    /// (`v[corner][axis]`): `K` has packed entry `k` `entry(k)`. Each lane gets the bits of
    /// one element at a time: the edges `v_a - v_0`, `K` times them (in the order of
    /// [`StressDerivative::symmetric_product`]), and corner 0's `-((h_1 + h_2) + h_3)`.
    #[inline(always)]
    pub(crate) fn lanes_product<L: Lane>(
        entry: impl Fn(usize) -> L,
        v: [[L; 3]; 4],
    ) -> [[L; 3]; 4] {
        let [[x0, y0, z0], [x1, y1, z1], [x2, y2, z2], [x3, y3, z3]] = v;
        let edges = [
            x1 - x0,
            y1 - y0,
            z1 - z0,
            x2 - x0,
            y2 - y0,
            z2 - z0,
            x3 - x0,
            y3 - y0,
            z3 - z0,
        ];
        let [a, b, c, d, e, f, g, i, j] = StressDerivative::symmetric_product(entry, &edges);
        [
            [-(a + d + g), -(b + e + i), -(c + f + j)],
            [a, b, c],
            [d, e, f],
            [g, i, j],
        ]
    }

    /// The 3x3 diagonal block of the element Hessian for corner `corner` (0..4; N/m),
    /// symmetric and positive semi-definite for projected data. A corner out of range gives
    /// the zero matrix. `rest` as in [`product`](TetHessian::product).
    #[inline]
    #[must_use]
    pub fn vertex_block(&self, _rest: &TetRest, corner: usize) -> Mat3 {
        let k = &self.stiffness;
        match corner {
            // g_0 = -(g_1 + g_2 + g_3): the sum of all nine blocks.
            0 => {
                let mut sum = Mat3::ZERO;
                for a in 0..3 {
                    for b in 0..3 {
                        sum += k.block(a, b);
                    }
                }
                sum
            }
            1..=3 => k.block(corner - 1, corner - 1),
            _ => Mat3::ZERO,
        }
    }
}

impl TetHessian {
    /// The 3x3 block of the 12x12 element Hessian with rows of corner `a` and columns of corner
    /// `b` (0..4; N/m): `K_ab` on the edges for `a, b >= 1`, and for corner 0 (whose
    /// displacement enters every edge with a minus sign) minus the sum over that corner's edge
    /// index, both sums for `a = b = 0`. `block(b, a)` is its transpose; a corner out of range
    /// gives the zero matrix. What an assembled (sparse) Hessian is built from.
    #[inline]
    #[must_use]
    pub fn corner_block(&self, a: usize, b: usize) -> Mat3 {
        let k = &self.stiffness;
        let column_sum = |edge_b: usize| k.block(0, edge_b) + k.block(1, edge_b) + k.block(2, edge_b);
        let row_sum = |edge_a: usize| k.block(edge_a, 0) + k.block(edge_a, 1) + k.block(edge_a, 2);
        match (a, b) {
            (0, 0) => column_sum(0) + column_sum(1) + column_sum(2),
            (0, 1..=3) => -column_sum(b - 1),
            (1..=3, 0) => -row_sum(a - 1),
            (1..=3, 1..=3) => k.block(a - 1, b - 1),
            _ => Mat3::ZERO,
        }
    }
}

/// The gradient `g_a` (m^-1) of corner `a`'s shape function: row `a - 1` of `Dm^-1` for
/// `a = 1, 2, 3`, minus their sum for `a = 0`; `None` out of range.
#[inline]
fn shape_gradient(rest: &TetRest, corner: usize) -> Option<Vec3> {
    let m = rest.dm_inv.transpose();
    match corner {
        0 => Some(-(m.x_axis + m.y_axis + m.z_axis)),
        1 => Some(m.x_axis),
        2 => Some(m.y_axis),
        3 => Some(m.z_axis),
        _ => None,
    }
}

/// The elastic force (N) on corner `corner` (0..4) of a tetrahedron and that corner's 3x3 block
/// of the projected (SPD) element Hessian (N/m), from one deformation gradient and one SVD:
/// the per-element work of Vertex Block Descent (Chen et al., "Vertex Block Descent", ACM TOG
/// 2024) for one vertex.
///
/// The force is the crate's `-V P g_a` with the direct stress [`Material::first_piola`], the
/// same bits as that corner's entry of [`TetRest::elastic_forces`]. The block is
/// [`TetHessian::vertex_block`]'s up to rounding: it contracts `V dP/dF` with `g_a` directly
/// (no 9x9 congruence), the cheaper way for one corner. A corner out of range gives zeros.
///
/// ```
/// use softfem::element::{TetHessian, TetRest, tet_vertex_force_and_block};
/// use softfem::glam::Vec3;
/// use softfem::material::StVK;
///
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
/// let tet = TetRest::new(rest)?;
/// let stvk = StVK::from_young_poisson(1.0e6, 0.3)?;
/// let x = rest.map(|p| p * 1.1);
/// let (force, block) = tet_vertex_force_and_block(&stvk, &tet, x, 2);
/// assert_eq!(force, tet.elastic_forces(&stvk, x)[2]);
/// // The same block as the cached element Hessian's, to rounding (formed in another order).
/// let cached = TetHessian::new(&stvk, &tet, x).vertex_block(&tet, 2);
/// assert!(block.abs_diff_eq(cached, 1e-5 * cached.x_axis.x.abs()));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[inline]
#[must_use]
pub fn tet_vertex_force_and_block<M: Material>(
    material: &M,
    rest: &TetRest,
    corners: [Vec3; 4],
    corner: usize,
) -> (Vec3, Mat3) {
    let Some(g) = shape_gradient(rest, corner) else {
        return (Vec3::ZERO, Mat3::ZERO);
    };
    let f = rest.deformation_gradient(corners);
    let [f0, f1, f2, f3] = rest.nodal_forces(material.first_piola(f));
    let force = match corner {
        0 => f0,
        1 => f1,
        2 => f2,
        _ => f3,
    };
    let derivative = material
        .projected_stress_derivative_from_svd(&svd3(f))
        .scaled(rest.volume);
    (force, derivative.vertex_block(g))
}
