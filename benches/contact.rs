//! The cost of body–body contact per solver iteration against a force pass, and the broad
//! phase's cost against the number of surface primitives (issue #39, deliverable 5).
//!
//! **Per iteration.** Two boxes of `n^3` cells of 5 tetrahedra (edge `a = 0.01 m`, stable
//! neo-Hookean E = 1 MPa, nu = 0.3; 10 000 tetrahedra in all at `n = 10`) face each other across
//! a gap of `0.1 a`, the second shifted sideways by `(0.37 a, 0.23 a)`, with the contact gap
//! `dhat = 0.15 a`: the two facing faces' vertices, edges and triangles are within `dhat` of
//! those across (the table prints the counts). Timed, f64, one thread:
//!
//! * **force pass**: zero a force buffer, then `energy_and_add_forces` over both boxes (the pass
//!   every solver evaluates once or more per iteration);
//! * **broad phase**: `proximity_pairs` over the two boxes' boundary surfaces;
//! * **barrier gradient**: `ContactPotential::add_gradient` over the pairs found (the energy
//!   and gradient the relaxation and Newton's line search evaluate);
//! * **contact per iteration**: the two above together, what an iteration adds to the force
//!   pass; the ratio to the force pass is the figure the issue asks for (target at most 1);
//! * **pair Hessians**: `ContactPotential::pair_hessians` (Newton's, once per iteration, with
//!   the 12x12 projection of every active pair).
//! * **with candidate reuse** (`ContactModel` with `CandidateReuse` buffers, what the solvers
//!   and the world run): the motion query a line search runs once (`admissible_step` to a point
//!   every vertex of which moved `0.05 a`, alternately in two opposite directions so that each
//!   call runs the grid, with the gap, and the CCD), and an evaluation inside that motion
//!   (`energy_and_add_forces` of the model, less the force pass: the kept pairs filtered, the
//!   barrier's energy and gradient; the filter alone is that less the barrier's row). Without
//!   reuse a line search runs a motion query too (gap 0, and the same CCD) and the broad phase
//!   for every evaluation; with it, the filter replaces that broad phase.
//!
//! **Scaling.** The broad phase on one box's surface at `n` = 8, 16, 32, 48 (cells per side):
//! ns per primitive, which stays flat where the cost is linear.
//!
//! Every operation is timed round-robin (blocks of about 20 ms, the least of 5 rounds; with
//! `SOFTFEM_BENCH_QUICK=1` 2 ms blocks and 3 rounds), and the table names the CPU it ran on.
//! `cargo bench -p softfem-benches --bench contact` (a few seconds).

mod common;

use std::hint::black_box;
use std::time::Instant;

use common::TablePass;
use softfem::f64::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};
use softfem::f64::element::TetRest;
use softfem::f64::generate::{BoxSplit, box_counts, fill_box};
use softfem::f64::material::StableNeoHookean;
use softfem::f64::mesh::TetMesh;
use softfem::f64::step::contact::boundary::ContactSurface;
use softfem::f64::step::contact::broad_phase::{BroadPhaseScratch, proximity_pairs};
use softfem::f64::step::contact::model::{CandidateReuse, ContactBuffers, ContactModel};
use softfem::f64::step::contact::potential::{ContactBarrier, ContactPotential, PairHessian};
use softfem::f64::step::{ElasticEnergy, TetElastic, scratch_len};
use softfem::glam::DVec3;

/// The cell edge (m).
const EDGE: f64 = 0.01;

/// Boxes of `n^3` cells side by side along x, `gap` (m) apart, each shifted by `(0.37, 0.23)`
/// cell edges in y and z against the one before (so that a vertex faces a triangle's interior,
/// not a vertex); positions and tetrahedra of all.
fn boxes(n: usize, count: usize, gap: f64) -> (Vec<DVec3>, Vec<[u32; 4]>) {
    let (nv, nt) = box_counts(n, n, n, BoxSplit::Alternating5).unwrap();
    let side = EDGE * n as f64;
    let (mut positions, mut tets) = (Vec::new(), Vec::new());
    for k in 0..count {
        let (mut x, mut t) = (vec![DVec3::ZERO; nv], vec![[0; 4]; nt]);
        let k = k as f64;
        let min = DVec3::new(k * (side + gap), k * 0.37 * EDGE, k * 0.23 * EDGE);
        fill_box(
            min,
            min + DVec3::splat(side),
            n,
            n,
            n,
            BoxSplit::Alternating5,
            &mut x,
            &mut t,
        )
        .unwrap();
        let offset = positions.len() as u32;
        positions.extend(x);
        tets.extend(t.iter().map(|tet| tet.map(|v| v + offset)));
    }
    (positions, tets)
}

