//! The static cantilever of issue #40 solved by Newton's method with each preconditioner, and
//! scikit-fem's linear solvers beside it on the same mesh.
//!
//! A 4 x 1 x 1 m bar along +x, clamped at x = 0, stable neo-Hookean (E = 1 MPa, nu = 0.3),
//! density 1 kg/m^3 under gravity along -z (a small, near-linear load), the five-tetrahedron box
//! mesh; `newton_quasi_static` to a relative residual of `1e-8` on one thread, with block-Jacobi
//! and with multilevel (smoothed-aggregation) CG. For each resolution the program prints Newton
//! and CG iterations, wall and CPU time, the hierarchy's build time and the mean tip deflection,
//! and writes the mesh (first line `NV NT`, then `x y z` per vertex, `a b c d` per tetrahedron)
//! to `target/cantilever/`.
//!
//! The peer: where `SOFTFEM_SKFEM_PEER` names the scikit-fem script (linear P1 elasticity on
//! that mesh: SuperLU, PARDISO, PyAMG smoothed aggregation, Jacobi CG; its header says what to
//! install), the program runs it on each mesh with `SOFTFEM_PYTHON` (default `python3`), one
//! thread (`OMP_NUM_THREADS=1` and the like), and prints its `RESULT` lines.
//!
//! ```text
//! cargo run --release -p softfem-examples --bin cantilever -- --cells 32x8x8 --cells 68x17x17
//! SOFTFEM_SKFEM_PEER=/path/to/skfem_cantilever.py SOFTFEM_PYTHON=.venv/bin/python \
//!     cargo run --release -p softfem-examples --bin cantilever
//! ```

use std::error::Error;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use clap::Parser;
use softfem::f64::element::{TetHessian, TetRest};
use softfem::f64::generate::{BoxSplit, box_counts, fill_box};
use softfem::f64::material::StableNeoHookean;
use softfem::f64::mesh::TetMesh;
use softfem::f64::step::{
    Multilevel, NewtonReport, NewtonScratch, NewtonSettings, Preconditioner, Scene, TetElastic,
    newton_quasi_static, scratch_len,
};
use softfem::f64::types::{Mat3, Vec3};

#[path = "../common/paths.rs"]
#[allow(dead_code)]
mod paths;

/// The bar's length along x (m); its section is 1 x 1 m.
const LENGTH: f64 = 4.0;
const DENSITY: f64 = 1.0;
const GRAVITY: Vec3 = Vec3::new(0.0, 0.0, -9.81);

#[derive(Parser, Debug)]
#[command(
    about = "Issue #40's static cantilever: block-Jacobi against multilevel Newton-CG, and scikit-fem beside it"
)]
struct Args {
    /// Cubes along x, y, z as `NXxNYxNZ` (five tetrahedra each); repeat for several meshes.
    #[arg(long = "cells", default_values = ["32x8x8", "68x17x17"], value_parser = parse_cells)]
    cells: Vec<(usize, usize, usize)>,
    /// The relative residual Newton's method stops at (and the peer's solvers).
    #[arg(long, default_value_t = 1e-8)]
    tolerance: f64,
    /// Young's modulus (Pa): 1e6 is issue #40's near-linear bar; 1e4 makes it droop far.
    #[arg(long, default_value_t = 1.0e6)]
    young: f64,
    /// Skip the block-Jacobi solve (slow at a million tetrahedra).
    #[arg(long)]
    no_block_jacobi: bool,
}

/// `NXxNYxNZ` as three positive counts.
fn parse_cells(text: &str) -> Result<(usize, usize, usize), String> {
    let counts: Vec<usize> = text
        .split('x')
        .map(|part| {
            part.trim()
                .parse::<usize>()
                .map_err(|e| format!("{text}: {e}"))
        })
        .collect::<Result<_, _>>()?;
    match counts[..] {
        [nx, ny, nz] if nx > 0 && ny > 0 && nz > 0 => Ok((nx, ny, nz)),
        _ => Err(format!(
            "{text}: expected three positive counts as NXxNYxNZ"
        )),
    }
}

