//! Speed of the time steppers on a box of about 100k tetrahedra (issue 4, deliverable 5): one
//! explicit step (forces + integration + ground) in steps per second, and the relaxation's cost
//! per iteration relative to one force evaluation. Single thread, f32.
//!
//! The body: a cube of edge 0.5 m in 26^3 cubes (Kuhn 6-tet split, `softfem::generate::fill_box`:
//! 105 456 tetrahedra, 19 683 vertices), soft rubber (E = 1 MPa, nu = 0.45, 1000 kg/m^3, lumped
//! masses), standing on the ground `z = 0` with its bottom layer of vertices on it, under
//! gravity; ground friction 0.5. Two models, stable neo-Hookean and StVK (`TetElastic`, direct
//! stress). Per model:
//!
//! * **force evaluation**: zero a force buffer, then `TetMesh::add_elastic_forces` over the whole
//!   mesh (the reference every ratio is relative to);
//! * **energy + forces**: the same with `ElasticEnergy::energy_and_add_forces`, the fused pass the
//!   relaxation evaluates;
//! * **explicit step**: `explicit_step` with `dt = 0.5 x stable_time_step`, one substep, gravity
//!   and ground (all its passes: backup of the state, forces, the blow-up indicator, the update
//!   with ground contact, the finiteness check, the kinetic energy). The state keeps evolving
//!   from call to call, as in a simulation: the box settles and oscillates on the ground;
//! * **relaxation**: `relax_step` (implicit Euler, dt = 1/60 s, gravity, ground) from the box at
//!   rest, with tolerance 0 so that it runs its whole iteration budget (20, and 40), the state
//!   reset before each call (two copies, included) and one `RelaxScratch` kept across calls as
//!   in a simulation, so its preconditioner (one stiffness bound per element) is computed by the
//!   first, untimed call only. The per-iteration cost is reported two ways:
//!   the whole call divided by the reported iterations (which spreads the call's fixed cost: the
//!   first evaluations and the final velocity pass), and the marginal cost `(T_40 - T_20) / (iterations_40 -
//!   iterations_20)`, which is the loop alone. Timed twice: with plain descent and first trial
//!   step 1 (the settings of the first table of docs/guide/10-performance.md) and with the defaults
//!   (`RelaxSettings::new`: Chebyshev acceleration, step 2), whose iterations are mostly
//!   accelerated trials (one fused pass and two vertex passes each). A second table gives the
//!   iterations and energy evaluations each call reported.
//!
//! * **stiffness bounds**: `stable_time_step`, which computes the same per-vertex stiffness
//!   bounds as the relaxation's preconditioner: the one-off cost of a scratch's first solve.
//! * **Hessian product**: zero an output buffer, then `TetMesh::add_hessian_product` with a
//!   cache of projected element Hessians built once (untimed) at the sagged state, in the
//!   direction of the sag (`sagged - rest`);
//! * **VBD**: `vbd_step` (dt = 1/60 s, gravity, ground, no line search, no acceleration) from
//!   rest, tolerance 0 so that it runs its whole budget of sweeps (2, and 4), state reset before
//!   each call and one `VbdScratch` kept across calls (the adjacency and colouring are built by
//!   the first, untimed call). An iteration is one sweep plus one fused energy-and-force pass
//!   (the stopping test); the marginal iteration `(T_4 - T_2) / 2` minus the fused pass is the
//!   sweep alone.
//!
//! The force evaluations run at the positions the 20-iteration relaxation reaches (the box sagged
//! under gravity for 1/60 s), so every element is deformed.
//!
//! `cargo bench -p softfem-benches --bench step` runs criterion (one group per model, flat
//! sampling, 10 samples) and then a plain `Instant` pass that times every operation of both models
//! round-robin, each timed block repeating one operation for about 50 ms, keeps the minimum per
//! operation and prints the markdown tables (ratios from one run). About a minute in all.
//!
//! `SOFTFEM_BENCH_QUICK=1` skips criterion and runs the table pass on a 12^3-cube box (10 368
//! tetrahedra) with short blocks: a smoke test that finishes in seconds.