/// The boundary triangles of `tets`.
fn surface_triangles(tets: &[[u32; 4]], vertex_count: usize) -> Vec<[u32; 3]> {
    let mut scratch = vec![BoundaryFace::default(); boundary_scratch_len(tets.len())];
    let faces = boundary_faces(tets, vertex_count, &mut scratch).unwrap();
    faces.iter().map(|face| face.triangle).collect()
}

/// The buffers of one broad-phase query over a surface.
struct Query {
    triangles: Vec<[u32; 3]>,
    vertices: Vec<u32>,
    edges: Vec<[u32; 2]>,
    slots: Vec<u32>,
    entries: Vec<u32>,
    vertex_triangle: Vec<[u32; 2]>,
    edge_edge: Vec<[u32; 2]>,
}

impl Query {
    fn new(triangles: Vec<[u32; 3]>, vertex_count: usize) -> Query {
        let f = triangles.len();
        let mut vertices = vec![0; scratch_len::boundary_vertices(f)];
        let mut edges = vec![[0; 2]; scratch_len::boundary_edges(f)];
        let (v, e) = {
            let surface =
                ContactSurface::from_triangles(&triangles, vertex_count, &mut vertices, &mut edges)
                    .unwrap();
            (surface.vertices.len(), surface.edges.len())
        };
        vertices.truncate(v);
        edges.truncate(e);
        let lengths = scratch_len::broad_phase(v, e, f);
        Query {
            triangles,
            vertices,
            edges,
            slots: vec![0; lengths.slots],
            entries: vec![0; lengths.entries],
            // Generous: a broad phase that needs more says so and the bench stops.
            vertex_triangle: vec![[0; 2]; 64 * v],
            edge_edge: vec![[0; 2]; 64 * e],
        }
    }

    fn primitives(&self) -> usize {
        self.vertices.len() + self.edges.len() + self.triangles.len()
    }

    /// The pair counts `(vertex–triangle, edge–edge)` of a query at `positions`.
    fn run(&mut self, positions: &[DVec3], dhat: f64) -> (usize, usize) {
        let surface = ContactSurface {
            vertices: &self.vertices,
            edges: &self.edges,
            triangles: &self.triangles,
        };
        let mut scratch = BroadPhaseScratch::new(&mut self.slots, &mut self.entries);
        let pairs = proximity_pairs(
            positions,
            dhat,
            &surface,
            &mut scratch,
            &mut self.vertex_triangle,
            &mut self.edge_edge,
        )
        .unwrap();
        (pairs.vertex_triangle.len(), pairs.edge_edge.len())
    }
}

/// The least time (ns) of one call of each operation, timed round-robin.
fn least_ns(operations: &mut [&mut dyn FnMut()], block_ns: f64, rounds: u32) -> Vec<f64> {
    let repetitions: Vec<u32> = operations
        .iter_mut()
        .map(|operation| {
            let start = Instant::now();
            operation();
            let once = start.elapsed().as_secs_f64() * 1e9;
            (block_ns / once.max(1.0)).clamp(1.0, 1e6) as u32
        })
        .collect();
    let mut best = vec![f64::INFINITY; operations.len()];
    for _ in 0..rounds {
        for ((operation, &count), best) in operations.iter_mut().zip(&repetitions).zip(&mut best) {
            let start = Instant::now();
            for _ in 0..count {
                operation();
            }
            *best = best.min(start.elapsed().as_secs_f64() * 1e9 / f64::from(count));
        }
    }
    best
}

fn main() {
    let (block_ns, rounds) = match common::table_pass() {
        TablePass::Skip => return,
        TablePass::Test => (1e5, 1),
        TablePass::Full if common::quick() => (2e6, 3),
        TablePass::Full => (2e7, 5),
    };
    per_iteration(block_ns, rounds);
    scaling(block_ns, rounds);
}

