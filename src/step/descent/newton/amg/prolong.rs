//! The prolongators: the tentative one from the near-null space restricted to each aggregate
//! and orthonormalised there (a thin QR per aggregate; the `R` factors are the next level's
//! near-null space), then smoothed by one damped Jacobi step, `P = (I - omega D^-1 A) P_tent`
//! with `omega = 4 / (3 rho(D^-1 A))` (Vaněk, Mandel and Brezina 1996, sections 3-4).

use alloc::vec::Vec;

use super::super::super::super::super::math;
use super::super::super::super::super::types::Real;
use super::super::super::super::model::ElasticModel;
use super::csr::{Csr, Multiply, Product};
use super::{MODES, OutOfMemory, filled};

/// A column of a local QR whose norm after orthogonalisation is below this fraction of its
/// norm before is taken as dependent on the earlier ones (an aggregate too small or too flat
/// to carry every rigid mode) and dropped: its column of `P_tent` is zero.
const DEPENDENT: Real = 1e-6;

/// The tentative prolongator over `nodes` nodes of `block` rows each, `aggregate[i]` node `i`'s
/// aggregate ([`NONE`](super::aggregate::NONE) for none) of `count`, and the near-null space
/// `modes` (row-major, [`MODES`] numbers a row). Returns `P_tent` (rows x `MODES count`) and the
/// coarse near-null space (`MODES count` rows).
pub(crate) fn tentative(
    (block, aggregate, count): (usize, &[u32], u32),
    modes: &[Real],
) -> Result<(Csr, Vec<Real>), OutOfMemory> {
    let rows = aggregate.len() * block;
    let count = count as usize;
    // The nodes of each aggregate, in node order: a counting sort.
    let mut first = filled(count + 1, 0usize)?;
    for &a in aggregate {
        if let Some(c) = first.get_mut((a as usize).saturating_add(1)) {
            *c += 1;
        }
    }
    for k in 1..first.len() {
        let previous = first.get(k - 1).copied().unwrap_or(0);
        if let Some(c) = first.get_mut(k) {
            *c += previous;
        }
    }
    let mut next = first.clone();
    let mut members = filled(first.last().copied().unwrap_or(0), 0u32)?;
    for (i, &a) in aggregate.iter().enumerate() {
        if let Some(at) = next.get_mut(a as usize) {
            if let Some(slot) = members.get_mut(*at) {
                *slot = i as u32;
            }
            *at += 1;
        }
    }
    // P_tent: MODES entries in every row of an aggregated node.
    let mut starts = filled(rows + 1, 0usize)?;
    for i in 0..rows {
        let aggregated = aggregate.get(i / block.max(1)).is_some_and(|&a| (a as usize) < count);
        let previous = starts.get(i).copied().unwrap_or(0);
        if let Some(s) = starts.get_mut(i + 1) {
            *s = previous + if aggregated { MODES } else { 0 };
        }
    }
    let entries = starts.last().copied().unwrap_or(0);
    let mut columns = filled(entries, 0u32)?;
    let mut values = filled(entries, 0.0)?;
    let mut coarse = filled(count * MODES * MODES, 0.0)?;
    let mut local: Vec<Real> = Vec::new();
    for a in 0..count {
        let nodes = members
            .get(first.get(a).copied().unwrap_or(0)..first.get(a + 1).copied().unwrap_or(0))
            .unwrap_or(&[]);
        let m = nodes.len() * block;
        // The aggregate's rows of the near-null space, column-major (MODES columns of m).
        local.clear();
        local.try_reserve(m * MODES).map_err(|_| OutOfMemory)?;
        local.resize(m * MODES, 0.0);
        for (l, &node) in nodes.iter().enumerate() {
            for r in 0..block {
                let row = node as usize * block + r;
                for c in 0..MODES {
                    let v = modes.get(row * MODES + c).copied().unwrap_or(0.0);
                    if let Some(slot) = local.get_mut(c * m + l * block + r) {
                        *slot = v;
                    }
                }
            }
        }
        let r_factor = orthonormalise(&mut local, m);
        for (c, column) in r_factor.iter().enumerate() {
            for (k, &v) in column.iter().enumerate() {
                // R is upper triangular: row k, column c.
                if let Some(slot) = coarse.get_mut((a * MODES + k) * MODES + c) {
                    *slot = v;
                }
            }
        }
        for (l, &node) in nodes.iter().enumerate() {
            for r in 0..block {
                let row = node as usize * block + r;
                let start = starts.get(row).copied().unwrap_or(0);
                for c in 0..MODES {
                    if let (Some(column), Some(value)) =
                        (columns.get_mut(start + c), values.get_mut(start + c))
                    {
                        *column = (a * MODES + c) as u32;
                        *value = local.get(c * m + l * block + r).copied().unwrap_or(0.0);
                    }
                }
            }
        }
    }
    Ok((
        Csr {
            rows,
            cols: count * MODES,
            starts,
            columns,
            values,
        },
        coarse,
    ))
}

