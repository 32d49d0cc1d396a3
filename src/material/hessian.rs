//! Second derivatives of the strain energy: the stress derivative `dP/dF` as a symmetric 9x9
//! matrix, and its projection onto the positive semi-definite cone by the analytic eigensystem
//! of an isotropic energy in the principal frame (`docs/math.md` section 6).
//!
//! # The eigensystem
//! With `F = U diag(s) V^T` (signed singular values, [`svd3`](super::svd3)) and `psi_i = dW/ds_i`
//! the principal stresses, the nine eigenmatrices of `d^2 W / dF^2` are (Smith, de Goes, Kim,
//! "Analytic Eigensystems for Isotropic Distortion Energies", ACM TOG 38(1), 2019; the same
//! blocks as Teran, Sifakis, Irving, Fedkiw, "Robust quasistatic finite elements and flesh
//! simulation", SCA 2005):
//! * three **scaling** modes `U diag(q) V^T`, `q` an eigenvector of the 3x3 principal Hessian
//!   `d^2 W / ds^2`, with its eigenvalue;
//! * for each pair `i < j` (the third axis `k`), a **flip** mode `U (e_i e_j^T + e_j e_i^T) V^T /
//!   sqrt 2` with eigenvalue `(psi_i - psi_j) / (s_i - s_j)` and a **twist** mode
//!   `U (e_i e_j^T - e_j e_i^T) V^T / sqrt 2` with eigenvalue `(psi_i + psi_j) / (s_i + s_j)`.
//!
//! The quotients are `0/0` at repeated singular values (`s_i = s_j`, every element at rest) and,
//! for the twist, at `s_i = -s_j` (an inverted element). The models here give them in closed
//! form without a division: a model written as `W(I_C, J)` with `a = 2 dW/dI_C`, `b = dW/dJ` has
//! `psi_i = a s_i + b s_j s_k`, so the flip eigenvalue is exactly `a - b s_k` and the twist
//! eigenvalue `a + b s_k`; StVK's are polynomials ([`StVK`](super::StVK)). The provided trait
//! methods (for models defined elsewhere) form the quotients and switch to their limits
//! (`H_ii - H_ij`, `H_ii + H_ij` of the principal Hessian) where the denominator is below
//! `sqrt(eps)` of the stretches.
//!
//! The projection clamps each of the nine eigenvalues at zero (NaN stays NaN), so the projected
//! derivative is symmetric positive semi-definite by construction; where every eigenvalue is
//! already `>= 0` it is the exact derivative, assembled from the same eigensystem.

use super::super::lanes::Lane;
use super::super::math;
use super::super::svd::Svd3;
use super::super::types::{Mat3, Real, Vec3};

/// The number of distinct entries of a symmetric 9x9 matrix.
const PACKED: usize = 45;

/// A symmetric 9x9 stress derivative `dP/dF` (Pa per unit of `F`), acting on `vec(dF)` in
/// column-major order: index `3 * column + row`, the order of `Mat3::to_cols_array`.
///
/// Stored as the 45 entries of its upper triangle, row by row (180 bytes in f32, 360 in f64).
/// `Default` is the zero matrix. Built by
/// [`Material::projected_stress_derivative`](super::Material::projected_stress_derivative) (SPD)
/// or [`Material::stress_derivative`](super::Material::stress_derivative) (exact).
///
/// ```
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::material::{Material, StVK};
///
/// let stvk = StVK::from_lame(1.0e6, 1.0e6)?;
/// let f = Mat3::from_diagonal(Vec3::new(1.1, 1.0, 0.9));
/// let d = stvk.projected_stress_derivative(f);
/// // Near rest the exact derivative is already SPD: the projection leaves it alone.
/// let df = Mat3::from_cols_array(&[0.1, 0.0, 0.2, 0.0, -0.1, 0.0, 0.3, 0.0, 0.05]);
/// let exact = stvk.first_piola_differential(f, df);
/// assert!(d.apply(df).abs_diff_eq(exact, 1e-5 * 1.0e6));
/// assert_eq!(d.entry(2, 6), d.entry(6, 2));
/// assert_eq!(d.entry(9, 0), 0.0); // out of range
/// # Ok::<(), softfem::MaterialError>(())
/// ```
// Transparent: a slice of `TetHessian`s is a flat array of packed entries (the grouped
// product's gather, `mesh/hessian.rs`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(transparent)]
pub struct StressDerivative {
    /// Upper triangle, row by row: `(i, j)` with `i <= j` at `i (17 - i) / 2 + j`.
    packed: [Real; PACKED],
}