/// The two facing boxes: contact per iteration against a force pass.
fn per_iteration(block_ns: f64, rounds: u32) {
    let n = 10;
    let dhat = 0.15 * EDGE;
    let (positions, tets) = boxes(n, 2, 0.1 * EDGE);
    let mut rest_data = vec![TetRest::default(); tets.len()];
    let mesh = TetMesh::new(&positions, &tets, &mut rest_data).unwrap();
    let body = TetElastic::new(
        mesh,
        StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap(),
    );
    let mut forces = vec![DVec3::ZERO; positions.len()];
    let mut query = Query::new(surface_triangles(&tets, positions.len()), positions.len());
    let (vt, ee) = query.run(&positions, dhat);
    // The pairs found, copied out so that the potential can hold them while the broad phase is
    // timed on its own buffers.
    let vertex_triangle = query.vertex_triangle[..vt].to_vec();
    let edge_edge = query.edge_edge[..ee].to_vec();
    let surface_vertices = query.vertices.clone();
    let surface_edges = query.edges.clone();
    let surface_triangles = query.triangles.clone();
    let potential = ContactPotential {
        barrier: ContactBarrier {
            stiffness: 1.0e9,
            gap: dhat,
        },
        surface: ContactSurface {
            vertices: &surface_vertices,
            edges: &surface_edges,
            triangles: &surface_triangles,
        },
        pairs: softfem::f64::step::contact::broad_phase::CandidatePairs {
            vertex_triangle: &vertex_triangle,
            edge_edge: &edge_edge,
        },
        rest_positions: &positions,
    };
    let mut gradient = vec![DVec3::ZERO; positions.len()];
    let mut hessians = vec![PairHessian::default(); vt + ee];
    let active = potential
        .pair_hessians(&positions, &mut hessians)
        .unwrap()
        .len();

    let mut force_pass = || {
        forces.fill(DVec3::ZERO);
        black_box(
            body.energy_and_add_forces(black_box(&positions), &mut forces)
                .unwrap(),
        );
    };
    let mut broad = || {
        black_box(query.run(black_box(&positions), dhat));
    };
    let mut barrier = || {
        gradient.fill(DVec3::ZERO);
        black_box(
            potential
                .add_gradient(black_box(&positions), &mut gradient)
                .unwrap(),
        );
    };
    let mut pair_hessians = || {
        black_box(
            potential
                .pair_hessians(black_box(&positions), &mut hessians)
                .unwrap()
                .len(),
        );
    };
    // The model the solvers run, with candidate reuse.
    let lengths = scratch_len::broad_phase(
        surface_vertices.len(),
        surface_edges.len(),
        surface_triangles.len(),
    );
    let (mut slots, mut entries) = (vec![0; lengths.slots], vec![0; lengths.entries]);
    let (mut model_vt, mut model_ee) = (
        vec![[0; 2]; 64 * surface_vertices.len()],
        vec![[0; 2]; 64 * surface_edges.len()],
    );
    let mut model_hessians = vec![PairHessian::default(); 4 * (vt + ee)];
    let mut bounds = vec![DVec3::ZERO; 2 * surface_vertices.len()];
    let (mut kept_vt, mut kept_ee) = (
        vec![[0; 2]; 128 * surface_vertices.len()],
        vec![[0; 2]; 128 * surface_edges.len()],
    );
    let mut model_rest = vec![TetRest::default(); tets.len()];
    let model = ContactModel::new(
        TetElastic::new(
            TetMesh::new(&positions, &tets, &mut model_rest).unwrap(),
            StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap(),
        ),
        ContactSurface {
            vertices: &surface_vertices,
            edges: &surface_edges,
            triangles: &surface_triangles,
        },
        &positions,
        ContactBarrier {
            stiffness: 1.0e9,
            gap: dhat,
        },
        ContactBuffers {
            slots: &mut slots,
            entries: &mut entries,
            vertex_triangle: &mut model_vt,
            edge_edge: &mut model_ee,
            hessians: &mut model_hessians,
            reuse: CandidateReuse {
                bounds: &mut bounds,
                vertex_triangle: &mut kept_vt,
                edge_edge: &mut kept_ee,
            },
            ..Default::default()
        },
    )
    .unwrap();
    let step = DVec3::new(0.03, -0.02, 0.03) * EDGE;
    let moved: [Vec<DVec3>; 2] =
        [1.0, -1.0].map(|sign| positions.iter().map(|&x| x + step * sign).collect());
    let mut side = 0;
    let mut motion_query = || {
        side = 1 - side;
        black_box(
            model
                .admissible_step(black_box(&positions), &moved[side])
                .unwrap(),
        );
    };
    let mut model_forces = vec![DVec3::ZERO; positions.len()];
    let mut kept_evaluation = || {
        model_forces.fill(DVec3::ZERO);
        black_box(
            model
                .energy_and_add_forces(black_box(&positions), &mut model_forces)
                .unwrap(),
        );
    };

    let times = least_ns(
        &mut [
            &mut force_pass,
            &mut broad,
            &mut barrier,
            &mut pair_hessians,
            &mut motion_query,
            &mut kept_evaluation,
        ],
        block_ns,
        rounds,
    );
    let [force, broad, barrier, hessian, motion, kept] =
        [times[0], times[1], times[2], times[3], times[4], times[5]];
    let counts = model.counts();
    assert!(
        counts.reused_queries > 0,
        "the evaluations did not use the kept pairs: {counts:?}"
    );
    let kept = kept - force;
    println!(
        "\nContact per solver iteration, f64, one thread, on {}: two boxes of {n}^3 cells \
         ({} tets), {} surface primitives, {vt} vertex-triangle and {ee} edge-edge candidate \
         pairs within dhat = {dhat} m, {active} of them active.\n",
        common::machine(),
        tets.len(),
        query.primitives()
    );
    let us = |ns: f64| format!("{:.1}", ns / 1e3);
    let ratio = |ns: f64| format!("{:.2}x", ns / force);
    common::print_markdown_table(
        &["operation", "us", "vs force pass"],
        [
            vec![
                "force pass (energy and forces)".into(),
                us(force),
                ratio(force),
            ],
            vec![
                "broad phase (proximity_pairs)".into(),
                us(broad),
                ratio(broad),
            ],
            vec![
                "barrier energy and gradient".into(),
                us(barrier),
                ratio(barrier),
            ],
            vec![
                "contact per iteration (the two above)".into(),
                us(broad + barrier),
                ratio(broad + barrier),
            ],
            vec![
                "pair Hessians, projected (Newton)".into(),
                us(hessian),
                ratio(hessian),
            ],
            vec![
                "with reuse: the kept pairs filtered (instead of the broad phase)".into(),
                us(kept - barrier),
                ratio(kept - barrier),
            ],
            vec![
                "with reuse: contact per evaluation (filter and barrier)".into(),
                us(kept),
                ratio(kept),
            ],
            vec![
                "with reuse: the motion query, once a line search (grid with the gap, CCD)".into(),
                us(motion),
                ratio(motion),
            ],
        ],
    );
}

/// The broad phase on one box's surface at growing resolution: ns per primitive.
fn scaling(block_ns: f64, rounds: u32) {
    println!(
        "\nBroad phase against surface size, f64, one thread, on {}: one box of n^3 cells \
         (edge {EDGE} m), dhat = {} m.\n",
        common::machine(),
        0.15 * EDGE
    );
    let mut rows = Vec::new();
    for n in [8, 16, 32, 48] {
        let (positions, tets) = boxes(n, 1, 0.0);
        let mut query = Query::new(surface_triangles(&tets, positions.len()), positions.len());
        let primitives = query.primitives();
        let (vt, ee) = query.run(&positions, 0.15 * EDGE);
        let ns = least_ns(
            &mut [&mut || {
                black_box(query.run(black_box(&positions), 0.15 * EDGE));
            }],
            block_ns,
            rounds,
        )[0];
        rows.push(vec![
            format!("{n}"),
            format!("{primitives}"),
            format!("{}", vt + ee),
            format!("{:.1}", ns / 1e3),
            format!("{:.0}", ns / primitives as f64),
        ]);
    }
    common::print_markdown_table(
        &["n", "primitives", "pairs", "us", "ns per primitive"],
        rows,
    );
}
