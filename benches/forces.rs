//! Throughput of the mesh force kernels in million tetrahedra per second, single thread, on boxes
//! of about 10k, 100k and 1M tetrahedra (Kuhn 6-tet split, `softfem::generate::fill_box`).
//!
//! Variants (f32 unless stated): `TetMesh::add_elastic_forces` (direct stress) for StVK,
//! neo-Hookean and stable neo-Hookean, and for StVK and stable neo-Hookean again on the mesh
//! with its rest data in blocks (`TetMesh::with_rest_blocks`, ids `*_blocks_f32`, as a
//! growable `Body` holds it); `add_elastic_forces_principal` (SVD path) for StVK and
//! stable neo-Hookean; `add_elastic_forces_clamped` (threshold 0.3) for stable neo-Hookean; StVK
//! direct in f64 (`softfem::f64`) for reference; and `elastic_energy` for StVK.
//!
//! Every force iteration zeroes the force buffer and then adds the forces of the whole mesh, so
//! the reported times include the zeroing (one pass over the vertices) and the finiteness check
//! of the positions that every kernel call makes. The energy variant has no buffer to zero.
//!
//! The deformed positions are the rest grid (the unit cube) through a fixed general affine map
//! (a matrix with no zero entries and no symmetry: stretch, shear and rotation; determinant about
//! 1.14) plus a deterministic per-vertex jitter of up to 8% of the grid spacing per coordinate, so
//! `F` differs from element to element and is never trivial, and `J > 0` everywhere (checked at
//! start-up; the tables print the range of `J`).
//!
//! `cargo bench -p softfem-benches --bench forces` runs two passes:
//! 1. criterion, one group per mesh size with `Throughput::Elements(tets)`, one benchmark per
//!    variant, each iteration one pass over the whole mesh, 10 samples each. The 1M group uses
//!    flat sampling and a longer measurement time (an iteration takes 25 to 200 ms there). With
//!    the table pass, the whole run takes about two minutes.
//! 2. a plain `Instant` pass that times every variant round-robin several times per mesh size,
//!    keeps the minimum per variant and prints one markdown table per mesh size (Mtets/s, ns/tet,
//!    throughput relative to StVK direct f32). Interleaving the variants and taking minima means
//!    the ratios come from the same machine state, which criterion's separate runs do not
//!    guarantee.
//!
//! Threads: `stvk_direct_partitioned_f32` is the deterministic partitioned scheme
//! (`mesh::TetPartition`: element pieces into a buffer, then a gather by vertex) run on this
//! thread, its cost against `stvk_direct_f32`; `explicit_step_f32` is one `explicit_step` of stable
//! neo-Hookean at half the proven stable step (the body falling from rest), and
//! `explicit_step_blocks_f32` the same with rest blocks; `relax_step_f32` and
//! `relax_step_20_f32` are one `relax_step` of 10 and of 20 descent iterations from the same
//! start (their evaluation counts printed first); after each table a second one gives the
//! relaxation iteration against the stable neo-Hookean direct force pass of the same run, per
//! width: per call (the 10-iteration call over 10) and marginal (the difference of the two
//! calls over 10, the loop without the call's fixed work), also as CSV rows
//! `relax_iteration_per_call_f32 <width>` and `relax_iteration_marginal_f32 <width>` (unit
//! "force passes"). With
//! `--features rayon` the same passes run on rayon pools of 1 and 2 threads
//! (`softfem::parallel`, `ParallelTetElastic`), and the tables are followed by the one-thread cost
//! and the 2-thread speed-ups. `SOFTFEM_BENCH_CSV=<path>` appends every row (Mtets/s, with its
//! thread count) to a CSV file.
//!
//! `SOFTFEM_BENCH_WIDTHS=1` skips criterion and runs instead a table pass of every one-thread
//! variant at every SIMD width the machine has (`softfem::simd::set_max_width`), all (variant,
//! width) pairs round-robin, after a STREAM-like triad that gives the memory roofline (GB/s and
//! Mtets/s at the bytes the layout streams per tetrahedron); with `SOFTFEM_BENCH_QUICK=1` too,
//! only the two smaller meshes.
//!
//! `SOFTFEM_BENCH_ONLY=<patterns>` (with `SOFTFEM_BENCH_WIDTHS=1`) keeps only the (variant,
//! width) pairs whose `"<id> <width>"` (`stvk_principal_f32 avx512`) contains one of the
//! comma-separated patterns: `SOFTFEM_BENCH_ONLY='principal_f32 avx512,stvk_direct_f32 avx512'`
//! times those three pairs alone, round-robin, for quick A/B runs of one kernel.
//!
//! `SOFTFEM_BENCH_QUICK=1` skips criterion and the 1M mesh and runs the table pass with few
//! repetitions: a smoke test that finishes in seconds.

mod common;

use std::hint::black_box;
use std::time::Duration;

use common::{TablePass, XorShift64Star};
use criterion::{Criterion, SamplingMode, Throughput};
use softfem::MeshError;
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::{DVec3, Mat3, Vec3};
use softfem::material::{NeoHookean, StVK, StableNeoHookean};
use softfem::mesh::{
    TetMesh, TetPartition, TetRestBlock, element_forces_len, partition_incident_len,
    partition_offsets_len, rest_block_count,
};
#[cfg(feature = "rayon")]
use softfem::parallel::ParallelTetElastic;
use softfem::simd::{self, Width};
use softfem::step::{
    ElasticEnergy, ExplicitScratch, ExplicitSettings, RelaxScratch, RelaxSettings, Scene,
    TetElastic, explicit_step, relax_step, scratch_len, stable_time_step,
};

