//! Command-line flags of the bouncy scene, with defaults and validation.
//!
//! clap turns every bad flag into a readable message and exit status 2; the value parsers here
//! add the physical ranges (a Poisson ratio must lie in (-1, 0.5), a density must be positive...).

use std::fmt;
use std::path::PathBuf;

use clap::{Parser, ValueEnum};
use softfem::generate::BoxSplit;

/// A soft body dropped onto the ground: it bounces, wobbles and settles.
///
/// Writes VTK frames (open them in ParaView) and an SVG filmstrip of the body at a few instants
/// into the output directory.
#[derive(Clone, Debug, Parser)]
#[command(name = "bouncy", version, allow_negative_numbers = true)]
pub struct Args {
    /// Hyperelastic material model.
    #[arg(long, value_enum, default_value_t = Model::StableNeoHookean)]
    pub model: Model,

    /// Time stepper: explicit symplectic Euler, or implicit Euler solved by preconditioned
    /// gradient descent ("relax"), Newton's method ("newton") or Vertex Block Descent ("vbd").
    #[arg(long, value_enum, default_value_t = Stepper::Explicit)]
    pub stepper: Stepper,

    /// Time step (s). Default: a safe fraction of the stable bound for explicit, 1/60 s for the
    /// implicit steppers (relax, newton, vbd).
    #[arg(long, value_parser = positive_finite)]
    pub dt: Option<f32>,

    /// Simulated time (s).
    #[arg(long, default_value_t = 3.0, value_parser = positive_finite_f64)]
    pub duration: f64,

    /// Cells per axis of the generated jelly cube (5 or 6 tetrahedra per cell, see --split);
    /// ignored with --mesh.
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..=200))]
    pub resolution: u32,

    /// How each cell of the jelly cube is split into tetrahedra; ignored with --mesh.
    #[arg(long, value_enum, default_value_t = Split::Alternating5)]
    pub split: Split,

    /// Edge length of the generated jelly cube (m); ignored with --mesh.
    #[arg(long, default_value_t = 0.2, value_parser = positive_finite)]
    pub size: f32,

    /// Height of the body's lowest point above the ground at the start (m).
    #[arg(long, default_value_t = 0.5, value_parser = non_negative_finite)]
    pub drop_height: f32,

    /// A TetGen mesh to drop instead of the jelly cube: the .node file, with the .ele file
    /// next to it (same name). Coordinates are taken as metres.
    #[arg(long, value_name = "PATH.node")]
    pub mesh: Option<PathBuf>,

    /// The ground's sticking speed for the implicit steppers (m/s, >= 0): positive puts the
    /// ground's Coulomb friction into the step's objective (`softfem::step::HalfSpace::
    /// sticking_speed`), 0 applies it to the velocity after each solve. Default: the library's.
    #[arg(long, value_parser = non_negative_finite)]
    pub sticking_speed: Option<f32>,

    /// Young's modulus (Pa).
    #[arg(long, visible_alias = "young", default_value_t = 5.0e4, value_parser = positive_finite)]
    pub young_modulus: f32,

    /// Poisson ratio, in (-1, 0.5).
    #[arg(long, visible_alias = "poisson", default_value_t = 0.45, value_parser = poisson_ratio)]
    pub poisson_ratio: f32,

    /// Density (kg/m^3).
    #[arg(long, default_value_t = 1000.0, value_parser = positive_finite)]
    pub density: f32,

    /// Output frames per simulated second (VTK files and filmstrip candidates).
    #[arg(long, default_value_t = 30.0, value_parser = positive_finite_f64)]
    pub frame_rate: f64,

    /// Write a VTK file every N output frames (0: no VTK files). Frame files of an earlier run
    /// in the output directory that this run did not write are removed.
    #[arg(long, default_value_t = 1)]
    pub vtk_every: u32,

    /// What the VTK files contain: the whole tetrahedral mesh or only its boundary surface.
    #[arg(long, value_enum, default_value_t = VtkContent::Volume)]
    pub vtk: VtkContent,

    /// Panels of the SVG filmstrip (instants evenly spaced from start to end).
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..=24))]
    pub panels: u32,

    /// Output directory (created if missing).
    #[arg(long, default_value = "out/bouncy")]
    pub out: PathBuf,

    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,

    /// Run even when the estimate printed before the run exceeds the scene's limits: 2 GiB
    /// of memory, 1 GiB of VTK files, a million steps or a minute of wall time.
    #[arg(long)]
    pub yes: bool,
}

