//! Second derivatives of the triangle model ([`TriangleStVK`]) and their SPD projection, for 2D
//! solids (`F` 2x2, `dP/dF` 4x4) and membranes (`F` 3x2, `dP/dF` 6x6), and the element
//! Hessian caches built on them (`docs/math.md` section 6).
//!
//! # Conventions
//! `vec(F)` is column-major: index `d * column + row` with `d` the dimension of the columns (2
//! or 3). `dP = dF S + F dS` with `dS = 2 mu dG + lambda tr(dG) I` and
//! `dG = (dF^T F + F^T dF) / 2` (2x2).
//!
//! # Projection
//! A membrane's `F` has no square SVD, so instead of the analytic eigensystem of the tetrahedra
//! the 4x4 or 6x6 symmetric derivative is diagonalised numerically by cyclic Jacobi rotations
//! (Golub and Van Loan, "Matrix Computations", section 8.5: ten sweeps, rounding-accurate for
//! these sizes) and its negative eigenvalues set to zero (NaN kept). A derivative that is
//! already positive semi-definite (every Jacobi eigenvalue `>= 0`) is returned as it was. The
//! modes that go negative are the ones of the tetrahedra: compression along an axis (StVK
//! softening below stretch `1/sqrt 3`) and, for a membrane, the out-of-plane modes `n w^T`
//! whose eigenvalue is the in-plane stress `w^T S w`, negative under compression (buckling).
//!
//! # Element Hessian
//! As for tetrahedra ([`TetHessian`](super::TetHessian)), the cache holds the stiffness on the
//! edge displacements `(v1 - v0, v2 - v0)`: `K = A T^T (dP/dF) T`, `dF = [v1 - v0, v2 - v0]
//! Dm^-1`, `A` the rest area; `(H v)_a = K (v1 - v0, v2 - v0)` for corners 1, 2 and
//! `-(h_1 + h_2)` for corner 0. Per element: 16 numbers for a 2D triangle (64 bytes in f32,
//! 128 in f64), 36 for a membrane (144 / 288 bytes).

use super::super::material::hessian::JacobiAngle;
use super::super::types::{Mat2, Mat3, Real, Vec2, Vec3};
use super::{TriRest, TriangleStVK, Vector};

/// A symmetric `N x N` matrix (full storage): a triangle's stress derivative `dP/dF` (Pa, on
/// `vec(dF)`, `N = 4` or `6`) or its element stiffness on the edge displacements (N/m).
/// `Default` is the zero matrix.
///
/// ```
/// use softfem::element::TriangleStVK;
/// use softfem::glam::Vec3;
/// use softfem::material::StVK;
///
/// let sheet = TriangleStVK::new(&StVK::from_lame(1.0e5, 1.0e5)?);
/// // A membrane squeezed in its plane: bending out of the plane (the z components of both
/// // columns, indices 2 and 5) releases energy, a negative curvature ...
/// let squeezed = [Vec3::X * 0.9, Vec3::Y * 0.9];
/// let exact = sheet.membrane_stress_derivative(squeezed);
/// assert!(exact.entry(2, 2) < 0.0 && exact.entry(5, 5) < 0.0);
/// // ... which the projection removes, keeping the in-plane stiffness.
/// let projected = sheet.membrane_projected_stress_derivative(squeezed);
/// assert_eq!((projected.entry(2, 2), projected.entry(5, 5)), (0.0, 0.0));
/// assert!((projected.entry(0, 0) - exact.entry(0, 0)).abs() < 1e-5 * exact.entry(0, 0));
/// # Ok::<(), softfem::MaterialError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SymmetricMatrix<const N: usize> {
    entries: [[Real; N]; N],
}

impl<const N: usize> Default for SymmetricMatrix<N> {
    #[inline]
    fn default() -> Self {
        SymmetricMatrix {
            entries: [[0.0; N]; N],
        }
    }
}