/// Cubes per axis of the benchmarked boxes, 6 tetrahedra per cube: 10 368, 105 456 and 998 250
/// tetrahedra.
const CELLS_PER_AXIS: [usize; 3] = [12, 26, 55];

/// Meshes in quick mode: the first two sizes.
const QUICK_MESHES: usize = 2;

/// Meshes with at least this many tetrahedra get criterion's flat sampling and a longer
/// measurement time.
const LARGE_MESH_TETS: usize = 500_000;

/// Young's modulus (Pa) and Poisson ratio of every material: a soft rubber.
const YOUNG: f32 = 1.0e6;
const POISSON: f32 = 0.45;

/// One `explicit_step` call on positions, velocities and scratch.
type StepFn<'s> = dyn Fn(&mut [Vec3], &mut [Vec3], &mut ExplicitScratch<'_, Vec3>) + 's;

/// Descent iterations of the two relaxation variants (their labels say 10 and 20): the
/// marginal cost of an iteration is the difference of the two calls over 10.
const RELAX_BUDGETS: [u32; 2] = [10, 20];

/// The ids of the two relaxation variants.
const RELAX_IDS: [&str; 2] = ["relax_step_f32", "relax_step_20_f32"];

/// The force pass the relaxation is measured against.
const RELAX_REFERENCE: &str = "stable_nh_direct_f32";

/// Pieces of the partitioned variants.
const PIECES: usize = 8;

/// Thread counts of the rayon variants (feature `rayon`).
#[cfg(feature = "rayon")]
const THREADS: [usize; 2] = [1, 2];

/// Stretch threshold of the clamped variant.
const CLAMP_THRESHOLD: f32 = 0.3;

/// Largest jitter per coordinate, as a fraction of the grid spacing.
const JITTER: f32 = 0.08;

/// One benchmarked box: the generated mesh, its deformed positions and the rest data the two
/// `TetMesh`es borrow, in both precisions.
struct DeformedBox {
    cells: usize,
    tets: Vec<[u32; 4]>,
    rest_positions: Vec<Vec3>,
    positions: Vec<Vec3>,
    rest_positions_f64: Vec<DVec3>,
    positions_f64: Vec<DVec3>,
    rest: Vec<softfem::element::TetRest>,
    rest_f64: Vec<softfem::f64::element::TetRest>,
    /// The rest data in blocks of 16 (`TetMesh::with_rest_blocks`) of the `*_blocks` variants.
    blocks: Vec<TetRestBlock>,
    /// The vertex-to-element adjacency of the partitioned variants.
    offsets: Vec<u32>,
    incident: Vec<u32>,
    /// Smallest and largest `J = det F` over the elements.
    j_range: (f32, f32),
}

/// What the tables and criterion say about a box, kept apart from the buffers the variants
/// borrow.
#[derive(Clone, Copy)]
struct MeshInfo {
    cells: usize,
    tets: usize,
    vertices: usize,
    j_range: (f32, f32),
}

