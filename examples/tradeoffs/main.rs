//! `cargo run --release -p softfem-examples --features charts --bin tradeoffs`: speed against
//! accuracy, measured.
//!
//! Each chart measures one trade-off and writes an SVG chart and the CSV of the numbers behind it
//! into the output directory: `target/tradeoffs/` by default (a scratch folder), or, with
//! `--update-docs`, the committed `docs/charts/` that the guide embeds:
//!
//! | chart | what it measures |
//! |---|---|
//! | `svd` | SVD error against ns per decomposition, 1..6 sweeps, f32/f64, nalgebra for reference |
//! | `forces` | force error against an f64 reference vs ns per tet: direct/principal, f32/f64, each model |
//! | `integrators` | trajectory error of a swinging bar vs wall time per simulated second, explicit and relaxation |
//! | `stability` | largest stable explicit step (bisection and eigenvalues) over the bound across E and nu; relaxation at the same steps |
//! | `inversion` | volume ratio over time of a tet and a block driven through inversion and released, per model |
//! | `convergence` | cantilever tip deflection against Euler–Bernoulli vs mesh resolution (5/6-tet splits), with its cost |
//! | `descent` | residual against wall time and iterations for GD (P = c I), GD plain, GD + Chebyshev, VBD and Newton on three scenes |
//!
//! `--quick` runs every chart at a reduced size (CI) and is refused with `--update-docs` or an
//! `--out` inside `docs/`, so the reduced run never replaces the committed charts; `--only NAME`
//! runs some of them. The run prints its progress and, at the end, the findings in numbers.
//!
//! `--static-scale` runs instead the static-solve scale check (no chart): a 10 800-tet
//! quasi-static cantilever solved by Newton to relative residual 1e-8, and what the
//! relaxation reaches in the same time, into `static_scale.csv` (with `--quick`: 400 tets).

// `single.rs` and `double.rs` each include `body.rs` against their own precision, as the crate
// does with its numeric modules.
#![allow(clippy::duplicate_mod)]

mod chart;
mod convergence;
mod descent;
mod double;
mod forces;
mod integrators;
mod inversion;
mod measure;
mod single;
mod stability_map;
mod static_scale;
mod svd;

#[path = "../common/paths.rs"]
mod paths;

use paths::{absolute, docs_dir, repository_root};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, ValueEnum};

/// Where the charts go unless `--out` or `--update-docs` says otherwise, relative to the
/// repository (not the current directory, which may be `docs/` itself): a scratch folder.
const DEFAULT_OUT: &str = "target/tradeoffs";

/// Measures speed against accuracy and writes SVG charts and their CSV files.
#[derive(Clone, Debug, Parser)]
#[command(name = "tradeoffs")]
pub struct Args {
    /// Output directory (created if missing) [default: target/tradeoffs of the repository]. The
    /// committed charts are regenerated only by `--update-docs` (or an explicit
    /// `--out docs/charts`).
    #[arg(long)]
    pub out: Option<PathBuf>,

    /// Write into the repository's docs/charts/, the charts the guide embeds (a full run only).
    #[arg(long, conflicts_with_all = ["out", "quick"])]
    pub update_docs: bool,

    /// Reduced sizes and repetitions: a smoke run for CI (well under a minute). Refused with an
    /// output directory inside docs/.
    #[arg(long)]
    pub quick: bool,

    /// Run only these charts (repeatable); default: all.
    #[arg(long, value_enum)]
    pub only: Vec<ChartName>,

    /// Run only the static-solve scale check (a 10 800-tet cantilever, Newton against the
    /// relaxation in the same time) into static_scale.csv; no chart.
    #[arg(long, conflicts_with_all = ["update_docs", "only"])]
    pub static_scale: bool,
}

/// The charts, in the order they run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ChartName {
    Svd,
    Forces,
    Integrators,
    Stability,
    Inversion,
    Convergence,
    Descent,
}

impl ChartName {
    const ALL: [ChartName; 7] = [
        ChartName::Svd,
        ChartName::Forces,
        ChartName::Integrators,
        ChartName::Stability,
        ChartName::Inversion,
        ChartName::Convergence,
        ChartName::Descent,
    ];

    fn run(self, size: Size, out: &Path) -> Result<Findings, String> {
        match self {
            ChartName::Svd => svd::run(size, out),
            ChartName::Forces => forces::run(size, out),
            ChartName::Integrators => integrators::run(size, out),
            ChartName::Stability => stability_map::run(size, out),
            ChartName::Inversion => inversion::run(size, out),
            ChartName::Convergence => convergence::run(size, out),
            ChartName::Descent => descent::run(size, out),
        }
    }
}

/// How much work each chart does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Size {
    /// `--quick`: small meshes, few repetitions.
    Quick,
    /// The default: what `docs/charts/` holds.
    Full,
}

/// What a chart found, in numbers, for the closing summary (and the guide).
#[derive(Clone, Debug)]
pub struct Findings {
    chart: &'static str,
    lines: Vec<String>,
}