impl<const N: usize> SymmetricMatrix<N> {
    /// Entry `(i, j)`; 0 for an index out of range (no panic).
    #[inline]
    #[must_use]
    pub fn entry(&self, i: usize, j: usize) -> Real {
        self.entries
            .get(i)
            .and_then(|row| row.get(j))
            .copied()
            .unwrap_or(0.0)
    }

    /// The product `self * x`, rows in order.
    #[inline]
    #[must_use]
    pub fn apply(&self, x: &[Real; N]) -> [Real; N] {
        self.entries
            .map(|row| row.iter().zip(x).map(|(&a, &b)| a * b).sum())
    }

    /// The congruence `factor T^T self T` with `T` from `E = [e_0, e_1]` (edges of dimension
    /// `d`, stacked as `d a + r`) to `dF = E m`: entry `((a, r), (b, s))` is
    /// `factor sum_{c,e} m_ac m_be self[(c, r), (e, s)]`.
    fn congruence(&self, m: Mat2, factor: Real, d: usize) -> SymmetricMatrix<N> {
        // m_ac: row a, column c (glam columns: m.col(c)[a]).
        let g = |a: usize, c: usize| {
            let column = if c == 0 { m.x_axis } else { m.y_axis };
            if a == 0 { column.x } else { column.y }
        };
        let mut out = SymmetricMatrix::default();
        for (i, row) in out.entries.iter_mut().enumerate() {
            let (a, r) = (i / d, i % d);
            for (j, value) in row.iter_mut().enumerate() {
                let (b, s) = (j / d, j % d);
                let mut sum = 0.0;
                for c in 0..2 {
                    for e in 0..2 {
                        sum += g(a, c) * g(b, e) * self.entry(d * c + r, d * e + s);
                    }
                }
                *value = factor * sum;
            }
        }
        out
    }

    /// The matrix with these rows (row `i`, column `j`: `rows[i][j]`), taken as they are: the
    /// caller makes them symmetric. Only tests use it now (the contact potential's projection
    /// checks its spectra against this solver).
    #[cfg(test)]
    #[inline]
    #[must_use]
    pub(crate) fn from_rows(rows: [[Real; N]; N]) -> SymmetricMatrix<N> {
        SymmetricMatrix { entries: rows }
    }

    /// The eigenvalues (unordered) and the eigenvectors (column `i` of the returned rows, i.e.
    /// `vectors[row][i]`, belongs to eigenvalue `i`) by ten sweeps of cyclic Jacobi rotations
    /// (see the module documentation).
    pub(crate) fn eigen(&self) -> ([Real; N], [[Real; N]; N]) {
        let mut a = self.entries;
        let mut q = [[0.0; N]; N];
        for (i, row) in q.iter_mut().enumerate() {
            if let Some(x) = row.get_mut(i) {
                *x = 1.0;
            }
        }
        for _ in 0..10 {
            for p in 0..N {
                for r in (p + 1)..N {
                    rotate(&mut a, &mut q, p, r);
                }
            }
        }
        let values: [Real; N] =
            core::array::from_fn(|i| a.get(i).and_then(|row| row.get(i)).copied().unwrap_or(0.0));
        (values, q)
    }

    /// The positive semi-definite part (see the module documentation): the matrix itself when
    /// every Jacobi eigenvalue is `>= 0`, else `Q max(Lambda, 0) Q^T`.
    pub(crate) fn positive_part(&self) -> SymmetricMatrix<N> {
        let (values, q) = self.eigen();
        if values.iter().all(|&l| l >= 0.0) {
            return *self;
        }
        let clamped = values.map(|l| if l < 0.0 { 0.0 } else { l });
        let mut out = SymmetricMatrix::default();
        for (i, row) in out.entries.iter_mut().enumerate() {
            for (j, value) in row.iter_mut().enumerate() {
                let qi = q.get(i).copied().unwrap_or([0.0; N]);
                let qj = q.get(j).copied().unwrap_or([0.0; N]);
                *value = qi
                    .iter()
                    .zip(&qj)
                    .zip(&clamped)
                    .map(|((&x, &y), &l)| x * l * y)
                    .sum();
            }
        }
        out
    }
}