impl DeformedBox {
    /// The unit cube in `cells^3` cubes, deformed by a fixed affine map plus jitter.
    fn new(cells: usize) -> Self {
        let (vertex_count, tet_count) = box_counts(cells, cells, cells, BoxSplit::Kuhn6).unwrap();
        let mut rest_positions = vec![Vec3::ZERO; vertex_count];
        let mut tets = vec![[0u32; 4]; tet_count];
        fill_box(
            Vec3::ZERO,
            Vec3::ONE,
            cells,
            cells,
            cells,
            BoxSplit::Kuhn6,
            &mut rest_positions,
            &mut tets,
        )
        .unwrap();

        // Columns of a general map (no symmetry, no zero entries), then a translation.
        let affine = Mat3::from_cols(
            Vec3::new(1.10, -0.10, 0.05),
            Vec3::new(0.15, 0.95, -0.12),
            Vec3::new(-0.05, 0.20, 1.05),
        );
        let offset = Vec3::new(0.3, -0.2, 0.1);
        let amplitude = JITTER / cells as f32;
        let mut rng = XorShift64Star(0x5eed_f0ce_5b0c_2026);
        let positions: Vec<Vec3> = rest_positions
            .iter()
            .map(|&x| {
                let jitter = Vec3::new(
                    rng.next_signed_unit(),
                    rng.next_signed_unit(),
                    rng.next_signed_unit(),
                );
                affine * x + offset + jitter * amplitude
            })
            .collect();

        let volume = |x: &[Vec3], [a, b, c, d]: [u32; 4]| {
            let [a, b, c, d] = [a, b, c, d].map(|v| x[v as usize]);
            Mat3::from_cols(b - a, c - a, d - a).determinant()
        };
        let j_range = tets
            .iter()
            .map(|&tet| volume(&positions, tet) / volume(&rest_positions, tet))
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), j| {
                (lo.min(j), hi.max(j))
            });
        assert!(
            j_range.0 > 0.0,
            "an element is inverted: J range {j_range:?}"
        );

        DeformedBox {
            cells,
            rest_positions_f64: rest_positions.iter().map(|x| x.as_dvec3()).collect(),
            positions_f64: positions.iter().map(|x| x.as_dvec3()).collect(),
            rest: vec![softfem::element::TetRest::default(); tet_count],
            rest_f64: vec![softfem::f64::element::TetRest::default(); tet_count],
            blocks: vec![TetRestBlock::ZERO; rest_block_count(tet_count)],
            offsets: vec![0; partition_offsets_len(vertex_count)],
            incident: vec![0; partition_incident_len(tet_count)],
            tets,
            rest_positions,
            positions,
            j_range,
        }
    }

    fn info(&self) -> MeshInfo {
        MeshInfo {
            cells: self.cells,
            tets: self.tets.len(),
            vertices: self.rest_positions.len(),
            j_range: self.j_range,
        }
    }

    /// Validates both meshes (filling the rest data) and returns every variant on them.
    fn variants(&mut self) -> Vec<Variant<'_>> {
        let DeformedBox {
            tets,
            rest_positions,
            positions,
            rest_positions_f64,
            positions_f64,
            rest,
            rest_f64,
            blocks,
            offsets,
            incident,
            ..
        } = self;
        let mesh = TetMesh::new(rest_positions, tets, rest).unwrap();
        let blocked = mesh.with_rest_blocks(blocks).unwrap();
        let mesh_f64 =
            softfem::f64::mesh::TetMesh::new(rest_positions_f64, tets, rest_f64).unwrap();
        let positions: &[Vec3] = positions;
        let positions_f64: &[DVec3] = positions_f64;

        let stvk = StVK::from_young_poisson(YOUNG, POISSON).unwrap();
        let neo_hookean = NeoHookean::from_young_poisson(YOUNG, POISSON).unwrap();
        let stable = StableNeoHookean::from_young_poisson(YOUNG, POISSON).unwrap();
        let stvk_f64 =
            softfem::f64::material::StVK::from_young_poisson(YOUNG.into(), POISSON.into()).unwrap();

        // Each force variant zeroes its own buffer, then runs one kernel over the whole mesh.
        let n = mesh.vertex_count();
        // Eight pieces: a few per thread of the two-core machine (the bits do not depend on it).
        let partition = TetPartition::new(mesh, PIECES, offsets, incident).unwrap();
        let mut variants = vec![
            Variant::forces(
                "StVK, direct, f32",
                "stvk_direct_f32",
                n,
                move |f: &mut [Vec3]| mesh.add_elastic_forces(&stvk, positions, f),
            ),
            Variant::forces(
                "StVK, direct, rest blocks, f32",
                "stvk_direct_blocks_f32",
                n,
                move |f: &mut [Vec3]| blocked.add_elastic_forces(&stvk, positions, f),
            ),
            Variant::forces(
                "neo-Hookean, direct, f32",
                "neo_hookean_direct_f32",
                n,
                move |f: &mut [Vec3]| mesh.add_elastic_forces(&neo_hookean, positions, f),
            ),
            Variant::forces(
                "stable neo-Hookean, direct, f32",
                "stable_nh_direct_f32",
                n,
                move |f: &mut [Vec3]| mesh.add_elastic_forces(&stable, positions, f),
            ),
            Variant::forces(
                "stable neo-Hookean, direct, rest blocks, f32",
                "stable_nh_direct_blocks_f32",
                n,
                move |f: &mut [Vec3]| blocked.add_elastic_forces(&stable, positions, f),
            ),
            Variant::forces(
                "StVK, principal (SVD), f32",
                "stvk_principal_f32",
                n,
                move |f: &mut [Vec3]| mesh.add_elastic_forces_principal(&stvk, positions, f),
            ),
            Variant::forces(
                "stable neo-Hookean, principal (SVD), f32",
                "stable_nh_principal_f32",
                n,
                move |f: &mut [Vec3]| mesh.add_elastic_forces_principal(&stable, positions, f),
            ),
            Variant::forces(
                "stable neo-Hookean, clamped (SVD, threshold 0.3), f32",
                "stable_nh_clamped_f32",
                n,
                move |f: &mut [Vec3]| {
                    mesh.add_elastic_forces_clamped(&stable, CLAMP_THRESHOLD, positions, f)
                },
            ),
            Variant::forces(
                "StVK, direct, f64",
                "stvk_direct_f64",
                mesh_f64.vertex_count(),
                move |f: &mut [DVec3]| mesh_f64.add_elastic_forces(&stvk_f64, positions_f64, f),
            ),
            Variant::forces(
                "stable neo-Hookean, fused energy + forces (relaxation pass), f32",
                "stable_nh_fused_f32",
                n,
                move |f: &mut [Vec3]| {
                    TetElastic::new(mesh, stable)
                        .energy_and_add_forces(positions, f)
                        .map(|energy| {
                            black_box(energy);
                        })
                },
            ),
            Variant {
                label: "StVK, `elastic_energy` (no forces), f32",
                id: "stvk_energy_f32",
                run: Box::new(move || {
                    black_box(mesh.elastic_energy(&stvk, black_box(positions)).unwrap());
                }),
                threads: 1,
                iterations: 0,
            },
        ];
        let mut element_forces = vec![[Vec3::ZERO; 4]; element_forces_len(mesh.element_count())];
        variants.push(Variant::forces(
            "StVK, direct, partitioned (pieces + gather, this thread), f32",
            "stvk_direct_partitioned_f32",
            n,
            move |f: &mut [Vec3]| {
                partition.add_elastic_forces(&stvk, positions, f, &mut element_forces)
            },
        ));
        variants.push(Variant::explicit_step(
            "stable neo-Hookean explicit step, sequential, f32",
            "explicit_step_f32",
            mesh,
            None,
            rest_positions,
            1,
        ));
        variants.push(Variant::explicit_step(
            "stable neo-Hookean explicit step, sequential, rest blocks, f32",
            "explicit_step_blocks_f32",
            blocked,
            None,
            rest_positions,
            1,
        ));
        variants.push(Variant::relax_step(mesh, positions, 0));
        variants.push(Variant::relax_step(mesh, positions, 1));
        #[cfg(feature = "rayon")]
        for threads in THREADS {
            variants.push(Variant::rayon_forces(partition, stvk, positions, threads));
            variants.push(Variant::explicit_step(
                [
                    "",
                    "stable neo-Hookean explicit step, rayon 1 thread, f32",
                    "stable neo-Hookean explicit step, rayon 2 threads, f32",
                ][threads],
                ["", "explicit_step_rayon1_f32", "explicit_step_rayon2_f32"][threads],
                mesh,
                Some(partition),
                rest_positions,
                threads,
            ));
        }
        variants
    }
}

