//! Throughput of the 3x3 SVD: softfem `svd3` in f32 and f64, `svd3_lanes` (a group of matrices per
//! call, SIMD) in f32 and f64, `svd3_sweeps` in f32 for 1 to 6 sweeps, and nalgebra's `Matrix3::<f32>::svd(true, true)` as the reference, all on the same batch
//! of matrices.
//!
//! `cargo bench --bench svd` runs two passes:
//! 1. criterion, one benchmark per variant, each iteration decomposing the whole batch (criterion
//!    reports elements/s);
//! 2. a plain `Instant` pass that times every variant round-robin several times, keeps the minimum
//!    per variant and prints a markdown table (ns per decomposition, speed-up over nalgebra) ready
//!    to paste into the README. Interleaving the variants and taking minima means the ratios come
//!    from the same machine state, which criterion's separate runs do not guarantee.
//!
//! `SOFTFEM_BENCH_QUICK=1` skips criterion and runs the table pass with few repetitions: a smoke
//! test that finishes in about a second (used by `.ci/run`).

mod common;

use std::hint::black_box;
use std::time::Duration;

use common::{TablePass, XorShift64Star};
use criterion::{BenchmarkId, Criterion, Throughput};
use nalgebra::Matrix3;
use softfem::glam::{DMat3, Mat3};

/// Matrices per batch: enough to defeat branch prediction on the input pattern, small enough
/// (36 KiB in f32) to stay in L1/L2 so the benchmark measures arithmetic, not memory.
const BATCH_LEN: usize = 1024;

/// Sweep counts benchmarked through `svd3_sweeps`.
const SWEEP_COUNTS: std::ops::RangeInclusive<u32> = 1..=6;

/// Half general matrices (entries uniform in `[-1, 1]`, so any conditioning and either sign of
/// the determinant), half deformation gradients near identity (`I + 0.2 * noise`, what an FEM
/// step mostly sees), shuffled so the two classes do not alternate predictably.
fn input_batch() -> Vec<Mat3> {
    let mut rng = XorShift64Star(0x5eed_50f7_fe11_2026);
    let mut batch: Vec<Mat3> = (0..BATCH_LEN)
        .map(|i| {
            let mut entries = [0.0f32; 9];
            for entry in &mut entries {
                *entry = rng.next_signed_unit();
            }
            let noise = Mat3::from_cols_array(&entries);
            if i % 2 == 0 {
                noise
            } else {
                Mat3::IDENTITY + noise * 0.2
            }
        })
        .collect();
    for i in (1..batch.len()).rev() {
        let j = rng.next_below(i + 1);
        batch.swap(i, j);
    }
    batch
}

/// The same batch in the representations each variant takes, converted once, outside timing.
struct Inputs {
    f32: Vec<Mat3>,
    f64: Vec<DMat3>,
    nalgebra: Vec<Matrix3<f32>>,
}

impl Inputs {
    fn new() -> Self {
        let f32 = input_batch();
        let f64 = f32.iter().map(Mat3::as_dmat3).collect();
        let nalgebra = f32
            .iter()
            .map(|m| Matrix3::from_column_slice(&m.to_cols_array()))
            .collect();
        Inputs { f32, f64, nalgebra }
    }
}

// One batch through each variant. Every result feeds the returned sum (singular values and one
// entry of each factor), so no part of any decomposition can be optimised away.

fn run_softfem_f32(batch: &[Mat3]) -> f32 {
    batch.iter().fold(0.0, |acc, &m| {
        let svd = softfem::svd::svd3(black_box(m));
        acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
    })
}

fn run_softfem_f64(batch: &[DMat3]) -> f64 {
    batch.iter().fold(0.0, |acc, &m| {
        let svd = softfem::f64::svd::svd3(black_box(m));
        acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
    })
}

fn run_softfem_f32_sweeps(batch: &[Mat3], sweeps: u32) -> f32 {
    batch.iter().fold(0.0, |acc, &m| {
        let svd = softfem::svd::svd3_sweeps(black_box(m), sweeps);
        acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
    })
}