/// This thread's CPU time (s), from Linux's `/proc/thread-self/schedstat` (NaN elsewhere).
fn thread_cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |ns| ns * 1e-9)
}

/// The mesh file the peer reads.
fn write_mesh(path: &Path, rest: &[Vec3], tets: &[[u32; 4]]) -> Result<(), Box<dyn Error>> {
    let mut text = String::with_capacity(40 * (rest.len() + tets.len()));
    writeln!(text, "{} {}", rest.len(), tets.len())?;
    for p in rest {
        writeln!(text, "{:.17e} {:.17e} {:.17e}", p.x, p.y, p.z)?;
    }
    for [a, b, c, d] in tets {
        writeln!(text, "{a} {b} {c} {d}")?;
    }
    std::fs::write(path, text)?;
    Ok(())
}

/// One static solve: the report, wall and CPU seconds, the mean tip deflection (m).
fn solve(
    model: &TetElastic<'_, StableNeoHookean>,
    (rest, masses, pinned): (&[Vec3], &[f64], &[bool]),
    preconditioner: Preconditioner,
    tolerance: f64,
) -> Result<(NewtonReport, f64, f64, f64), Box<dyn Error>> {
    let n = rest.len();
    let len = scratch_len::newton(n, model.mesh.element_count());
    let mut vectors = vec![Vec3::ZERO; len.vectors];
    let mut blocks = vec![Mat3::ZERO; len.blocks];
    let mut hessians = vec![TetHessian::default(); len.hessians];
    let scene = Scene::new(1.0).with_gravity(GRAVITY);
    let settings = NewtonSettings::new()
        .with_tolerance(tolerance, 50)
        .with_preconditioner(preconditioner);
    let mut x = rest.to_vec();
    let (cpu, clock) = (thread_cpu_seconds(), Instant::now());
    let report = newton_quasi_static(
        model,
        masses,
        pinned,
        &scene,
        &settings,
        &mut x,
        &mut NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians),
    )?;
    let (wall, cpu) = (clock.elapsed().as_secs_f64(), thread_cpu_seconds() - cpu);
    let tip: Vec<f64> = rest
        .iter()
        .zip(&x)
        .filter(|(r, _)| r.x == LENGTH)
        .map(|(r, x)| x.z - r.z)
        .collect();
    let tip = tip.iter().sum::<f64>() / tip.len().max(1) as f64;
    Ok((report, wall, cpu, tip))
}

