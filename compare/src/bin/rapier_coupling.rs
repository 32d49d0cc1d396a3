//! rapier owns the rigid bodies and their contacts, softfem owns the jelly: two-way coupling,
//! staggered one frame (issue #42, item 5; `docs/math.md` section 8.14 of the softfem crate).
//!
//! Two scenes, each frame of `1/60` s:
//! * **crate**: a rapier crate (a dynamic cuboid) dropped onto a softfem jelly that rests on the
//!   ground. The crate's pose and velocities become a softfem [`Collider`]; the jelly's step
//!   reports the [`Reaction`] on it (`Body::step_with_reactions`), which goes back to rapier as
//!   an impulse and an angular impulse about the crate's centre; then rapier steps.
//! * **chain**: a jelly hanging from a chain of rapier links (spherical joints from a fixed
//!   anchor), started off the vertical so that it swings. The jelly's top face is attached hard
//!   to the last link: its vertices are kinematic targets on the link's predicted pose, and the
//!   attachment's reaction (`Body::attachment_reaction`) goes back to the link.
//!
//! Writes, under `--out`: `crate.csv` and `chain.csv` (the rigid bodies' motion and the
//! coupling's impulses per frame), VTK frames of each jelly (`crate/`, `chain/`), and
//! `rapier_coupling.svg`, a filmstrip of both scenes. Prints the checks (the crate came to rest
//! on the jelly, the jelly carries its weight; the chain swings and the jelly stays attached)
//! and the frame times of each side.
//!
//!     cargo run --release --manifest-path compare/Cargo.toml --bin rapier_coupling

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Parser;
use rapier3d::prelude as rp;
use softfem::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};
use softfem::body::{Body, Solver, VecStorage};
use softfem::glam::{Quat, Vec3};
use softfem::material::StableNeoHookean;
use softfem::step::{Collider, HalfSpace, Reaction};

#[path = "../../../examples/bouncy/vtk.rs"]
#[allow(dead_code)]
mod vtk;

/// The frame (s).
const DT: f32 = 1.0 / 60.0;
const GRAVITY: f32 = 9.81;

#[derive(Parser, Debug)]
#[command(about = "A rapier crate on a softfem jelly and a jelly hanging from a rapier chain")]
struct Args {
    /// Simulated seconds of each scene.
    #[arg(long, default_value_t = 4.0)]
    duration: f32,

    /// Output directory (created if missing).
    #[arg(long, default_value = "target/compare/rapier_coupling")]
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

type Jelly = Body<VecStorage, StableNeoHookean>;

fn to_rapier(v: Vec3) -> rp::Vector {
    rp::Vector::new(v.x, v.y, v.z)
}

fn from_rapier(v: rp::Vector) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

fn rotation_of(body: &rp::RigidBody) -> Quat {
    let q = body.rotation();
    Quat::from_xyzw(q.x, q.y, q.z, q.w)
}

/// A rigid box as the filmstrip draws it: centre, half extents, rotation.
#[derive(Clone, Copy)]
struct Block {
    centre: Vec3,
    half: Vec3,
    rotation: Quat,
}

/// One panel of the filmstrip: the jelly's positions and the rigid boxes.
struct Panel {
    time: f32,
    jelly: Vec<Vec3>,
    blocks: Vec<Block>,
}

/// Frame times (s) of one side, CPU time of the process.
#[derive(Default)]
struct Times(Vec<f64>);

impl Times {
    fn summary(&self) -> String {
        let mut sorted = self.0.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
        let max = sorted.last().copied().unwrap_or(0.0);
        format!("median {:.3} ms, max {:.3} ms", median * 1e3, max * 1e3)
    }
}

/// CPU time of the whole process (s): `clock_gettime(CLOCK_PROCESS_CPUTIME_ID)`.
fn cpu_time() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid, writable timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) };
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

/// The jelly's boundary triangles (outward).
fn boundary(jelly: &Jelly) -> Result<Vec<[u32; 3]>, String> {
    let tets = jelly.tets();
    let mut scratch = vec![BoundaryFace::default(); boundary_scratch_len(tets.len())];
    let faces =
        boundary_faces(tets, jelly.vertex_count(), &mut scratch).map_err(|e| e.to_string())?;
    Ok(faces.iter().map(|f| f.triangle).collect())
}