impl StressDerivative {
    /// All entries zero (a buffer's initial value).
    pub const ZERO: StressDerivative = StressDerivative {
        packed: [0.0; PACKED],
    };
}

impl Default for StressDerivative {
    #[inline]
    fn default() -> Self {
        StressDerivative::ZERO
    }
}

impl StressDerivative {
    /// `a x` for the symmetric 9x9 `a` whose packed entry `k` (upper triangle, row by row, as
    /// [`StressDerivative`] stores it) is `entry(k)`, for any [`Lane`] type: `out_j = (0 + a_0j
    /// x_0 + ... + a_(j-1)j x_(j-1)) + (a_jj x_j + ... + a_j8 x_8)`, each parenthesis summed left
    /// to right: the order of the row sweep that [`apply_array`](Self::apply_array) was (row `i`
    /// adds its entries times `x_i` to the later `out_j`, then its own dot product to `out_i`),
    /// written out so that it compiles without loops or bounds checks, and so that every lane of
    /// a group of elements gets the bits of one element at a time.
    #[inline(always)]
    pub(crate) fn symmetric_product<L: Lane>(entry: impl Fn(usize) -> L, x: &[L; 9]) -> [L; 9] {
        let a00 = entry(0);
        let a01 = entry(1);
        let a02 = entry(2);
        let a03 = entry(3);
        let a04 = entry(4);
        let a05 = entry(5);
        let a06 = entry(6);
        let a07 = entry(7);
        let a08 = entry(8);
        let a11 = entry(9);
        let a12 = entry(10);
        let a13 = entry(11);
        let a14 = entry(12);
        let a15 = entry(13);
        let a16 = entry(14);
        let a17 = entry(15);
        let a18 = entry(16);
        let a22 = entry(17);
        let a23 = entry(18);
        let a24 = entry(19);
        let a25 = entry(20);
        let a26 = entry(21);
        let a27 = entry(22);
        let a28 = entry(23);
        let a33 = entry(24);
        let a34 = entry(25);
        let a35 = entry(26);
        let a36 = entry(27);
        let a37 = entry(28);
        let a38 = entry(29);
        let a44 = entry(30);
        let a45 = entry(31);
        let a46 = entry(32);
        let a47 = entry(33);
        let a48 = entry(34);
        let a55 = entry(35);
        let a56 = entry(36);
        let a57 = entry(37);
        let a58 = entry(38);
        let a66 = entry(39);
        let a67 = entry(40);
        let a68 = entry(41);
        let a77 = entry(42);
        let a78 = entry(43);
        let a88 = entry(44);
        let [x0, x1, x2, x3, x4, x5, x6, x7, x8] = *x;
        let zero = L::splat(0.0);
        let y0 = (zero)
            + (a00 * x0
                + a01 * x1
                + a02 * x2
                + a03 * x3
                + a04 * x4
                + a05 * x5
                + a06 * x6
                + a07 * x7
                + a08 * x8);
        let y1 = (zero + a01 * x0)
            + (a11 * x1
                + a12 * x2
                + a13 * x3
                + a14 * x4
                + a15 * x5
                + a16 * x6
                + a17 * x7
                + a18 * x8);
        let y2 = (zero + a02 * x0 + a12 * x1)
            + (a22 * x2 + a23 * x3 + a24 * x4 + a25 * x5 + a26 * x6 + a27 * x7 + a28 * x8);
        let y3 = (zero + a03 * x0 + a13 * x1 + a23 * x2)
            + (a33 * x3 + a34 * x4 + a35 * x5 + a36 * x6 + a37 * x7 + a38 * x8);
        let y4 = (zero + a04 * x0 + a14 * x1 + a24 * x2 + a34 * x3)
            + (a44 * x4 + a45 * x5 + a46 * x6 + a47 * x7 + a48 * x8);
        let y5 = (zero + a05 * x0 + a15 * x1 + a25 * x2 + a35 * x3 + a45 * x4)
            + (a55 * x5 + a56 * x6 + a57 * x7 + a58 * x8);
        let y6 = (zero + a06 * x0 + a16 * x1 + a26 * x2 + a36 * x3 + a46 * x4 + a56 * x5)
            + (a66 * x6 + a67 * x7 + a68 * x8);
        let y7 =
            (zero + a07 * x0 + a17 * x1 + a27 * x2 + a37 * x3 + a47 * x4 + a57 * x5 + a67 * x6)
                + (a77 * x7 + a78 * x8);
        let y8 = (zero
            + a08 * x0
            + a18 * x1
            + a28 * x2
            + a38 * x3
            + a48 * x4
            + a58 * x5
            + a68 * x6
            + a78 * x7)
            + (a88 * x8);
        [y0, y1, y2, y3, y4, y5, y6, y7, y8]
    }