mod common;

use std::hint::black_box;
use std::time::{Duration, Instant};

use common::TablePass;
use criterion::{Criterion, SamplingMode};
use softfem::element::TetHessian;
use softfem::element::TetRest;
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::Vec3;
use softfem::material::{Material, StVK, StableNeoHookean};
use softfem::mesh::TetMesh;
use softfem::step::{
    ElasticEnergy, ExplicitScratch, ExplicitSettings, HalfSpace, RelaxReport, RelaxScratch,
    RelaxSettings, Scene, TetElastic, VbdScratch, VbdSettings, explicit_step, relax_step,
    scratch_len, stable_time_step, vbd_step,
};

/// Cubes per axis of the benchmarked box: 105 456 tetrahedra.
const CELLS: usize = 26;

/// Cubes per axis in quick mode: 10 368 tetrahedra.
const QUICK_CELLS: usize = 12;

/// Edge of the cube (m).
const EDGE: f32 = 0.5;

/// Young's modulus (Pa), Poisson ratio and density (kg/m^3): a soft rubber.
const YOUNG: f32 = 1.0e6;
const POISSON: f32 = 0.45;
const DENSITY: f32 = 1000.0;

/// Gravity (m/s^2), along -z onto the ground `z = 0`.
const GRAVITY: Vec3 = Vec3::new(0.0, 0.0, -9.81);

/// Coulomb friction coefficient of the ground.
const FRICTION: f32 = 0.5;

/// The explicit time step as a fraction of `stable_time_step`.
const DT_FRACTION: f32 = 0.5;

/// The relaxation's time step (s): one display frame at 60 Hz.
const RELAX_DT: f32 = 1.0 / 60.0;

/// The relaxation's iteration budgets (tolerance 0: each call runs its whole budget).
const RELAX_BUDGETS: [u32; 2] = [20, 40];

/// VBD's sweep budgets (tolerance 0: each call runs its whole budget).
const VBD_BUDGETS: [u32; 2] = [2, 4];

/// The target for the relaxation: cost per iteration over one force evaluation.
const RELAX_TARGET: f64 = 1.3;

/// The box's geometry and masses, owned here and borrowed by every benchmarked operation.
struct Geometry {
    cells: usize,
    rest_positions: Vec<Vec3>,
    tets: Vec<[u32; 4]>,
    rest: Vec<TetRest>,
    masses: Vec<f32>,
}

impl Geometry {
    /// A cube of edge [`EDGE`] in `cells^3` cubes, centred on the z axis, its lowest face on
    /// `z = 0`.
    fn new(cells: usize) -> Self {
        let (vertex_count, tet_count) = box_counts(cells, cells, cells, BoxSplit::Kuhn6).unwrap();
        let mut rest_positions = vec![Vec3::ZERO; vertex_count];
        let mut tets = vec![[0u32; 4]; tet_count];
        let half = Vec3::new(EDGE / 2.0, EDGE / 2.0, 0.0);
        fill_box(
            -half,
            half + Vec3::new(0.0, 0.0, EDGE),
            cells,
            cells,
            cells,
            BoxSplit::Kuhn6,
            &mut rest_positions,
            &mut tets,
        )
        .unwrap();
        let mut rest = vec![TetRest::default(); tet_count];
        let mut masses = vec![0.0; vertex_count];
        TetMesh::new(&rest_positions, &tets, &mut rest)
            .unwrap()
            .lumped_masses(DENSITY, &mut masses)
            .unwrap();
        Geometry {
            cells,
            rest_positions,
            tets,
            rest,
            masses,
        }
    }
}

/// The operations of one model, in this order.
const FORCES: usize = 0;
const FUSED: usize = 1;
const EXPLICIT: usize = 2;
const RELAX_SHORT: usize = 3;
const RELAX_LONG: usize = 4;
const PRECONDITIONER: usize = 5;
const HESSIAN_PRODUCT: usize = 6;
const VBD_SHORT: usize = 7;
const VBD_LONG: usize = 8;
const CHEBYSHEV_SHORT: usize = 9;
const CHEBYSHEV_LONG: usize = 10;

