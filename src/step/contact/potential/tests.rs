//! The contact potential against finite differences, its projection against the eigenvalues,
//! its assembly against a dense reference, and its refusals.

// Index loops over slots, coordinates and matrix entries read as the formulas they check.
#![allow(clippy::needless_range_loop)]

extern crate std;
use std::{vec, vec::Vec};

use super::super::super::super::element::SymmetricMatrix;
use super::super::boundary::boundary_edges;
use super::super::broad_phase::{BroadPhaseScratch, proximity_pairs};
use super::super::distance::{EdgeEdgeKind, edge_edge_kind, edge_edge_mollifier_value};
use super::project::{project, to_rows};
use super::*;

/// Whether this copy runs in f64 (finite differences are checked only there).
fn double() -> bool {
    Real::EPSILON < 1e-10
}

/// A deterministic xorshift64 stream.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> Real {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) as Real
    }
    /// Uniform in the cube of half-width `half`.
    fn vec(&mut self, half: Real) -> Vec3 {
        Vec3::new(self.unit(), self.unit(), self.unit()) * (2.0 * half) - Vec3::splat(half)
    }
}

/// Entry `(i, j)` of block `(k, l)`.
fn entry(hessian: &[[Mat3; 4]; 4], k: usize, l: usize, i: usize, j: usize) -> Real {
    hessian[k][l].col(j)[i]
}

/// `points` with coordinate `i` of slot `k` moved by `step`.
fn moved(mut points: [Vec3; 4], k: usize, i: usize, step: Real) -> [Vec3; 4] {
    points[k][i] += step;
    points
}

/// The largest difference between `gradient` and central differences of `value`, over the
/// largest gradient entry.
fn gradient_error(
    value: impl Fn([Vec3; 4]) -> Real,
    points: [Vec3; 4],
    gradient: [Vec3; 4],
    h: Real,
) -> Real {
    let (mut error, mut scale): (Real, Real) = (0.0, 0.0);
    for k in 0..4 {
        for i in 0..3 {
            let fd = (value(moved(points, k, i, h)) - value(moved(points, k, i, -h))) / (2.0 * h);
            error = error.max((fd - gradient[k][i]).abs());
            scale = scale.max(gradient[k][i].abs());
        }
    }
    error / scale
}

/// The largest difference between `hessian` and central differences of `gradient`, over the
/// largest Hessian entry.
fn hessian_error(
    gradient: impl Fn([Vec3; 4]) -> [Vec3; 4],
    points: [Vec3; 4],
    hessian: &[[Mat3; 4]; 4],
    h: Real,
) -> Real {
    let (mut error, mut scale): (Real, Real) = (0.0, 0.0);
    for l in 0..4 {
        for j in 0..3 {
            let plus = gradient(moved(points, l, j, h));
            let minus = gradient(moved(points, l, j, -h));
            for k in 0..4 {
                for i in 0..3 {
                    let fd = (plus[k][i] - minus[k][i]) / (2.0 * h);
                    let exact = entry(hessian, k, l, i, j);
                    error = error.max((fd - exact).abs());
                    scale = scale.max(exact.abs());
                }
            }
        }
    }
    error / scale
}

const BARRIER: ContactBarrier = ContactBarrier {
    stiffness: 1e3,
    gap: 1.0,
};

/// The configurations of the derivative tests, all at distances in `(0.2, 0.8)` with the gap
/// 1: (points, edge-edge mollifier threshold or `None` for a point–triangle pair).
fn configurations() -> Vec<([Vec3; 4], Option<Real>)> {
    let v = |x: Real, y: Real, z: Real| Vec3::new(x, y, z);
    let triangle = [v(0.0, 0.0, 0.0), v(1.0, 0.1, 0.0), v(0.1, 1.2, 0.2)];
    let with = |p: Vec3| [p, triangle[0], triangle[1], triangle[2]];
    vec![
        // The point above the face, beside an edge, beyond a corner.
        (with(v(0.3, 0.3, 0.4)), None),
        (with(v(0.5, -0.3, 0.3)), None),
        (with(v(-0.3, -0.2, 0.25)), None),
        // Crossing edges, the mollifier 1 (eps_x = 1e-3 |u|^2 |v|^2 far below c).
        (
            [
                v(-0.5, 0.0, 0.0),
                v(0.6, 0.1, 0.0),
                v(0.1, -0.6, 0.45),
                v(-0.1, 0.5, 0.35),
            ],
            Some(1e-3),
        ),
        // Nearly parallel edges crossing 0.3 apart at 0.03 rad: c = |u|^2 |v|^2 sin^2 = 9e-4
        // |u|^2 |v|^2, the threshold from a rest shape 3 times that: m about 0.55.
        (
            [
                v(-1.0, 0.0, 0.0),
                v(1.0, 0.0, 0.0),
                v(-1.0, -0.03, 0.3),
                v(1.0, 0.03, 0.3),
            ],
            Some(3.0 * 9e-4 * 4.0 * 4.0),
        ),
    ]
}