/// A benchmarked variant: its table label, its criterion id and one pass over the whole mesh.
struct Variant<'a> {
    label: &'static str,
    id: &'static str,
    run: Box<dyn FnMut() + 'a>,
    /// Threads the variant runs on.
    threads: usize,
    /// Descent iterations per run of a relaxation variant (0 for the others).
    iterations: u32,
}

impl<'a> Variant<'a> {
    /// A force variant: each run zeroes a force buffer of `vertex_count` entries (owned by the
    /// variant), then calls `add` on it.
    fn forces<V: Copy + Default + 'a>(
        label: &'static str,
        id: &'static str,
        vertex_count: usize,
        mut add: impl FnMut(&mut [V]) -> Result<(), MeshError> + 'a,
    ) -> Self {
        let mut forces = vec![V::default(); vertex_count];
        Variant {
            label,
            id,
            run: Box::new(move || {
                forces.fill(V::default());
                add(black_box(&mut forces)).unwrap();
                black_box(&forces);
            }),
            threads: 1,
            iterations: 0,
        }
    }

    /// `softfem::parallel::add_elastic_forces` (StVK direct) on a pool of `threads` threads.
    #[cfg(feature = "rayon")]
    fn rayon_forces(
        partition: TetPartition<'a>,
        stvk: StVK,
        positions: &'a [Vec3],
        threads: usize,
    ) -> Self {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut element_forces = vec![[Vec3::ZERO; 4]; partition.mesh().element_count()];
        let mut forces = vec![Vec3::ZERO; partition.mesh().vertex_count()];
        Variant {
            label: [
                "",
                "StVK, direct, rayon 1 thread, f32",
                "StVK, direct, rayon 2 threads, f32",
            ][threads],
            id: ["", "stvk_direct_rayon1_f32", "stvk_direct_rayon2_f32"][threads],
            run: Box::new(move || {
                forces.fill(Vec3::ZERO);
                pool.install(|| {
                    softfem::parallel::add_elastic_forces(
                        &partition,
                        &stvk,
                        black_box(positions),
                        &mut forces,
                        &mut element_forces,
                    )
                })
                .unwrap();
                black_box(&forces);
            }),
            threads,
            iterations: 0,
        }
    }

    /// One explicit step (stable neo-Hookean, half the proven stable step, gravity) of the box
    /// falling from rest, sequential or (with `partition`) on a rayon pool of `threads`.
    fn explicit_step(
        label: &'static str,
        id: &'static str,
        mesh: TetMesh<'a>,
        partition: Option<TetPartition<'a>>,
        rest: &'a [Vec3],
        threads: usize,
    ) -> Self {
        let (body, masses) = rubber_body(mesh);
        let n = mesh.vertex_count();
        let mut stiffness = vec![0.0; n];
        let dt = 0.5 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
        let scene = Scene::new(dt).with_gravity(Vec3::new(0.0, -9.81, 0.0));
        let settings = ExplicitSettings::new();
        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; n]);
        let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
        let mut step = move |model: &StepFn<'_>| {
            let mut scratch = ExplicitScratch::new(&mut buffer);
            model(&mut x, &mut v, &mut scratch);
        };
        let run: Box<dyn FnMut() + 'a> = match partition {
            None => Box::new(move || {
                step(&|x, v, scratch| {
                    explicit_step(&body, &masses, &[], &scene, &settings, x, v, scratch).unwrap();
                });
            }),
            #[cfg(feature = "rayon")]
            Some(partition) => {
                let pool = Box::leak(Box::new(
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap(),
                ));
                let element_forces = vec![[Vec3::ZERO; 4]; mesh.element_count()].leak();
                let energies = vec![0.0; mesh.element_count()].leak();
                let parallel = ParallelTetElastic::new(body, partition, element_forces, energies)
                    .unwrap()
                    .with_pool(pool);
                Box::new(move || {
                    step(&|x, v, scratch| {
                        explicit_step(&parallel, &masses, &[], &scene, &settings, x, v, scratch)
                            .unwrap();
                    });
                })
            }
            #[cfg(not(feature = "rayon"))]
            Some(_) => unreachable!("the rayon variants need the rayon feature"),
        };
        Variant {
            label,
            id,
            run,
            threads,
            iterations: 0,
        }
    }
}