    /// Packed entry `k` (the storage order of [`symmetric_product`](Self::symmetric_product));
    /// 0 past the last.
    #[inline(always)]
    pub(crate) fn packed_entry(&self, k: usize) -> Real {
        self.packed.get(k).copied().unwrap_or(0.0)
    }
}

/// The packed position of `(i, j)`, `i, j < 9`.
#[inline(always)]
const fn packed_index(i: usize, j: usize) -> usize {
    let (low, high) = if i <= j { (i, j) } else { (j, i) };
    low * (17 - low) / 2 + high
}

impl StressDerivative {
    /// Entry `(i, j)` (Pa), `i, j` in `0..9` in the `vec(F)` order `3 * column + row`; 0 for an
    /// index out of range (no panic). Symmetric: `entry(i, j) == entry(j, i)`.
    #[inline]
    #[must_use]
    pub fn entry(&self, i: usize, j: usize) -> Real {
        if i < 9 && j < 9 {
            self.packed.get(packed_index(i, j)).copied().unwrap_or(0.0)
        } else {
            0.0
        }
    }

    /// The product `dP = (dP/dF) : dF` (Pa) for a direction `df` (dimensionless). The entries are
    /// visited in a fixed order, so the result is the same on every target.
    #[inline]
    #[must_use]
    pub fn apply(&self, df: Mat3) -> Mat3 {
        Mat3::from_cols_array(&self.apply_array(&df.to_cols_array()))
    }

    /// `self * x` on a `vec(dF)` array: row `i` of the upper triangle gives `out_i` its
    /// diagonal and right-hand terms (a dot product) and adds its entries times `x_i` to the
    /// later `out_j` (symmetry), rows in order.
    #[inline]
    pub(crate) fn apply_array(&self, x: &[Real; 9]) -> [Real; 9] {
        Self::symmetric_product(|k| self.packed_entry(k), x)
    }

    /// This derivative times `factor` (e.g. a rest volume, giving J per unit of `F^2`).
    #[inline]
    #[must_use]
    pub fn scaled(&self, factor: Real) -> StressDerivative {
        StressDerivative {
            packed: self.packed.map(|a| a * factor),
        }
    }

    /// The 3x3 block `sum_{c,d} g_c g_d D[(c, r), (d, s)]` (row `r`, column `s`): the
    /// derivative's action on `dF = dx g^T` seen from `dx`, `dF_{rc} = dx_r g_c`. With `g` the
    /// gradient of a corner's shape function this is that corner's diagonal block of the
    /// element Hessian (over the rest volume).
    #[inline]
    #[must_use]
    pub fn vertex_block(&self, g: Vec3) -> Mat3 {
        let g = g.to_array();
        let mut block = [[0.0; 3]; 3];
        for (r, row) in block.iter_mut().enumerate() {
            for (s, value) in row.iter_mut().enumerate() {
                let mut sum = 0.0;
                for (c, &gc) in g.iter().enumerate() {
                    let mut inner = 0.0;
                    for (d, &gd) in g.iter().enumerate() {
                        inner += gd * self.entry(3 * c + r, 3 * d + s);
                    }
                    sum += gc * inner;
                }
                *value = sum;
            }
        }
        // `block[r][s]` is row r, column s; glam takes columns.
        Mat3::from_cols_array_2d(&[
            [block[0][0], block[1][0], block[2][0]],
            [block[0][1], block[1][1], block[2][1]],
            [block[0][2], block[1][2], block[2][2]],
        ])
    }

