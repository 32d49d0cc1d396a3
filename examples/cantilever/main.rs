//! The static cantilever of issue #40 solved by Newton's method with each preconditioner, and
//! scikit-fem's linear solvers beside it on the same mesh.
//!
//! A 4 x 1 x 1 m bar along +x, clamped at x = 0, stable neo-Hookean (E = 1 MPa, nu = 0.3),
//! density 1 kg/m^3 under gravity along -z (a small, near-linear load), the five-tetrahedron box
//! mesh; `newton_quasi_static` to a relative residual of `1e-8` on one thread, with block-Jacobi
//! and with multilevel (smoothed-aggregation) CG. For each resolution the program prints Newton
//! and CG iterations, wall and CPU time, the hierarchy's build time and the mean tip deflection,
//! and writes the mesh (first line `NV NT`, then `x y z` per vertex, `a b c d` per tetrahedron)
//! to `target/cantilever/`. With `--threads` (feature `rayon`) it solves again with multilevel
//! CG on a pool of each thread count (`ParallelTetElastic`: the force, Hessian and CG passes
//! and the V-cycle on the pool), checks the answer against the one-thread solve bit for bit,
//! and prints wall and process CPU time. The peak resident memory (`VmHWM`) is printed after
//! softfem's solves at each size (the process's peak so far: the sizes run smallest first).
//!
//! The peer: where `SOFTFEM_SKFEM_PEER` names the scikit-fem script (linear P1 elasticity on
//! that mesh: SuperLU, PARDISO, PyAMG smoothed aggregation, Jacobi CG; its header says what to
//! install), the program runs it on each mesh with `SOFTFEM_PYTHON` (default `python3`), one
//! thread (`OMP_NUM_THREADS=1` and the like), and prints its `RESULT` lines: once for the
//! direct solvers and once for the iterative ones, each run's peak resident memory sampled
//! from `/proc` every 10 ms while it runs (Linux).
//!
//! ```text
//! cargo run --release -p softfem-examples --bin cantilever -- --cells 32x8x8 --cells 68x17x17
//! SOFTFEM_SKFEM_PEER=/path/to/skfem_cantilever.py SOFTFEM_PYTHON=.venv/bin/python \
//!     cargo run --release -p softfem-examples --features rayon --bin cantilever -- --threads 2
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
    /// Also solve with multilevel CG on a rayon pool of this many threads (feature `rayon`);
    /// repeat for several counts.
    #[arg(long)]
    threads: Vec<usize>,
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

/// This process's CPU time (s), user and system, from Linux's `/proc/self/stat` (NaN elsewhere).
#[cfg(feature = "rayon")]
fn process_cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // The fields after the command name's closing parenthesis: utime and stime are the 12th
    // and 13th, in clock ticks of 1/100 s.
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or(Vec::new(), |(_, rest)| rest.split_whitespace().collect());
    let ticks = |k: usize| fields.get(k).and_then(|f| f.parse::<f64>().ok());
    match (ticks(11), ticks(12)) {
        (Some(user), Some(system)) => (user + system) / 100.0,
        _ => f64::NAN,
    }
}

/// The peak resident memory (MB) of process `pid` so far, `VmHWM` in `/proc/PID/status`.
fn peak_resident_mb(pid: &str) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
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

/// What one static solve gives.
struct Solved {
    report: NewtonReport,
    /// Wall and CPU seconds (the thread's on one thread, the process's on a pool).
    wall: f64,
    cpu: f64,
    /// The positions (m).
    x: Vec<Vec3>,
}

/// One static solve on the calling thread.
fn solve(
    model: &TetElastic<'_, StableNeoHookean>,
    (rest, masses, pinned): (&[Vec3], &[f64], &[bool]),
    preconditioner: Preconditioner,
    tolerance: f64,
) -> Result<Solved, Box<dyn Error>> {
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
    Ok(Solved {
        report,
        wall,
        cpu,
        x,
    })
}

/// The mean tip deflection (m) of `x`: the z displacement of the vertices at x = 4 m.
fn tip(rest: &[Vec3], x: &[Vec3]) -> f64 {
    let tip: Vec<f64> = rest
        .iter()
        .zip(x)
        .filter(|(r, _)| r.x == LENGTH)
        .map(|(r, x)| x.z - r.z)
        .collect();
    tip.iter().sum::<f64>() / tip.len().max(1) as f64
}