/// One benchmarked operation: its criterion id and one call.
struct Operation<'a> {
    id: &'static str,
    run: Box<dyn FnMut() + 'a>,
    /// Calls per timed block of the table pass (set by calibration).
    calls: u32,
}

impl<'a> Operation<'a> {
    fn new(id: &'static str, run: impl FnMut() + 'a) -> Self {
        Operation {
            id,
            run: Box::new(run),
            calls: 1,
        }
    }
}

/// One model on the box: its operations and what the tables say about it.
struct Case<'a> {
    name: &'static str,
    id: &'static str,
    /// `stable_time_step` (s) and the explicit step used.
    bound: f32,
    dt: f32,
    /// Vertices projected out of the ground in the first explicit step.
    contacts: usize,
    /// What the two relaxation calls report (the same every call: the state is reset).
    relax: [RelaxReport; 2],
    /// The same for the two calls with the default settings (Chebyshev acceleration).
    chebyshev: [RelaxReport; 2],
    /// The sweeps the two VBD calls report.
    vbd_sweeps: [u32; 2],
    operations: Vec<Operation<'a>>,
}

/// Builds the operations of `material` on `mesh` (see the file documentation).
fn case<'a, M: Material + 'a>(
    name: &'static str,
    id: &'static str,
    mesh: TetMesh<'a>,
    rest_positions: &'a [Vec3],
    masses: &'a [f32],
    material: M,
) -> Case<'a> {
    let n = mesh.vertex_count();
    let body = TetElastic::new(mesh, material);
    let ground = HalfSpace::new(Vec3::Z, 0.0).with_friction(FRICTION);
    // What the implicit steps (the relaxation and VBD) act on.
    let implicit_scene = Scene::new(RELAX_DT)
        .with_gravity(GRAVITY)
        .with_ground(ground);

    // The relaxation from rest, state reset before each call.
    // `accelerated`: the defaults (Chebyshev, first trial step 2); otherwise plain descent,
    // first trial step 1: the settings the first table of docs/guide/10-performance.md was measured with.
    let relax_settings = |budget: u32, accelerated: bool| {
        let settings = RelaxSettings::new().with_tolerance(0.0, budget);
        if accelerated {
            settings
        } else {
            settings.with_chebyshev(0.0, 1.0, 0)
        }
    };
    let relaxation = |budget: u32, accelerated: bool| {
        let settings = relax_settings(budget, accelerated);
        let mut positions = rest_positions.to_vec();
        let mut velocities = vec![Vec3::ZERO; n];
        // As in a simulation, one scratch serves every call: the first call (outside the
        // timing) computes the preconditioner, the later ones reuse it. It borrows buffers
        // that outlive the closure.
        let vectors: &'a mut [Vec3] =
            Box::leak(vec![Vec3::ZERO; scratch_len::relax(n)].into_boxed_slice());
        let scalars: &'a mut [f32] = Box::leak(vec![0.0; n].into_boxed_slice());
        let mut scratch = RelaxScratch::new(vectors, scalars);
        move || {
            positions.copy_from_slice(rest_positions);
            velocities.fill(Vec3::ZERO);
            let report = relax_step(
                &body,
                masses,
                &[],
                &implicit_scene,
                &settings,
                &mut positions,
                &mut velocities,
                &mut scratch,
            )
            .unwrap();
            black_box(&positions);
            report
        }
    };
    let mut relax_short = relaxation(RELAX_BUDGETS[0], false);
    let mut relax_long = relaxation(RELAX_BUDGETS[1], false);
    let short_report = relax_short();
    let long_report = relax_long();
    let mut chebyshev_short = relaxation(RELAX_BUDGETS[0], true);
    let mut chebyshev_long = relaxation(RELAX_BUDGETS[1], true);
    let chebyshev_reports = [chebyshev_short(), chebyshev_long()];
    // The sagged state, from a separate call of the short relaxation.
    let sagged = {
        let settings = relax_settings(RELAX_BUDGETS[0], false);
        let mut positions = rest_positions.to_vec();
        let mut velocities = vec![Vec3::ZERO; n];
        let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
        let mut scalars = vec![0.0; n];
        let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
        relax_step(
            &body,
            masses,
            &[],
            &implicit_scene,
            &settings,
            &mut positions,
            &mut velocities,
            &mut scratch,
        )
        .unwrap();
        positions
    };

    // The explicit stepper, state evolving across calls. The scratch keeps the blow-up
    // detector's history between calls, so it borrows a buffer that outlives the closure.
    let mut stiffness = vec![0.0; n];
    let bound = stable_time_step(&body, masses, &[], &mut stiffness).unwrap();
    let dt = DT_FRACTION * bound;
    let explicit_scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground);
    let settings = ExplicitSettings::new();
    let mut positions = rest_positions.to_vec();
    let mut velocities = vec![Vec3::ZERO; n];
    let buffer: &'a mut [Vec3] =
        Box::leak(vec![Vec3::ZERO; scratch_len::explicit(n)].into_boxed_slice());
    let mut scratch = ExplicitScratch::new(buffer);
    let mut step = move || {
        explicit_step(
            &body,
            masses,
            &[],
            &explicit_scene,
            &settings,
            &mut positions,
            &mut velocities,
            &mut scratch,
        )
        .unwrap()
    };
    let contacts = step().ground_contacts;

    // VBD from rest, state reset before each call, one scratch (topology built once).
    let vbd = |budget: u32| {
        let settings = VbdSettings::new()
            .with_tolerance(0.0, budget)
            .with_line_search(0);
        let mut positions = rest_positions.to_vec();
        let mut velocities = vec![Vec3::ZERO; n];
        let vectors: &'a mut [Vec3] =
            Box::leak(vec![Vec3::ZERO; scratch_len::vbd(n)].into_boxed_slice());
        let indices: &'a mut [u32] = Box::leak(
            vec![0; scratch_len::vbd_indices(n, mesh.element_count())].into_boxed_slice(),
        );
        let mut scratch = VbdScratch::new(vectors, indices);
        move || {
            positions.copy_from_slice(rest_positions);
            velocities.fill(Vec3::ZERO);
            let report = vbd_step(
                &body,
                masses,
                &[],
                &implicit_scene,
                &settings,
                &mut positions,
                &mut velocities,
                &mut scratch,
            )
            .unwrap();
            black_box(&positions);
            report.iterations
        }
    };
    let mut vbd_short = vbd(VBD_BUDGETS[0]);
    let mut vbd_long = vbd(VBD_BUDGETS[1]);
    let vbd_sweeps = [vbd_short(), vbd_long()];

    // The Hessian product with a cache built once at the sagged state.
    let mut cache = vec![TetHessian::default(); mesh.element_count()];
    mesh.projected_hessians(&material, &sagged, &mut cache)
        .unwrap();
    let direction: Vec<Vec3> = sagged
        .iter()
        .zip(rest_positions)
        .map(|(x, r)| *x - *r)
        .collect();
    let mut products = vec![Vec3::ZERO; n];

    let mut forces = vec![Vec3::ZERO; n];
    let mut fused_forces = vec![Vec3::ZERO; n];
    let fused_positions = sagged.clone();
    Case {
        name,
        id,
        bound,
        dt,
        contacts,
        relax: [short_report, long_report],
        chebyshev: chebyshev_reports,
        vbd_sweeps,
        operations: vec![
            Operation::new("force_evaluation", move || {
                forces.fill(Vec3::ZERO);
                mesh.add_elastic_forces(&material, black_box(&sagged), &mut forces)
                    .unwrap();
                black_box(&forces);
            }),
            Operation::new("energy_and_forces", move || {
                fused_forces.fill(Vec3::ZERO);
                let energy = body
                    .energy_and_add_forces(black_box(&fused_positions), &mut fused_forces)
                    .unwrap();
                black_box((energy, &fused_forces));
            }),
            Operation::new("explicit_step", move || {
                black_box(step());
            }),
            Operation::new("relax_20_iterations", move || {
                black_box(relax_short());
            }),
            Operation::new("relax_40_iterations", move || {
                black_box(relax_long());
            }),
            Operation::new("stiffness_bounds", move || {
                black_box(stable_time_step(&body, masses, &[], &mut stiffness).unwrap());
            }),
            Operation::new("hessian_product", move || {
                products.fill(Vec3::ZERO);
                mesh.add_hessian_product(&cache, black_box(&direction), &mut products)
                    .unwrap();
                black_box(&products);
            }),
            Operation::new("vbd_2_sweeps", move || {
                black_box(vbd_short());
            }),
            Operation::new("vbd_4_sweeps", move || {
                black_box(vbd_long());
            }),
            Operation::new("relax_chebyshev_20_iterations", move || {
                black_box(chebyshev_short());
            }),
            Operation::new("relax_chebyshev_40_iterations", move || {
                black_box(chebyshev_long());
            }),
        ],
    }
}