    /// The congruence `factor T^T D T` of this matrix `D` (a 9x9 on `vec(dF)`) with the map
    /// `T` from three vectors `dv_a` (stacked as `3 a + r`) to `dF = sum_a dv_a m_a^T`, `m_a`
    /// row `a` of `m`: entry `((a, r), (b, s))` is `factor sum_{c,d} m_ac m_bd D[(c, r), (d, s)]`.
    /// With `m = Dm^-1` and `factor = V` this is a tetrahedron's stiffness on the edge
    /// displacements `v_{a+1} - v_0` (see `element/hessian.rs`).
    pub(crate) fn congruence(&self, m: Mat3, factor: Real) -> StressDerivative {
        let columns = m.to_cols_array_2d();
        // m_ac: row a, column c.
        let g: [[Real; 3]; 3] = core::array::from_fn(|a| {
            core::array::from_fn(|c| {
                columns
                    .get(c)
                    .and_then(|col| col.get(a))
                    .copied()
                    .unwrap_or(0.0)
            })
        });
        let full = self.unpacked();
        // W[(c, r)][(b, s)] = sum_d m_bd D[(c, r), (d, s)], row by row of D.
        let w: [[Real; 9]; 9] = full.map(|row| {
            core::array::from_fn(|j| {
                let (b, s) = (j / 3, j % 3);
                let gb = g.get(b).copied().unwrap_or([0.0; 3]);
                let at = |d: usize| row.get(3 * d + s).copied().unwrap_or(0.0);
                gb[0] * at(0) + gb[1] * at(1) + gb[2] * at(2)
            })
        });
        let mut out = StressDerivative::default();
        let mut entries = out.packed.iter_mut();
        for i in 0..9 {
            let (a, r) = (i / 3, i % 3);
            let ga = g.get(a).copied().unwrap_or([0.0; 3]);
            let rows = |c: usize| w.get(3 * c + r).copied().unwrap_or([0.0; 9]);
            let (w0, w1, w2) = (rows(0), rows(1), rows(2));
            for j in i..9 {
                let at = |row: &[Real; 9]| row.get(j).copied().unwrap_or(0.0);
                let sum = ga[0] * at(&w0) + ga[1] * at(&w1) + ga[2] * at(&w2);
                if let Some(entry) = entries.next() {
                    *entry = factor * sum;
                }
            }
        }
        out
    }

    /// The full 9x9 matrix, row by row.
    #[inline]
    fn unpacked(&self) -> [[Real; 9]; 9] {
        let mut full = [[0.0; 9]; 9];
        let mut entries = self.packed.iter();
        for i in 0..9 {
            for j in i..9 {
                let a = entries.next().copied().unwrap_or(0.0);
                if let Some(x) = full.get_mut(i).and_then(|row| row.get_mut(j)) {
                    *x = a;
                }
                if let Some(x) = full.get_mut(j).and_then(|row| row.get_mut(i)) {
                    *x = a;
                }
            }
        }
        full
    }

    /// The 3x3 block of rows `3 a .. 3 a + 3` and columns `3 b .. 3 b + 3` (row `r`, column
    /// `s` at `(3 a + r, 3 b + s)`).
    #[inline]
    pub(crate) fn block(&self, a: usize, b: usize) -> Mat3 {
        let e = |r: usize, s: usize| self.entry(3 * a + r, 3 * b + s);
        Mat3::from_cols(
            Vec3::new(e(0, 0), e(1, 0), e(2, 0)),
            Vec3::new(e(0, 1), e(1, 1), e(2, 1)),
            Vec3::new(e(0, 2), e(1, 2), e(2, 2)),
        )
    }

    /// Adds `weight * x x^T`.
    #[inline(always)]
    fn add_outer(&mut self, weight: Real, x: &[Real; 9]) {
        let mut rows: &mut [Real] = &mut self.packed;
        for (i, &xi) in x.iter().enumerate() {
            let Some((row, rest)) = core::mem::take(&mut rows).split_at_mut_checked(9 - i) else {
                break;
            };
            rows = rest;
            let wxi = weight * xi;
            for (a, &xj) in row.iter_mut().zip(x.get(i..).unwrap_or(&[])) {
                *a += wxi * xj;
            }
        }
    }

    /// Adds `weight * (x y^T + y x^T)`.
    #[inline(always)]
    fn add_symmetric_outer(&mut self, weight: Real, x: &[Real; 9], y: &[Real; 9]) {
        let mut rows: &mut [Real] = &mut self.packed;
        for (i, (&xi, &yi)) in x.iter().zip(y).enumerate() {
            let Some((row, rest)) = core::mem::take(&mut rows).split_at_mut_checked(9 - i) else {
                break;
            };
            rows = rest;
            let tails = x
                .get(i..)
                .unwrap_or(&[])
                .iter()
                .zip(y.get(i..).unwrap_or(&[]));
            for (a, (&xj, &yj)) in row.iter_mut().zip(tails) {
                *a += weight * (xi * yj + yi * xj);
            }
        }
    }
}