/// The hyperelastic models of `softfem::material`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Model {
    /// Saint Venant–Kirchhoff (cheapest; softens under strong compression).
    #[value(name = "stvk")]
    StVK,
    /// The isochoric neo-Hookean (barrier at J = 0).
    NeoHookean,
    /// Stable neo-Hookean (smooth through inversion).
    StableNeoHookean,
}

impl fmt::Display for Model {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Model::StVK => "StVK",
            Model::NeoHookean => "neo-Hookean",
            Model::StableNeoHookean => "stable neo-Hookean",
        })
    }
}

/// The cell splits of `softfem::generate::BoxSplit`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Split {
    /// 5 tetrahedra per cell, alternating between neighbours: the mesh keeps the cube's
    /// half turns (and mirrors at even --resolution), so a flat drop lands where it fell.
    #[value(name = "alternating5")]
    Alternating5,
    /// 6 tetrahedra per cell around the diagonal (1, 1, 1) (Kuhn): not mirror-symmetric, and
    /// its nearly incompressible response is anisotropic; a flat drop tips it, and with
    /// friction it walks along (-1, -1) (0.08 m per axis in the first second).
    #[value(name = "kuhn6")]
    Kuhn6,
}

impl Split {
    /// The library's split.
    pub fn box_split(self) -> BoxSplit {
        match self {
            Split::Alternating5 => BoxSplit::Alternating5,
            Split::Kuhn6 => BoxSplit::Kuhn6,
        }
    }
}

/// The time steppers of `softfem::step`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Stepper {
    /// Explicit symplectic Euler.
    Explicit,
    /// Implicit Euler by preconditioned gradient descent.
    Relax,
    /// Implicit Euler by Newton's method (projected Hessian, conjugate gradients).
    Newton,
    /// Implicit Euler by Vertex Block Descent (per-vertex Newton steps, Gauss–Seidel order).
    Vbd,
}

impl fmt::Display for Stepper {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stepper::Explicit => "explicit",
            Stepper::Relax => "relax",
            Stepper::Newton => "newton",
            Stepper::Vbd => "vbd",
        })
    }
}

/// What goes into each VTK file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum VtkContent {
    /// Every tetrahedron (cell type 10), with per-tet volume ratio.
    Volume,
    /// The boundary triangles (cell type 5), each with its tetrahedron's volume ratio.
    Surface,
}

fn parse_number(text: &str) -> Result<f32, String> {
    text.trim()
        .parse::<f32>()
        .map_err(|_| format!("`{text}` is not a number"))
}

fn positive_finite(text: &str) -> Result<f32, String> {
    let value = parse_number(text)?;
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(format!("must be a positive finite number, got {text}"))
    }
}

/// As [`positive_finite`], in f64: times are kept in f64 so that `--duration 0.2` ends at 0.2 s,
/// not at the f32 nearest it.
fn positive_finite_f64(text: &str) -> Result<f64, String> {
    positive_finite(text)?;
    Ok(text.trim().parse::<f64>().unwrap_or(f64::NAN))
}

fn non_negative_finite(text: &str) -> Result<f32, String> {
    let value = parse_number(text)?;
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(format!("must be a finite number >= 0, got {text}"))
    }
}

