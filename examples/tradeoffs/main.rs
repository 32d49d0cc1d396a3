//! `cargo run --release --example tradeoffs`: speed against accuracy, measured.
//!
//! Each chart measures one trade-off and writes an SVG chart and the CSV of the numbers behind it
//! into the output directory (`docs/charts/` by default, what the README embeds):
//!
//! | chart | what it measures |
//! |---|---|
//! | `svd` | SVD error against ns per decomposition, 1..6 sweeps, f32/f64, nalgebra for reference |
//! | `forces` | force error against an f64 reference vs ns per tet: direct/principal, f32/f64, each model |
//! | `integrators` | trajectory error of a swinging bar vs wall time per simulated second, explicit and relaxation |
//! | `stability` | largest stable explicit step (bisection and eigenvalues) over the bound across E and nu; relaxation at the same steps |
//! | `inversion` | volume ratio over time of a tet and a block driven through inversion and released, per model |
//! | `convergence` | cantilever tip deflection against Euler–Bernoulli vs mesh resolution (5/6-tet splits), with its cost |
//!
//! `--quick` runs every chart at a reduced size (CI); `--only NAME` runs some of them. The run
//! prints its progress and, at the end, the findings in numbers.

// `single.rs` and `double.rs` each include `body.rs` against their own precision, as the crate
// does with its numeric modules.
#![allow(clippy::duplicate_mod)]

mod chart;
mod convergence;
mod double;
mod forces;
mod integrators;
mod inversion;
mod measure;
mod single;
mod stability_map;
mod svd;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, ValueEnum};

/// Measures speed against accuracy and writes SVG charts and their CSV files.
#[derive(Clone, Debug, Parser)]
#[command(name = "tradeoffs")]
pub struct Args {
    /// Output directory (created if missing).
    #[arg(long, default_value = "docs/charts")]
    pub out: PathBuf,

    /// Reduced sizes and repetitions: a smoke run for CI (well under a minute).
    #[arg(long)]
    pub quick: bool,

    /// Run only these charts (repeatable); default: all.
    #[arg(long, value_enum)]
    pub only: Vec<ChartName>,
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
}

impl ChartName {
    const ALL: [ChartName; 6] = [
        ChartName::Svd,
        ChartName::Forces,
        ChartName::Integrators,
        ChartName::Stability,
        ChartName::Inversion,
        ChartName::Convergence,
    ];

    fn run(self, size: Size, out: &Path) -> Result<Findings, String> {
        match self {
            ChartName::Svd => svd::run(size, out),
            ChartName::Forces => forces::run(size, out),
            ChartName::Integrators => integrators::run(size, out),
            ChartName::Stability => stability_map::run(size, out),
            ChartName::Inversion => inversion::run(size, out),
            ChartName::Convergence => convergence::run(size, out),
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

/// What a chart found, in numbers, for the closing summary (and the README).
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

fn tradeoffs(args: &Args) -> Result<(), String> {
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let size = if args.quick { Size::Quick } else { Size::Full };
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
        args.out.display()
    );
    let started = Instant::now();
    let mut all = Vec::new();
    for chart in charts {
        let chart_started = Instant::now();
        println!("{chart:?}:");
        let findings = chart
            .run(size, &args.out)
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
        assert_eq!(args.out, PathBuf::from("x"));
        let defaults = Args::try_parse_from(["tradeoffs"]).unwrap();
        assert_eq!(defaults.out, PathBuf::from("docs/charts"));
        assert!(Args::try_parse_from(["tradeoffs", "--only", "nothing"]).is_err());
    }
}
