//! Newton's cost against the relaxation's on the convergence chart's quasi-static cantilever
//! (f64, one thread), and the cost of its parts against a force evaluation.
//!
//! The body: the cantilever of `examples/tradeoffs/convergence.rs` (1 m x 0.1 m x 0.1 m,
//! `n` cells through the thickness and `10 n` along, 5-tet split, stable neo-Hookean E = 1 MPa,
//! nu = 0.3, clamped at x = 0, an end load for Euler–Bernoulli's deflection of 1e-3 m carried
//! by masses of `|f| / g` on the end face, 1e-12 kg elsewhere), for `n` = 2 (400 tets) and 3
//! (1350 tets). Per mesh:
//!
//! * **force pass**: zero a force buffer, then `energy_and_add_forces` (the fused pass every
//!   solver evaluates) at the solved shape;
//! * **projected Hessians**: `projected_hessians` there (one SVD per element, the cache);
//! * **Hessian product**: zero an output buffer, then `add_hessian_product` with that cache;
//! * **Newton to 1e-8**: `newton_quasi_static` from rest, relative tolerance 1e-8, its defaults;
//! * **relaxation to 1e-6**: `relax_quasi_static` from rest, Chebyshev `rho = 0.9999` and step
//!   2 (the convergence chart's), relative tolerance 1e-6.
//!
//! Criterion times the three passes (ns per tetrahedron in the table pass below); the table
//! pass then times every operation round-robin (each block repeated for about 50 ms, the least
//! of 5 rounds; the solves are run 3 times, least kept) and prints the ratios: product over
//! force pass, and relaxation time over Newton time, from the same run. `cargo bench -p
//! softfem-benches --bench hessian` (about a minute; `SOFTFEM_BENCH_QUICK=1` skips criterion, times
//! 5 ms blocks and runs one solve each).

mod common;

use std::hint::black_box;
use std::time::{Duration, Instant};

use common::TablePass;
use criterion::Criterion;
use softfem::f64::element::{TetHessian, TetRest};
use softfem::f64::generate::{BoxSplit, box_counts, fill_box};
use softfem::f64::material::StableNeoHookean;
use softfem::f64::mesh::TetMesh;
use softfem::f64::step::{
    ElasticEnergy, ElasticHessian, NewtonReport, NewtonScratch, NewtonSettings, RelaxReport,
    RelaxScratch, RelaxSettings, Scene, TetElastic, newton_quasi_static, relax_quasi_static,
    scratch_len,
};
use softfem::glam::{DMat3, DVec3};

const LENGTH: f64 = 1.0;
const HEIGHT: f64 = 0.1;
const YOUNG: f64 = 1.0e6;
const POISSON: f64 = 0.3;
const G: f64 = 9.81;
/// The end load (N): Euler–Bernoulli gives a deflection of `1e-3 L`.
const LOAD: f64 = 3.0 * YOUNG * HEIGHT * HEIGHT * HEIGHT * HEIGHT / 12.0 * 1e-3 / (LENGTH * LENGTH);

/// The cantilever with `n` cells through the thickness.
struct Beam {
    rest: Vec<DVec3>,
    tets: Vec<[u32; 4]>,
    masses: Vec<f64>,
    pinned: Vec<bool>,
}

impl Beam {
    fn new(n: usize) -> Beam {
        let along = 10 * n;
        let (nv, nt) = box_counts(along, n, n, BoxSplit::Alternating5).unwrap();
        let (mut rest, mut tets) = (vec![DVec3::ZERO; nv], vec![[0; 4]; nt]);
        let size = DVec3::new(LENGTH, HEIGHT, HEIGHT);
        fill_box(
            DVec3::ZERO,
            size,
            along,
            n,
            n,
            BoxSplit::Alternating5,
            &mut rest,
            &mut tets,
        )
        .unwrap();
        // The tributary share of grid line `i` of `n` cells (ends half), from the coordinate.
        let share = |c: f64| {
            let i = (c / HEIGHT * n as f64).round() as usize;
            if i == 0 || i == n {
                0.5 / n as f64
            } else {
                1.0 / n as f64
            }
        };
        let masses = rest
            .iter()
            .map(|p| {
                if p.x == LENGTH {
                    LOAD * share(p.y) * share(p.z) / G
                } else {
                    1e-12
                }
            })
            .collect();
        let pinned = rest.iter().map(|p| p.x == 0.0).collect();
        Beam {
            rest,
            tets,
            masses,
            pinned,
        }
    }
}

