//! The loop's coordinates: the reference point a solve is measured from, next to the body,
//! so that rounding stays relative to the body's size rather than its distance from the origin,
//! and the shift there and back (see the descent module's documentation).

use super::*;

/// The reference point the loop's coordinates are measured from (see the module
/// documentation): along every axis on which `m = min_i |x_i| > e = max_i |x_i - x_0|`, the
/// first vertex's coordinate `c = x_0`; zero along the others.
///
/// Every `x_i - c` is then exact. Along such an axis every coordinate has `c`'s sign: one of
/// the other sign would be `|x_i| + |c| >= 2 m > e` from `c`. Say `c > 0` (the negative case is
/// its mirror image) and take any `y = x_i`. Then `y <= c + e < c + m <= 2c`, and `y >= c / 2`:
/// if `m >= c / 2` because `y >= m`, else because `y >= c - e > c - m > c / 2`. So
/// `c / 2 <= y <= 2c`, and `y - c` is exact by Sterbenz's lemma (Goldberg 1991, theorem 11; no
/// underflow: `m > 0`). A body straddling the origin along an axis (`m <= e`) has coordinates no
/// larger than its extent there already, and is not shifted along it.
pub(crate) fn reference_point<V: Vector>(positions: &[V]) -> V {
    positions.first().map_or(V::ZERO, |&first| {
        Extents::of(positions, first).reference_point(first)
    })
}

/// [`reference_point`] with the extents taken in blocks run by `model`: the same point (a
/// minimum and a maximum do not depend on how the vertices are grouped).
pub(super) fn split_reference_point<V: Vector + Send + Sync>(
    model: &impl ElasticModel,
    positions: &[V],
) -> V {
    let Some(&first) = positions.first() else {
        return V::ZERO;
    };
    let block = |_, positions: &[V]| Extents::of(positions, first);
    let extents = model.run_vertex_pass(Blocks::new(positions.len(), positions, &block));
    extents.reference_point(first)
}

/// Along each axis (x, y, z), the least `|x_i|` and the largest `|x_i - x_0|` over some
/// vertices (`INFINITY` and 0 over none).
#[derive(Clone, Copy)]
pub(super) struct Extents([(Real, Real); 3]);

/// The bit of each axis in a fixed-axis mask.
pub(super) const AXES: [u8; 3] = [1, 2, 4];

impl Extents {
    /// The extents of `positions` about `first`.
    fn of<V: Vector>(positions: &[V], first: V) -> Self {
        let along = |v: V, axis: u8| V::ZERO.axes_from(v, axis).abs_sum();
        let mut extents: [(Real, Real); 3] = [(Real::INFINITY, 0.0); 3];
        for &x in positions {
            for ((nearest, extent), axis) in extents.iter_mut().zip(AXES) {
                *nearest = nearest.min(along(x, axis));
                *extent = extent.max(along(x - first, axis));
            }
        }
        Extents(extents)
    }

    /// The reference point of vertices with these extents about the first vertex, `first`.
    fn reference_point<V: Vector>(self, first: V) -> V {
        let far = self
            .0
            .iter()
            .zip(AXES)
            .filter(|&(&(nearest, extent), axis)| axis & V::ALL_AXES != 0 && nearest > extent)
            .fold(0, |far, (_, axis)| far | axis);
        V::ZERO.axes_from(first, far)
    }
}

impl Total for Extents {
    #[inline(always)]
    fn combine(left: Self, right: Self) -> Self {
        let mut extents = left.0;
        for ((nearest, extent), &(right_nearest, right_extent)) in extents.iter_mut().zip(&right.0)
        {
            *nearest = nearest.min(right_nearest);
            *extent = extent.max(right_extent);
        }
        Extents(extents)
    }
}

/// Adds `shift` to every entry of `values` (`-c` into the loop's coordinates, `c` back).
pub(super) fn translate<V: Vector>(values: &mut [V], shift: V) {
    if shift != V::ZERO {
        for value in values {
            *value += shift;
        }
    }
}