/// `vec(u v^T)` in column-major order: entry `3 c + r` is `u_r v_c`.
#[inline(always)]
fn vec_outer(u: Vec3, v: Vec3) -> [Real; 9] {
    [
        u.x * v.x,
        u.y * v.x,
        u.z * v.x,
        u.x * v.y,
        u.y * v.y,
        u.z * v.y,
        u.x * v.z,
        u.y * v.z,
        u.z * v.z,
    ]
}

/// `max(x, 0)` that keeps NaN (a NaN eigenvalue must not become a finite zero).
#[inline(always)]
fn clamp_negative(x: Real) -> Real {
    math::select(x < 0.0, 0.0, x)
}

/// The third axis of each pair: pair `k` is `(i, j) = ((k + 1) % 3, (k + 2) % 3)` sorted, i.e.
/// `k = 0: (1, 2)`, `k = 1: (0, 2)`, `k = 2: (0, 1)`.
const PAIRS: [(usize, usize); 3] = [(1, 2), (0, 2), (0, 1)];

/// The derivative assembled from the principal-frame eigensystem of the module documentation:
/// `hessian` the 3x3 principal Hessian `d^2 W / ds^2` at `svd.sigma`, `pairs = [flip, twist]`
/// with component `k` the eigenvalue of pair `PAIRS[k]`. With `project`, every eigenvalue is
/// clamped at zero; a principal Hessian that is already PSD (Sylvester's test on all principal
/// minors) is used as it is, so that an SPD derivative is reproduced exactly.
pub(super) fn principal_frame_derivative(
    svd: &Svd3,
    hessian: Mat3,
    pairs: [Vec3; 2],
    project: bool,
) -> StressDerivative {
    let (u, v) = (svd.u, svd.v);
    let columns = |m: Mat3| [m.x_axis, m.y_axis, m.z_axis];
    let (u_cols, v_cols) = (columns(u), columns(v));
    let scaling = if project {
        positive_part(hessian)
    } else {
        hessian
    };
    let mut out = StressDerivative::default();
    let diagonal_modes = [0, 1, 2].map(|i| vec_outer(pick(&u_cols, i), pick(&v_cols, i)));
    let h = scaling.to_cols_array_2d();
    for i in 0..3 {
        let row = h.get(i).copied().unwrap_or([0.0; 3]);
        let di = diagonal_modes.get(i).copied().unwrap_or([0.0; 9]);
        out.add_outer(row.get(i).copied().unwrap_or(0.0), &di);
        for j in (i + 1)..3 {
            // Symmetric: the mean of (i, j) and (j, i), exact for a symmetric Hessian.
            let hij = h.get(j).and_then(|c| c.get(i)).copied().unwrap_or(0.0);
            let hji = row.get(j).copied().unwrap_or(0.0);
            let dj = diagonal_modes.get(j).copied().unwrap_or([0.0; 9]);
            out.add_symmetric_outer(0.5 * (hij + hji), &di, &dj);
        }
    }
    let [flip, twist] = pairs.map(|v| v.to_array());
    for (k, &(i, j)) in PAIRS.iter().enumerate() {
        let a = vec_outer(pick(&u_cols, i), pick(&v_cols, j));
        let b = vec_outer(pick(&u_cols, j), pick(&v_cols, i));
        let symmetric: [Real; 9] = core::array::from_fn(|n| pick9(&a, n) + pick9(&b, n));
        let antisymmetric: [Real; 9] = core::array::from_fn(|n| pick9(&a, n) - pick9(&b, n));
        let (mut lf, mut lt) = (
            flip.get(k).copied().unwrap_or(0.0),
            twist.get(k).copied().unwrap_or(0.0),
        );
        if project {
            lf = clamp_negative(lf);
            lt = clamp_negative(lt);
        }
        // The modes (a +- b) / sqrt 2: weight 1/2 on the unnormalised outer products.
        out.add_outer(0.5 * lf, &symmetric);
        out.add_outer(0.5 * lt, &antisymmetric);
    }
    out
}

#[inline(always)]
fn pick(columns: &[Vec3; 3], i: usize) -> Vec3 {
    columns.get(i).copied().unwrap_or(Vec3::ZERO)
}