/// The exact terms of a configuration.
fn terms(points: [Vec3; 4], threshold: Option<Real>) -> PairTerms {
    match threshold {
        None => point_triangle_terms(&BARRIER, points),
        Some(eps_x) => edge_edge_terms(&BARRIER, points, eps_x),
    }
}

/// Gradient against central differences of the value, the exact Hessian against central
/// differences of the gradient (f64). Steps: `h = 1e-6` m at distances `>= 0.2` m: truncation
/// `(h / d)^2 ~ 1e-11` relative, rounding `eps / h ~ 1e-10` relative; measured at most
/// `1.5e-10` (gradient) and `1.7e-10` (Hessian), tolerance `1e-7`.
#[test]
fn pair_derivatives_match_finite_differences() {
    if !double() {
        return;
    }
    let h = 1e-6;
    for (points, threshold) in configurations() {
        let exact = terms(points, threshold);
        assert!(exact.active && exact.value > 0.0, "{points:?}");
        if let Some(eps_x) = threshold {
            let [a0, a1, b0, b1] = points;
            let m = edge_edge_mollifier_value(a0, a1, b0, b1, eps_x);
            assert_eq!(edge_edge_kind(a0, a1, b0, b1), EdgeEdgeKind::Interior);
            if eps_x > 1e-2 {
                assert!(m > 0.3 && m < 0.8, "the mollifier is active: {m}");
            }
        }
        let value = |x: [Vec3; 4]| terms(x, threshold).value;
        let gradient = |x: [Vec3; 4]| terms(x, threshold).gradient;
        let g = gradient_error(value, points, exact.gradient, h);
        assert!(g < 1e-7, "{points:?}: gradient {g}");
        let hs = hessian_error(gradient, points, &exact.hessian, h);
        assert!(hs < 1e-7, "{points:?}: Hessian {hs}");
        // The public function carries the same value and gradient, bit for bit.
        let public = match threshold {
            None => point_triangle_potential(&BARRIER, points, [0, 1, 2, 3]),
            Some(eps_x) => edge_edge_potential(&BARRIER, points, eps_x, [0, 1, 2, 3]),
        };
        assert_eq!(public.value.to_bits(), exact.value.to_bits());
        assert_eq!(public.gradient, exact.gradient);
    }
}

/// The gradient-only path (what `add_gradient` sums) gives the full path's value, gradient and
/// activity bit for bit, at random pairs of both kinds: active, inactive, mollified (each kind
/// counted), and touching.
#[test]
fn gradient_terms_match_the_full_terms_bit_for_bit() {
    let mut rng = Rng(0x5eed_0393);
    let barrier = ContactBarrier {
        stiffness: 1.0e3,
        gap: 0.5,
    };
    let bits = |g: [Vec3; 4]| g.map(|v| v.to_array().map(Real::to_bits));
    let (mut active, mut inactive, mut mollified) = ([0usize; 2], [0usize; 2], 0);
    for trial in 0..2000 {
        let points = [rng.vec(1.0), rng.vec(1.0), rng.vec(1.0), rng.vec(1.0)];
        let edge = trial % 2 == 1;
        // Thresholds from 0 to past typical c (|u|^2 |v|^2 up to ~10): the mollifier both
        // fades and is 1.
        let threshold = 0.5 * rng.unit();
        let (full, gradient) = if edge {
            (
                edge_edge_terms(&barrier, points, threshold),
                edge_edge_gradient_terms(&barrier, points, threshold),
            )
        } else {
            (
                point_triangle_terms(&barrier, points),
                point_triangle_gradient_terms(&barrier, points),
            )
        };
        assert_eq!(gradient.value.to_bits(), full.value.to_bits(), "{points:?}");
        assert_eq!(bits(gradient.gradient), bits(full.gradient), "{points:?}");
        assert_eq!(gradient.active, full.active, "{points:?}");
        let kind = usize::from(edge);
        if full.active {
            active[kind] += 1;
            let [a0, a1, b0, b1] = points;
            if edge && edge_edge_mollifier_value(a0, a1, b0, b1, threshold) < 1.0 {
                mollified += 1;
            }
        } else {
            inactive[kind] += 1;
        }
    }
    assert!(
        active.iter().chain(&inactive).all(|&n| n > 20),
        "{active:?} {inactive:?}"
    );
    assert!(mollified > 20, "{mollified}");
    // Touching pairs: +inf and zero gradient on both paths.
    let v = |x: Real, y: Real, z: Real| Vec3::new(x, y, z);
    let on = [
        v(0.2, 0.2, 0.0),
        v(0.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.0, 1.0, 0.0),
    ];
    let crossing = [
        v(-1.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.0, -1.0, 0.0),
        v(0.0, 1.0, 0.0),
    ];
    for gradient in [
        point_triangle_gradient_terms(&barrier, on),
        edge_edge_gradient_terms(&barrier, crossing, 1e-3),
    ] {
        assert_eq!(gradient.value, Real::INFINITY);
        assert_eq!(gradient.gradient, [Vec3::ZERO; 4]);
        assert!(!gradient.active);
    }
}

