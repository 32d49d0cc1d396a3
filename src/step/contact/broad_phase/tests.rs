//! The broad phase against a brute-force reference, and its refusals.

// `f64::from` widens the f32 copy's coordinates and is the identity in the f64 copy.
#![allow(clippy::useless_conversion)]

extern crate std;
use std::{vec, vec::Vec};

use super::*;

/// A deterministic xorshift64 stream.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> Real {
        (self.next() >> 11) as Real / (1u64 << 53) as Real
    }
    fn vec(&mut self, scale: Real) -> Vec3 {
        Vec3::new(self.unit(), self.unit(), self.unit()) * scale
    }
}

/// The outward faces of a positively oriented tetrahedron (as `asset::surface`).
const FACES: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

/// An owned surface: the lists a `ContactSurface` borrows.
struct Lists {
    vertices: Vec<u32>,
    edges: Vec<[u32; 2]>,
    triangles: Vec<[u32; 3]>,
}

impl Lists {
    fn surface(&self) -> ContactSurface<'_> {
        ContactSurface {
            vertices: &self.vertices,
            edges: &self.edges,
            triangles: &self.triangles,
        }
    }
}

/// `tets` tetrahedra of size about `size` (m) scattered in a cube of edge `spread` (m):
/// their positions and surface (every vertex, the tets' six edges, four faces).
fn scattered_tets(rng: &mut Rng, tets: u32, size: Real, spread: Real) -> (Vec<Vec3>, Lists) {
    let mut positions = Vec::new();
    let mut lists = Lists {
        vertices: Vec::new(),
        edges: Vec::new(),
        triangles: Vec::new(),
    };
    for t in 0..tets {
        let centre = rng.vec(spread);
        for _ in 0..4 {
            positions.push(centre + rng.vec(size) - Vec3::splat(size * 0.5));
        }
        let base = 4 * t;
        lists.vertices.extend((0..4).map(|v| base + v));
        for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            lists.edges.push([base + a, base + b]);
        }
        lists
            .triangles
            .extend(FACES.iter().map(|f| f.map(|v| v + base)));
    }
    (positions, lists)
}

/// The grown box of `corners` over both position sets, written out axis by axis (the
/// definition in the module docs, independent of `Boxes`).
fn reference_box(start: &[Vec3], end: &[Vec3], corners: &[u32], dhat: Real) -> [[Real; 3]; 2] {
    let mut lo = [Real::INFINITY; 3];
    let mut hi = [Real::NEG_INFINITY; 3];
    for &c in corners {
        for x in [start[c as usize], end[c as usize]] {
            for axis in 0..3 {
                lo[axis] = lo[axis].min(x[axis]);
                hi[axis] = hi[axis].max(x[axis]);
            }
        }
    }
    let half = dhat * 0.5;
    [lo.map(|l| l - half), hi.map(|h| h + half)]
}

fn reference_overlap(a: [[Real; 3]; 2], b: [[Real; 3]; 2]) -> bool {
    (0..3).all(|axis| a[0][axis] <= b[1][axis] && b[0][axis] <= a[1][axis])
}

/// The O(n^2) reference: every pair tested.
fn brute_force(
    start: &[Vec3],
    end: &[Vec3],
    dhat: Real,
    lists: &Lists,
) -> (Vec<[u32; 2]>, Vec<[u32; 2]>) {
    let mut vt = Vec::new();
    for (i, &v) in lists.vertices.iter().enumerate() {
        let vb = reference_box(start, end, &[v], dhat);
        for (j, t) in lists.triangles.iter().enumerate() {
            if !t.contains(&v) && reference_overlap(vb, reference_box(start, end, t, dhat)) {
                vt.push([i as u32, j as u32]);
            }
        }
    }
    let mut ee = Vec::new();
    for (i, a) in lists.edges.iter().enumerate() {
        for (j, b) in lists.edges.iter().enumerate().skip(i + 1) {
            let shared = a.iter().any(|v| b.contains(v));
            if !shared
                && reference_overlap(
                    reference_box(start, end, a, dhat),
                    reference_box(start, end, b, dhat),
                )
            {
                ee.push([i as u32, j as u32]);
            }
        }
    }
    (vt, ee)
}

/// The (vertex, triangle) and (edge, edge) pairs of a query.
type Pairs = (Vec<[u32; 2]>, Vec<[u32; 2]>);