#[inline(always)]
fn pick9(x: &[Real; 9], i: usize) -> Real {
    x.get(i).copied().unwrap_or(0.0)
}

/// The positive semi-definite part `Q max(L, 0) Q^T` of a symmetric 3x3 matrix, or the matrix
/// itself when it is already PSD (all principal minors `>= 0`; NaN fails the test and takes
/// the eigen path, which propagates it).
pub(super) fn positive_part(m: Mat3) -> Mat3 {
    let a = m.to_cols_array_2d();
    let e = |i: usize, j: usize| a.get(j).and_then(|c| c.get(i)).copied().unwrap_or(0.0);
    let minor = |i: usize, j: usize| e(i, i) * e(j, j) - e(i, j) * e(j, i);
    let psd = e(0, 0) >= 0.0
        && e(1, 1) >= 0.0
        && e(2, 2) >= 0.0
        && minor(0, 1) >= 0.0
        && minor(0, 2) >= 0.0
        && minor(1, 2) >= 0.0
        && m.determinant() >= 0.0;
    if psd {
        return m;
    }
    let (values, vectors) = symmetric_eigen3(m);
    let clamped = Vec3::new(
        clamp_negative(values.x),
        clamp_negative(values.y),
        clamp_negative(values.z),
    );
    vectors.mul_diagonal_scale(clamped) * vectors.transpose()
}

/// Eigenvalues and eigenvectors (columns, orthonormal) of the symmetric part of `m`, by cyclic
/// Jacobi rotations (Golub and Van Loan, "Matrix Computations", section 8.5): six sweeps of
/// the three pairs, skipping zero off-diagonal entries; 3x3 Jacobi converges quadratically, so
/// this is rounding-accurate for every finite input. No branches that can fail, no panic; NaN
/// propagates.
pub(super) fn symmetric_eigen3(m: Mat3) -> (Vec3, Mat3) {
    let c = m.to_cols_array_2d();
    let mut a = [[0.0; 3]; 3];
    for (i, row) in a.iter_mut().enumerate() {
        for (j, value) in row.iter_mut().enumerate() {
            let ij = c.get(j).and_then(|col| col.get(i)).copied().unwrap_or(0.0);
            let ji = c.get(i).and_then(|col| col.get(j)).copied().unwrap_or(0.0);
            *value = 0.5 * (ij + ji);
        }
    }
    let mut q = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..6 {
        for (p, r) in [(0usize, 1usize), (0, 2), (1, 2)] {
            jacobi_rotation(&mut a, &mut q, p, r);
        }
    }
    let diag = |i: usize| a.get(i).and_then(|row| row.get(i)).copied().unwrap_or(0.0);
    let col = |j: usize| {
        Vec3::new(
            q.first().and_then(|row| row.get(j)).copied().unwrap_or(0.0),
            q.get(1).and_then(|row| row.get(j)).copied().unwrap_or(0.0),
            q.get(2).and_then(|row| row.get(j)).copied().unwrap_or(0.0),
        )
    };
    (
        Vec3::new(diag(0), diag(1), diag(2)),
        Mat3::from_cols(col(0), col(1), col(2)),
    )
}

/// The plane rotation of a symmetric Jacobi step that zeroes the off-diagonal entry `apr` of
/// the 2x2 block `[[app, apr], [apr, arr]]` (Golub and Van Loan, algorithm 8.4.2): the smaller of
/// the two angles. Shared by every symmetric Jacobi eigen-solver of the crate (the 3x3 stress
/// derivatives here, the triangle and membrane blocks of `element`, the contact pairs of
/// `step::contact::potential`), so they rotate with the same bits.
#[derive(Clone, Copy, Debug)]
pub(crate) struct JacobiAngle {
    /// `tan` of the angle: the smaller root of `t^2 + 2 theta t - 1 = 0`, `theta = (arr - app)
    /// / (2 apr)`.
    pub t: Real,
    /// `cos` of the angle.
    pub cos: Real,
    /// `sin` of the angle.
    pub sin: Real,
}

