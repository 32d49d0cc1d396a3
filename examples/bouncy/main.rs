//! `cargo run --release --example bouncy`: a soft jelly cube (or any TetGen mesh, `--mesh`)
//! dropped onto the ground.
//!
//! Today this builds the scene from the flags, validates the mesh and material, and writes the
//! initial state: `frame_0000.vtk` (ParaView) and `filmstrip.svg` in the output directory. The
//! time loop (`scene::run`) is written and tested; it is driven once `softfem::step` lands, and
//! until then nothing here pretends to move the body.

mod cli;
mod filmstrip;
// The time loop (`scene::run`, `RunConfig`, `StepInfo`...), the progress bar and the summary are
// tested but not called until `softfem::step` drives them; these two allows go then.
#[allow(dead_code)]
mod progress;
#[allow(dead_code)]
mod scene;
mod surface;
mod vtk;

use std::path::Path;
use std::process::ExitCode;

use clap::Parser;

use cli::{Args, VtkContent};
use filmstrip::{Camera, Filmstrip, Recorder};
use scene::{AnyMaterial, Body, FrameView, Geometry, State};
use softfem::element::TetRest;

fn main() -> ExitCode {
    let args = Args::parse(); // bad flags: clap prints the reason and exits with status 2
    match bouncy(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn bouncy(args: &Args) -> Result<(), String> {
    let geometry = Geometry::from_args(args)?;
    let mut rest = Vec::<TetRest>::new();
    let body = Body::new(&geometry, &mut rest, args.density)?;
    let material = AnyMaterial::new(args.model, args.young_modulus, args.poisson_ratio)?;
    let state = State::at_rest(&geometry);

    println!(
        "body      {}: {} vertices, {} tetrahedra, {} surface triangles",
        geometry.source,
        body.mesh.vertex_count(),
        body.mesh.element_count(),
        body.surface.len()
    );
    if geometry.reoriented > 0 || geometry.dropped_vertices > 0 {
        println!(
            "          {} tetrahedra reoriented, {} unused vertices dropped",
            geometry.reoriented, geometry.dropped_vertices
        );
    }
    println!(
        "material  {}, E = {} Pa, nu = {}, density {} kg/m^3, mass {:.3} kg",
        args.model,
        args.young_modulus,
        args.poisson_ratio,
        args.density,
        body.total_mass()
    );
    let h_min = body.shortest_edge(&geometry.rest_positions);
    println!(
        "          shortest edge {h_min:.4} m, wave speed {:.1} m/s",
        material.wave_speed(args.density)
    );
    println!(
        "drop      lowest point {} m above the ground, {} s simulated",
        args.drop_height, args.duration
    );

    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let mut writer = FrameWriter::new(args, &body);
    let mut recorder = Recorder::new(
        args.panels as usize,
        f64::from(args.duration),
        1.0 / f64::from(args.frame_rate),
    );
    let initial = FrameView {
        index: 0,
        step: 0,
        time: 0.0,
        positions: &state.positions,
        velocities: &state.velocities,
    };
    writer.write(&initial)?;
    recorder.offer(0.0, &state.positions);
    writer.finish()?;

    let title = format!(
        "softfem bouncy: {}, {} stepper, E = {} kPa, ν = {}",
        args.model,
        args.stepper,
        args.young_modulus / 1000.0,
        args.poisson_ratio
    );
    let subtitle = format!(
        "{}; {} tets; ρ = {} kg/m³; initial state only (time stepping arrives with softfem::step)",
        geometry.source,
        body.mesh.element_count(),
        args.density
    );
    write_filmstrip(&args.out, &title, &subtitle, &body, &recorder)?;

    let energies = body.energies(&material, &state.positions, &state.velocities)?;
    println!(
        "energy    {:.4} J (gravity {:.4} J, elastic {:.4} J, kinetic {:.4} J)",
        energies.total(),
        energies.potential,
        energies.elastic,
        energies.kinetic
    );
    println!(
        "wrote     {} (VTK: ParaView) and {}",
        args.out.join(vtk::frame_file_name(0)).display(),
        args.out.join("filmstrip.svg").display()
    );
    println!("time stepping arrives with softfem::step: this run wrote the initial state only");
    Ok(())
}

/// Writes the VTK frames (every `--vtk-every`-th output frame) and, at the end, the series file.
struct FrameWriter<'a> {
    args: &'a Args,
    body: &'a Body<'a>,
    written: Vec<(String, f64)>,
    ratios: Vec<f32>,
    surface_ratios: Vec<f32>,
}

impl<'a> FrameWriter<'a> {
    fn new(args: &'a Args, body: &'a Body<'a>) -> Self {
        FrameWriter {
            args,
            body,
            written: Vec::new(),
            ratios: Vec::new(),
            surface_ratios: Vec::new(),
        }
    }

    fn write(&mut self, frame: &FrameView<'_>) -> Result<(), String> {
        let every = self.args.vtk_every as usize;
        if every == 0 || frame.index % every != 0 {
            return Ok(());
        }
        self.body.volume_ratios(frame.positions, &mut self.ratios);
        let (cells, volume_ratios) = match self.args.vtk {
            VtkContent::Volume => (vtk::Cells::Tets(self.body.mesh.tets()), &self.ratios),
            VtkContent::Surface => {
                self.surface_ratios.clear();
                let owners = &self.body.surface.owners;
                self.surface_ratios
                    .extend(owners.iter().map(|&tet| self.ratios[tet as usize]));
                (
                    vtk::Cells::Triangles(&self.body.surface.triangles),
                    &self.surface_ratios,
                )
            }
        };
        let name = vtk::frame_file_name(self.written.len());
        let path = self.args.out.join(&name);
        let title = format!(
            "softfem bouncy, frame {}, t = {} s",
            frame.index, frame.time
        );
        vtk::write_frame_file(
            &path,
            &vtk::Frame {
                title: &title,
                time: frame.time,
                positions: frame.positions,
                velocities: frame.velocities,
                cells,
                volume_ratios,
            },
        )
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        self.written.push((name, frame.time));
        Ok(())
    }

    fn finish(&self) -> Result<(), String> {
        if self.written.is_empty() {
            return Ok(());
        }
        let path = self.args.out.join("frames.vtk.series");
        vtk::write_series_file(&path, &self.written)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))
    }
}

fn write_filmstrip(
    out: &Path,
    title: &str,
    subtitle: &str,
    body: &Body<'_>,
    recorder: &Recorder,
) -> Result<(), String> {
    let snapshots = recorder.snapshots();
    let svg = Filmstrip {
        title,
        subtitle,
        triangles: &body.surface.triangles,
        snapshots: &snapshots,
        camera: Camera::default(),
    }
    .to_svg();
    let path = out.join("filmstrip.svg");
    std::fs::write(&path, svg).map_err(|e| format!("cannot write {}: {e}", path.display()))
}