/// Runs the grid query with buffers of `scratch_len` lengths and room for `room` pairs of
/// each kind.
fn query(
    start: &[Vec3],
    end: Option<&[Vec3]>,
    dhat: Real,
    lists: &Lists,
    room: usize,
) -> Result<Pairs, ContactError> {
    let surface = lists.surface();
    let len = scratch_len::broad_phase(
        surface.vertices.len(),
        surface.edges.len(),
        surface.triangles.len(),
    );
    let mut slots = vec![0; len.slots];
    let mut entries = vec![0; len.entries];
    let mut scratch = BroadPhaseScratch::new(&mut slots, &mut entries);
    let mut vt = vec![[0; 2]; room];
    let mut ee = vec![[0; 2]; room];
    let pairs = match end {
        None => proximity_pairs(start, dhat, &surface, &mut scratch, &mut vt, &mut ee)?,
        Some(end) => motion_pairs(start, end, dhat, &surface, &mut scratch, &mut vt, &mut ee)?,
    };
    Ok((pairs.vertex_triangle.to_vec(), pairs.edge_edge.to_vec()))
}

fn assert_sorted_unique(pairs: &[[u32; 2]]) {
    assert!(
        pairs.windows(2).all(|w| w[0] < w[1]),
        "sorted, no duplicates"
    );
}

#[test]
fn proximity_matches_brute_force_on_random_scenes() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut total = (0, 0);
    for round in 0..40 {
        let tets = 1 + (rng.next() % 60) as u32;
        let size = 0.05 + rng.unit();
        let spread = 0.5 + 4.0 * rng.unit();
        let dhat = if round % 5 == 0 {
            0.0
        } else {
            0.2 * rng.unit()
        };
        let (positions, lists) = scattered_tets(&mut rng, tets, size, spread);
        let (vt, ee) = query(&positions, None, dhat, &lists, 100_000).unwrap();
        let (ref_vt, ref_ee) = brute_force(&positions, &positions, dhat, &lists);
        assert_sorted_unique(&vt);
        assert_sorted_unique(&ee);
        assert_eq!(vt, ref_vt, "round {round}");
        assert_eq!(ee, ref_ee, "round {round}");
        total = (total.0 + vt.len(), total.1 + ee.len());
    }
    // The scenes are dense enough for the comparison to mean something.
    assert!(total.0 > 1000 && total.1 > 1000, "{total:?}");
}

#[test]
fn motion_matches_brute_force_on_random_scenes() {
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    for round in 0..30 {
        let tets = 1 + (rng.next() % 40) as u32;
        let (start, lists) = scattered_tets(&mut rng, tets, 0.3, 3.0);
        let reach = if round % 3 == 0 { 3.0 } else { 0.3 };
        let end: Vec<Vec3> = start
            .iter()
            .map(|&x| x + rng.vec(reach) - Vec3::splat(reach * 0.5))
            .collect();
        let dhat = if round % 2 == 0 { 0.0 } else { 0.05 };
        let (vt, ee) = query(&start, Some(&end), dhat, &lists, 100_000).unwrap();
        let (ref_vt, ref_ee) = brute_force(&start, &end, dhat, &lists);
        assert_eq!(vt, ref_vt, "round {round}");
        assert_eq!(ee, ref_ee, "round {round}");
    }
}

#[test]
fn returned_pairs_share_no_vertex_and_lie_within_the_gap() {
    let mut rng = Rng(7);
    let (positions, lists) = scattered_tets(&mut rng, 80, 0.2, 2.0);
    let dhat = 0.05;
    let (vt, ee) = query(&positions, None, dhat, &lists, 100_000).unwrap();
    // The gap along an axis between two point sets, in f64 so that it is not the code's
    // rounding being checked; a rounding of the coordinates (~1e-7 m in f32) is allowed.
    let gap = |a: &[u32], b: &[u32]| {
        (0..3)
            .map(|axis| {
                let bounds = |c: &[u32]| {
                    c.iter()
                        .map(|&v| f64::from(positions[v as usize][axis]))
                        .fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)))
                };
                let ((alo, ahi), (blo, bhi)) = (bounds(a), bounds(b));
                (blo - ahi).max(alo - bhi)
            })
            .fold(f64::MIN, f64::max)
    };
    // The boxes' few roundings of coordinates below 4 m.
    let tolerance = 32.0 * f64::from(Real::EPSILON);
    for &[v, t] in &vt {
        let vertex = lists.vertices[v as usize];
        let triangle = lists.triangles[t as usize];
        assert!(!triangle.contains(&vertex));
        assert!(gap(&[vertex], &triangle) <= f64::from(dhat) + tolerance);
    }
    for &[a, b] in &ee {
        let (a, b) = (lists.edges[a as usize], lists.edges[b as usize]);
        assert!(!a.iter().any(|v| b.contains(v)));
        assert!(gap(&a, &b) <= f64::from(dhat) + tolerance);
    }
    assert!(!vt.is_empty() && !ee.is_empty());
}