/// What both quasi-static solves act on: gravity (they ignore the time step).
fn scene() -> Scene<'static, DVec3> {
    Scene::new(1.0).with_gravity(DVec3::new(0.0, 0.0, -G))
}

/// Newton's and the relaxation's settings.
fn newton_settings() -> NewtonSettings {
    NewtonSettings::new().with_tolerance(1e-8, 50)
}

fn relax_settings() -> RelaxSettings {
    RelaxSettings::new()
        .with_tolerance(1e-6, 2_000_000)
        .with_chebyshev(0.9999, 2.0, 0)
}

/// Everything one mesh's measurements need (the beam and its rest data leaked: a bench
/// process measures a fixed set of meshes and then exits).
struct Bench {
    beam: &'static Beam,
    model: TetElastic<'static, StableNeoHookean>,
    solved: Vec<DVec3>,
    cache: Vec<TetHessian>,
    forces: Vec<DVec3>,
    direction: Vec<DVec3>,
}

impl Bench {
    fn new(n: usize) -> Bench {
        let beam: &'static Beam = Box::leak(Box::new(Beam::new(n)));
        let rest_data = Box::leak(vec![TetRest::default(); beam.tets.len()].into_boxed_slice());
        let mesh = TetMesh::new(&beam.rest, &beam.tets, rest_data).unwrap();
        let material = StableNeoHookean::from_young_poisson(YOUNG, POISSON).unwrap();
        let mut bench = Bench {
            beam,
            model: TetElastic::new(mesh, material),
            solved: beam.rest.clone(),
            cache: vec![TetHessian::default(); beam.tets.len()],
            forces: vec![DVec3::ZERO; beam.rest.len()],
            direction: vec![DVec3::ZERO; beam.rest.len()],
        };
        let (report, solved) = bench.newton();
        assert!(report.converged, "{report:?}");
        bench.direction = solved
            .iter()
            .zip(&beam.rest)
            .map(|(x, r)| *x - *r)
            .collect();
        bench.solved = solved;
        bench.projection();
        bench
    }

    fn newton(&self) -> (NewtonReport, Vec<DVec3>) {
        let n = self.beam.rest.len();
        let len = scratch_len::newton(n, self.beam.tets.len());
        let (mut vectors, mut blocks, mut hessians) = (
            vec![DVec3::ZERO; len.vectors],
            vec![DMat3::ZERO; len.blocks],
            vec![TetHessian::default(); len.hessians],
        );
        let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
        let mut x = self.beam.rest.clone();
        let beam = self.beam;
        let (scene, settings) = (scene(), newton_settings());
        let report = newton_quasi_static(
            &self.model,
            &beam.masses,
            &beam.pinned,
            &scene,
            &settings,
            &mut x,
            &mut scratch,
        )
        .unwrap();
        (report, x)
    }