/// Writes the jelly's frame `index` into `dir` as VTK (its boundary, each triangle with its
/// tetrahedron's volume ratio).
fn write_vtk(dir: &Path, index: usize, time: f32, jelly: &Jelly) -> Result<(), String> {
    let tets = jelly.tets();
    let mut scratch = vec![BoundaryFace::default(); boundary_scratch_len(tets.len())];
    let faces =
        boundary_faces(tets, jelly.vertex_count(), &mut scratch).map_err(|e| e.to_string())?;
    let volume = |x: &[Vec3], t: [u32; 4]| {
        let p = t.map(|i| x[i as usize]);
        (p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]) / 6.0
    };
    let ratios: Vec<f32> = faces
        .iter()
        .map(|f| {
            let t = tets[f.tet as usize];
            volume(jelly.positions(), t) / volume(jelly.rest_positions(), t)
        })
        .collect();
    let triangles: Vec<[u32; 3]> = faces.iter().map(|f| f.triangle).collect();
    let frame = vtk::Frame {
        title: "softfem jelly coupled with rapier",
        time: f64::from(time),
        positions: jelly.positions(),
        velocities: jelly.velocities(),
        cells: vtk::Cells::Triangles(&triangles),
        volume_ratios: &ratios,
    };
    vtk::write_frame_file(&dir.join(vtk::frame_file_name(index)), &frame).map_err(|e| e.to_string())
}

/// What a scene's run gives back.
struct SceneRun {
    panels: Vec<Panel>,
    /// Whether the scene has the ground `y = 0` (drawn grey).
    ground: bool,
    triangles: Vec<[u32; 3]>,
    softfem: Times,
    rapier: Times,
}

/// Panels at `count` instants evenly spread over the run.
fn panel_due(frame: usize, frames: usize, count: usize) -> bool {
    (0..count).any(|k| frame == k * (frames - 1) / (count - 1).max(1))
}

const PANELS: usize = 6;