/// A triangle in the plane `z = 0`, a vertex above its centroid at height `h`, and two
/// crossing edges `h` apart.
fn just_apart(h: Real) -> (Vec<Vec3>, Lists) {
    let positions = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.3, 0.3, h),
        // Edge 4-5 along x at z = 5, edge 6-7 along y at z = 5 + h.
        Vec3::new(0.0, 0.5, 5.0),
        Vec3::new(1.0, 0.5, 5.0),
        Vec3::new(0.5, 0.0, 5.0 + h),
        Vec3::new(0.5, 1.0, 5.0 + h),
    ];
    let lists = Lists {
        vertices: vec![3],
        edges: vec![[4, 5], [6, 7]],
        triangles: vec![[0, 1, 2]],
    };
    (positions, lists)
}

#[test]
fn pairs_just_inside_the_gap_are_found_and_just_outside_are_not() {
    let dhat = 0.01;
    // Distance 0.99 dhat: the vertex-triangle distance is its height, the edges' distance
    // their separation in z (they cross seen from above).
    let (positions, lists) = just_apart(0.99 * dhat);
    let (vt, ee) = query(&positions, None, dhat, &lists, 4).unwrap();
    assert_eq!(vt, [[0, 0]]);
    assert_eq!(ee, [[0, 1]]);
    // 1.01 dhat apart along z, so the boxes' gap along z exceeds dhat.
    let (positions, lists) = just_apart(1.01 * dhat);
    let (vt, ee) = query(&positions, None, dhat, &lists, 4).unwrap();
    assert!(vt.is_empty() && ee.is_empty());
}

#[test]
fn a_vertex_flying_through_a_triangle_is_a_motion_candidate() {
    let (start, lists) = just_apart(1.0);
    let mut end = start.clone();
    end[3].z = -1.0;
    // Both ends are 1 m from the triangle: no proximity pair at either.
    for positions in [&start, &end] {
        let (vt, _) = query(positions, None, 0.01, &lists, 4).unwrap();
        assert!(vt.is_empty());
    }
    let (vt, _) = query(&start, Some(&end), 0.0, &lists, 4).unwrap();
    assert_eq!(vt, [[0, 0]]);
}

#[test]
fn a_huge_primitive_and_far_apart_points_coarsen_the_grid() {
    let mut rng = Rng(99);
    let (mut positions, mut lists) = scattered_tets(&mut rng, 40, 0.1, 1.0);
    // One triangle spanning the scene a thousand times over: the mean box sets cells
    // about 0.15 m wide, and this one box would cover millions of them.
    let base = positions.len() as u32;
    positions.extend([
        Vec3::new(-500.0, -500.0, 0.5),
        Vec3::new(500.0, -500.0, 0.5),
        Vec3::new(0.0, 500.0, 0.5),
    ]);
    lists.triangles.push([base, base + 1, base + 2]);
    let exact = |positions: &[Vec3], lists: &Lists, dhat: Real| {
        let found = query(positions, None, dhat, lists, 100_000).unwrap();
        assert_eq!(found, brute_force(positions, positions, dhat, lists));
    };
    exact(&positions, &lists, 0.05);
    // And points 1e30 m away: cells of 2^-20 of the scene.
    positions.extend([Vec3::new(1e30, 0.0, 0.0), Vec3::new(0.0, -1e30, 0.0)]);
    lists.vertices.extend([base + 3, base + 4]);
    lists.edges.push([base + 3, base + 4]);
    for dhat in [0.0, 0.05] {
        exact(&positions, &lists, dhat);
    }
    // Coordinates whose differences overflow: the one-cell fallback, still exact.
    let big = Real::MAX * 0.75;
    let far = [
        Vec3::new(-big, 0.0, 0.0),
        Vec3::new(big, 0.0, 0.0),
        Vec3::new(0.0, big, -big),
    ];
    positions.extend(far);
    let n = positions.len() as u32;
    lists.triangles.push([n - 3, n - 2, n - 1]);
    exact(&positions, &lists, 0.0);
}