/// `v^T H v` over the twelve coordinates.
fn quadratic_form(hessian: &[[Mat3; 4]; 4], v: [Vec3; 4]) -> Real {
    let mut sum = 0.0;
    for k in 0..4 {
        for l in 0..4 {
            sum += v[k].dot(hessian[k][l] * v[l]);
        }
    }
    sum
}

/// Random active pairs of both kinds: the projected Hessian is exactly symmetric, its Jacobi
/// eigenvalues are `>= -tolerance`, `v^T H v >= -tolerance` for random `v`, and `H+ - H` is
/// semi-definite too (the projection only removes the negative part). Tolerances: rounding of
/// the 12x12 reconstruction, `16 eps` times the largest eigenvalue (measured: `1 eps`) and
/// `256 eps 48 |H|_max` for the forms (`|v_i| <= 1`).
#[test]
fn projection_is_symmetric_semi_definite_and_removes_only_the_negative_part() {
    let mut rng = Rng(0x5eed_0391);
    let barrier = ContactBarrier {
        stiffness: 1.0,
        gap: 0.5,
    };
    let (mut tested, mut indefinite) = (0, 0);
    while tested < 200 {
        let points = [rng.vec(1.0), rng.vec(1.0), rng.vec(1.0), rng.vec(1.0)];
        let edge = tested % 2 == 1;
        let exact = if edge {
            edge_edge_terms(&barrier, points, 1e-2)
        } else {
            point_triangle_terms(&barrier, points)
        };
        if !exact.active {
            continue;
        }
        tested += 1;
        let projected = project(&exact.hessian);
        for k in 0..4 {
            for l in 0..4 {
                assert_eq!(projected[k][l], projected[l][k].transpose());
            }
        }
        let (values, _) = SymmetricMatrix::from_rows(to_rows(&projected)).eigen();
        let largest = values.iter().fold(0.0, |m: Real, l| m.max(l.abs()));
        assert!(
            values.iter().all(|&l| l >= -16.0 * Real::EPSILON * largest),
            "{values:?}"
        );
        let (exact_values, _) = SymmetricMatrix::from_rows(to_rows(&exact.hessian)).eigen();
        if exact_values.iter().any(|&l| l < 0.0) {
            indefinite += 1;
        }
        let difference = |k: usize, l: usize| projected[k][l] - exact.hessian[k][l];
        let removed: [[Mat3; 4]; 4] =
            core::array::from_fn(|k| core::array::from_fn(|l| difference(k, l)));
        let norm = exact
            .hessian
            .iter()
            .flatten()
            .flat_map(|b| b.to_cols_array())
            .fold(0.0, |m: Real, e| m.max(e.abs()));
        for _ in 0..20 {
            let v = [rng.vec(1.0), rng.vec(1.0), rng.vec(1.0), rng.vec(1.0)];
            let tolerance = 256.0 * Real::EPSILON * 12.0 * norm * 4.0;
            assert!(quadratic_form(&projected, v) >= -tolerance);
            assert!(quadratic_form(&removed, v) >= -tolerance);
        }
    }
    // The chain rule's Hessian is indefinite in general (b' < 0 times the distance's Hessian),
    // so the projection was exercised.
    assert!(indefinite > 100, "{indefinite}");
}