/// The crate scene. Returns its panels and times; prints and checks its outcome.
fn crate_scene(frames: usize, out: &Path) -> Result<SceneRun, String> {
    // The jelly: 0.4 x 0.2 x 0.4 m, 50 kPa, on the ground y = 0.
    let material = StableNeoHookean::from_young_poisson(5.0e4, 0.45).map_err(|e| e.to_string())?;
    let (low, high) = (Vec3::new(-0.2, 0.0, -0.2), Vec3::new(0.2, 0.2, 0.2));
    let mut jelly =
        Jelly::from_box(low, high, [6, 3, 6], 1000.0, material).map_err(|e| e.to_string())?;
    jelly.set_gravity(Vec3::new(0.0, -GRAVITY, 0.0));
    jelly.set_ground(Some(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5)));
    jelly
        .set_solver(Solver::newton())
        .map_err(|e| e.to_string())?;
    let triangles = boundary(&jelly)?;

    // rapier: the ground and a 0.24 m crate of 400 kg/m^3 (5.5 kg), dropped from 0.3 m above
    // the jelly, turning a little.
    let half = Vec3::splat(0.12);
    let mut world = rp::PhysicsWorld::new();
    world.integration_parameters.dt = DT;
    world.insert(
        rp::RigidBodyBuilder::fixed().translation(rp::Vector::new(0.0, -0.5, 0.0)),
        rp::ColliderBuilder::cuboid(2.0, 0.5, 2.0),
    );
    let (crate_body, _) = world.insert(
        rp::RigidBodyBuilder::dynamic()
            .translation(rp::Vector::new(0.03, 0.62, 0.0))
            .angvel(rp::Vector::new(0.0, 0.0, 1.0)),
        rp::ColliderBuilder::cuboid(half.x, half.y, half.z).density(400.0),
    );
    let mass = world.bodies[crate_body].mass();
    let weight = mass * GRAVITY;

    let dir = out.join("crate");
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let mut csv = String::from("time,crate_y,crate_vy,force_on_crate_y,touching_vertices\n");
    let (mut panels, mut softfem_times, mut rapier_times) =
        (Vec::new(), Times::default(), Times::default());
    let mut reactions = [Reaction::ZERO];
    let mut forces = Vec::new();
    let mut lowest = f32::INFINITY;
    // The crate's speed from its motion over the last frame (m/s).
    let mut speed = f32::INFINITY;
    for frame in 0..frames {
        let body = &world.bodies[crate_body];
        let (centre, rotation) = (from_rapier(body.translation()), rotation_of(body));
        let crate_collider = Collider::cuboid(centre, half, rotation)
            .with_velocity(from_rapier(body.linvel()), from_rapier(body.angvel()))
            .with_friction(0.5);
        let time = frame as f32 * DT;
        if panel_due(frame, frames, PANELS) {
            panels.push(Panel {
                time,
                jelly: jelly.positions().to_vec(),
                blocks: vec![Block {
                    centre,
                    half,
                    rotation,
                }],
            });
        }
        if frame % 2 == 0 {
            write_vtk(&dir, frame / 2, time, &jelly)?;
        }

        let colliders = [crate_collider];
        let start = cpu_time();
        let report = jelly
            .step_with_reactions(&jelly.scene(DT).with_colliders(&colliders), &mut reactions)
            .map_err(|e| format!("softfem, frame {frame}: {e}"))?;
        softfem_times.0.push(cpu_time() - start);
        if !report.converged() {
            eprintln!("softfem: frame {frame} did not converge: {report:?}");
        }

        let body = &mut world.bodies[crate_body];
        body.apply_impulse(to_rapier(reactions[0].impulse), true);
        body.apply_torque_impulse(to_rapier(reactions[0].angular_impulse), true);
        let before = from_rapier(body.translation());
        let start = cpu_time();
        world.step();
        rapier_times.0.push(cpu_time() - start);

        let body = &world.bodies[crate_body];
        let (y, vy) = (body.translation().y, body.linvel().y);
        speed = (from_rapier(body.translation()) - before).length() / DT;
        lowest = lowest.min(y);
        let force = reactions[0].force(DT).y;
        forces.push(force);
        let _ = writeln!(
            csv,
            "{:.5},{y:.6},{vy:.6},{force:.4},{}",
            time + DT,
            reactions[0].vertices
        );
        if !(y.is_finite() && vy.is_finite()) {
            return Err(format!(
                "the crate left the finite numbers at frame {frame}"
            ));
        }
    }
    std::fs::write(out.join("crate.csv"), csv).map_err(|e| e.to_string())?;

    // The checks: the crate rests on the jelly, which carries its weight.
    let y = world.bodies[crate_body].translation().y;
    let last = (frames / 4).max(1);
    let mean_force = forces[frames - last..].iter().sum::<f32>() / last as f32;
    let jelly_top = jelly
        .positions()
        .iter()
        .map(|x| x.y)
        .fold(f32::MIN, f32::max);
    println!(
        "crate: {mass:.2} kg dropped from 0.62 m; lowest {lowest:.3} m, at the end {y:.3} m moving \
         {speed:.3} m/s; the jelly's top at {jelly_top:.3} m; mean force of the jelly on the crate \
         over the last {:.2} s {mean_force:.2} N (weight {weight:.2} N)",
        last as f32 * DT
    );
    let resting = speed < 0.01 && (mean_force - weight).abs() < 0.02 * weight;
    if frames as f32 * DT >= 3.0 && !resting {
        return Err("the crate did not come to rest on the jelly".into());
    }
    Ok(SceneRun {
        panels,
        ground: true,
        triangles,
        softfem: softfem_times,
        rapier: rapier_times,
    })
}

