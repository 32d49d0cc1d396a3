//! What a run will cost, estimated before it starts: memory, VTK output, steps and wall time,
//! and the limits above which the scene asks for `--yes` instead of starting.
//!
//! The rates are measured with this example (release build, one core of a shared 2-core AMD
//! EPYC under load): peak resident memory 47 MB at 320 000 tetrahedra, 142 MB at 1.08 million and
//! 573 MB at 5 million, which 110 B per tetrahedron and 150 B per vertex (mesh, rest data, state,
//! scratch, the filmstrip's snapshots and the surface's face table while it is built) match
//! within 25 % (46, 153 and 705 MB estimated); 66 ns per tetrahedron and step (explicit) and per
//! tetrahedron and iteration (relaxation) at 40 000 tetrahedra, 72 to 76 ns at 320 000 and 1.08
//! million once the setup is taken off (the estimate takes 90 ns), and 8 to 11 us per tetrahedron
//! of setup (building, checking, surface, masses, filmstrip); ASCII VTK frames of about 68 B per
//! vertex and 30 B per tetrahedron (35 B per surface triangle): the default scene writes 91
//! frames of 56.2 kB on average, 5.12 MB (the rates give 5.07 MB). Relaxation iterations per step
//! grow with the mesh: 21, 47 and 120 on cubes of 6, 10 and 20 cells per edge, fitted by
//! `6 (tets / 5)^(1/3)`.

use softfem::generate::{BoxSplit, box_counts};

use crate::cli::{Args, Stepper, VtkContent};

/// Bytes of memory per tetrahedron and per vertex.
const MEMORY_BYTES: (f64, f64) = (110.0, 150.0);
/// Wall time per tetrahedron and step (explicit) or iteration (relaxation), in seconds.
const SECONDS_PER_TET_PASS: f64 = 9e-8;
/// Newton's cost per step in tetrahedron passes at [`SECONDS_PER_TET_PASS`]: 2.2 to 3.2 ms per
/// step on the default jelly cube (1080 tets, 1.4 Newton and 7 CG iterations per step; two
/// runs at different loads) is 23 to 33 of them.
const NEWTON_PASSES_PER_STEP: f64 = 30.0;
/// VBD's, likewise: 3.6 ms per step on the default cube (6.6 sweeps per step, with the
/// estimated Chebyshev `rho`) was 37 passes; with the fixed `rho` now 4.5 sweeps per step, in
/// proportion about 25.
const VBD_PASSES_PER_STEP: f64 = 25.0;
/// Wall time per tetrahedron (s) of building and checking the mesh, its surface and masses,
/// and drawing the filmstrip.
const SETUP_SECONDS_PER_TET: f64 = 1e-5;
/// VTK bytes per vertex, per tetrahedron and per surface triangle.
const VTK_BYTES: (f64, f64, f64) = (68.0, 30.0, 35.0);

/// Above any of these the scene asks for `--yes`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Memory (bytes).
    pub memory_bytes: f64,
    /// VTK output (bytes).
    pub output_bytes: f64,
    /// Steps of the stepper.
    pub steps: u64,
    /// Wall time (s).
    pub wall_seconds: f64,
}

/// The scene's limits: 2 GiB of memory, 1 GiB of VTK files, a million steps, a minute.
pub const LIMITS: Limits = Limits {
    memory_bytes: 2.0 * (1u64 << 30) as f64,
    output_bytes: (1u64 << 30) as f64,
    steps: 1_000_000,
    wall_seconds: 60.0,
};

/// The sizes an estimate needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshSize {
    /// Vertices.
    pub vertices: usize,
    /// Tetrahedra.
    pub tets: usize,
    /// Boundary triangles.
    pub surface_triangles: usize,
}

impl MeshSize {
    /// The jelly cube of `cells` per edge split by `split`, counted without building it.
    pub fn jelly_cube(cells: usize, split: BoxSplit) -> Result<MeshSize, String> {
        let (vertices, tets) =
            box_counts(cells, cells, cells, split).map_err(|e| format!("jelly cube: {e}"))?;
        Ok(MeshSize {
            vertices,
            tets,
            surface_triangles: 12 * cells * cells,
        })
    }
}