/// The projection's spectrum is the exact Hessian's with the negative eigenvalues set to zero,
/// both spectra from the independent ten-sweep Jacobi of `SymmetricMatrix`, sorted, at random
/// active pairs of both kinds (with the mollifier fading at some). Tolerance: `64 eps` times
/// the largest eigenvalue (Jacobi's backward error on 12x12, a few eps per sweep).
#[test]
fn projection_spectrum_is_the_clamped_exact_spectrum() {
    let mut rng = Rng(0x5eed_0394);
    let barrier = ContactBarrier {
        stiffness: 1.0,
        gap: 0.5,
    };
    let sorted = |hessian: &[[Mat3; 4]; 4]| {
        let (mut values, _) = SymmetricMatrix::from_rows(to_rows(hessian)).eigen();
        values.sort_by(|a, b| a.total_cmp(b));
        values
    };
    let (mut tested, mut clamped) = (0, 0);
    while tested < 200 {
        let points = [rng.vec(1.0), rng.vec(1.0), rng.vec(1.0), rng.vec(1.0)];
        let exact = if tested % 2 == 1 {
            edge_edge_terms(&barrier, points, 0.5 * rng.unit())
        } else {
            point_triangle_terms(&barrier, points)
        };
        if !exact.active {
            continue;
        }
        tested += 1;
        let expected = sorted(&exact.hessian).map(|l| l.max(0.0));
        let projected = sorted(&project(&exact.hessian));
        let largest = expected.iter().fold(0.0, |m: Real, l| m.max(l.abs()));
        let tolerance = 64.0 * Real::EPSILON * largest;
        for (got, want) in projected.iter().zip(&expected) {
            assert!(
                (got - want).abs() <= tolerance,
                "{projected:?} {expected:?}"
            );
        }
        clamped += usize::from(sorted(&exact.hessian)[0] < -tolerance);
    }
    assert!(clamped > 100, "{clamped}");
}

/// A Hessian that is already positive definite comes back bit for bit (a random `A A^T + I`,
/// exactly symmetric since products commute).
#[test]
fn projection_keeps_a_positive_definite_hessian() {
    let mut rng = Rng(0x5eed_0392);
    for _ in 0..20 {
        let mut a = [[0.0 as Real; 12]; 12];
        a.iter_mut().flatten().for_each(|x| *x = rng.unit() - 0.5);
        let mut hessian = [[Mat3::ZERO; 4]; 4];
        for k in 0..4 {
            for l in 0..4 {
                let columns: [[Real; 3]; 3] = core::array::from_fn(|j| {
                    core::array::from_fn(|i| {
                        let (r, c) = (3 * k + i, 3 * l + j);
                        let mut sum = if r == c { 1.0 } else { 0.0 };
                        for (x, y) in a[r].iter().zip(&a[c]) {
                            sum += x * y;
                        }
                        sum
                    })
                });
                hessian[k][l] = Mat3::from_cols_array_2d(&columns);
            }
        }
        assert_eq!(project(&hessian), hessian);
    }
}

