//! `cargo run --release -p softfem-examples --bin asset`: from a game asset to a soft body and
//! back.
//!
//! Takes a closed triangle surface (a procedural long-eared creature, or any OBJ with
//! `--surface`), voxel-meshes it into tetrahedra (`softfem::asset::voxel`), embeds the surface's
//! vertices in the tetrahedra (`softfem::asset::embed`), drops the body on the ground with the jelly of
//! the bouncy scene (stable neo-Hookean, E = 50 kPa, nu = 0.45, 1000 kg/m^3, explicit steps at
//! half the stable bound), and every frame deforms the detailed surface from the simulated one:
//! OBJ files with normals (`frame_0000.obj`, ...) and a filmstrip SVG of the render surface,
//! plus the undeformed asset as `surface.obj`.

mod creature;
// The bouncy scene's filmstrip drawing, shared as is; this scene records at a fixed frame
// interval, so the bouncy scene's frame-interval setter goes unused here.
#[path = "../bouncy/filmstrip.rs"]
#[allow(dead_code)]
mod filmstrip;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;

use filmstrip::{Camera, Filmstrip, Recorder};
use softfem::asset::embed::{Embedding, embed_points_vec};
use softfem::asset::obj::{read_obj_file, write_obj_file};
use softfem::asset::surface::vertex_normals;
use softfem::asset::voxel::{VoxelGrid, VoxelOptions, voxel_mesh};
use softfem::element::TetRest;
use softfem::glam::Vec3;
use softfem::material::StableNeoHookean;
use softfem::mesh::TetMesh;
use softfem::step::{
    ExplicitScratch, ExplicitSettings, HalfSpace, Scene, TetElastic, explicit_step, scratch_len,
    stable_time_step,
};

/// Gravity (m/s^2) along -z.
const GRAVITY: Vec3 = Vec3::new(0.0, 0.0, -9.81);
/// The jelly of the bouncy scene.
const YOUNG_MODULUS: f32 = 5.0e4;
const POISSON_RATIO: f32 = 0.45;
const DENSITY: f32 = 1000.0;
/// Mass-proportional damping (1/s) and ground friction, as in the bouncy scene.
const DAMPING: f32 = 0.5;
const FRICTION: f32 = 0.6;
/// Explicit steps at this fraction of the stable bound.
const SAFETY_FRACTION: f32 = 0.5;