fn poisson_ratio(text: &str) -> Result<f32, String> {
    let value = parse_number(text)?;
    // nu = 1/2 is incompressible (infinite lambda); nu <= -1 has a non-positive bulk modulus.
    if value > -1.0 && value < 0.5 {
        Ok(value)
    } else {
        Err(format!(
            "the Poisson ratio must lie strictly between -1 and 0.5, got {text}"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(flags: &[&str]) -> Result<Args, clap::Error> {
        Args::try_parse_from(std::iter::once("bouncy").chain(flags.iter().copied()))
    }

    #[test]
    fn defaults_describe_the_jelly_cube() {
        let args = parse(&[]).unwrap();
        assert_eq!(args.model, Model::StableNeoHookean);
        assert_eq!(args.stepper, Stepper::Explicit);
        assert_eq!(args.resolution, 6);
        assert_eq!(args.split, Split::Alternating5);
        assert_eq!((args.size, args.drop_height), (0.2, 0.5));
        assert_eq!(
            (args.young_modulus, args.poisson_ratio, args.density),
            (5.0e4, 0.45, 1000.0)
        );
        assert_eq!(args.duration, 3.0);
        assert_eq!(args.dt, None);
        assert_eq!(args.out, PathBuf::from("out/bouncy"));
        assert!(args.mesh.is_none());
    }

    #[test]
    fn flags_parse() {
        let args = parse(&[
            "--model",
            "stvk",
            "--stepper",
            "relax",
            "--dt",
            "0.01",
            "--poisson",
            "-0.2",
            "--mesh",
            "assets/meshes/cube.node",
        ])
        .unwrap();
        assert_eq!(args.model, Model::StVK);
        assert_eq!(args.stepper, Stepper::Relax);
        assert_eq!(args.dt, Some(0.01));
        assert_eq!(args.poisson_ratio, -0.2);
        assert_eq!(args.mesh, Some(PathBuf::from("assets/meshes/cube.node")));
    }

    #[test]
    fn every_stepper_parses_and_prints_its_flag_name() {
        for (name, stepper) in [
            ("explicit", Stepper::Explicit),
            ("relax", Stepper::Relax),
            ("newton", Stepper::Newton),
            ("vbd", Stepper::Vbd),
        ] {
            let args = parse(&["--stepper", name]).unwrap();
            assert_eq!(args.stepper, stepper);
            assert_eq!(stepper.to_string(), name);
        }
        let error = parse(&["--stepper", "newtons"]).unwrap_err().to_string();
        assert!(error.contains("newton") && error.contains("vbd"), "{error}");
    }

    /// The README's text about the scene, paragraph by paragraph: its section (from "**Run the
    /// main example scene**" to the next "**Run") and every other paragraph naming `bouncy` or
    /// "the scene", with each fenced block and each code span that is a command of another
    /// program left out (`cargo`, `sudo`, `apt-get`, `rustup`, after any `NAME=value`
    /// environment settings: those hold that program's flags).
    fn readme_scene_text() -> Vec<String> {
        let readme = include_str!("../../README.md");
        let marker = "**Run the main example scene**";
        let start = readme.find(marker).expect("the README's scene section");
        let (before, from_section) = readme.split_at(start);
        let end = from_section[marker.len()..].find("**Run").unwrap() + marker.len();
        let (section, after) = from_section.split_at(end);
        let others = before.split("\n\n").chain(after.split("\n\n"));
        let others = others.filter(|text| text.contains("bouncy") || text.contains("the scene"));
        section
            .split("\n\n")
            .chain(others)
            .map(|paragraph| {
                // Fenced blocks are either commands (cargo's flags) or listings (the layout's
                // file names), never the scene's flags.
                let unfenced: String = paragraph.split("```").step_by(2).collect();
                let segments = unfenced.split('`').enumerate().filter(|(i, segment)| {
                    let code = segment.trim_start().trim_start_matches("sh").trim_start();
                    // A command may start with environment settings (`NAME=value cargo ...`).
                    let program_word = code
                        .split_whitespace()
                        .find(|word| !word.contains('='))
                        .unwrap_or("");
                    let command = ["cargo", "sudo", "apt-get", "rustup"].contains(&program_word);
                    i % 2 == 0 || !command
                });
                let kept: Vec<&str> = segments.map(|(_, segment)| segment).collect();
                kept.join("`").replace('\n', " ")
            })
            .collect()
    }

    /// Every `--flag` the README mentions for the scene is one of the CLI's names or aliases,
    /// and every `` `--flag value | value` `` span it shows parses, so the two cannot drift
    /// apart.
    #[test]
    fn every_flag_the_readme_names_exists() {
        use clap::CommandFactory;
        let mut command = Args::command();
        command.build();
        let known: Vec<String> = command
            .get_arguments()
            .flat_map(|arg| {
                let aliases = arg.get_all_aliases().into_iter().flatten();
                arg.get_long().into_iter().chain(aliases)
            })
            .map(|name| format!("--{name}"))
            .collect();
        let text = readme_scene_text();
        let mut flags = Vec::new();
        for paragraph in &text {
            let words = paragraph.split(|c: char| c.is_whitespace() || "`(),;".contains(c));
            flags.extend(words.filter(|word| {
                word.strip_prefix("--")
                    .is_some_and(|name| name.starts_with(|c: char| c.is_ascii_lowercase()))
            }));
        }
        for flag in &flags {
            assert!(
                known.iter().any(|k| k == flag),
                "README names {flag}, which the CLI lacks"
            );
        }
        assert!(flags.len() >= 10, "only {flags:?} found in the README");
        for paragraph in &text {
            for span in paragraph.split('`').skip(1).step_by(2) {
                let mut tokens = span.split_whitespace();
                let Some(flag) = tokens
                    .next()
                    .filter(|t| t.starts_with("--") && *t != "--help")
                else {
                    continue;
                };
                for value in tokens.filter(|token| *token != "|") {
                    let parsed = parse(&[flag, value]);
                    assert!(
                        parsed.is_ok(),
                        "README: `{flag} {value}`: {}",
                        parsed.unwrap_err()
                    );
                }
            }
        }
    }

    /// clap suggests the nearest flag for a misspelt one.
    #[test]
    fn misspelt_flags_get_a_suggestion() {
        let error = parse(&["--poison-ratio", "0.3"]).unwrap_err().to_string();
        assert!(
            error.contains("tip: a similar argument exists: '--poisson-ratio'"),
            "{error}"
        );
        let error = parse(&["--durration", "1"]).unwrap_err().to_string();
        assert!(error.contains("'--duration'"), "{error}");
    }

    #[test]
    fn short_names_are_aliases_of_the_long_ones() {
        let long = parse(&["--young-modulus", "7e4", "--poisson-ratio", "0.3"]).unwrap();
        let short = parse(&["--young", "7e4", "--poisson", "0.3"]).unwrap();
        assert_eq!((long.young_modulus, long.poisson_ratio), (7e4, 0.3));
        assert_eq!((short.young_modulus, short.poisson_ratio), (7e4, 0.3));
    }

    #[test]
    fn bad_values_are_rejected_with_the_reason() {
        for (flags, reason) in [
            (&["--poisson", "0.5"][..], "strictly between -1 and 0.5"),
            (&["--poisson", "-1"][..], "strictly between -1 and 0.5"),
            (&["--young", "0"][..], "positive finite"),
            (&["--density", "nan"][..], "positive finite"),
            (&["--dt", "-0.1"][..], "positive finite"),
            (&["--drop-height", "-1"][..], "finite number >= 0"),
            (&["--duration", "abc"][..], "not a number"),
            (&["--resolution", "0"][..], "resolution"),
            (&["--model", "rubber"][..], "rubber"),
        ] {
            let error = parse(flags).unwrap_err().to_string();
            assert!(error.contains(reason), "{flags:?}: {error}");
        }
    }
}