/// At and beyond the gap: exactly zero value, gradient and Hessian; touching: `+inf` with zero
/// derivatives, never NaN, also for parallel edges (mollifier 0) and a zero stiffness.
#[test]
fn zero_beyond_the_gap_and_infinite_at_contact() {
    let v = |x: Real, y: Real, z: Real| Vec3::new(x, y, z);
    let triangle = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)];
    let with = |p: Vec3| [p, triangle[0], triangle[1], triangle[2]];
    let barrier = ContactBarrier {
        stiffness: 1e6,
        gap: 0.25,
    };
    let zero = |pair: &PairPotential| {
        pair.value == 0.0
            && pair.gradient == [Vec3::ZERO; 4]
            && pair.hessian == [[Mat3::ZERO; 4]; 4]
    };
    for height in [0.25, 0.3, 10.0] {
        let p = v(0.2, 0.2, height);
        let pair = point_triangle_potential(&barrier, with(p), [0; 4]);
        assert!(zero(&pair), "{height}: {pair:?}");
        let (a0, a1) = (v(-1.0, 0.5, 0.0), v(1.0, 0.5, 0.0));
        let edges = [a0, a1, v(0.0, -1.0, height), v(0.0, 1.0, height)];
        assert!(zero(&edge_edge_potential(&barrier, edges, 1e-3, [0; 4])));
    }
    let blocked = |pair: &PairPotential| {
        pair.value == Real::INFINITY
            && pair.gradient == [Vec3::ZERO; 4]
            && pair.hessian == [[Mat3::ZERO; 4]; 4]
    };
    for stiffness in [0.0, 1.0] {
        let barrier = ContactBarrier {
            stiffness,
            gap: 0.25,
        };
        let on = v(0.2, 0.2, 0.0);
        let pair = point_triangle_potential(&barrier, with(on), [0; 4]);
        assert!(blocked(&pair), "{pair:?}");
        // Crossing edges, and parallel overlapping ones (mollifier 0): touching either way.
        let crossing = [
            v(-1.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.0, -1.0, 0.0),
            v(0.0, 1.0, 0.0),
        ];
        let parallel = [
            v(-1.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(0.0, 0.0, 0.0),
            v(2.0, 0.0, 0.0),
        ];
        for edges in [crossing, parallel] {
            assert!(blocked(&edge_edge_potential(&barrier, edges, 1e-3, [0; 4])));
        }
    }
    // Very close pairs, huge stiffness: +inf or finite, never NaN.
    for height in [1e-20, 1e-12, 1e-6] {
        let barrier = ContactBarrier {
            stiffness: Real::MAX,
            gap: 1.0,
        };
        let p = v(0.2, 0.2, height);
        let pair = point_triangle_potential(&barrier, with(p), [0; 4]);
        assert!(!pair.value.is_nan());
        assert!(pair.gradient.iter().all(|g| !g.is_nan()));
        assert!(pair.hessian.iter().flatten().all(|h| !h.is_nan()));
    }
}

/// Two tetrahedra facing each other within the gap: B's top edge (vertices 4, 5) lies 1 mm
/// below A's bottom face, crossing A's bottom edge 0-1 at 0.02 rad (the mollifier active), its
/// end 5 under the face and end 4 just beside it. Rest positions a little apart from these.
struct Scene {
    positions: Vec<Vec3>,
    rest: Vec<Vec3>,
    vertices: Vec<u32>,
    edges: Vec<[u32; 2]>,
    triangles: Vec<[u32; 3]>,
    vertex_triangle: Vec<[u32; 2]>,
    edge_edge: Vec<[u32; 2]>,
}

const GAP: Real = 0.01;

fn scene() -> Scene {
    let v = |x: Real, y: Real, z: Real| Vec3::new(x, y, z);
    let depth = 1e-3;
    let positions = vec![
        v(0.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.0, 1.0, 0.0),
        v(0.0, 0.0, 1.0),
        v(0.2, -0.004, -depth),
        v(0.6, 0.004, -depth),
        v(0.1, -0.1, -0.7),
        v(0.6, 0.2, -0.6),
    ];
    let rest: Vec<Vec3> = positions
        .iter()
        .map(|&x| x * 1.01 + Vec3::Z * 0.1)
        .collect();
    const FACES: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let triangles: Vec<[u32; 3]> = FACES
        .iter()
        .chain(&FACES)
        .enumerate()
        .map(|(i, f)| f.map(|x| x + 4 * (i as u32 / 4)))
        .collect();
    let mut edge_buffer = vec![[0; 2]; 3 * triangles.len()];
    let edges = boundary_edges(&triangles, 8, &mut edge_buffer)
        .unwrap()
        .to_vec();
    let vertices: Vec<u32> = (0..8).collect();
    let surface = ContactSurface {
        vertices: &vertices,
        edges: &edges,
        triangles: &triangles,
    };
    let (mut slots, mut entries) = (vec![0; 64], vec![0; 8 * 64]);
    let mut scratch = BroadPhaseScratch::new(&mut slots, &mut entries);
    let (mut vt, mut ee) = (vec![[0; 2]; 256], vec![[0; 2]; 256]);
    let pairs = proximity_pairs(&positions, GAP, &surface, &mut scratch, &mut vt, &mut ee).unwrap();
    let (vertex_triangle, edge_edge) = (pairs.vertex_triangle.to_vec(), pairs.edge_edge.to_vec());
    Scene {
        positions,
        rest,
        vertices,
        edges,
        triangles,
        vertex_triangle,
        edge_edge,
    }
}