impl JacobiAngle {
    /// The rotation zeroing `apr` (which must not be 0; the callers skip a zero entry).
    #[inline(always)]
    pub fn zeroing(app: Real, arr: Real, apr: Real) -> JacobiAngle {
        let theta = (arr - app) / (2.0 * apr);
        // For a huge theta, theta^2 would overflow and t = 1 / (2 theta) to rounding.
        const HUGE: Real = 1.0e15;
        let t = if theta.abs() > HUGE {
            0.5 / theta
        } else {
            let sign = if theta < 0.0 { -1.0 } else { 1.0 };
            sign / (theta.abs() + math::sqrt(theta * theta + 1.0))
        };
        let cos = 1.0 / math::sqrt(t * t + 1.0);
        JacobiAngle {
            t,
            cos,
            sin: t * cos,
        }
    }
}

/// One Jacobi rotation zeroing `a[p][r]` (`p < r`), accumulated into the columns of `q`.
#[inline(always)]
fn jacobi_rotation(a: &mut [[Real; 3]; 3], q: &mut [[Real; 3]; 3], p: usize, r: usize) {
    let get = |a: &[[Real; 3]; 3], i: usize, j: usize| {
        a.get(i).and_then(|row| row.get(j)).copied().unwrap_or(0.0)
    };
    let apr = get(a, p, r);
    if apr == 0.0 {
        return;
    }
    let (app, arr) = (get(a, p, p), get(a, r, r));
    let JacobiAngle { t, cos, sin } = JacobiAngle::zeroing(app, arr, apr);
    let other = 3 - p - r;
    let (aop, aor) = (get(a, other, p), get(a, other, r));
    let new_op = cos * aop - sin * aor;
    let new_or = sin * aop + cos * aor;
    let set = |a: &mut [[Real; 3]; 3], i: usize, j: usize, x: Real| {
        if let Some(v) = a.get_mut(i).and_then(|row| row.get_mut(j)) {
            *v = x;
        }
    };
    set(a, p, p, app - t * apr);
    set(a, r, r, arr + t * apr);
    set(a, p, r, 0.0);
    set(a, r, p, 0.0);
    set(a, other, p, new_op);
    set(a, p, other, new_op);
    set(a, other, r, new_or);
    set(a, r, other, new_or);
    for row in q.iter_mut() {
        let (qp, qr) = (
            row.get(p).copied().unwrap_or(0.0),
            row.get(r).copied().unwrap_or(0.0),
        );
        if let Some(x) = row.get_mut(p) {
            *x = cos * qp - sin * qr;
        }
        if let Some(x) = row.get_mut(r) {
            *x = sin * qp + cos * qr;
        }
    }
}

/// The principal Hessian of a model written as `W(I_C, J)`, from `(a, b) = (2 W_I, W_J)` and
/// the second derivatives `(W_II, W_IJ, W_JJ)`: with `dI_C/ds_i = 2 s_i`, `dJ/ds_i = p_i`
/// (`p_i` the product of the other two stretches) and `d p_i / d s_j = s_k`,
/// `H_ij = 4 W_II s_i s_j + 2 W_IJ (s_i p_j + p_i s_j) + W_JJ p_i p_j + a delta_ij
/// + b (1 - delta_ij) s_k`.
pub(super) fn invariant_principal_hessian(
    s: Vec3,
    (a, b): (Real, Real),
    (w_ii, w_ij, w_jj): (Real, Real, Real),
) -> Mat3 {
    let s = s.to_array();
    let p = [s[1] * s[2], s[2] * s[0], s[0] * s[1]];
    let entry = |i: usize, j: usize| {
        let (si, sj) = (pick3(&s, i), pick3(&s, j));
        let (pi, pj) = (pick3(&p, i), pick3(&p, j));
        let second = 4.0 * w_ii * (si * sj) + 2.0 * w_ij * (si * pj + pi * sj) + w_jj * (pi * pj);
        if i == j {
            second + a
        } else {
            second + b * pick3(&s, 3 - i - j)
        }
    };
    Mat3::from_cols_array_2d(&[0, 1, 2].map(|j| [0, 1, 2].map(|i| entry(i, j))))
}

#[inline(always)]
fn pick3(x: &[Real; 3], i: usize) -> Real {
    x.get(i).copied().unwrap_or(0.0)
}

/// `[flip, twist]` eigenvalues of a model written as `W(I_C, J)`, pair `k` (third axis `k`):
/// `a - b s_k` and `a + b s_k` (see the module documentation), exact at repeated stretches.
pub(super) fn invariant_pair_eigenvalues(s: Vec3, (a, b): (Real, Real)) -> [Vec3; 2] {
    [Vec3::splat(a) - s * b, Vec3::splat(a) + s * b]
}