/// A multilevel static solve on a pool of `threads` threads.
#[cfg(feature = "rayon")]
fn solve_threads(
    model: &TetElastic<'_, StableNeoHookean>,
    (rest, masses, pinned): (&[Vec3], &[f64], &[bool]),
    threads: usize,
    tolerance: f64,
) -> Result<Solved, Box<dyn Error>> {
    use softfem::f64::mesh::{
        TetPartition, element_forces_len, partition_incident_len, partition_offsets_len,
    };
    use softfem::f64::parallel::ParallelTetElastic;
    let mesh = model.mesh;
    let (n, elements) = (mesh.vertex_count(), mesh.element_count());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let (mut offsets, mut incident) = (
        vec![0; partition_offsets_len(n)],
        vec![0; partition_incident_len(elements)],
    );
    // Four pieces per thread, as the `parallel` example.
    let partition = TetPartition::new(mesh, 4 * threads, &mut offsets, &mut incident)?;
    let (mut element_forces, mut energies) = (
        vec![[Vec3::ZERO; 4]; element_forces_len(elements)],
        vec![0.0; elements],
    );
    let body = ParallelTetElastic::new(*model, partition, &mut element_forces, &mut energies)?
        .with_pool(&pool);
    let len = scratch_len::newton(n, elements);
    let mut vectors = vec![Vec3::ZERO; len.vectors];
    let mut blocks = vec![Mat3::ZERO; len.blocks];
    let mut hessians = vec![TetHessian::default(); len.hessians];
    let scene = Scene::new(1.0).with_gravity(GRAVITY);
    let settings = NewtonSettings::new()
        .with_tolerance(tolerance, 50)
        .with_preconditioner(Preconditioner::Multilevel);
    let mut x = rest.to_vec();
    let (cpu, clock) = (process_cpu_seconds(), Instant::now());
    let report = newton_quasi_static(
        &body,
        masses,
        pinned,
        &scene,
        &settings,
        &mut x,
        &mut NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians),
    )?;
    let (wall, cpu) = (clock.elapsed().as_secs_f64(), process_cpu_seconds() - cpu);
    Ok(Solved {
        report,
        wall,
        cpu,
        x,
    })
}