impl Scene {
    fn potential(&self) -> ContactPotential<'_> {
        ContactPotential {
            barrier: ContactBarrier {
                stiffness: 1e8,
                gap: GAP,
            },
            surface: ContactSurface {
                vertices: &self.vertices,
                edges: &self.edges,
                triangles: &self.triangles,
            },
            pairs: CandidatePairs {
                vertex_triangle: &self.vertex_triangle,
                edge_edge: &self.edge_edge,
            },
            rest_positions: &self.rest,
        }
    }
}

/// The energy is the per-pair values summed in order, bit for bit; several pairs of each kind
/// are active, one edge pair with the mollifier below 1.
#[test]
fn energy_is_the_sum_of_the_pairs() {
    let scene = scene();
    let potential = scene.potential();
    let x = &scene.positions;
    let barrier = potential.barrier;
    let mut sum: Real = 0.0;
    let (mut active_vt, mut active_ee, mut mollified) = (0, 0, 0);
    for &[vertex, triangle] in &scene.vertex_triangle {
        let [a, b, c] = scene.triangles[triangle as usize];
        let p = scene.vertices[vertex as usize];
        let points = [x[p as usize], x[a as usize], x[b as usize], x[c as usize]];
        let pair = point_triangle_potential(&barrier, points, [p, a, b, c]);
        active_vt += usize::from(pair.value > 0.0);
        sum += pair.value;
    }
    for &[first, second] in &scene.edge_edge {
        let ([a0, a1], [b0, b1]) = (scene.edges[first as usize], scene.edges[second as usize]);
        let ids = [a0, a1, b0, b1];
        let points = ids.map(|i| x[i as usize]);
        let rest = ids.map(|i| scene.rest[i as usize]);
        let eps_x = edge_edge_mollifier_threshold(rest[0], rest[1], rest[2], rest[3]);
        let pair = edge_edge_potential(&barrier, points, eps_x, ids);
        if pair.value > 0.0 {
            active_ee += 1;
            let m = edge_edge_mollifier_value(points[0], points[1], points[2], points[3], eps_x);
            mollified += usize::from(m < 1.0);
        }
        sum += pair.value;
    }
    assert!(
        active_vt >= 2 && active_ee >= 2 && mollified >= 1,
        "{active_vt} {active_ee}"
    );
    let energy = potential.energy(x).unwrap();
    assert!(energy > 0.0);
    assert_eq!(energy.to_bits(), sum.to_bits());
    let mut gradient = vec![Vec3::ZERO; 8];
    assert_eq!(
        potential.add_gradient(x, &mut gradient).unwrap().to_bits(),
        sum.to_bits()
    );
}