/// Drop a voxel-meshed asset on the ground and write its deformed render surface.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Args {
    /// Simulated time (s).
    #[arg(long, default_value_t = 2.0)]
    duration: f32,

    /// A closed OBJ surface to use instead of the procedural creature (coordinates in metres).
    #[arg(long)]
    surface: Option<PathBuf>,

    /// Voxel cells along the longest side of the surface's bounding box.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(2..=100))]
    cells: u32,

    /// The fraction of a cell (sampled at 3 x 3 x 3 points) that must lie inside the surface for
    /// the cell to be kept. Small values keep the cells the surface passes through, so the
    /// render surface lies inside the simulated body and does not sink into the ground.
    #[arg(long, default_value_t = 0.1)]
    coverage: f32,

    /// Height of the body's lowest point above the ground at the start (m).
    #[arg(long, default_value_t = 0.3)]
    drop_height: f32,

    /// Output frames per simulated second.
    #[arg(long, default_value_t = 30.0)]
    frame_rate: f32,

    /// Panels of the filmstrip.
    #[arg(long, default_value_t = 6)]
    panels: u32,

    /// Output directory (created if missing).
    #[arg(long, default_value = "out/asset")]
    out: PathBuf,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: &Args) -> Result<(), String> {
    if !(args.duration > 0.0 && args.frame_rate > 0.0 && args.drop_height >= 0.0) {
        return Err("--duration and --frame-rate must be positive, --drop-height >= 0".into());
    }
    let (source, mut surface, triangles) = match &args.surface {
        Some(path) => {
            let obj = read_obj_file(path).map_err(|e| e.to_string())?;
            (path.display().to_string(), obj.positions, obj.triangles)
        }
        None => {
            let (positions, triangles) = creature::creature(3);
            ("procedural creature".to_string(), positions, triangles)
        }
    };
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    // The asset as meshed, before it is placed: `assets/meshes/creature.obj` is this file.
    write_obj_file(args.out.join("surface.obj"), &surface, &triangles, None)
        .map_err(|e| e.to_string())?;
    // Lift the surface so that its lowest point is at the drop height.
    let lowest = surface.iter().map(|x| x.z).fold(f32::INFINITY, f32::min);
    surface
        .iter_mut()
        .for_each(|x| x.z += args.drop_height - lowest);
    println!(
        "surface   {source}: {} vertices, {} triangles",
        surface.len(),
        triangles.len()
    );

    let started = Instant::now();
    let grid = VoxelGrid::with_resolution(&surface, args.cells as usize)
        .map_err(|e| format!("voxel grid: {e}"))?;
    let options = VoxelOptions {
        samples_per_axis: 3,
        min_coverage: args.coverage,
        remove_hanging: true,
    };
    let body = voxel_mesh(&surface, &triangles, &grid, &options)
        .map_err(|e| format!("voxel meshing {source}: {e}"))?;
    println!(
        "voxels    {} x {} x {} cells of {:.4} m: {} vertices, {} tetrahedra ({:.1} ms)",
        grid.cells[0],
        grid.cells[1],
        grid.cells[2],
        grid.cell_size,
        body.positions.len(),
        body.tets.len(),
        started.elapsed().as_secs_f64() * 1e3
    );
    if body.tets.is_empty() {
        return Err("the surface is thinner than a cell everywhere: use more --cells".into());
    }

    // Centre sampling leaves the surface up to a cell diagonal outside the voxels.
    let margin = grid.cell_size * 3f32.sqrt();
    let started = Instant::now();
    let embedded = embed_points_vec(&body.positions, &body.tets, &surface, margin)
        .map_err(|e| format!("embedding the surface: {e}"))?;
    let embedding =
        Embedding::new(&embedded, &body.tets, body.positions.len()).map_err(|e| e.to_string())?;
    let outside = embedded
        .iter()
        .filter(|e| e.weights.iter().any(|&w| w < 0.0))
        .count();
    println!(
        "embedded  {} surface vertices ({} just outside the voxels, margin {margin:.4} m) in {:.1} ms",
        surface.len(),
        outside,
        started.elapsed().as_secs_f64() * 1e3
    );

    let mut rest = vec![TetRest::default(); body.tets.len()];
    let mesh = TetMesh::new(&body.positions, &body.tets, &mut rest).map_err(|e| e.to_string())?;
    let mut masses = vec![0.0; body.positions.len()];
    mesh.lumped_masses(DENSITY, &mut masses)
        .map_err(|e| e.to_string())?;
    let jelly = StableNeoHookean::from_young_poisson(YOUNG_MODULUS, POISSON_RATIO)
        .map_err(|e| e.to_string())?;
    let model = TetElastic::new(mesh, jelly);
    let mut stiffness = vec![0.0; body.positions.len()];
    let bound = stable_time_step(&model, &masses, &[], &mut stiffness)
        .map_err(|e| format!("stable time step: {e}"))?;
    let dt = SAFETY_FRACTION * bound;
    println!(
        "jelly     stable neo-Hookean, E = {YOUNG_MODULUS} Pa, nu = {POISSON_RATIO}, {DENSITY} kg/m^3, mass {:.3} kg",
        masses.iter().sum::<f32>()
    );
    println!("stepper   explicit, dt {dt:.3e} s (stable bound {bound:.3e} s)");

    let scene = Scene::new(dt)
        .with_gravity(GRAVITY)
        .with_ground(HalfSpace::new(Vec3::Z, 0.0).with_friction(FRICTION));
    let settings = ExplicitSettings::new().with_damping(DAMPING);
    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(body.positions.len())];
    let mut scratch = ExplicitScratch::new(&mut buffer);
    let mut positions = body.positions.clone();
    let mut velocities = vec![Vec3::ZERO; positions.len()];
    let mut render = surface.clone();
    let mut normals = vec![Vec3::ZERO; surface.len()];

    let frame_interval = 1.0 / f64::from(args.frame_rate);
    let mut recorder = Recorder::new(
        args.panels as usize,
        f64::from(args.duration),
        frame_interval,
    );
    let steps = (f64::from(args.duration) / f64::from(dt)).ceil() as u64;
    let mut next_frame = 0.0f64;
    let mut frames = 0usize;
    let mut deform_time = 0.0f64;
    let mut lowest_render = f32::INFINITY;
    let started = Instant::now();
    for step in 0..=steps {
        let time = step as f64 * f64::from(dt);
        if time + 1e-9 >= next_frame {
            let deform_started = Instant::now();
            embedding
                .deform(&positions, &mut render)
                .map_err(|e| e.to_string())?;
            vertex_normals(&render, &triangles, &mut normals).map_err(|e| e.to_string())?;
            deform_time += deform_started.elapsed().as_secs_f64();
            lowest_render = render.iter().map(|x| x.z).fold(lowest_render, f32::min);
            let path = args.out.join(format!("frame_{frames:04}.obj"));
            write_obj_file(&path, &render, &triangles, Some(&normals))
                .map_err(|e| e.to_string())?;
            recorder.offer(time, &render);
            frames += 1;
            next_frame += frame_interval;
        }
        if step == steps {
            break;
        }
        explicit_step(
            &model,
            &masses,
            &[],
            &scene,
            &settings,
            &mut positions,
            &mut velocities,
            &mut scratch,
        )
        .map_err(|e| format!("step {step}: {e}"))?;
    }
    let wall = started.elapsed().as_secs_f64();
    let per_vertex = deform_time * 1e9 / (frames * surface.len()) as f64;
    println!(
        "simulated {} s in {steps} steps, {wall:.2} s wall; {frames} frames, deform + normals {per_vertex:.1} ns per render vertex",
        args.duration
    );
    println!(
        "          lowest render point {lowest_render:.4} m (the simulated vertices stop at 0)"
    );

    let snapshots = recorder.snapshots();
    let title = format!(
        "softfem asset: {source}, voxel-meshed and embedded, E = {} kPa, ν = {POISSON_RATIO}",
        YOUNG_MODULUS / 1000.0
    );
    let subtitle = format!(
        "{} render triangles over {} tets ({} cells along the longest side)",
        triangles.len(),
        body.tets.len(),
        args.cells
    );
    let svg = Filmstrip {
        title: &title,
        subtitle: &subtitle,
        triangles: &triangles,
        snapshots: &snapshots,
        camera: Camera::default(),
    }
    .to_svg();
    let path = args.out.join("filmstrip.svg");
    std::fs::write(&path, svg).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    println!(
        "wrote     {frames} OBJ frames ({}) and {}",
        args.out.join("frame_0000.obj").display(),
        path.display()
    );
    Ok(())
}