impl<'a> Variant<'a> {
    /// One `relax_step` (stable neo-Hookean, `1/60` s, gravity, no ground) of exactly
    /// `RELAX_BUDGETS[budget]` descent iterations (tolerance 0) from the deformed `positions`
    /// at rest, the state reset before each run; the preconditioner is computed once, before
    /// the timing (the scratch keeps it, as in a simulation). Prints what one step does
    /// (iterations, evaluations of the energy and forces, backtracks), so that the table's time
    /// per step divides into a time per iteration and per evaluation.
    fn relax_step(mesh: TetMesh<'a>, positions: &'a [Vec3], budget: usize) -> Self {
        let (body, masses) = rubber_body(mesh);
        let n = mesh.vertex_count();
        let scene = Scene::new(1.0 / 60.0).with_gravity(Vec3::new(0.0, -9.81, 0.0));
        let settings = RelaxSettings::new().with_tolerance(0.0, RELAX_BUDGETS[budget]);
        let (mut x, mut v) = (positions.to_vec(), vec![Vec3::ZERO; n]);
        // Leaked so that the scratch, and the preconditioner it keeps, lives across the runs.
        let mut scratch = RelaxScratch::new(
            vec![Vec3::ZERO; scratch_len::relax(n)].leak(),
            vec![0.0; n].leak(),
        );
        let mut step = move || {
            x.copy_from_slice(positions);
            v.fill(Vec3::ZERO);
            relax_step(
                &body,
                &masses,
                &[],
                &scene,
                &settings,
                &mut x,
                &mut v,
                &mut scratch,
            )
            .unwrap()
        };
        let report = step();
        println!(
            "relax_step on {} tets: {} iterations, {} energy and force evaluations, {} \
             backtracks per step",
            mesh.element_count(),
            report.iterations,
            report.energy_evaluations,
            report.backtracks,
        );
        Variant {
            label: [
                "stable neo-Hookean relax_step (10 iterations), sequential, f32",
                "stable neo-Hookean relax_step (20 iterations), sequential, f32",
            ][budget],
            id: RELAX_IDS[budget],
            run: Box::new(move || {
                black_box(step());
            }),
            threads: 1,
            iterations: report.iterations,
        }
    }
}

/// The relaxation iteration against the force pass of the same run (stable neo-Hookean direct,
/// f32), per SIMD width (or at the width the machine picks): `force`, `short` and `long` are
/// the ns per tetrahedron of one force pass and of one call of each budget (`None` where a
/// variant was not timed). Prints the per-call cost (the short call's time over its
/// iterations, the call's fixed work spread over them) and the marginal cost of an iteration
/// (`common::marginal` of the two calls: the loop alone) in ns per tetrahedron and as a ratio
/// to the force pass, and appends both ratios as CSV rows.
fn print_relax_costs(tets: usize, iterations: [u32; 2], rows: &[(&str, usize, Option<[f64; 3]>)]) {
    let timed: Vec<(&str, usize, [f64; 3])> = rows
        .iter()
        .filter_map(|&(width, lanes, ns)| ns.map(|ns| (width, lanes, ns)))
        .collect();
    if timed.is_empty() {
        return;
    }
    let [short_budget, long_budget] = iterations;
    println!();
    println!(
        "Relaxation iteration (relax_step, stable neo-Hookean, Chebyshev defaults, tolerance 0) \
         against the stable neo-Hookean direct force pass of the same run: per call = the \
         {short_budget}-iteration call / {short_budget}; marginal = ({long_budget}-iteration \
         call - {short_budget}-iteration call) / {extra} (the same start; the call's fixed work \
         cancels).",
        extra = long_budget.saturating_sub(short_budget),
    );
    println!();
    let costs: Vec<(&str, usize, f64, f64, f64)> = timed
        .iter()
        .map(|&(width, lanes, [force, short, long])| {
            let per_call = short / f64::from(short_budget.max(1));
            let marginal = common::marginal((short, short_budget), (long, long_budget));
            (width, lanes, force, per_call, marginal)
        })
        .collect();
    common::print_markdown_table(
        &[
            "width",
            "force pass ns/tet",
            "per call ns/tet/iteration",
            "per call vs force pass",
            "marginal ns/tet/iteration",
            "marginal vs force pass",
        ],
        costs.iter().map(|&(width, _, force, per_call, marginal)| {
            vec![
                width.to_owned(),
                format!("{force:.1}"),
                format!("{per_call:.1}"),
                format!("{:.2}x", per_call / force),
                format!("{marginal:.1}"),
                format!("{:.2}x", marginal / force),
            ]
        }),
    );
    common::append_csv_rows(
        &costs
            .iter()
            .flat_map(|&(width, lanes, force, per_call, marginal)| {
                [("per_call", per_call), ("marginal", marginal)].map(|(kind, ns)| common::CsvRow {
                    bench: "forces",
                    workload: format!("relax_iteration_{kind}_f32 {width}"),
                    size: tets,
                    lanes,
                    threads: 1,
                    value: ns / force,
                    unit: "force passes",
                })
            })
            .collect::<Vec<_>>(),
    );
}

