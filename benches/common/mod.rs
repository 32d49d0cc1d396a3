//! What the benchmarks share (included with `mod common;`): the deterministic input stream, the
//! round-robin minimum timing of the table pass, the command-line and quick-mode handling, and
//! the pieces of the markdown tables.

// Each bench crate compiles its own copy of this module and uses only part of it (the force
// benchmark draws no random indices), so the items one crate leaves unused would otherwise warn.
#![allow(dead_code)]

use std::time::Instant;

/// xorshift64* (Vigna 2016): deterministic, dependency-free, good enough for benchmark inputs.
pub struct XorShift64Star(pub u64);

impl XorShift64Star {
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in `[-1, 1)`, from the top 24 bits so every value is exact in f32.
    pub fn next_signed_unit(&mut self) -> f32 {
        let bits = (self.next_u64() >> 40) as u32;
        bits as f32 / (1u32 << 23) as f32 - 1.0
    }

    /// Uniform in `0..n`.
    pub fn next_below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// Whether `SOFTFEM_BENCH_QUICK=1` asks for the smoke-test run: no criterion, a short table pass.
pub fn quick() -> bool {
    std::env::var("SOFTFEM_BENCH_QUICK").is_ok_and(|value| value == "1")
}

/// What the table pass after criterion should do, from the command line.
pub enum TablePass {
    /// `--list` or `--profile-time`: not a measurement, so no table.
    Skip,
    /// `--test` (`cargo bench -p softfem-benches -- --test`): only checks that everything runs, so
    /// one short pass.
    Test,
    /// A real measurement.
    Full,
}

/// The [`TablePass`] the command line asks for. A flag counts alone (`--test`) or with a value
/// (`--profile-time=5`).
pub fn table_pass() -> TablePass {
    let args: Vec<String> = std::env::args().collect();
    let has_flag = |flag: &str| {
        args.iter()
            .any(|arg| arg == flag || arg.strip_prefix(flag).is_some_and(|v| v.starts_with('=')))
    };
    if has_flag("--list") || has_flag("--profile-time") {
        TablePass::Skip
    } else if has_flag("--test") {
        TablePass::Test
    } else {
        TablePass::Full
    }
}

/// Calls `run` on every variant once (warming caches, branch predictors and CPU frequency), then
/// times it round-robin `rounds` times, `repetitions` calls per timed block, and returns the
/// minimum ns per item for each variant, where one call processes `items_per_run` items. The
/// minimum is the estimate least disturbed by other processes, and interleaving the variants
/// means their ratios come from the same machine state.
pub fn round_robin_min_ns<V>(
    variants: &mut [V],
    mut run: impl FnMut(&mut V),
    repetitions: u32,
    items_per_run: usize,
    rounds: u32,
) -> Vec<f64> {
    for variant in variants.iter_mut() {
        run(variant);
    }
    let items_per_block = f64::from(repetitions) * items_per_run as f64;
    let mut best = vec![f64::INFINITY; variants.len()];
    for _ in 0..rounds {
        for (variant, best) in variants.iter_mut().zip(&mut best) {
            let start = Instant::now();
            for _ in 0..repetitions {
                run(variant);
            }
            let ns = start.elapsed().as_secs_f64() * 1e9 / items_per_block;
            *best = best.min(ns);
        }
    }
    best
}

/// The CPU model from `/proc/cpuinfo` where there is one, so a pasted table says what it ran on.
fn cpu_model() -> Option<String> {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    cpuinfo
        .lines()
        .find_map(|line| line.strip_prefix("model name")?.split_once(':'))
        .map(|(_, model)| model.trim().to_owned())
}

/// `"<CPU model> (<architecture>)"`, for the caption of a table.
pub fn machine() -> String {
    format!(
        "{} ({})",
        cpu_model().unwrap_or_else(|| "unknown CPU".into()),
        std::env::consts::ARCH
    )
}

/// Prints a markdown table: a left-aligned first column and right-aligned numeric columns.
pub fn print_markdown_table(header: &[&str], rows: impl IntoIterator<Item = Vec<String>>) {
    let row = |cells: &[String]| println!("| {} |", cells.join(" | "));
    row(&header
        .iter()
        .map(|cell| cell.to_string())
        .collect::<Vec<_>>());
    let rule: Vec<&str> = (0..header.len())
        .map(|column| if column == 0 { "---" } else { "---:" })
        .collect();
    println!("|{}|", rule.join("|"));
    for cells in rows {
        row(&cells);
    }
}

/// One measured workload, as a row of the CSV file that `SOFTFEM_BENCH_CSV=<path>` asks for
/// (columns `bench,workload,size,lanes,threads,value,unit`).
pub struct CsvRow {
    /// The bench target (`svd`, `forces`, `step`).
    pub bench: &'static str,
    /// What was measured, e.g. `softfem svd3_batch f32 avx512`.
    pub workload: String,
    /// The problem size: matrices per batch, tetrahedra of the mesh, ...
    pub size: usize,
    /// Values processed at once (1 for scalar code).
    pub lanes: usize,
    /// Threads used.
    pub threads: usize,
    /// The measured figure.
    pub value: f64,
    /// Its unit, e.g. `ns/matrix`, `Mtets/s`.
    pub unit: &'static str,
}

/// The header line of the CSV file.
const CSV_HEADER: &str = "bench,workload,size,lanes,threads,value,unit";

/// A CSV field, quoted when it holds a comma, a quote or a line break.
fn csv_field(field: &str) -> String {
    if field.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", field.replace('"', "\"\""))
    } else {
        field.to_owned()
    }
}