impl Findings {
    pub fn new(chart: &'static str) -> Findings {
        Findings {
            chart,
            lines: Vec::new(),
        }
    }

    pub fn line(&mut self, line: String) {
        self.lines.push(line);
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    match tradeoffs(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

impl Args {
    /// The directory the charts are written into, or why this run may not write anywhere: a
    /// `--quick` run into `docs/` would replace the committed charts with the reduced ones.
    fn output_dir(&self, cwd: &Path) -> Result<PathBuf, String> {
        let out = match (&self.out, self.update_docs) {
            (_, true) => docs_dir().join("charts"),
            (Some(out), false) => absolute(out, cwd),
            (None, false) => repository_root().join(DEFAULT_OUT),
        };
        if self.quick && out.starts_with(absolute(&docs_dir(), cwd)) {
            return Err(format!(
                "--quick writes reduced charts; it may not write into {} (the committed charts). \
                 Leave out --out (it writes into {DEFAULT_OUT}), or make a full run with \
                 --update-docs",
                out.display()
            ));
        }
        Ok(out)
    }
}

fn tradeoffs(args: &Args) -> Result<(), String> {
    let cwd = std::env::current_dir().map_err(|e| format!("no current directory: {e}"))?;
    let out = args.output_dir(&cwd)?;
    std::fs::create_dir_all(&out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let size = if args.quick { Size::Quick } else { Size::Full };
    if args.static_scale {
        println!(
            "tradeoffs: the static-solve scale check, writing into {}",
            out.display()
        );
        let findings = static_scale::run(size, &out)?;
        for line in &findings.lines {
            println!("  {line}");
        }
        return Ok(());
    }
    let charts: Vec<ChartName> = if args.only.is_empty() {
        ChartName::ALL.to_vec()
    } else {
        ChartName::ALL
            .into_iter()
            .filter(|c| args.only.contains(c))
            .collect()
    };
    println!(
        "tradeoffs: {} chart(s), {} size, writing into {}",
        charts.len(),
        if args.quick { "quick" } else { "full" },
        out.display()
    );
    let started = Instant::now();
    let mut all = Vec::new();
    for chart in charts {
        let chart_started = Instant::now();
        println!("{chart:?}:");
        let findings = chart
            .run(size, &out)
            .map_err(|e| format!("{chart:?}: {e}"))?;
        println!("  done in {:.1} s", chart_started.elapsed().as_secs_f64());
        all.push(findings);
    }
    println!(
        "\nfindings ({:.1} s in all):",
        started.elapsed().as_secs_f64()
    );
    for findings in &all {
        println!("{}:", findings.chart);
        for line in &findings.lines {
            println!("  {line}");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_parse() {
        let args = Args::try_parse_from([
            "tradeoffs",
            "--quick",
            "--only",
            "svd",
            "--only",
            "inversion",
            "--out",
            "x",
        ])
        .unwrap();
        assert!(args.quick);
        assert_eq!(args.only, vec![ChartName::Svd, ChartName::Inversion]);
        assert_eq!(args.out, Some(PathBuf::from("x")));
        assert!(Args::try_parse_from(["tradeoffs", "--only", "nothing"]).is_err());
    }

    #[test]
    fn by_default_nothing_is_written_into_docs() {
        let root = repository_root();
        let docs = root.join("docs");
        // From the repository root (where `cargo run` is usually typed) and from docs/ itself.
        for cwd in [root.to_path_buf(), docs.clone()] {
            for args in [&["tradeoffs"][..], &["tradeoffs", "--quick"]] {
                let out = Args::try_parse_from(args)
                    .unwrap()
                    .output_dir(&cwd)
                    .unwrap();
                assert!(
                    !out.starts_with(&docs),
                    "{args:?} in {cwd:?} writes into {out:?}"
                );
            }
        }
        let defaults = Args::try_parse_from(["tradeoffs"]).unwrap();
        assert_eq!(
            defaults.output_dir(root).unwrap(),
            root.join("target/tradeoffs")
        );
    }

    #[test]
    fn only_an_explicit_full_run_regenerates_the_committed_charts() {
        let root = repository_root();
        let charts = root.join("docs/charts");
        let update = Args::try_parse_from(["tradeoffs", "--update-docs"]).unwrap();
        assert_eq!(update.output_dir(Path::new("/")).unwrap(), charts);
        let explicit = Args::try_parse_from(["tradeoffs", "--out", "docs/charts"]).unwrap();
        assert_eq!(explicit.output_dir(root).unwrap(), charts);
        // The reduced run is refused wherever it would land inside docs/.
        for out in [
            "docs/charts",
            "./docs/charts/",
            "target/../docs/charts",
            "docs",
        ] {
            let quick = Args::try_parse_from(["tradeoffs", "--quick", "--out", out]).unwrap();
            assert!(
                quick.output_dir(root).is_err(),
                "--quick --out {out} accepted"
            );
        }
        assert!(Args::try_parse_from(["tradeoffs", "--quick", "--update-docs"]).is_err());
        assert!(Args::try_parse_from(["tradeoffs", "--out", "x", "--update-docs"]).is_err());
    }
}