/// [`translate`] in blocks run by `model`, then (where `copy_to` is not empty) the result
/// copied into `copy_to`, in the same pass.
pub(super) fn split_translate<V: Vector + Send + Sync>(
    model: &impl ElasticModel,
    values: &mut [V],
    shift: V,
    copy_to: &mut [V],
) {
    let block = |_, (values, copy_to): (&mut [V], &mut [V])| {
        translate(values, shift);
        copy(copy_to, values);
    };
    model.run_vertex_pass(Blocks::new(values.len(), (values, copy_to), &block));
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::super::super::super::types::{Real, Vec2, Vec3};
    use super::super::super::vertex_pass::{Total, VERTEX_BLOCK};
    use super::{Extents, reference_point};

    /// A 0.4 x 0.1 x 0.1 m grid of points, moved by `offset`.
    fn grid(offset: Vec3) -> Vec<Vec3> {
        let mut points = Vec::new();
        for i in 0..=8 {
            for j in 0..=3 {
                for k in 0..=3 {
                    let p = Vec3::new(0.05 * i as Real, j as Real / 30.0, k as Real / 30.0);
                    points.push(p + offset);
                }
            }
        }
        points
    }

    #[test]
    fn a_body_straddling_the_origin_is_not_shifted() {
        assert_eq!(reference_point(&grid(Vec3::ZERO)), Vec3::ZERO);
        // 0.35 m away along x is within the body's extent (0.4 m): not shifted along x; 0.05 m
        // along y and z, within 0.1 m: not shifted there either.
        let near = Vec3::new(0.35, 0.05, -0.15);
        assert_eq!(reference_point(&grid(near)), Vec3::ZERO);
        assert_eq!(reference_point::<Vec3>(&[]), Vec3::ZERO);
        // A coordinate of zero (or minus zero) everywhere is never shifted: `m > e` fails.
        let flat = [Vec3::new(0.0, -0.0, 1.0), Vec3::new(0.0, -0.0, 1.0)];
        assert_eq!(
            reference_point(&flat).to_array().map(Real::to_bits)[..2],
            [0, 0]
        );
    }

    #[test]
    fn far_axes_take_the_first_vertex_and_the_shift_is_exact() {
        for offset in [
            Vec3::new(0.45, 0.0, 0.0),
            Vec3::new(60.0, 0.0, 0.0),
            Vec3::new(-60.0, 0.0, 0.25),
            Vec3::new(1e4, -1e4, 1e4),
        ] {
            let points = grid(offset);
            let c = reference_point(&points);
            // Along x the body is 0.4 m wide, along y and z 0.1 m: far where |offset| > that.
            let expected = |far: bool, value: Real| if far { value } else { 0.0 };
            let first = points[0];
            assert_eq!(c.x, expected(offset.x.abs() > 0.4, first.x), "{offset}");
            assert_eq!(c.y, expected(offset.y.abs() > 0.1, first.y), "{offset}");
            assert_eq!(c.z, expected(offset.z.abs() > 0.1, first.z), "{offset}");
            for &p in &points {
                // Exact both ways (Sterbenz): the shifted point comes back bit for bit.
                assert_eq!((p - c) + c, p, "{offset}: {p}");
                assert!((p - c).abs().max_element() <= 0.41, "{offset}: {p}");
            }
        }
    }

    /// `a - b` is exact: the rounding error of the difference by Knuth's TwoSum (itself exact
    /// in round-to-nearest) is zero.
    fn exact_difference(a: Real, b: Real) -> bool {
        let (a, b) = (a, -b);
        let s = a + b;
        let b_part = s - a;
        let error = (a - (s - b_part)) + (b - b_part);
        error == 0.0
    }

    /// The proof in [`reference_point`]'s documentation, checked on point sets built at the edge
    /// of the rule: pseudo-random sets whose nearest coordinate lies just above, at or just
    /// below their extent, in both signs and over many magnitudes, with the first vertex
    /// anywhere in the set. Wherever the rule shifts, every difference from the reference point
    /// is exact; and it shifts the sets just above the edge.
    #[test]
    fn wherever_the_rule_shifts_every_difference_is_exact() {
        let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut shifted = 0;
        for set in 0..4000 {
            // The set spans [lo, hi] with lo = width * ratio, the ratio near 1 (the edge).
            let scale = libm::pow(10.0, 6.0 * next() - 3.0);
            let ratio = [1.0 + 1e-6, 1.0, 1.0 - 1e-6, 1.0 + next(), 0.5 + next()][set % 5];
            let sign = if next() < 0.5 { -1.0 } else { 1.0 };
            let width = scale;
            let lo = width * ratio;
            let values: Vec<Real> = (0..17)
                .map(|k| {
                    let t = match k {
                        0 => next(),
                        1 => 0.0,
                        2 => 1.0,
                        _ => next(),
                    };
                    (sign * (lo + width * t)) as Real
                })
                .collect();
            let points: Vec<Vec3> = values.iter().map(|&v| Vec3::new(v, 0.0, 0.0)).collect();
            let c = reference_point(&points).x;
            if c == 0.0 {
                continue;
            }
            shifted += 1;
            assert_eq!(c, values[0]);
            for &y in &values {
                assert!(exact_difference(y, c), "set {set}: {y} - {c}");
            }
        }
        // Every set whose rounded nearest coordinate exceeds its rounded extent shifts: most
        // of those above the edge, none of those well below it.
        assert!(shifted > 1500, "{shifted} of 4000");
    }

    #[test]
    fn two_dimensional_points_shift_along_their_two_axes() {
        let points = [
            Vec2::new(60.0, 0.0),
            Vec2::new(60.5, 0.1),
            Vec2::new(60.25, 0.05),
        ];
        assert_eq!(reference_point(&points), Vec2::new(60.0, 0.0));
    }

    /// The extents of a body taken in two parts and combined are those of the whole body, bit
    /// for bit, wherever it is cut (the split reference point is the one-pass one), on a body
    /// far from the origin whose points are not sorted along any axis.
    #[test]
    fn extents_combined_over_any_cut_are_the_whole_body_s() {
        let points: Vec<Vec3> = (0..3 * VERTEX_BLOCK + 5)
            .map(|i| {
                let t = i as Real;
                Vec3::new(
                    60.0 + (t * 0.37).sin(),
                    -1e3 + (t * 1.3).cos(),
                    0.25 * (t * 0.11).sin(),
                )
            })
            .collect();
        let first = points[0];
        let whole = Extents::of(&points, first);
        for cut in [0, 1, VERTEX_BLOCK, 2 * VERTEX_BLOCK + 3, points.len()] {
            let (left, right) = points.split_at(cut);
            let combined = Extents::combine(Extents::of(left, first), Extents::of(right, first));
            for ((a, b), (c, d)) in combined.0.iter().zip(&whole.0) {
                assert_eq!(
                    (a.to_bits(), b.to_bits()),
                    (c.to_bits(), d.to_bits()),
                    "cut {cut}"
                );
            }
            assert_eq!(combined.reference_point(first), reference_point(&points));
        }
        // Far along x (|x| >= 59 against an extent of at most 2) and y (|y| ~ 1e3, extent 2),
        // near along z (|z| down to 0), as the rule says.
        assert_eq!(reference_point(&points), Vec3::new(first.x, first.y, 0.0));
    }
}