/// The criterion group of one model, one benchmark per operation.
fn criterion_group(c: &mut Criterion, tets: usize, case: &mut Case<'_>) {
    // "step_105k_stable_nh", "step_105k_stvk".
    let mut group = c.benchmark_group(format!("step_{}k_{}", (tets + 500) / 1000, case.id));
    // The relaxation calls take tens of milliseconds: flat sampling needs 10 of them per
    // sample set where linear sampling would need 55.
    group
        .sampling_mode(SamplingMode::Flat)
        .sample_size(10)
        .measurement_time(Duration::from_secs(2));
    for operation in &mut case.operations {
        group.bench_function(operation.id, |b| b.iter(&mut operation.run));
    }
    group.finish();
}

/// How long one timed block of the table pass should take, and round-robin rounds.
struct TablePlan {
    block: Duration,
    rounds: u32,
}

/// Milliseconds, with three significant digits or so.
fn ms(ns: f64) -> String {
    let ms = ns * 1e-6;
    if ms >= 10.0 {
        format!("{ms:.1}")
    } else {
        format!("{ms:.3}")
    }
}

fn print_tables(geometry: &Geometry, cases: &mut [Case<'_>], plan: &TablePlan) {
    // Calibration: after a warm-up call, time one call and repeat it enough to fill a block.
    for operation in cases.iter_mut().flat_map(|case| &mut case.operations) {
        (operation.run)();
        let start = Instant::now();
        (operation.run)();
        let once = start.elapsed().as_secs_f64().max(1e-9);
        operation.calls = (plan.block.as_secs_f64() / once).ceil().clamp(1.0, 1e5) as u32;
    }
    let mut operations: Vec<&mut Operation<'_>> = cases
        .iter_mut()
        .flat_map(|case| &mut case.operations)
        .collect();
    let block_ns = common::round_robin_min_ns(
        &mut operations,
        |operation| {
            for _ in 0..operation.calls {
                (operation.run)();
            }
        },
        1,
        1,
        plan.rounds,
    );
    // Nanoseconds per call, per model.
    let per_call: Vec<f64> = block_ns
        .iter()
        .zip(&operations)
        .map(|(ns, operation)| ns / f64::from(operation.calls))
        .collect();
    drop(operations);
    let mut per_call = per_call.into_iter();
    let ns: Vec<Vec<f64>> = cases
        .iter()
        .map(|case| per_call.by_ref().take(case.operations.len()).collect())
        .collect();

    let tets = geometry.tets.len();
    let vertices = geometry.rest_positions.len();
    println!();
    println!(
        "Time stepping on a box of {tets} tetrahedra ({cells}^3 cubes, Kuhn 6-tet split, \
         {vertices} vertices, edge {EDGE} m) standing on the ground z = 0 under gravity \
         (friction {FRICTION}); E = {YOUNG:e} Pa, nu = {POISSON}, {DENSITY} kg/m^3; one thread, \
         f32. Explicit: dt = {DT_FRACTION} x stable_time_step ({dt}), one substep, gravity and \
         ground, state evolving from call to call ({contacts}). Relaxation: relax_step, \
         dt = 1/60 s, gravity and ground, tolerance 0 (whole budget), from rest (state reset per \
         call; one scratch for all calls, so the preconditioner is computed once). Force evaluations at the sagged state the 20-iteration relaxation reaches. \
         Minimum of {rounds} round-robin rounds of about {block} ms per operation, on {machine}.",
        cells = geometry.cells,
        dt = cases
            .iter()
            .map(|case| format!("{}: {:.3e} s of {:.3e} s", case.name, case.dt, case.bound))
            .collect::<Vec<_>>()
            .join("; "),
        contacts = cases
            .iter()
            .map(|case| format!(
                "{}: {} ground contacts in the first step",
                case.name, case.contacts
            ))
            .collect::<Vec<_>>()
            .join("; "),
        rounds = plan.rounds,
        block = plan.block.as_millis(),
        machine = common::machine(),
    );
    println!();
    let mut rows = Vec::new();
    for (case, ns) in cases.iter().zip(&ns) {
        let force = ns[FORCES];
        let row = |operation: &str, ns: f64, rate: &str| {
            vec![
                case.name.to_owned(),
                operation.to_owned(),
                ms(ns),
                format!("{:.0} {rate}", 1e9 / ns),
                format!("{:.2}x", ns / force),
            ]
        };
        let [short, long] = case.relax;
        rows.push(row(
            "force evaluation (zero + `add_elastic_forces`)",
            force,
            "evaluations/s",
        ));
        rows.push(row(
            "energy + forces (`energy_and_add_forces`, fused)",
            ns[FUSED],
            "evaluations/s",
        ));
        rows.push(row(
            "**explicit step** (forces + integration + ground)",
            ns[EXPLICIT],
            "**steps/s**",
        ));
        for ((report, index), budget) in [(short, RELAX_SHORT), (long, RELAX_LONG)]
            .into_iter()
            .zip(RELAX_BUDGETS)
        {
            rows.push(row(
                &format!(
                    "relaxation iteration: {budget}-iteration call / {} iterations",
                    report.iterations
                ),
                ns[index] / f64::from(report.iterations),
                "iterations/s",
            ));
        }
        rows.push(row(
            &format!(
                "**relaxation iteration, marginal** (({}-call - {}-call) / extra iterations)",
                RELAX_BUDGETS[1], RELAX_BUDGETS[0]
            ),
            common::marginal(
                (ns[RELAX_SHORT], short.iterations),
                (ns[RELAX_LONG], long.iterations),
            ),
            "iterations/s",
        ));
        let [cheb_short, cheb_long] = case.chebyshev;
        rows.push(row(
            &format!(
                "relaxation iteration, defaults (Chebyshev): {}-iteration call / {} iterations",
                RELAX_BUDGETS[0], cheb_short.iterations
            ),
            ns[CHEBYSHEV_SHORT] / f64::from(cheb_short.iterations.max(1)),
            "iterations/s",
        ));
        rows.push(row(
            &format!(
                "**relaxation iteration, defaults (Chebyshev), marginal** (({}-call - {}-call) / \
                 extra iterations)",
                RELAX_BUDGETS[1], RELAX_BUDGETS[0]
            ),
            common::marginal(
                (ns[CHEBYSHEV_SHORT], cheb_short.iterations),
                (ns[CHEBYSHEV_LONG], cheb_long.iterations),
            ),
            "iterations/s",
        ));
        rows.push(row(
            "per-vertex stiffness bounds (`stable_time_step`; the relaxation's preconditioner, \
             computed once per scratch)",
            ns[PRECONDITIONER],
            "evaluations/s",
        ));
        rows.push(row(
            "Hessian product (zero + `add_hessian_product`, cached projected element Hessians)",
            ns[HESSIAN_PRODUCT],
            "products/s",
        ));
        let [vbd_short, vbd_long] = case.vbd_sweeps;
        let vbd_iteration = common::marginal((ns[VBD_SHORT], vbd_short), (ns[VBD_LONG], vbd_long));
        rows.push(row(
            &format!(
                "VBD iteration, marginal (({}-sweep call - {}-sweep call) / extra sweeps; a \
                 sweep + a fused pass)",
                VBD_BUDGETS[1], VBD_BUDGETS[0]
            ),
            vbd_iteration,
            "iterations/s",
        ));
        rows.push(row(
            "**VBD sweep** (marginal iteration - fused pass; no line search)",
            vbd_iteration - ns[FUSED],
            "sweeps/s",
        ));
    }
    common::print_markdown_table(
        &[
            "model",
            "operation",
            "ms per call",
            "rate",
            "time vs one force evaluation",
        ],
        rows,
    );

    println!();
    println!(
        "What each relax_step call reported (identical every call: same start state). Energy \
         evaluations are fused energy-and-force passes: one per trial plus those of the initial \
         guesses (and of the rigid guess the defaults' stopping test takes after friction on the \
         velocity)."
    );
    println!();
    common::print_markdown_table(
        &[
            "model",
            "settings",
            "budget",
            "iterations",
            "energy evaluations",
            "evaluations per iteration",
            "final / initial residual",
        ],
        cases.iter().flat_map(|case| {
            let plain = RELAX_BUDGETS
                .iter()
                .zip(case.relax)
                .map(|run| ("plain, step 1", run));
            let chebyshev = RELAX_BUDGETS
                .iter()
                .zip(case.chebyshev)
                .map(|run| ("defaults (Chebyshev)", run));
            plain.chain(chebyshev).map(|(settings, (budget, report))| {
                vec![
                    case.name.to_owned(),
                    settings.to_owned(),
                    budget.to_string(),
                    report.iterations.to_string(),
                    report.energy_evaluations.to_string(),
                    format!(
                        "{:.2}",
                        f64::from(report.energy_evaluations) / f64::from(report.iterations.max(1))
                    ),
                    format!("{:.2e}", report.residual / report.initial_residual),
                ]
            })
        }),
    );

    println!();
    println!(
        "Issue 4's target: relaxation cost per iteration <= {RELAX_TARGET}x one force evaluation."
    );
}

fn main() {
    let quick = common::quick();
    let geometry = Geometry::new(if quick { QUICK_CELLS } else { CELLS });
    let mut rest = geometry.rest.clone();
    let mesh = TetMesh::new(&geometry.rest_positions, &geometry.tets, &mut rest).unwrap();
    let positions: &[Vec3] = &geometry.rest_positions;
    let masses: &[f32] = &geometry.masses;
    let mut cases = vec![
        case(
            "stable neo-Hookean",
            "stable_nh",
            mesh,
            positions,
            masses,
            StableNeoHookean::from_young_poisson(YOUNG, POISSON).unwrap(),
        ),
        case(
            "StVK",
            "stvk",
            mesh,
            positions,
            masses,
            StVK::from_young_poisson(YOUNG, POISSON).unwrap(),
        ),
    ];

    if quick {
        let plan = TablePlan {
            block: Duration::from_millis(5),
            rounds: 3,
        };
        print_tables(&geometry, &mut cases, &plan);
        return;
    }

    // Command-line flags (`--measurement-time`, a name filter, ...) override the defaults here,
    // except the groups' own sampling settings (see `criterion_group`).
    let mut criterion = Criterion::default()
        .without_plots()
        .warm_up_time(Duration::from_millis(300))
        .configure_from_args();
    for case in &mut cases {
        criterion_group(&mut criterion, geometry.tets.len(), case);
    }
    criterion.final_summary();

    let plan = match common::table_pass() {
        TablePass::Skip => return,
        TablePass::Test => TablePlan {
            block: Duration::ZERO,
            rounds: 1,
        },
        TablePass::Full => TablePlan {
            block: Duration::from_millis(50),
            rounds: 7,
        },
    };
    print_tables(&geometry, &mut cases, &plan);
}