fn run_softfem_f32_lanes(batch: &[Mat3]) -> f32 {
    batch
        .chunks_exact(softfem::lanes::LANES)
        .fold(0.0, |acc, chunk| {
            let group: &[Mat3; softfem::lanes::LANES] = chunk.try_into().unwrap();
            softfem::svd::svd3_lanes(black_box(group))
                .iter()
                .fold(acc, |acc, svd| {
                    acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
                })
        })
}

fn run_softfem_f64_lanes(batch: &[DMat3]) -> f64 {
    batch
        .chunks_exact(softfem::f64::lanes::LANES)
        .fold(0.0, |acc, chunk| {
            let group: &[DMat3; softfem::f64::lanes::LANES] = chunk.try_into().unwrap();
            softfem::f64::svd::svd3_lanes(black_box(group))
                .iter()
                .fold(acc, |acc, svd| {
                    acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
                })
        })
}

fn run_nalgebra_f32(batch: &[Matrix3<f32>]) -> f32 {
    batch.iter().fold(0.0, |acc, &m| {
        let svd = black_box(m).svd(true, true);
        let u = svd.u.map_or(0.0, |u| u[(0, 0)]);
        let v_t = svd.v_t.map_or(0.0, |v_t| v_t[(2, 2)]);
        acc + svd.singular_values.sum() + u + v_t
    })
}

/// A lower bound for any scalar 3x3 Jacobi SVD with exact rotations: only the chain of dependent
/// operations of `DEFAULT_SWEEPS` sweeps (three rotations each, every rotation needing the
/// previous one's result), as `jacobi_rotation` and `apply_symmetric` in `src/svd.rs` form it:
/// `r = sqrt(d^2 + y^2)`, `h = sqrt((|d| + r)^2 + y^2)`, and the next off-diagonal entry
/// `(|d| + r) (q - t p) / h`. No `v`, no QR, no sorting: the real `svd3` does all of this and
/// more, so it cannot be faster than this row.
fn run_rotation_chain(batch: &[Mat3]) -> f32 {
    let rotations = 3 * softfem::svd::DEFAULT_SWEEPS;
    batch.iter().fold(0.0, |acc, &m| {
        let m = black_box(m);
        let (mut d, mut apq, other) = (m.x_axis.x - m.y_axis.y, m.y_axis.x, m.z_axis.x);
        for _ in 0..rotations {
            let y = apq + apq;
            let r = (d * d + y * y).sqrt();
            let den = d.abs() + r;
            let h = (den * den + y * y).sqrt();
            let t = y / den;
            let next = den * (other - t * apq) / h;
            d -= t * apq;
            apq = next;
        }
        acc + apq + d
    })
}

/// A benchmarked variant: its table label and one pass over the batch.
struct Variant<'a> {
    label: String,
    run_batch: Box<dyn Fn() -> f64 + 'a>,
}

/// Every variant, nalgebra first (it is the reference for the speed-up column).
fn variants(inputs: &Inputs) -> Vec<Variant<'_>> {
    let mut variants = vec![
        Variant {
            label: "nalgebra `Matrix3::<f32>::svd(true, true)`".into(),
            run_batch: Box::new(|| f64::from(run_nalgebra_f32(&inputs.nalgebra))),
        },
        Variant {
            label: format!(
                "softfem `svd3` f32 ({} sweeps, default)",
                softfem::svd::DEFAULT_SWEEPS
            ),
            run_batch: Box::new(|| f64::from(run_softfem_f32(&inputs.f32))),
        },
        Variant {
            label: format!(
                "softfem `svd3` f64 ({} sweeps, default)",
                softfem::f64::svd::DEFAULT_SWEEPS
            ),
            run_batch: Box::new(|| run_softfem_f64(&inputs.f64)),
        },
        Variant {
            label: format!(
                "softfem `svd3_lanes` f32 ({} matrices per call)",
                softfem::lanes::LANES
            ),
            run_batch: Box::new(|| f64::from(run_softfem_f32_lanes(&inputs.f32))),
        },
        Variant {
            label: format!(
                "softfem `svd3_lanes` f64 ({} matrices per call)",
                softfem::f64::lanes::LANES
            ),
            run_batch: Box::new(|| run_softfem_f64_lanes(&inputs.f64)),
        },
    ];
    variants.push(Variant {
        label: format!(
            "lower bound: the {} dependent rotations of {} sweeps alone (2 square roots and a \
             division each, nothing else)",
            3 * softfem::svd::DEFAULT_SWEEPS,
            softfem::svd::DEFAULT_SWEEPS
        ),
        run_batch: Box::new(|| f64::from(run_rotation_chain(&inputs.f32))),
    });
    for sweeps in SWEEP_COUNTS {
        variants.push(Variant {
            label: format!(
                "softfem `svd3_sweeps` f32, {sweeps} sweep{}",
                if sweeps == 1 { "" } else { "s" }
            ),
            run_batch: Box::new(move || f64::from(run_softfem_f32_sweeps(&inputs.f32, sweeps))),
        });
    }
    variants
}