/// The iteration budgets of the two relaxation variants, as [`print_relax_costs`] reads them.
fn relax_budgets(variants: &[Variant<'_>]) -> [u32; 2] {
    RELAX_IDS.map(|id| {
        variants
            .iter()
            .find(|v| v.id == id)
            .map_or(0, |v| v.iterations)
    })
}

/// The stepped body of the step variants: stable neo-Hookean rubber on `mesh`, and its lumped
/// masses (density 1000 kg/m^3).
fn rubber_body(mesh: TetMesh<'_>) -> (TetElastic<'_, StableNeoHookean>, Vec<f32>) {
    let body = TetElastic::new(
        mesh,
        StableNeoHookean::from_young_poisson(YOUNG, POISSON).unwrap(),
    );
    let mut masses = vec![0.0; mesh.vertex_count()];
    mesh.lumped_masses(1000.0, &mut masses).unwrap();
    (body, masses)
}

/// The criterion group of one mesh size, one benchmark per variant.
fn criterion_group(c: &mut Criterion, info: &MeshInfo, variants: &mut [Variant<'_>]) {
    // "forces_10k", "forces_105k", "forces_998k".
    let mut group = c.benchmark_group(format!("forces_{}k", (info.tets + 500) / 1000));
    group.throughput(Throughput::Elements(info.tets as u64));
    if info.tets >= LARGE_MESH_TETS {
        // 25 to 200 ms per iteration: linear sampling (1 + 2 + ... + 10 iterations per sample)
        // would need 55 of them; flat sampling needs 10.
        group
            .sampling_mode(SamplingMode::Flat)
            .sample_size(10)
            .measurement_time(Duration::from_secs(3));
    }
    for variant in variants.iter_mut() {
        group.bench_function(variant.id, |b| b.iter(&mut variant.run));
    }
    group.finish();
}

/// Tetrahedra per timed block (repetitions are rounded up to cover it), and round-robin rounds
/// over all variants.
struct TablePlan {
    tets_per_block: usize,
    rounds: u32,
}

/// Whether `SOFTFEM_BENCH_WIDTHS=1` asks for the per-width table pass (no criterion).
fn widths_mode() -> bool {
    std::env::var("SOFTFEM_BENCH_WIDTHS").is_ok_and(|value| value == "1")
}

/// Whether the (variant `id`, `width`) pair is one that `SOFTFEM_BENCH_ONLY` keeps (all of
/// them when it is unset or empty).
fn selected(id: &str, width: Width) -> bool {
    let Ok(patterns) = std::env::var("SOFTFEM_BENCH_ONLY") else {
        return true;
    };
    let name = format!("{id} {}", width.name());
    patterns.trim().is_empty()
        || patterns
            .split(',')
            .any(|pattern| name.contains(pattern.trim()))
}

/// The per-width table: every one-thread variant at every SIMD width this machine has
/// (`softfem::simd::set_max_width`), all round-robin in one pass, so the ratios between widths
/// come from one machine state.
fn print_width_table(info: &MeshInfo, variants: &mut [Variant<'_>], plan: &TablePlan) {
    let tets = info.tets;
    let repetitions = u32::try_from(plan.tets_per_block.div_ceil(tets).max(1)).unwrap();
    let widths: Vec<Width> = Width::ALL
        .into_iter()
        .filter(|&w| w <= simd::detected_width())
        .collect();
    let mut items: Vec<(usize, Width)> = variants
        .iter()
        .enumerate()
        .filter(|(_, v)| v.threads == 1 && !v.id.contains("rayon") && !v.id.contains("partitioned"))
        .flat_map(|(i, _)| widths.iter().map(move |&w| (i, w)))
        .filter(|&(i, w)| selected(variants[i].id, w))
        .collect();
    let ns = common::round_robin_min_ns(
        &mut items,
        |&mut (i, width)| {
            simd::set_max_width(width);
            (variants[i].run)();
        },
        repetitions,
        tets,
        plan.rounds,
    );
    simd::set_max_width(Width::Avx512);
    println!();
    println!(
        "Per SIMD width, {tets} tetrahedra ({n}^3 cubes), one thread; minimum of {rounds} \
         round-robin rounds of {repetitions} passes over every (variant, width), on {machine}.",
        n = info.cells,
        rounds = plan.rounds,
        machine = common::machine(),
    );
    println!();
    let scalar_ns = |i: usize| {
        items
            .iter()
            .zip(&ns)
            .find(|((j, w), _)| *j == i && *w == Width::Scalar)
            .map(|(_, &ns)| ns)
    };
    common::print_markdown_table(
        &[
            "variant",
            "width",
            "lanes",
            "Mtets/s",
            "ns/tet",
            "vs scalar",
        ],
        items.iter().zip(&ns).map(|(&(i, width), ns)| {
            let v = &variants[i];
            let lanes = if v.id.ends_with("f64") {
                width.lanes_f64()
            } else {
                width.lanes_f32()
            };
            vec![
                v.label.to_owned(),
                width.name().to_owned(),
                lanes.to_string(),
                format!("{:.1}", 1e3 / ns),
                format!("{ns:.1}"),
                scalar_ns(i).map_or("-".to_owned(), |s| format!("{:.2}x", s / ns)),
            ]
        }),
    );
    common::append_csv_rows(
        &items
            .iter()
            .zip(&ns)
            .map(|(&(i, width), ns)| {
                let v = &variants[i];
                let lanes = if v.id.ends_with("f64") {
                    width.lanes_f64()
                } else {
                    width.lanes_f32()
                };
                let unit = if v.id.starts_with("explicit") {
                    "steps/s"
                } else {
                    "Mtets/s"
                };
                let value = if v.id.starts_with("explicit") {
                    1e9 / (ns * tets as f64)
                } else {
                    1e3 / ns
                };
                common::CsvRow {
                    bench: "forces",
                    workload: format!("{} {}", v.id, width.name()),
                    size: tets,
                    lanes,
                    threads: 1,
                    value,
                    unit,
                }
            })
            .collect::<Vec<_>>(),
    );
    let timed = |id: &str, width: Width| {
        items
            .iter()
            .zip(&ns)
            .find(|((i, w), _)| variants[*i].id == id && *w == width)
            .map(|(_, &ns)| ns)
    };
    let relax_rows: Vec<(&str, usize, Option<[f64; 3]>)> = widths
        .iter()
        .map(|&width| {
            let ns = [RELAX_REFERENCE, RELAX_IDS[0], RELAX_IDS[1]].map(|id| timed(id, width));
            let [force, short, long] = ns;
            let all = force.zip(short).zip(long).map(|((f, s), l)| [f, s, l]);
            (width.name(), width.lanes_f32(), all)
        })
        .collect();
    print_relax_costs(tets, relax_budgets(variants), &relax_rows);
}

/// The memory roofline of the force pass: a STREAM-like triad `a[i] = b[i] + s c[i]` over f32
/// arrays of 64 MiB each (twice the last-level cache of the machine this was written on, so
/// every pass comes from DRAM), one thread, best of 10 passes; STREAM's convention counts 12
/// bytes per element (two loads and a store, write-allocate traffic not counted). Returns GB/s.
fn stream_triad_gb_per_s() -> f64 {
    let n = 16 << 20;
    let (mut a, b, c) = (vec![0.0f32; n], vec![1.0f32; n], vec![2.0f32; n]);
    let scale = black_box(3.0f32);
    let mut best = f64::INFINITY;
    for _ in 0..10 {
        let start = std::time::Instant::now();
        for ((a, b), c) in a.iter_mut().zip(&b).zip(&c) {
            *a = b + scale * c;
        }
        black_box(&mut a);
        best = best.min(start.elapsed().as_secs_f64());
    }
    assert!(a.iter().all(|&x| x == 7.0));
    (12 * n) as f64 / best / 1e9
}

/// Bytes the f32 force pass streams per tetrahedron from this layout: the four `u32` corner
/// indices and the `TetRest` (`Dm^-1` and the volume); positions and forces (12 bytes each per
/// vertex, about a sixth of a vertex per tetrahedron in these boxes) mostly stay in cache.
const STREAMED_BYTES_PER_TET: usize =
    size_of::<[u32; 4]>() + size_of::<softfem::element::TetRest>();

fn print_roofline() {
    let triad = stream_triad_gb_per_s();
    let roofline = triad * 1e3 / STREAMED_BYTES_PER_TET as f64;
    println!();
    println!(
        "Memory roofline: STREAM-like triad {triad:.1} GB/s (one thread, f32, 3 x 64 MiB), \
         {STREAMED_BYTES_PER_TET} bytes streamed per tetrahedron (indices + rest data) = \
         {roofline:.0} Mtets/s."
    );
    common::append_csv_rows(&[
        common::CsvRow {
            bench: "forces",
            workload: "stream triad f32".to_owned(),
            size: 16 << 20,
            lanes: 1,
            threads: 1,
            value: triad,
            unit: "GB/s",
        },
        common::CsvRow {
            bench: "forces",
            workload: "memory roofline".to_owned(),
            size: STREAMED_BYTES_PER_TET,
            lanes: 1,
            threads: 1,
            value: roofline,
            unit: "Mtets/s",
        },
    ]);
}

fn print_table(info: &MeshInfo, variants: &mut [Variant<'_>], plan: &TablePlan) {
    if widths_mode() {
        print_width_table(info, variants, plan);
        return;
    }
    let tets = info.tets;
    // Mesh passes per timed block: enough to cover `plan.tets_per_block`, at least one.
    let repetitions = u32::try_from(plan.tets_per_block.div_ceil(tets).max(1)).unwrap();
    let ns = common::round_robin_min_ns(
        variants,
        |variant| (variant.run)(),
        repetitions,
        tets,
        plan.rounds,
    );
    let reference_ns = ns[0];
    let (j_min, j_max) = info.j_range;
    println!();
    println!(
        "Forces on a box of {tets} tetrahedra ({n}^3 cubes, Kuhn 6-tet split, {vertices} \
         vertices), affine deformation plus jitter (J in [{j_min:.3}, {j_max:.3}]); one thread; \
         each force pass zeroes the force buffer, then adds the forces of every tetrahedron \
         (zeroing included in the time). Minimum of {rounds} round-robin rounds of \
         {repetitions} mesh passes per variant, on {machine}.",
        n = info.cells,
        vertices = info.vertices,
        rounds = plan.rounds,
        machine = common::machine(),
    );
    println!();
    common::print_markdown_table(
        &[
            "variant",
            "Mtets/s",
            "ns/tet",
            "throughput vs StVK direct f32",
        ],
        variants.iter().zip(&ns).map(|(variant, ns)| {
            vec![
                variant.label.to_owned(),
                format!("{:.1}", 1e3 / ns),
                format!("{ns:.1}"),
                format!("{:.2}x", reference_ns / ns),
            ]
        }),
    );
    let by_id = |id: &str| {
        variants
            .iter()
            .zip(&ns)
            .find(|(variant, _)| variant.id == id)
            .map(|(_, &ns)| ns)
    };
    let ratio = |slow: &str, fast: &str| by_id(slow).zip(by_id(fast)).map(|(s, f)| s / f);
    let percent = |ratio: Option<f64>| {
        ratio.map_or("-".to_owned(), |r| format!("{:+.1} %", (r - 1.0) * 100.0))
    };
    println!();
    println!(
        "Deterministic scheme, one-thread cost against the sequential pass: StVK forces {}          (pieces on this thread), {} (rayon, 1 thread); explicit step {} (rayon, 1 thread).",
        percent(ratio("stvk_direct_partitioned_f32", "stvk_direct_f32")),
        percent(ratio("stvk_direct_rayon1_f32", "stvk_direct_f32")),
        percent(ratio("explicit_step_rayon1_f32", "explicit_step_f32")),
    );
    let relax = [RELAX_REFERENCE, RELAX_IDS[0], RELAX_IDS[1]].map(by_id);
    let [force, short, long] = relax;
    print_relax_costs(
        tets,
        relax_budgets(variants),
        &[(
            "native",
            softfem::lanes::LANES,
            force.zip(short).zip(long).map(|((f, s), l)| [f, s, l]),
        )],
    );
    let speed_up = |r: Option<f64>| r.map_or("-".to_owned(), |r| format!("{r:.2}x"));
    println!(
        "Speed-up, 2 threads against 1 (rayon, same bits): StVK forces {}, explicit step {};          2 threads against the sequential code: forces {}, explicit step {}.",
        speed_up(ratio("stvk_direct_rayon1_f32", "stvk_direct_rayon2_f32")),
        speed_up(ratio(
            "explicit_step_rayon1_f32",
            "explicit_step_rayon2_f32"
        )),
        speed_up(ratio("stvk_direct_f32", "stvk_direct_rayon2_f32")),
        speed_up(ratio("explicit_step_f32", "explicit_step_rayon2_f32")),
    );
    common::append_csv_rows(
        &variants
            .iter()
            .zip(&ns)
            .map(|(variant, ns)| common::CsvRow {
                bench: "forces",
                workload: variant.label.to_owned(),
                size: tets,
                lanes: softfem::lanes::LANES,
                threads: variant.threads,
                value: 1e3 / ns,
                unit: "Mtets/s",
            })
            .collect::<Vec<_>>(),
    );
}

fn print_tables(cases: &mut [(MeshInfo, Vec<Variant<'_>>)], plan: &TablePlan) {
    for (info, variants) in cases {
        print_table(info, variants, plan);
    }
}

fn main() {
    let quick = common::quick();
    let mesh_count = if quick {
        QUICK_MESHES
    } else {
        CELLS_PER_AXIS.len()
    };

    // The boxes own the buffers and the variants borrow them, so the boxes are built first.
    let mut boxes: Vec<DeformedBox> = CELLS_PER_AXIS[..mesh_count]
        .iter()
        .map(|&cells| DeformedBox::new(cells))
        .collect();
    let mut cases: Vec<(MeshInfo, Vec<Variant<'_>>)> = boxes
        .iter_mut()
        .map(|mesh| (mesh.info(), mesh.variants()))
        .collect();

    if widths_mode() {
        print_roofline();
        print_tables(
            &mut cases,
            &TablePlan {
                tets_per_block: 2_000_000,
                rounds: 3,
            },
        );
        return;
    }
    if quick {
        print_tables(
            &mut cases,
            &TablePlan {
                tets_per_block: 200_000,
                rounds: 3,
            },
        );
        return;
    }

    // Ten samples in about 1.8 s per benchmark on the two smaller meshes and 3.3 s on the largest
    // keep the criterion pass near a minute; command-line flags (`--measurement-time`,
    // `--sample-size`, a name filter, ...) override these, except the largest mesh's own
    // sampling settings (see `criterion_group`).
    let mut criterion = Criterion::default()
        .without_plots()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_millis(1500))
        .sample_size(10)
        .configure_from_args();
    for (info, variants) in &mut cases {
        criterion_group(&mut criterion, info, variants);
    }
    criterion.final_summary();

    let plan = match common::table_pass() {
        TablePass::Skip => return,
        TablePass::Test => TablePlan {
            tets_per_block: 1,
            rounds: 1,
        },
        TablePass::Full => TablePlan {
            tets_per_block: 4_000_000,
            rounds: 5,
        },
    };
    print_tables(&mut cases, &plan);
}