/// One Jacobi rotation zeroing `a[p][r]` (`p < r`) of a symmetric `N x N`, accumulated into the
/// columns of `q`.
fn rotate<const N: usize>(a: &mut [[Real; N]; N], q: &mut [[Real; N]; N], p: usize, r: usize) {
    let get = |a: &[[Real; N]; N], i: usize, j: usize| {
        a.get(i).and_then(|row| row.get(j)).copied().unwrap_or(0.0)
    };
    let apr = get(a, p, r);
    if apr == 0.0 {
        return;
    }
    let JacobiAngle { cos, sin, .. } = JacobiAngle::zeroing(get(a, p, p), get(a, r, r), apr);
    // a <- J^T a J with J the rotation in the (p, r) plane: columns, then rows.
    for row in a.iter_mut() {
        let (x, y) = (
            row.get(p).copied().unwrap_or(0.0),
            row.get(r).copied().unwrap_or(0.0),
        );
        if let Some(v) = row.get_mut(p) {
            *v = cos * x - sin * y;
        }
        if let Some(v) = row.get_mut(r) {
            *v = sin * x + cos * y;
        }
    }
    let (row_p, row_r) = (
        a.get(p).copied().unwrap_or([0.0; N]),
        a.get(r).copied().unwrap_or([0.0; N]),
    );
    if let Some(row) = a.get_mut(p) {
        for ((v, &x), &y) in row.iter_mut().zip(&row_p).zip(&row_r) {
            *v = cos * x - sin * y;
        }
    }
    if let Some(row) = a.get_mut(r) {
        for ((v, &x), &y) in row.iter_mut().zip(&row_p).zip(&row_r) {
            *v = sin * x + cos * y;
        }
    }
    // Exactly zero where the rotation was aimed, symmetric elsewhere by construction.
    if let Some(v) = a.get_mut(p).and_then(|row| row.get_mut(r)) {
        *v = 0.0;
    }
    if let Some(v) = a.get_mut(r).and_then(|row| row.get_mut(p)) {
        *v = 0.0;
    }
    for row in q.iter_mut() {
        let (x, y) = (
            row.get(p).copied().unwrap_or(0.0),
            row.get(r).copied().unwrap_or(0.0),
        );
        if let Some(v) = row.get_mut(p) {
            *v = cos * x - sin * y;
        }
        if let Some(v) = row.get_mut(r) {
            *v = sin * x + cos * y;
        }
    }
}

/// The column types of triangle deformation gradients, by coordinates.
trait Coordinates: Vector {
    /// The number of coordinates (2 or 3).
    const DIM: usize;
    /// Coordinate `r` (0 out of range).
    fn coordinate(self, r: usize) -> Real;
    /// The unit vector along axis `r` (zero out of range).
    fn unit(r: usize) -> Self;
}

/// [`Coordinates`] of a glam vector type with the unit vectors `axes`, in order.
macro_rules! coordinates {
    ($vector:ident, $dim:literal, [$($axis:ident),*]) => {
        impl Coordinates for $vector {
            const DIM: usize = $dim;
            #[inline(always)]
            fn coordinate(self, r: usize) -> Real {
                self.to_array().get(r).copied().unwrap_or(0.0)
            }
            #[inline(always)]
            fn unit(r: usize) -> Self {
                [$($vector::$axis),*].get(r).copied().unwrap_or($vector::ZERO)
            }
        }
    };
}
coordinates!(Vec2, 2, [X, Y]);
coordinates!(Vec3, 3, [X, Y, Z]);