/// The gradient buffer against central differences of the total energy in every coordinate of
/// every vertex (f64). `h = 1e-8` m against the closest distance 1e-3 m: truncation `(h /
/// d)^2 ~ 1e-10`, rounding `eps E / h` far below the gradient; measured at most `6.1e-11` of the
/// largest component, tolerance `1e-8`. Translation invariance: the gradients sum to zero.
#[test]
fn gradient_matches_finite_differences_of_the_energy() {
    let scene = scene();
    let potential = scene.potential();
    let mut gradient = vec![Vec3::ZERO; 8];
    potential
        .add_gradient(&scene.positions, &mut gradient)
        .unwrap();
    let largest = gradient
        .iter()
        .fold(0.0, |m: Real, g| m.max(g.abs().max_element()));
    assert!(largest > 0.0);
    let sum: Vec3 = gradient.iter().sum();
    assert!(sum.length() < 64.0 * Real::EPSILON * largest, "{sum}");
    if !double() {
        return;
    }
    let h = 1e-8;
    for vertex in 0..8 {
        for i in 0..3 {
            let at = |step: Real| {
                let mut x = scene.positions.clone();
                x[vertex][i] += step;
                potential.energy(&x).unwrap()
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            let error = (fd - gradient[vertex][i]).abs();
            assert!(
                error < 1e-8 * largest,
                "{vertex} {i}: {fd} {}",
                gradient[vertex][i]
            );
        }
    }
}

/// The stored pair Hessians: each equals the per-pair function's; the sum of their products
/// equals the dense matrix assembled from them on random vectors; the diagonal blocks equal
/// that matrix's diagonal; a translation is in its null space (to rounding).
#[test]
fn stored_hessians_products_and_diagonal_match_the_dense_matrix() {
    let scene = scene();
    let potential = scene.potential();
    let x = &scene.positions;
    let n = x.len();
    let candidates = scene.vertex_triangle.len() + scene.edge_edge.len();
    let mut stored = vec![PairHessian::default(); candidates];
    let hessians = potential.pair_hessians(x, &mut stored).unwrap().to_vec();
    assert!(hessians.len() >= 4 && hessians.len() <= candidates);
    // Every stored Hessian is some active pair's projected Hessian.
    let mut reference = Vec::new();
    potential.for_each_pair(x, |pair| {
        let (terms, vertices) = pair.terms(&potential.barrier);
        if terms.active {
            reference.push(terms.projected(vertices));
        }
    });
    assert_eq!(reference.len(), hessians.len());
    for (pair, stored) in reference.iter().zip(&hessians) {
        assert_eq!(
            (pair.vertices, pair.hessian),
            (stored.vertices, stored.hessian)
        );
    }
    let mut dense = vec![vec![0.0 as Real; 3 * n]; 3 * n];
    for pair in &hessians {
        for k in 0..4 {
            for l in 0..4 {
                for i in 0..3 {
                    for j in 0..3 {
                        let r = 3 * pair.vertices[k] as usize + i;
                        let c = 3 * pair.vertices[l] as usize + j;
                        dense[r][c] += entry(&pair.hessian, k, l, i, j);
                    }
                }
            }
        }
    }
    let largest = dense
        .iter()
        .flatten()
        .fold(0.0, |m: Real, e| m.max(e.abs()));
    let mut rng = Rng(0x5eed_0393);
    for _ in 0..10 {
        let v: Vec<Vec3> = (0..n).map(|_| rng.vec(1.0)).collect();
        let mut product = vec![Vec3::ZERO; n];
        add_hessian_product(&hessians, &v, &mut product).unwrap();
        for r in 0..3 * n {
            let expected: Real = (0..3 * n).map(|c| dense[r][c] * v[c / 3][c % 3]).sum();
            let got = product[r / 3][r % 3];
            assert!(
                (got - expected).abs() < 256.0 * Real::EPSILON * largest,
                "{r}"
            );
        }
    }
    let mut diagonal = vec![Mat3::ZERO; n];
    potential.add_hessian_diagonal(x, &mut diagonal).unwrap();
    for (vertex, block) in diagonal.iter().enumerate() {
        for i in 0..3 {
            for j in 0..3 {
                let expected = dense[3 * vertex + i][3 * vertex + j];
                let got = block.col(j)[i];
                assert!(
                    (got - expected).abs() < 64.0 * Real::EPSILON * largest,
                    "{vertex}"
                );
            }
        }
    }
    // Translations: the exact Hessian annihilates them and the projection keeps the null space,
    // up to the Jacobi solver's rounding (measured 120 eps of the largest entry in f32, 60 in
    // f64).
    for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
        let v = vec![axis; n];
        let mut product = vec![Vec3::ZERO; n];
        add_hessian_product(&hessians, &v, &mut product).unwrap();
        let worst = product.iter().fold(0.0, |m: Real, p| m.max(p.length()));
        assert!(
            worst < 1024.0 * Real::EPSILON * largest,
            "{worst} of {largest}"
        );
    }
}