#[test]
fn a_short_output_buffer_reports_the_exact_count() {
    let mut rng = Rng(3);
    let (positions, lists) = scattered_tets(&mut rng, 30, 0.4, 1.0);
    let (ref_vt, ref_ee) = brute_force(&positions, &positions, 0.02, &lists);
    assert!(ref_vt.len() > 10 && ref_ee.len() > 10);
    assert_eq!(
        query(&positions, None, 0.02, &lists, ref_vt.len() - 1),
        Err(ContactError::Capacity {
            buffer: ContactBuffer::VertexTrianglePairs,
            needed: ref_vt.len(),
            capacity: ref_vt.len() - 1,
        })
    );
    // Room for the vertex-triangle pairs but not the edge pairs: the edge pairs' count.
    let surface = lists.surface();
    let len = scratch_len::broad_phase(lists.vertices.len(), lists.edges.len(), 120);
    let mut slots = vec![0; len.slots];
    let mut entries = vec![0; len.entries];
    let mut scratch = BroadPhaseScratch::new(&mut slots, &mut entries);
    let mut vt = vec![[0; 2]; ref_vt.len()];
    let mut ee = vec![[0; 2]; ref_ee.len() - 3];
    assert_eq!(
        proximity_pairs(&positions, 0.02, &surface, &mut scratch, &mut vt, &mut ee),
        Err(ContactError::Capacity {
            buffer: ContactBuffer::EdgeEdgePairs,
            needed: ref_ee.len(),
            capacity: ref_ee.len() - 3,
        })
    );
    // A short entries buffer is refused up front with the length it needs.
    let mut short = vec![0; len.entries - 1];
    let mut scratch = BroadPhaseScratch::new(&mut slots, &mut short);
    assert_eq!(
        proximity_pairs(&positions, 0.02, &surface, &mut scratch, &mut vt, &mut ee),
        Err(ContactError::Capacity {
            buffer: ContactBuffer::Entries,
            needed: len.entries,
            capacity: len.entries - 1,
        })
    );
}

#[test]
fn a_table_of_one_slot_is_slow_but_exact() {
    let mut rng = Rng(11);
    let (positions, lists) = scattered_tets(&mut rng, 20, 0.3, 1.0);
    let surface = lists.surface();
    let len = scratch_len::broad_phase(lists.vertices.len(), lists.edges.len(), 80);
    let mut slots = [0; 2];
    let mut entries = vec![0; len.entries];
    let mut scratch = BroadPhaseScratch::new(&mut slots, &mut entries);
    let (mut vt, mut ee) = (vec![[0; 2]; 10_000], vec![[0; 2]; 10_000]);
    let pairs =
        proximity_pairs(&positions, 0.01, &surface, &mut scratch, &mut vt, &mut ee).unwrap();
    let (ref_vt, ref_ee) = brute_force(&positions, &positions, 0.01, &lists);
    assert_eq!(pairs.vertex_triangle, ref_vt);
    assert_eq!(pairs.edge_edge, ref_ee);
}

#[test]
fn refusals_name_the_vertex_the_buffer_and_the_entry() {
    let (mut positions, lists) = just_apart(0.5);
    let end = positions.clone();
    assert_eq!(
        query(&positions, None, -1.0, &lists, 4),
        Err(ContactError::Gap)
    );
    assert_eq!(
        query(&positions, None, Real::NAN, &lists, 4),
        Err(ContactError::Gap)
    );
    assert_eq!(
        query(&positions, Some(&end[..7]), 0.0, &lists, 4),
        Err(ContactError::BufferLength {
            buffer: ContactBuffer::EndPositions,
            expected: 8,
            actual: 7
        })
    );
    let mut bad_end = end.clone();
    bad_end[6].y = Real::INFINITY;
    assert_eq!(
        query(&positions, Some(&bad_end), 0.0, &lists, 4),
        Err(ContactError::NonFinitePosition {
            buffer: ContactBuffer::EndPositions,
            vertex: 6
        })
    );
    positions[5].x = Real::NAN;
    assert_eq!(
        query(&positions, Some(&bad_end), 0.0, &lists, 4),
        Err(ContactError::NonFinitePosition {
            buffer: ContactBuffer::Positions,
            vertex: 5
        })
    );
    let (positions, mut lists) = just_apart(0.5);
    lists.edges.push([2, 8]);
    assert_eq!(
        query(&positions, None, 0.0, &lists, 4),
        Err(ContactError::IndexOutOfRange {
            buffer: ContactBuffer::Edges,
            element: 2,
            index: 8
        })
    );
    // Empty surfaces need no scratch.
    let empty = Lists {
        vertices: vec![],
        edges: vec![],
        triangles: vec![],
    };
    assert_eq!(
        query(&positions, None, 0.0, &empty, 0),
        Ok((vec![], vec![]))
    );
}