impl TriangleStVK {
    /// `dP` of a deformation gradient given by its columns (either dimension).
    fn differential<V: Vector>(&self, [f0, f1]: [V; 2], [d0, d1]: [V; 2]) -> [V; 2] {
        let (lambda, mu) = self.lame();
        let (g00, g01, g11) = (
            0.5 * (f0.dot(f0) - 1.0),
            0.5 * f0.dot(f1),
            0.5 * (f1.dot(f1) - 1.0),
        );
        let (h00, h01, h11) = (d0.dot(f0), 0.5 * (d0.dot(f1) + f0.dot(d1)), d1.dot(f1));
        let volumetric = lambda * (g00 + g11);
        let (s00, s01, s11) = (
            2.0 * mu * g00 + volumetric,
            2.0 * mu * g01,
            2.0 * mu * g11 + volumetric,
        );
        let d_volumetric = lambda * (h00 + h11);
        let (t00, t01, t11) = (
            2.0 * mu * h00 + d_volumetric,
            2.0 * mu * h01,
            2.0 * mu * h11 + d_volumetric,
        );
        [
            d0 * s00 + d1 * s01 + f0 * t00 + f1 * t01,
            d0 * s01 + d1 * s11 + f0 * t01 + f1 * t11,
        ]
    }

    /// The exact derivative as a matrix, column `j` the differential along unit `j`.
    fn derivative<V: Coordinates, const N: usize>(&self, f: [V; 2]) -> SymmetricMatrix<N> {
        let d = V::DIM;
        let mut columns = [[0.0; N]; N];
        for (j, column) in columns.iter_mut().enumerate() {
            let unit = V::unit(j % d);
            let df = if j < d {
                [unit, V::ZERO]
            } else {
                [V::ZERO, unit]
            };
            let [p0, p1] = self.differential(f, df);
            for (i, value) in column.iter_mut().enumerate() {
                let p = if i < d { p0 } else { p1 };
                *value = p.coordinate(i % d);
            }
        }
        // Symmetric in exact arithmetic; the mean removes rounding asymmetry.
        let mut out = SymmetricMatrix::default();
        for (i, row) in out.entries.iter_mut().enumerate() {
            for (j, value) in row.iter_mut().enumerate() {
                let at = |a: usize, b: usize| {
                    columns
                        .get(a)
                        .and_then(|c| c.get(b))
                        .copied()
                        .unwrap_or(0.0)
                };
                *value = 0.5 * (at(j, i) + at(i, j));
            }
        }
        out
    }

    /// The exact stress differential `dP = (dP/dF) : dF` (Pa) of a 2D deformation gradient `f`
    /// in the direction `df`.
    #[inline]
    #[must_use]
    pub fn first_piola_differential(&self, f: Mat2, df: Mat2) -> Mat2 {
        let [p0, p1] = self.differential([f.x_axis, f.y_axis], [df.x_axis, df.y_axis]);
        Mat2::from_cols(p0, p1)
    }

    /// The exact stress differential (Pa, 3x2 as columns) of a membrane deformation gradient
    /// `f` (3x2, columns) in the direction `df`.
    #[inline]
    #[must_use]
    pub fn membrane_first_piola_differential(&self, f: [Vec3; 2], df: [Vec3; 2]) -> [Vec3; 2] {
        self.differential(f, df)
    }

    /// The exact 4x4 stress derivative `dP/dF` (Pa) of a 2D deformation gradient `f`
    /// (`vec` index `2 * column + row`).
    #[inline]
    #[must_use]
    pub fn stress_derivative(&self, f: Mat2) -> SymmetricMatrix<4> {
        self.derivative([f.x_axis, f.y_axis])
    }

    /// The 4x4 stress derivative of a 2D deformation gradient `f` projected onto the symmetric
    /// positive semi-definite matrices (see the module documentation).
    #[inline]
    #[must_use]
    pub fn projected_stress_derivative(&self, f: Mat2) -> SymmetricMatrix<4> {
        self.stress_derivative(f).positive_part()
    }

    /// The exact 6x6 stress derivative `dP/dF` (Pa) of a membrane deformation gradient `f`
    /// (3x2, columns; `vec` index `3 * column + row`).
    #[inline]
    #[must_use]
    pub fn membrane_stress_derivative(&self, f: [Vec3; 2]) -> SymmetricMatrix<6> {
        self.derivative(f)
    }