/// The estimated cost of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Peak memory (bytes).
    pub memory_bytes: f64,
    /// VTK files written.
    pub vtk_files: u64,
    /// Their size (bytes).
    pub vtk_bytes: f64,
    /// Steps, once the time step is known.
    pub steps: Option<u64>,
    /// Wall time (s), once the time step is known.
    pub wall_seconds: Option<f64>,
}

impl Estimate {
    /// The run `args` describe on a mesh of `size`, with `frames` output frames and, if known,
    /// `steps` steps.
    pub fn new(args: &Args, size: MeshSize, frames: u64, steps: Option<u64>) -> Estimate {
        let (vertices, tets) = (size.vertices as f64, size.tets as f64);
        let vtk_files = match args.vtk_every {
            0 => 0,
            every => frames.div_ceil(u64::from(every)),
        };
        let cells = match args.vtk {
            VtkContent::Volume => VTK_BYTES.1 * tets,
            VtkContent::Surface => VTK_BYTES.2 * size.surface_triangles as f64,
        };
        let passes_per_step = match args.stepper {
            Stepper::Explicit => 1.0,
            Stepper::Relax => 6.0 * (tets / 5.0).cbrt(),
            Stepper::Newton => NEWTON_PASSES_PER_STEP,
            Stepper::Vbd => VBD_PASSES_PER_STEP,
        };
        Estimate {
            memory_bytes: MEMORY_BYTES.0 * tets + MEMORY_BYTES.1 * vertices,
            vtk_files,
            vtk_bytes: vtk_files as f64 * (VTK_BYTES.0 * vertices + cells),
            steps,
            wall_seconds: steps.map(|steps| {
                (steps as f64 * passes_per_step * SECONDS_PER_TET_PASS + SETUP_SECONDS_PER_TET)
                    * tets
            }),
        }
    }

    /// One line: "about 3.1 MB of memory, 91 VTK files (5.1 MB), 8054 steps in about 0.8 s".
    pub fn describe(&self) -> String {
        let mut text = format!(
            "about {} of memory, {} VTK files ({})",
            bytes(self.memory_bytes),
            self.vtk_files,
            bytes(self.vtk_bytes)
        );
        if let (Some(steps), Some(seconds)) = (self.steps, self.wall_seconds) {
            text += &format!(", {steps} steps in about {}", duration(seconds));
        }
        text
    }

    /// What exceeds `limits`, one phrase each.
    pub fn excesses(&self, limits: &Limits) -> Vec<String> {
        let mut over = Vec::new();
        if self.memory_bytes > limits.memory_bytes {
            over.push(format!(
                "{} of memory (limit {})",
                bytes(self.memory_bytes),
                bytes(limits.memory_bytes)
            ));
        }
        if self.vtk_bytes > limits.output_bytes {
            over.push(format!(
                "{} of VTK files (limit {}; --vtk-every N or --vtk surface write less)",
                bytes(self.vtk_bytes),
                bytes(limits.output_bytes)
            ));
        }
        if let Some(steps) = self.steps.filter(|&steps| steps > limits.steps) {
            over.push(format!("{steps} steps (limit {})", limits.steps));
        }
        if let Some(seconds) = self.wall_seconds.filter(|&s| s > limits.wall_seconds) {
            over.push(format!(
                "about {} of wall time (limit {})",
                duration(seconds),
                duration(limits.wall_seconds)
            ));
        }
        over
    }

    /// `Ok` if the run is within [`LIMITS`] or `yes` (the `--yes` flag) is set; otherwise the
    /// message that tells the user what is too big and how to go ahead. `hint` is appended.
    pub fn check(&self, yes: bool, hint: &str) -> Result<(), String> {
        let over = self.excesses(&LIMITS);
        if over.is_empty() || yes {
            return Ok(());
        }
        Err(format!(
            "this run would need {}{hint}; pass --yes to run it anyway",
            over.join(", ")
        ))
    }
}