fn criterion_benches(c: &mut Criterion, inputs: &Inputs) {
    let mut group = c.benchmark_group("svd3");
    group.throughput(Throughput::Elements(BATCH_LEN as u64));
    group.bench_function("nalgebra_f32", |b| {
        b.iter(|| run_nalgebra_f32(&inputs.nalgebra));
    });
    group.bench_function("softfem_f32", |b| {
        b.iter(|| run_softfem_f32(&inputs.f32));
    });
    group.bench_function("softfem_f64", |b| {
        b.iter(|| run_softfem_f64(&inputs.f64));
    });
    group.bench_function("softfem_f32_lanes", |b| {
        b.iter(|| run_softfem_f32_lanes(&inputs.f32));
    });
    group.bench_function("softfem_f64_lanes", |b| {
        b.iter(|| run_softfem_f64_lanes(&inputs.f64));
    });
    for sweeps in SWEEP_COUNTS {
        group.bench_with_input(
            BenchmarkId::new("softfem_f32_sweeps", sweeps),
            &sweeps,
            |b, &sweeps| b.iter(|| run_softfem_f32_sweeps(&inputs.f32, sweeps)),
        );
    }
    group.finish();
}

/// Repetitions of the batch per timed block, and round-robin rounds over all variants.
struct TablePlan {
    repetitions: u32,
    rounds: u32,
}

fn print_table(variants: &mut [Variant<'_>], plan: &TablePlan) {
    let ns = common::round_robin_min_ns(
        variants,
        |variant| {
            black_box((variant.run_batch)());
        },
        plan.repetitions,
        BATCH_LEN,
        plan.rounds,
    );
    let reference_ns = ns[0];
    println!();
    println!(
        "SVD of 3x3 matrices: {BATCH_LEN} inputs (half general, half near identity), minimum of \
         {} round-robin rounds of {} batches per variant, on {}.",
        plan.rounds,
        plan.repetitions,
        common::machine(),
    );
    println!();
    common::print_markdown_table(
        &["variant", "ns/decomposition", "speed-up vs nalgebra f32"],
        variants.iter().zip(&ns).map(|(variant, ns)| {
            vec![
                variant.label.clone(),
                format!("{ns:.1}"),
                format!("{:.2}x", reference_ns / ns),
            ]
        }),
    );
}

fn main() {
    let inputs = Inputs::new();
    let mut variants = variants(&inputs);

    if common::quick() {
        print_table(
            &mut variants,
            &TablePlan {
                repetitions: 5,
                rounds: 3,
            },
        );
        return;
    }

    // Nine benchmarks at ~2.5 s each keep the whole run near 30 s; command-line flags
    // (`--measurement-time`, `--sample-size`, a name filter, ...) still override these.
    let mut criterion = Criterion::default()
        .without_plots()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30)
        .configure_from_args();
    criterion_benches(&mut criterion, &inputs);
    criterion.final_summary();

    let plan = match common::table_pass() {
        TablePass::Skip => return,
        TablePass::Test => TablePlan {
            repetitions: 1,
            rounds: 1,
        },
        TablePass::Full => TablePlan {
            repetitions: 200,
            rounds: 5,
        },
    };
    print_table(&mut variants, &plan);
}