    /// The 6x6 membrane stress derivative projected onto the symmetric positive semi-definite
    /// matrices (see the module documentation).
    #[inline]
    #[must_use]
    pub fn membrane_projected_stress_derivative(&self, f: [Vec3; 2]) -> SymmetricMatrix<6> {
        self.membrane_stress_derivative(f).positive_part()
    }
}

/// Generates the element Hessian cache of one kind of triangle.
macro_rules! triangle_hessian {
    ($name:ident, $vector:ident, $block:ident, $n:literal, $dim:literal, $derivative:ident,
     $projected:ident, $gradient:ident, $kind:literal, $bytes:literal) => {
        #[doc = concat!("The cached projected (SPD) element Hessian of a ", $kind, " triangle: \
            its stiffness `K = A T^T (dP/dF) T` on the edge displacements (N/m), ", $bytes,
                    " per element (see the module documentation). `Default` (zero) sizes buffers.")]
        #[derive(Clone, Copy, Debug, Default, PartialEq)]
        pub struct $name {
            stiffness: SymmetricMatrix<$n>,
        }

        impl $name {
            #[doc = concat!("The projected Hessian data of `material` on the ", $kind,
                        " triangle `rest` at deformed positions `corners` (m).")]
            #[inline]
            #[must_use]
            pub fn new(material: &TriangleStVK, rest: &TriRest, corners: [$vector; 3]) -> Self {
                let f = rest.$gradient(corners);
                Self::from_derivative(&material.$projected(f), rest)
            }

            /// The exact (unprojected, possibly indefinite) Hessian data.
            #[inline]
            #[must_use]
            pub fn exact(material: &TriangleStVK, rest: &TriRest, corners: [$vector; 3]) -> Self {
                let f = rest.$gradient(corners);
                Self::from_derivative(&material.$derivative(f), rest)
            }

            fn from_derivative(derivative: &SymmetricMatrix<$n>, rest: &TriRest) -> Self {
                $name {
                    stiffness: derivative.congruence(rest.dm_inv, rest.area, $dim),
                }
            }

            /// The element Hessian times the corner displacements `v` (m): `H v`.
            #[inline]
            #[must_use]
            pub fn product(&self, v: [$vector; 3]) -> [$vector; 3] {
                let [v0, v1, v2] = v;
                let (e1, e2) = (v1 - v0, v2 - v0);
                let x: [Real; $n] = core::array::from_fn(|i| {
                    let e = if i < $dim { e1 } else { e2 };
                    e.coordinate(i % $dim)
                });
                let h = self.stiffness.apply(&x);
                let column = |a: usize| {
                    $vector::from_array(core::array::from_fn(|r| {
                        h.get($dim * a + r).copied().unwrap_or(0.0)
                    }))
                };
                let (h1, h2) = (column(0), column(1));
                [-(h1 + h2), h1, h2]
            }

            /// The diagonal block of the element Hessian for corner `corner` (0..3), symmetric
            /// PSD for projected data; zero out of range.
            #[inline]
            #[must_use]
            pub fn vertex_block(&self, corner: usize) -> $block {
                let k = &self.stiffness;
                let block = |a: usize, b: usize| {
                    $block::from_cols_array_2d(&core::array::from_fn(|s| {
                        core::array::from_fn(|r| k.entry($dim * a + r, $dim * b + s))
                    }))
                };
                match corner {
                    0 => block(0, 0) + block(0, 1) + block(1, 0) + block(1, 1),
                    1 => block(0, 0),
                    2 => block(1, 1),
                    _ => $block::ZERO,
                }
            }
        }
    };
}

triangle_hessian!(
    TriHessian,
    Vec2,
    Mat2,
    4,
    2,
    stress_derivative,
    projected_stress_derivative,
    deformation_gradient,
    "2D",
    "64 bytes in f32 and 128 in f64"
);
triangle_hessian!(
    MembraneHessian,
    Vec3,
    Mat3,
    6,
    3,
    membrane_stress_derivative,
    membrane_projected_stress_derivative,
    membrane_deformation_gradient,
    "membrane",
    "144 bytes in f32 and 288 in f64"
);