/// The chain scene.
fn chain_scene(frames: usize, out: &Path) -> Result<SceneRun, String> {
    // Three links of 0.04 x 0.2 x 0.04 m, 5000 kg/m^3 (1.6 kg each), from a fixed anchor at
    // 1.2 m, tilted 0.6 rad off the vertical about z.
    let (links, link_half, tilt) = (3, Vec3::new(0.02, 0.1, 0.02), 0.6f32);
    let anchor = Vec3::new(0.0, 1.2, 0.0);
    let rotation = Quat::from_rotation_z(tilt);
    let mut world = rp::PhysicsWorld::new();
    world.integration_parameters.dt = DT;
    let fixed = world.insert_body(rp::RigidBodyBuilder::fixed().translation(to_rapier(anchor)));
    let mut previous = fixed;
    let mut handles = Vec::new();
    for k in 0..links {
        let centre = anchor + rotation * Vec3::new(0.0, -(2 * k + 1) as f32 * link_half.y, 0.0);
        let (handle, _) = world.insert(
            rp::RigidBodyBuilder::dynamic()
                .translation(to_rapier(centre))
                .rotation(rp::Vector::new(0.0, 0.0, tilt)),
            rp::ColliderBuilder::cuboid(link_half.x, link_half.y, link_half.z).density(5000.0),
        );
        // The joint at the top of link k: the anchor's origin, or the bottom of link k - 1.
        let above = if k == 0 {
            Vec3::ZERO
        } else {
            Vec3::new(0.0, -link_half.y, 0.0)
        };
        let joint = rp::SphericalJointBuilder::new()
            .local_anchor1(to_rapier(above))
            .local_anchor2(to_rapier(Vec3::new(0.0, link_half.y, 0.0)));
        world.insert_impulse_joint(previous, handle, joint);
        handles.push(handle);
        previous = handle;
    }
    let last = previous;

    // The jelly: a 0.1 m cube of 20 kPa (1 kg) under the last link, built upright then turned
    // with the chain; its top face attached to the link.
    let material = StableNeoHookean::from_young_poisson(2.0e4, 0.45).map_err(|e| e.to_string())?;
    let (low, high) = (Vec3::new(-0.05, -0.1, -0.05), Vec3::new(0.05, 0.0, 0.05));
    let mut jelly =
        Jelly::from_box(low, high, [4; 3], 1000.0, material).map_err(|e| e.to_string())?;
    jelly.set_gravity(Vec3::new(0.0, -GRAVITY, 0.0));
    jelly
        .set_solver(Solver::newton())
        .map_err(|e| e.to_string())?;
    let triangles = boundary(&jelly)?;
    let bottom = anchor + rotation * Vec3::new(0.0, -2.0 * links as f32 * link_half.y, 0.0);
    for x in jelly.positions_mut() {
        *x = bottom + rotation * *x;
    }
    let link = &world.bodies[last];
    let (link_centre, link_rotation) = (from_rapier(link.translation()), rotation_of(link));
    let top: Vec<u32> = (0..jelly.vertex_count() as u32)
        .filter(|&i| jelly.rest_positions()[i as usize].y == 0.0)
        .collect();
    // Each attached vertex in the link's frame.
    let local: Vec<Vec3> = top
        .iter()
        .map(|&i| link_rotation.inverse() * (jelly.positions()[i as usize] - link_centre))
        .collect();

    let centre_of =
        |jelly: &Jelly| jelly.positions().iter().sum::<Vec3>() / jelly.vertex_count() as f32;
    let rest_hang = (centre_of(&jelly) - link_centre).length();
    let dir = out.join("chain");
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let mut csv =
        String::from("time,link_x,link_y,jelly_centre_x,jelly_centre_y,force_on_link_y\n");
    let (mut panels, mut softfem_times, mut rapier_times) =
        (Vec::new(), Times::default(), Times::default());
    let (mut leftmost, mut rightmost) = (f32::INFINITY, f32::NEG_INFINITY);
    let mut stretch_worst: f32 = 0.0;
    for frame in 0..frames {
        let time = frame as f32 * DT;
        if panel_due(frame, frames, PANELS) {
            let blocks = handles
                .iter()
                .map(|&h| {
                    let b = &world.bodies[h];
                    Block {
                        centre: from_rapier(b.translation()),
                        half: link_half,
                        rotation: rotation_of(b),
                    }
                })
                .collect();
            panels.push(Panel {
                time,
                jelly: jelly.positions().to_vec(),
                blocks,
            });
        }
        if frame % 2 == 0 {
            write_vtk(&dir, frame / 2, time, &jelly)?;
        }
        // The link's pose at the end of the frame, predicted from its velocities.
        let link = &world.bodies[last];
        let spin = from_rapier(link.angvel());
        let centre = from_rapier(link.translation()) + from_rapier(link.linvel()) * DT;
        let turn = Quat::from_scaled_axis(spin * DT);
        let pose = (turn * rotation_of(link)).normalize();
        for (&i, &l) in top.iter().zip(&local) {
            jelly
                .set_target(i as usize, centre + pose * l)
                .map_err(|e| e.to_string())?;
        }
        let start = cpu_time();
        let report = jelly
            .step_with_reactions(&jelly.scene(DT), &mut [])
            .map_err(|e| format!("softfem, frame {frame}: {e}"))?;
        softfem_times.0.push(cpu_time() - start);
        if !report.converged() {
            eprintln!("softfem: frame {frame} did not converge: {report:?}");
        }
        let reaction = jelly
            .attachment_reaction(&top, centre)
            .map_err(|e| e.to_string())?;
        let link = &mut world.bodies[last];
        link.apply_impulse(to_rapier(reaction.impulse), true);
        link.apply_torque_impulse(to_rapier(reaction.angular_impulse), true);
        let start = cpu_time();
        world.step();
        rapier_times.0.push(cpu_time() - start);

        let link_at = from_rapier(world.bodies[last].translation());
        let jelly_centre = centre_of(&jelly);
        leftmost = leftmost.min(jelly_centre.x);
        rightmost = rightmost.max(jelly_centre.x);
        // How far the jelly's centre is from the link's, against the distance at rest.
        let hang = (jelly_centre - centre).length();
        stretch_worst = stretch_worst.max((hang / rest_hang - 1.0).abs());
        let _ = writeln!(
            csv,
            "{:.5},{:.6},{:.6},{:.6},{:.6},{:.4}",
            time + DT,
            link_at.x,
            link_at.y,
            jelly_centre.x,
            jelly_centre.y,
            reaction.force(DT).y
        );
        if !jelly_centre.is_finite() || !link_at.is_finite() {
            return Err(format!(
                "the chain left the finite numbers at frame {frame}"
            ));
        }
    }
    std::fs::write(out.join("chain.csv"), csv).map_err(|e| e.to_string())?;
    println!(
        "chain: the jelly swung between x = {leftmost:.3} and {rightmost:.3} m; its centre stayed within \
         {:.1} % of its distance at rest from the link's centre",
        stretch_worst * 100.0
    );
    if frames as f32 * DT >= 2.0 && (rightmost - leftmost < 0.2 || stretch_worst > 0.2) {
        return Err("the jelly did not swing on the chain as it should".into());
    }
    Ok(SceneRun {
        panels,
        ground: false,
        triangles,
        softfem: softfem_times,
        rapier: rapier_times,
    })
}