    fn relax(&self) -> RelaxReport {
        let n = self.beam.rest.len();
        let (mut vectors, mut scalars) = (vec![DVec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
        let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
        let mut x = self.beam.rest.clone();
        let beam = self.beam;
        let (scene, settings) = (scene(), relax_settings());
        relax_quasi_static(
            &self.model,
            &beam.masses,
            &beam.pinned,
            &scene,
            &settings,
            &mut x,
            &mut scratch,
        )
        .unwrap()
    }

    fn force_pass(&mut self) -> f64 {
        self.forces.fill(DVec3::ZERO);
        self.model
            .energy_and_add_forces(black_box(&self.solved), &mut self.forces)
            .unwrap()
    }

    fn product(&mut self) {
        self.forces.fill(DVec3::ZERO);
        self.model
            .add_hessian_product(&self.cache, black_box(&self.direction), &mut self.forces)
            .unwrap();
    }

    fn projection(&mut self) {
        self.model
            .projected_hessians(black_box(&self.solved), &mut self.cache)
            .unwrap();
    }
}

/// The least time of `rounds` blocks of about `block` each, per call of `run` (s).
fn least_per_call(rounds: u32, block: Duration, mut run: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..rounds {
        let started = Instant::now();
        let mut calls = 0u32;
        while calls == 0 || started.elapsed() < block {
            run();
            calls += 1;
        }
        best = best.min(started.elapsed().as_secs_f64() / f64::from(calls));
    }
    best
}

fn criterion_passes(benches: &mut [Bench]) {
    let mut criterion = Criterion::default()
        .sample_size(20)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(500))
        .configure_from_args();
    for bench in benches.iter_mut() {
        let tets = bench.beam.tets.len();
        let mut group = criterion.benchmark_group(format!("hessian/{tets} tets"));
        group.bench_function("force pass", |b| b.iter(|| black_box(bench.force_pass())));
        group.bench_function("Hessian product", |b| b.iter(|| bench.product()));
        group.bench_function("projected Hessians", |b| b.iter(|| bench.projection()));
        group.finish();
    }
    criterion.final_summary();
}

fn main() {
    let pass = common::table_pass();
    if matches!(pass, TablePass::Skip) {
        return;
    }
    let quick = common::quick() || matches!(pass, TablePass::Test);
    let mut benches: Vec<Bench> = [2, 3].into_iter().map(Bench::new).collect();
    if !quick {
        criterion_passes(&mut benches);
    }
    // Quick runs keep the five interleaved rounds (a pass takes tens of microseconds, so 5 ms
    // blocks still hold a hundred calls): one round made the product's ratio swing from 0.3 to
    // 6 between runs on a loaded machine.
    let (rounds, block, solves) = if quick {
        (5, Duration::from_millis(5), 1)
    } else {
        (5, Duration::from_millis(50), 3)
    };
    println!("\nmachine: {}", common::machine());
    let mut rows = Vec::new();
    for bench in &mut benches {
        let tets = bench.beam.tets.len();
        let mut times = [f64::INFINITY; 3];
        for _ in 0..rounds {
            times[0] = times[0].min(least_per_call(1, block, || {
                black_box(bench.force_pass());
            }));
            times[1] = times[1].min(least_per_call(1, block, || bench.product()));
            times[2] = times[2].min(least_per_call(1, block, || bench.projection()));
        }
        let (mut newton_time, mut relax_time) = (f64::INFINITY, f64::INFINITY);
        let (mut newton, mut relax) = (None, None);
        for _ in 0..solves {
            let started = Instant::now();
            newton = Some(bench.newton().0);
            newton_time = newton_time.min(started.elapsed().as_secs_f64());
            let started = Instant::now();
            relax = Some(bench.relax());
            relax_time = relax_time.min(started.elapsed().as_secs_f64());
        }
        let (newton, relax) = (newton.unwrap(), relax.unwrap());
        let per_tet = |s: f64| format!("{:.0}", s * 1e9 / tets as f64);
        rows.push(vec![
            tets.to_string(),
            per_tet(times[0]),
            per_tet(times[1]),
            format!("{:.2}", times[1] / times[0]),
            per_tet(times[2]),
            format!(
                "{} / {} CG, {:.1e}, {:.2} ms",
                newton.iterations,
                newton.details.cg_iterations,
                newton.residual / newton.initial_residual.max(newton.target / 1e-8),
                newton_time * 1e3
            ),
            format!(
                "{}, {}{}, {:.1e}, {:.1} ms",
                relax.iterations,
                relax.converged,
                if relax.stagnated { " (stagnated)" } else { "" },
                relax.residual / relax.initial_residual,
                relax_time * 1e3
            ),
            format!("{:.1}", relax_time / newton_time),
        ]);
    }
    common::print_markdown_table(
        &[
            "tets",
            "force pass ns/tet",
            "Hessian product ns/tet",
            "product / force",
            "projected Hessians ns/tet",
            "Newton to 1e-8 (iterations / CG, relative residual, time)",
            "relaxation to 1e-6 (iterations, converged, relative residual, time)",
            "relaxation / Newton time",
        ],
        rows,
    );
}