/// Runs the peer on `mesh_path` with `flags`, printing its `RESULT` lines and its peak
/// resident memory (sampled every 10 ms while it runs).
fn run_peer(
    python: &std::ffi::OsStr,
    script: &std::ffi::OsStr,
    mesh_path: &Path,
    tolerance: f64,
    flags: &[&str],
) -> Result<(), Box<dyn Error>> {
    println!(
        "  peer: {} {} {}",
        python.to_string_lossy(),
        Path::new(script).display(),
        flags.join(" ")
    );
    let mut child = Command::new(python)
        .arg(script)
        .arg(mesh_path)
        .arg("--tol")
        .arg(format!("{tolerance:e}"))
        .args(flags)
        .envs([
            ("OMP_NUM_THREADS", "1"),
            ("MKL_NUM_THREADS", "1"),
            ("OPENBLAS_NUM_THREADS", "1"),
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .map_err(|e| {
            format!(
                "could not run the peer with {}: {e}",
                python.to_string_lossy()
            )
        })?;
    // Read its output on other threads while this one samples its memory.
    let take = |pipe: Option<Box<dyn std::io::Read + Send>>| {
        std::thread::spawn(move || {
            let mut text = String::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_string(&mut text);
            }
            text
        })
    };
    let stdout = take(child.stdout.take().map(|p| Box::new(p) as _));
    let stderr = take(child.stderr.take().map(|p| Box::new(p) as _));
    let pid = child.id().to_string();
    let mut peak: Option<f64> = None;
    let status = loop {
        if let Some(mb) = peak_resident_mb(&pid) {
            peak = Some(peak.map_or(mb, |p: f64| p.max(mb)));
        }
        if let Some(status) = child.try_wait()? {
            break status;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    let (stdout, stderr) = (
        stdout.join().unwrap_or_default(),
        stderr.join().unwrap_or_default(),
    );
    for line in stdout.lines() {
        println!("  {line}");
    }
    println!(
        "  RESULT skfem peak_rss_mb={} ({})",
        peak.map_or("unknown".to_string(), |mb| format!("{mb:.0}")),
        flags.join(" ")
    );
    if !status.success() {
        println!(
            "  peer failed ({status}): {}",
            stderr.lines().last().unwrap_or("")
        );
    }
    Ok(())
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
    if cfg!(not(feature = "rayon")) && !args.threads.is_empty() {
        return Err("--threads needs the `rayon` feature: cargo run --release -p softfem-examples --features rayon --bin cantilever".into());
    }
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
        let clock = thread_cpu_seconds();
        multilevel.build(&model, &hessians, &masses, 0.0, &pinned, &rest)?;
        let build = thread_cpu_seconds() - clock;
        let levels: Vec<String> = multilevel
            .level_sizes()
            .map(|(rows, entries)| format!("{rows} ({entries} entries)"))
            .collect();
        println!(
            "  hierarchy: build {build:.3} s CPU, levels {}",
            levels.join(", ")
        );
        // What one CG iteration costs: a V-cycle and a matrix-free Hessian product.
        let residual: Vec<Vec3> = pinned
            .iter()
            .map(|&p| if p { Vec3::ZERO } else { Vec3::ONE })
            .collect();
        let mut out = vec![Vec3::ZERO; vertices];
        let clock = thread_cpu_seconds();
        for _ in 0..10 {
            multilevel.apply(&residual, &mut out)?;
        }
        let cycle = (thread_cpu_seconds() - clock) / 10.0;
        let clock = thread_cpu_seconds();
        for _ in 0..10 {
            mesh.add_hessian_product(&hessians, &residual, &mut out)?;
        }
        let product = (thread_cpu_seconds() - clock) / 10.0;
        println!(
            "  one V-cycle {:.2} ms, one Hessian product {:.2} ms (CPU)",
            cycle * 1e3,
            product * 1e3
        );
        drop(multilevel);

        let mut preconditioners = vec![Preconditioner::Multilevel];
        if !args.no_block_jacobi {
            preconditioners.insert(0, Preconditioner::BlockJacobi);
        }
        #[cfg_attr(not(feature = "rayon"), allow(unused_variables, unused_mut))]
        #[cfg(feature = "rayon")]
        let mut multilevel_x: Vec<Vec3> = Vec::new();
        for preconditioner in preconditioners {
            let Solved {
                report,
                wall,
                cpu,
                x,
            } = solve(
                &model,
                (&rest, &masses, &pinned),
                preconditioner,
                args.tolerance,
            )?;
            println!(
                "  RESULT softfem {preconditioner:?} tets={elements} threads=1 newton={} cg={} cg_per_newton={:.1} builds={} \
                 wall_s={wall:.3} cpu_s={cpu:.3} converged={} residual={:.2e} tip_uz_mm={:.6}",
                report.iterations,
                report.details.cg_iterations,
                f64::from(report.details.cg_iterations) / f64::from(report.iterations.max(1)),
                report.details.multilevel_builds,
                report.converged,
                report.residual / report.initial_residual,
                tip(&rest, &x) * 1000.0
            );
            // The one-thread answer the threaded runs are compared with, bit for bit.
            #[cfg(feature = "rayon")]
            if preconditioner == Preconditioner::Multilevel {
                multilevel_x = x;
            }
            #[cfg(not(feature = "rayon"))]
            let _ = x;
        }
        #[cfg(feature = "rayon")]
        for &threads in &args.threads {
            let Solved {
                report,
                wall,
                cpu,
                x,
            } = solve_threads(&model, (&rest, &masses, &pinned), threads, args.tolerance)?;
            let same = x.len() == multilevel_x.len()
                && x.iter()
                    .zip(&multilevel_x)
                    .all(|(a, b)| a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits));
            println!(
                "  RESULT softfem Multilevel tets={elements} threads={threads} newton={} cg={} \
                 wall_s={wall:.3} process_cpu_s={cpu:.2} same_bits_as_one_thread={same}",
                report.iterations, report.details.cg_iterations,
            );
            if !same {
                return Err(
                    format!("{threads} threads: not the one-thread answer bit for bit").into(),
                );
            }
        }
        println!(
            "  RESULT softfem peak_rss_mb={}",
            peak_resident_mb("self").map_or("unknown".to_string(), |mb| format!("{mb:.0}"))
        );

        let mesh_path = out_dir.join(format!("cantilever-{elements}.txt"));
        write_mesh(&mesh_path, &rest, &tets)?;
        println!("  mesh written to {}", mesh_path.display());
        if let Some(script) = &peer {
            // The direct solvers (SuperLU only up to 200k tetrahedra, as PARDISO with it), then
            // the iterative ones, each run's memory apart.
            if elements <= 200_000 {
                run_peer(
                    &python,
                    script,
                    &mesh_path,
                    args.tolerance,
                    &["--direct", "1", "--amg", "0"],
                )?;
            }
            run_peer(
                &python,
                script,
                &mesh_path,
                args.tolerance,
                &["--direct", "0", "--amg", "1"],
            )?;
        }
    }
    Ok(())
}