/// Orthonormalises the [`MODES`] columns of length `m` stored one after another in `columns`
/// (modified Gram-Schmidt, applied twice, which is enough for orthogonality to rounding:
/// Giraud, Langou and Rozložník 2005), zeroing dependent ones; returns `R` by columns
/// (`r[c][k]`, zero below the diagonal), so that the input is `Q R`.
fn orthonormalise(columns: &mut [Real], m: usize) -> [[Real; MODES]; MODES] {
    let mut r = [[0.0; MODES]; MODES];
    for c in 0..MODES {
        let norm_before = math::sqrt(dot(columns, (c, c), m));
        for _ in 0..2 {
            for k in 0..c {
                let projection = dot(columns, (k, c), m);
                if let Some(entry) = r.get_mut(c).and_then(|col| col.get_mut(k)) {
                    *entry += projection;
                }
                for i in 0..m {
                    let q = columns.get(k * m + i).copied().unwrap_or(0.0);
                    if let Some(v) = columns.get_mut(c * m + i) {
                        *v -= projection * q;
                    }
                }
            }
        }
        let norm = math::sqrt(dot(columns, (c, c), m));
        let keep = norm > DEPENDENT * norm_before && norm > 0.0 && norm.is_finite();
        let scale = if keep { 1.0 / norm } else { 0.0 };
        for i in 0..m {
            if let Some(v) = columns.get_mut(c * m + i) {
                *v *= scale;
            }
        }
        if let Some(entry) = r.get_mut(c).and_then(|col| col.get_mut(c)) {
            *entry = if keep { norm } else { 0.0 };
        }
    }
    r
}

/// The dot product of columns `a` and `b` (of length `m`).
#[inline]
fn dot(columns: &[Real], (a, b): (usize, usize), m: usize) -> Real {
    let mut sum = 0.0;
    for i in 0..m {
        let x = columns.get(a * m + i).copied().unwrap_or(0.0);
        let y = columns.get(b * m + i).copied().unwrap_or(0.0);
        sum += x * y;
    }
    sum
}

/// The power iterations of [`spectral_radius`].
const POWER_ITERATIONS: u32 = 20;

/// An estimate of the largest eigenvalue of `D^-1 A` (`inverse_diagonal` = `D^-1`, zero on
/// frozen rows), `A` symmetric positive semi-definite: the Rayleigh quotient of the symmetric
/// `D^-1/2 A D^-1/2` after [`POWER_ITERATIONS`] power steps from a fixed start vector, raised by
/// 5 % (the quotient approaches the radius from below).
pub(crate) fn spectral_radius<F: ElasticModel>(
    model: &F,
    matrix: &Csr,
    inverse_diagonal: &[Real],
) -> Result<Real, OutOfMemory> {
    let n = matrix.rows;
    let root: Vec<Real> = {
        let mut root = filled(n, 0.0)?;
        for (s, &d) in root.iter_mut().zip(inverse_diagonal) {
            *s = math::sqrt(d.max(0.0));
        }
        root
    };
    // A fixed start with every component non-zero and no symmetry of the mesh.
    let mut x = filled(n, 0.0)?;
    for (i, v) in x.iter_mut().enumerate() {
        *v = 1.0 + (i.wrapping_mul(7919) % 1009) as Real / 1009.0;
    }
    let mut scaled = filled(n, 0.0)?;
    let mut y = filled(n, 0.0)?;
    let mut estimate = 0.0;
    for _ in 0..POWER_ITERATIONS {
        let norm = math::sqrt(x.iter().map(|v| v * v).fold(0.0, |a, b| a + b));
        if !(norm > 0.0 && norm.is_finite()) {
            break;
        }
        for v in x.iter_mut() {
            *v /= norm;
        }
        for ((s, &v), &r) in scaled.iter_mut().zip(&x).zip(&root) {
            *s = v * r;
        }
        model.run_vertex_pass(Product {
            matrix,
            x: &scaled,
            y: &mut y,
        });
        for (v, &r) in y.iter_mut().zip(&root) {
            *v *= r;
        }
        estimate = x.iter().zip(&y).map(|(a, b)| a * b).fold(0.0, |a, b| a + b);
        core::mem::swap(&mut x, &mut y);
    }
    Ok(1.05 * estimate)
}

/// `P = P_tent - omega D^-1 (A P_tent)`, `omega = 4 / (3 rho)`: the pattern of `A P_tent`
/// (which contains `P_tent`'s where every aggregated row has a diagonal entry).
pub(crate) fn smoothed<F: ElasticModel>(
    model: &F,
    matrix: &Csr,
    inverse_diagonal: &[Real],
    tentative: &Csr,
) -> Result<Csr, OutOfMemory> {
    let rho = spectral_radius(model, matrix, inverse_diagonal)?;
    let omega = if rho > 0.0 && rho.is_finite() {
        4.0 / (3.0 * rho)
    } else {
        0.0
    };
    let mut product = model.run_vertex_pass(Multiply {
        left: matrix,
        right: tentative,
    })?;
    for i in 0..product.rows {
        let scale = -omega * inverse_diagonal.get(i).copied().unwrap_or(0.0);
        let start = product.starts.get(i).copied().unwrap_or(0);
        let end = product.starts.get(i + 1).copied().unwrap_or(start);
        let (t_columns, t_values) = tentative.row(i);
        let columns = product.columns.get(start..end).unwrap_or(&[]);
        // Both rows ascend: merge P_tent's entries into the product's.
        let mut k = 0;
        let mut adds: [(usize, Real); MODES] = [(usize::MAX, 0.0); MODES];
        for (slot, (&c, &v)) in adds.iter_mut().zip(t_columns.iter().zip(t_values)) {
            while columns.get(k).is_some_and(|&p| p < c) {
                k += 1;
            }
            if columns.get(k) == Some(&c) {
                *slot = (start + k, v);
            }
        }
        for value in product.values.get_mut(start..end).unwrap_or(&mut []) {
            *value *= scale;
        }
        for &(at, v) in &adds {
            if let Some(value) = product.values.get_mut(at) {
                *value += v;
            }
        }
    }
    Ok(product)
}