fn run(args: &Args) -> Result<(), String> {
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 60.0) {
        return Err(format!("--duration {} is not in (0, 60] s", args.duration));
    }
    let frames = ((args.duration / DT).round() as usize).max(2);
    std::fs::create_dir_all(&args.out).map_err(|e| e.to_string())?;
    let crate_run = crate_scene(frames, &args.out)?;
    let chain_run = chain_scene(frames, &args.out)?;
    for (name, run) in [("crate", &crate_run), ("chain", &chain_run)] {
        println!(
            "{name}: frame times (CPU) softfem {}, rapier {}",
            run.softfem.summary(),
            run.rapier.summary()
        );
    }
    let svg = filmstrip(&[
        ("A rapier crate dropped on a softfem jelly", &crate_run),
        ("A softfem jelly hanging from a rapier chain", &chain_run),
    ]);
    let path = args.out.join("rapier_coupling.svg");
    std::fs::write(&path, svg).map_err(|e| e.to_string())?;
    println!("wrote {}", path.display());
    Ok(())
}

/// The filmstrip: one row per scene, one panel per instant, a side view (looking along -z, x to
/// the right, y up), the faces drawn back to front and shaded by their normal.
fn filmstrip(rows: &[(&str, &SceneRun)]) -> String {
    let (panel, gap, margin, title) = (200.0f32, 10.0f32, 14.0f32, 26.0f32);
    let columns = rows.iter().map(|(_, r)| r.panels.len()).max().unwrap_or(1) as f32;
    let width = 2.0 * margin + columns * panel + (columns - 1.0) * gap;
    let row_height = title + panel + 18.0;
    let height = 40.0 + rows.len() as f32 * row_height;
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0}" height="{height:.0}" viewBox="0 0 {width:.0} {height:.0}" font-family="Helvetica, Arial, sans-serif">"#
    );
    let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        svg,
        r#"<text x="{margin}" y="24" font-size="16" font-weight="bold">softfem jelly, rapier rigid bodies: two-way coupling, 1/60 s frames</text>"#
    );
    let light = Vec3::new(-0.4, 0.8, 0.6).normalize();
    for (r, (name, run)) in rows.iter().enumerate() {
        let top = 40.0 + r as f32 * row_height;
        let _ = writeln!(
            svg,
            r#"<text x="{margin}" y="{:.1}" font-size="13">{name}</text>"#,
            top + 16.0
        );
        // One scale for the row: every panel's points.
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &run.panels {
            for &x in p
                .jelly
                .iter()
                .chain(p.blocks.iter().flat_map(corners).collect::<Vec<_>>().iter())
            {
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
        if run.ground {
            lo.y = lo.y.min(0.0);
        }
        let extent = (hi.x - lo.x).max(hi.y - lo.y).max(1e-3) * 1.1;
        let scale = (panel - 2.0 * margin) / extent;
        let mid = (lo + hi) / 2.0;
        for (c, p) in run.panels.iter().enumerate() {
            let left = margin + c as f32 * (panel + gap);
            let ox = left + panel / 2.0;
            let oy = top + title + panel / 2.0;
            let to = |x: Vec3| ((ox + (x.x - mid.x) * scale), (oy - (x.y - mid.y) * scale));
            let _ = writeln!(
                svg,
                r##"<rect x="{left:.1}" y="{:.1}" width="{panel}" height="{panel}" fill="#f6f6f6"/>"##,
                top + title
            );
            let (_, ground) = to(Vec3::ZERO);
            if run.ground && ground <= top + title + panel && ground >= top + title {
                let _ = writeln!(
                    svg,
                    r##"<rect x="{left:.1}" y="{ground:.1}" width="{panel}" height="{:.1}" fill="#d8d8d8"/>"##,
                    top + title + panel - ground
                );
            }
            // Every face: (depth, points, colour).
            let mut faces: Vec<(f32, Vec<Vec3>, Vec3)> = Vec::new();
            for t in &run.triangles {
                let q = t.map(|i| p.jelly[i as usize]);
                faces.push((0.0, q.to_vec(), Vec3::new(224.0, 52.0, 96.0)));
            }
            for b in &p.blocks {
                let k = corners(b);
                for face in [
                    [0, 2, 3, 1],
                    [4, 5, 7, 6],
                    [0, 1, 5, 4],
                    [2, 6, 7, 3],
                    [0, 4, 6, 2],
                    [1, 3, 7, 5],
                ] {
                    let colour = if p.blocks.len() == 1 {
                        Vec3::new(176.0, 122.0, 64.0)
                    } else {
                        Vec3::new(120.0, 128.0, 140.0)
                    };
                    faces.push((0.0, face.iter().map(|&i| k[i]).collect(), colour));
                }
            }
            let mut drawn: Vec<(f32, String)> = Vec::new();
            for (_, points, colour) in &faces {
                let normal = (points[1] - points[0]).cross(points[2] - points[0]);
                if normal.z <= 0.0 {
                    continue; // facing away from the camera (which looks along -z)
                }
                let shade = 0.35 + 0.65 * normal.normalize().dot(light).max(0.0);
                let c = *colour * shade;
                let depth = points.iter().map(|x| x.z).sum::<f32>() / points.len() as f32;
                let mut path = String::new();
                for (k, &x) in points.iter().enumerate() {
                    let (sx, sy) = to(x);
                    let _ = write!(path, "{}{sx:.1},{sy:.1} ", if k == 0 { "M" } else { "L" });
                }
                drawn.push((
                    depth,
                    format!(
                        r#"<path d="{path}Z" fill="rgb({:.0},{:.0},{:.0})" stroke="rgb({:.0},{:.0},{:.0})" stroke-width="0.4"/>"#,
                        c.x, c.y, c.z, c.x, c.y, c.z
                    ),
                ));
            }
            drawn.sort_by(|a, b| a.0.total_cmp(&b.0));
            for (_, element) in drawn {
                let _ = writeln!(svg, "{element}");
            }
            let _ = writeln!(
                svg,
                r##"<text x="{:.1}" y="{:.1}" font-size="11" fill="#444" text-anchor="middle">t = {:.2} s</text>"##,
                left + panel / 2.0,
                top + title + panel + 13.0,
                p.time
            );
        }
    }
    let _ = writeln!(svg, "</svg>");
    svg
}

/// A box's eight corners: bit 0 of the index is +x, bit 1 +y, bit 2 +z.
fn corners(b: &Block) -> Vec<Vec3> {
    (0..8)
        .map(|i| {
            let s = Vec3::new(
                if i & 1 == 1 { 1.0 } else { -1.0 },
                if i & 2 == 2 { 1.0 } else { -1.0 },
                if i & 4 == 4 { 1.0 } else { -1.0 },
            );
            b.centre + b.rotation * (s * b.half)
        })
        .collect()
}