/// `dP = (dP/dF) : dF` of a model written as `W(I_C, J)`: `P = a F + b cof(F)` with
/// `da = 2 W_II dI + 2 W_IJ dJ`, `db = W_IJ dI + W_JJ dJ`, `dI = 2 F : dF`, `dJ = cof(F) : dF`
/// and `d cof(F)` column by column (`cof_0 = F_1 x F_2`: `dF_1 x F_2 + F_1 x dF_2`, cyclically).
pub(super) fn invariant_first_piola_differential(
    f: Mat3,
    df: Mat3,
    (a, b): (Real, Real),
    (w_ii, w_ij, w_jj): (Real, Real, Real),
) -> Mat3 {
    let cof = Mat3::from_cols(
        f.y_axis.cross(f.z_axis),
        f.z_axis.cross(f.x_axis),
        f.x_axis.cross(f.y_axis),
    );
    let d_cof = Mat3::from_cols(
        df.y_axis.cross(f.z_axis) + f.y_axis.cross(df.z_axis),
        df.z_axis.cross(f.x_axis) + f.z_axis.cross(df.x_axis),
        df.x_axis.cross(f.y_axis) + f.x_axis.cross(df.y_axis),
    );
    let contract =
        |x: Mat3, y: Mat3| x.x_axis.dot(y.x_axis) + x.y_axis.dot(y.y_axis) + x.z_axis.dot(y.z_axis);
    let d_ic = 2.0 * contract(f, df);
    let d_j = contract(cof, df);
    let da = 2.0 * w_ii * d_ic + 2.0 * w_ij * d_j;
    let db = w_ij * d_ic + w_jj * d_j;
    f * da + df * a + cof * db + d_cof * b
}

/// The provided principal Hessian of [`Material`](super::Material): central differences of
/// `principal_stress` with step `eps^(1/3) max(1, |s|)`, symmetrised (truncation and rounding
/// both of order `eps^(2/3)` relative).
pub(super) fn difference_principal_hessian(stress: impl Fn(Vec3) -> Vec3, s: Vec3) -> Mat3 {
    let scale = s.abs().max_element().max(1.0);
    let step = math::cbrt(Real::EPSILON) * scale;
    let column = |axis: Vec3| (stress(s + axis * step) - stress(s - axis * step)) / (2.0 * step);
    let h = Mat3::from_cols(column(Vec3::X), column(Vec3::Y), column(Vec3::Z));
    (h + h.transpose()) * 0.5
}

/// The provided `[flip, twist]` eigenvalues of [`Material`](super::Material): the quotients
/// `(psi_i - psi_j) / (s_i - s_j)` and `(psi_i + psi_j) / (s_i + s_j)`, replaced by their limits
/// `(H_ii + H_jj)/2 -+ H_ij` where the denominator is below `sqrt(eps) max(1, |s|)` (the
/// isotropy of `W` makes `psi_i - psi_j` vanish at `s_i = s_j` and `psi_i + psi_j` at
/// `s_i = -s_j`).
pub(super) fn quotient_pair_eigenvalues(psi: Vec3, hessian: Mat3, s: Vec3) -> [Vec3; 2] {
    let threshold = math::sqrt(Real::EPSILON) * s.abs().max_element().max(1.0);
    let (psi, s) = (psi.to_array(), s.to_array());
    let h = hessian.to_cols_array_2d();
    let e = |i: usize, j: usize| h.get(j).and_then(|c| c.get(i)).copied().unwrap_or(0.0);
    let mut flip = [0.0; 3];
    let mut twist = [0.0; 3];
    for (k, &(i, j)) in PAIRS.iter().enumerate() {
        let (si, sj, pi, pj) = (pick3(&s, i), pick3(&s, j), pick3(&psi, i), pick3(&psi, j));
        let mean_diagonal = 0.5 * (e(i, i) + e(j, j));
        let off = 0.5 * (e(i, j) + e(j, i));
        let difference = si - sj;
        let sum = si + sj;
        if let Some(x) = flip.get_mut(k) {
            *x = if difference.abs() > threshold {
                (pi - pj) / difference
            } else {
                mean_diagonal - off
            };
        }
        if let Some(x) = twist.get_mut(k) {
            *x = if sum.abs() > threshold {
                (pi + pj) / sum
            } else {
                mean_diagonal + off
            };
        }
    }
    [Vec3::from_array(flip), Vec3::from_array(twist)]
}