/// `bytes` as "512 B", "3.1 MB", "5.6 GB" (powers of 1000).
pub fn bytes(bytes: f64) -> String {
    match bytes {
        b if b < 1e3 => format!("{b:.0} B"),
        b if b < 1e6 => format!("{:.1} kB", b / 1e3),
        b if b < 1e9 => format!("{:.1} MB", b / 1e6),
        b if b < 1e12 => format!("{:.1} GB", b / 1e9),
        b => format!("{:.1} TB", b / 1e12),
    }
}

/// `seconds` as "0.8 s", "12 min", "2.3 h".
pub fn duration(seconds: f64) -> String {
    match seconds {
        s if s < 120.0 => format!("{s:.1} s"),
        s if s < 7200.0 => format!("{:.0} min", s / 60.0),
        s => format!("{:.1} h", s / 3600.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    fn args(flags: &[&str]) -> Args {
        Args::try_parse_from(std::iter::once("bouncy").chain(flags.iter().copied())).unwrap()
    }

    #[test]
    fn jelly_cube_counts_match_the_generator() {
        let size = MeshSize::jelly_cube(6, BoxSplit::Alternating5).unwrap();
        assert_eq!(
            (size.vertices, size.tets, size.surface_triangles),
            (343, 1080, 432)
        );
    }

    /// The default scene is well inside the limits; `--resolution 200` (40 million tetrahedra)
    /// is refused for its memory and output before anything is built, unless `--yes`.
    #[test]
    fn huge_runs_are_refused_without_yes() {
        let small = Estimate::new(
            &args(&[]),
            MeshSize::jelly_cube(6, BoxSplit::Alternating5).unwrap(),
            91,
            Some(8054),
        );
        assert!(small.excesses(&LIMITS).is_empty(), "{small:?}");
        assert!(small.check(false, "").is_ok());
        // 91 files of 343 * 68 + 1080 * 30 bytes: 5.07 MB (5.12 MB written).
        assert!((small.vtk_bytes - 91.0 * (343.0 * 68.0 + 1080.0 * 30.0)).abs() < 1.0);

        let flags = ["--resolution", "200"];
        let size = MeshSize::jelly_cube(200, BoxSplit::Alternating5).unwrap();
        let huge = Estimate::new(&args(&flags), size, 91, None);
        let message = huge.check(false, "").unwrap_err();
        assert!(message.contains("of memory (limit 2.1 GB)"), "{message}");
        assert!(message.contains("GB of VTK files"), "{message}");
        assert!(message.contains("pass --yes"), "{message}");
        assert!(huge.check(true, "").is_ok());
        // 40 million tets at 110 B and 8.1 million vertices at 150 B: 5.6 GB.
        assert!((huge.memory_bytes / 1e9 - 5.6).abs() < 0.05, "{huge:?}");
        // Without VTK files only the memory is too much.
        let quiet = Estimate::new(&args(&["--vtk-every", "0"]), size, 91, None);
        assert_eq!(quiet.vtk_files, 0);
        assert_eq!(quiet.excesses(&LIMITS).len(), 1);
    }

    #[test]
    fn long_runs_are_refused_by_steps_and_time() {
        let size = MeshSize::jelly_cube(6, BoxSplit::Alternating5).unwrap();
        let long = Estimate::new(&args(&[]), size, 91, Some(5_600_000));
        let over = long.excesses(&LIMITS);
        assert_eq!(over.len(), 2, "{over:?}");
        assert!(
            over[0].contains("5600000 steps (limit 1000000)"),
            "{over:?}"
        );
        // 5.6e6 steps * 1080 tets * 90 ns (+ 1080 * 10 us of setup): 544 s.
        assert!(over[1].contains("about 9 min of wall time"), "{over:?}");
    }

    #[test]
    fn units_read_well() {
        assert_eq!(bytes(512.0), "512 B");
        assert_eq!(bytes(3.1e6), "3.1 MB");
        assert_eq!(bytes(5.6e9), "5.6 GB");
        assert_eq!(duration(0.83), "0.8 s");
        assert_eq!(duration(720.0), "12 min");
        assert_eq!(duration(8280.0), "2.3 h");
    }
}