/// Appends `rows` to the file named by `SOFTFEM_BENCH_CSV`, writing the header first when the
/// file is new or empty; does nothing when the variable is unset. A relative path is taken from
/// the repository root (cargo runs a bench in its package's folder, `benches/`), so
/// `SOFTFEM_BENCH_CSV=target/parallel.csv` typed at the root writes `target/parallel.csv`.
/// Several benches can append to one file, so the guide's tables and the charts come from one
/// run. Panics (failing the bench) if the file cannot be written: a run asked to record must not
/// silently lose rows.
pub fn append_csv_rows(rows: &[CsvRow]) {
    use std::io::Write;
    let Some(path) = std::env::var_os("SOFTFEM_BENCH_CSV") else {
        return;
    };
    let repository_root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let path = repository_root.join(path);
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .unwrap_or_else(|error| panic!("SOFTFEM_BENCH_CSV={path:?}: {error}"));
    let is_new = file.metadata().map(|m| m.len() == 0).unwrap_or(true);
    let mut text = String::new();
    if is_new {
        text.push_str(CSV_HEADER);
        text.push('\n');
    }
    for row in rows {
        text.push_str(&format!(
            "{},{},{},{},{},{},{}\n",
            csv_field(row.bench),
            csv_field(&row.workload),
            row.size,
            row.lanes,
            row.threads,
            row.value,
            csv_field(row.unit),
        ));
    }
    file.write_all(text.as_bytes())
        .unwrap_or_else(|error| panic!("SOFTFEM_BENCH_CSV={path:?}: {error}"));
}

/// The marginal cost of one iteration of an iterative call, from two calls from the same start
/// that ran `short.1` and `long.1` iterations in `short.0` and `long.0` (any unit of time):
/// `(T_long - T_short) / (iterations_long - iterations_short)`, the loop alone, without the
/// call's fixed work (checks, initial evaluations, the final update), which cancels. At least
/// one extra iteration is assumed, so that a call that stopped early does not divide by zero.
pub fn marginal(short: (f64, u32), long: (f64, u32)) -> f64 {
    let extra = f64::from(long.1.saturating_sub(short.1).max(1));
    (long.0 - short.0) / extra
}