/// Every refusal names its buffer, and nothing is written on any of them.
#[test]
fn refusals_name_the_buffer_and_write_nothing() {
    let scene = scene();
    let good = scene.potential();
    let x = &scene.positions;
    let marker = Vec3::splat(7.0);
    let check = |potential: ContactPotential<'_>, positions: &[Vec3], expected: ContactError| {
        assert_eq!(potential.energy(positions), Err(expected));
        let mut gradient = vec![marker; positions.len()];
        assert_eq!(
            potential.add_gradient(positions, &mut gradient),
            Err(expected)
        );
        assert!(gradient.iter().all(|&g| g == marker));
        let mut diagonal = vec![Mat3::IDENTITY; positions.len()];
        assert_eq!(
            potential.add_hessian_diagonal(positions, &mut diagonal),
            Err(expected)
        );
        assert!(diagonal.iter().all(|&d| d == Mat3::IDENTITY));
        let mut stored = vec![PairHessian::default(); 64];
        assert_eq!(
            potential.pair_hessians(positions, &mut stored),
            Err(expected)
        );
        assert!(stored.iter().all(|s| *s == PairHessian::default()));
    };
    let mut bad = good;
    bad.barrier.gap = -1.0;
    check(bad, x, ContactError::Gap);
    bad.barrier.gap = Real::NAN;
    check(bad, x, ContactError::Gap);
    let mut bad = good;
    bad.barrier.stiffness = Real::INFINITY;
    check(bad, x, ContactError::Stiffness);
    let mut bad = good;
    bad.rest_positions = &scene.rest[..7];
    let length = |buffer, expected, actual| ContactError::BufferLength {
        buffer,
        expected,
        actual,
    };
    check(bad, x, length(ContactBuffer::RestPositions, 8, 7));
    let range = |buffer, element, index| ContactError::IndexOutOfRange {
        buffer,
        element,
        index,
    };
    let (vertices, edges, triangles) = ([0, 9], [[0, 1], [2, 8]], [[0, 1, 2], [3, 4, 12]]);
    let mut bad = good;
    bad.surface.vertices = &vertices;
    check(bad, x, range(ContactBuffer::Vertices, 1, 9));
    let mut bad = good;
    bad.surface.edges = &edges;
    check(bad, x, range(ContactBuffer::Edges, 1, 8));
    let mut bad = good;
    bad.surface.triangles = &triangles;
    check(bad, x, range(ContactBuffer::Triangles, 1, 12));
    let (vt, ee) = ([[0, 0], [8, 0]], [[0, 1], [1, 99]]);
    let mut bad = good;
    bad.pairs.vertex_triangle = &vt;
    check(bad, x, range(ContactBuffer::VertexTrianglePairs, 1, 8));
    let mut bad = good;
    bad.pairs.edge_edge = &ee;
    check(bad, x, range(ContactBuffer::EdgeEdgePairs, 1, 99));
    let mut nan = x.clone();
    nan[3].y = Real::NAN;
    let positions = ContactBuffer::Positions;
    check(
        good,
        &nan,
        ContactError::NonFinitePosition {
            buffer: positions,
            vertex: 3,
        },
    );
    // Output lengths.
    let mut short = vec![marker; 7];
    assert_eq!(
        good.add_gradient(x, &mut short),
        Err(length(ContactBuffer::Gradient, 8, 7))
    );
    assert!(short.iter().all(|&g| g == marker));
    let mut short = vec![Mat3::IDENTITY; 9];
    let expected = length(ContactBuffer::HessianDiagonal, 8, 9);
    assert_eq!(good.add_hessian_diagonal(x, &mut short), Err(expected));
    let candidates = scene.vertex_triangle.len() + scene.edge_edge.len();
    let mut stored = vec![PairHessian::default(); candidates];
    let active = good.pair_hessians(x, &mut stored).unwrap().len();
    assert!(
        active > 1 && active < candidates,
        "{active} of {candidates}"
    );
    let mut short = vec![PairHessian::default(); active - 1];
    let expected = ContactError::Capacity {
        buffer: ContactBuffer::PairHessians,
        needed: active,
        capacity: active - 1,
    };
    assert_eq!(good.pair_hessians(x, &mut short), Err(expected));
    // Exactly the active pairs fit.
    let mut exact = vec![PairHessian::default(); active];
    assert_eq!(
        good.pair_hessians(x, &mut exact).unwrap(),
        &stored[..active]
    );
    // The product: lengths, then the stored vertices.
    let mut stored = vec![PairHessian::default(); candidates];
    let hessians = good.pair_hessians(x, &mut stored).unwrap().to_vec();
    let direction = vec![Vec3::X; 8];
    let mut product = vec![marker; 7];
    let expected = length(ContactBuffer::Product, 8, 7);
    assert_eq!(
        add_hessian_product(&hessians, &direction, &mut product),
        Err(expected)
    );
    let mut wrong = hessians.clone();
    wrong[1].vertices[2] = 8;
    let mut product = vec![marker; 8];
    let expected = range(ContactBuffer::PairHessians, 1, 8);
    assert_eq!(
        add_hessian_product(&wrong, &direction, &mut product),
        Err(expected)
    );
    assert!(product.iter().all(|&p| p == marker));
}