fn main() -> Result<(), Box<dyn Error>> {
    let args = Args::parse();
    let out_dir: PathBuf = paths::repository_root().join("target").join("cantilever");
    std::fs::create_dir_all(&out_dir)?;
    let peer = std::env::var_os("SOFTFEM_SKFEM_PEER");
    let python = std::env::var_os("SOFTFEM_PYTHON").unwrap_or_else(|| "python3".into());
    println!(
        "static cantilever {LENGTH} x 1 x 1 m, E {:e} Pa, nu 0.3, density {DENSITY}, tolerance {:e}, one thread",
        args.young, args.tolerance
    );
    for &(nx, ny, nz) in &args.cells {
        let split = BoxSplit::Alternating5;
        let (vertices, elements) = box_counts(nx, ny, nz, split)?;
        let (mut rest, mut tets) = (vec![Vec3::ZERO; vertices], vec![[0u32; 4]; elements]);
        fill_box(
            Vec3::ZERO,
            Vec3::new(LENGTH, 1.0, 1.0),
            nx,
            ny,
            nz,
            split,
            &mut rest,
            &mut tets,
        )?;
        let mut rest_data = vec![TetRest::default(); elements];
        let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
        let mut masses = vec![0.0; vertices];
        mesh.lumped_masses(DENSITY, &mut masses)?;
        let pinned: Vec<bool> = rest.iter().map(|p| p.x == 0.0).collect();
        let model = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(args.young, 0.3)?);
        println!("{nx}x{ny}x{nz} cubes: {elements} tets, {vertices} vertices");

        // One build at the rest shape: the setup the multilevel solve pays.
        let mut hessians = vec![TetHessian::default(); elements];
        mesh.projected_hessians(&model.material, &rest, &mut hessians)?;
        let mut multilevel = Multilevel::new();
        let clock = Instant::now();
        multilevel.build(&model, &hessians, &masses, 0.0, &pinned, &rest)?;
        let build = clock.elapsed().as_secs_f64();
        let levels: Vec<String> = multilevel
            .level_sizes()
            .map(|(rows, entries)| format!("{rows} ({entries} entries)"))
            .collect();
        println!(
            "  hierarchy: build {build:.3} s, levels {}",
            levels.join(", ")
        );
        // What one CG iteration costs: a V-cycle and a matrix-free Hessian product.
        let residual: Vec<Vec3> = pinned
            .iter()
            .map(|&p| if p { Vec3::ZERO } else { Vec3::ONE })
            .collect();
        let mut out = vec![Vec3::ZERO; vertices];
        let clock = Instant::now();
        for _ in 0..10 {
            multilevel.apply(&residual, &mut out)?;
        }
        let cycle = clock.elapsed().as_secs_f64() / 10.0;
        let clock = Instant::now();
        for _ in 0..10 {
            mesh.add_hessian_product(&hessians, &residual, &mut out)?;
        }
        let product = clock.elapsed().as_secs_f64() / 10.0;
        println!(
            "  one V-cycle {:.2} ms, one Hessian product {:.2} ms",
            cycle * 1e3,
            product * 1e3
        );
        drop(multilevel);

        let mut preconditioners = vec![Preconditioner::Multilevel];
        if !args.no_block_jacobi {
            preconditioners.insert(0, Preconditioner::BlockJacobi);
        }
        for preconditioner in preconditioners {
            let (report, wall, cpu, tip) = solve(
                &model,
                (&rest, &masses, &pinned),
                preconditioner,
                args.tolerance,
            )?;
            println!(
                "  RESULT softfem {preconditioner:?} tets={elements} newton={} cg={} cg_per_newton={:.1} builds={} \
                 wall_s={wall:.3} cpu_s={cpu:.3} converged={} residual={:.2e} tip_uz_mm={:.6}",
                report.iterations,
                report.details.cg_iterations,
                f64::from(report.details.cg_iterations) / f64::from(report.iterations.max(1)),
                report.details.multilevel_builds,
                report.converged,
                report.residual / report.initial_residual,
                tip * 1000.0
            );
        }

        let mesh_path = out_dir.join(format!("cantilever-{elements}.txt"));
        write_mesh(&mesh_path, &rest, &tets)?;
        println!("  mesh written to {}", mesh_path.display());
        if let Some(script) = &peer {
            println!(
                "  peer: {} {}",
                python.to_string_lossy(),
                Path::new(script).display()
            );
            let output = Command::new(&python)
                .arg(script)
                .arg(&mesh_path)
                .arg("--tol")
                .arg(format!("{:e}", args.tolerance))
                .arg("--direct")
                .arg(if elements <= 200_000 { "1" } else { "0" })
                .envs([
                    ("OMP_NUM_THREADS", "1"),
                    ("MKL_NUM_THREADS", "1"),
                    ("OPENBLAS_NUM_THREADS", "1"),
                ])
                .output()
                .map_err(|e| {
                    format!(
                        "could not run the peer with {}: {e}",
                        python.to_string_lossy()
                    )
                })?;
            for line in String::from_utf8_lossy(&output.stdout).lines() {
                println!("  {line}");
            }
            if !output.status.success() {
                println!(
                    "  peer failed ({}): {}",
                    output.status,
                    String::from_utf8_lossy(&output.stderr)
                        .lines()
                        .last()
                        .unwrap_or("")
                );
            }
        }
    }
    Ok(())
}
