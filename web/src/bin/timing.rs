//! Steps the page's scene natively and prints the time per step: the denominator of the
//! wasm/native ratio (`node web/test/speed.mjs` runs this and the page in one sitting).
//!
//! `cargo run --release -p softfem-web --bin web-timing -- [STEPS] [RUNS] [STEPPER] [SCENE]`
//!
//! Each run builds the scene `SCENE` (0 the playground, the default; 1 the pile) at `t = 0`
//! with the page's default settings (Stable Neo-Hookean, 1/60 s) but the stepper `STEPPER`
//! (0 explicit, 1 relaxation, 2 Newton, 3 Vertex Block Descent; default 3, the page's, which
//! the pile takes as Newton) and takes `STEPS` steps (default 120); the building is not
//! timed. Prints one line per run, `run K: T ms per step`, with the FNV-1a digest of the
//! positions reached (`Stage::position_digest`), then the minimum and the median.
//! `SOFTFEM_MAX_WIDTH=scalar` (or `sse`, `avx2`) caps the SIMD width
//! (`softfem::simd::set_max_width`), to see what the lanes give natively.

use std::process::ExitCode;
use std::time::Instant;

use softfem_web::scene::{Settings, Stepper};
use softfem_web::stage::{Kind, Stage};

fn run(steps: usize, stepper: Stepper, kind: Kind) -> Result<(f64, u64), String> {
    let settings = Settings {
        stepper,
        ..Settings::default()
    };
    let mut playground = Stage::new(kind, settings).map_err(|e| e.to_string())?;
    let started = Instant::now();
    for step in 0..steps {
        playground.step().map_err(|e| format!("step {step}: {e}"))?;
    }
    let elapsed = started.elapsed().as_secs_f64();
    if !playground.finite() {
        return Err("a position or velocity is not finite".into());
    }
    Ok((elapsed * 1e3 / steps as f64, playground.position_digest()))
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let number = |k: usize, default: usize| -> Result<usize, String> {
        match args.get(k) {
            None => Ok(default),
            Some(text) => text
                .parse::<usize>()
                .map_err(|_| format!("{text:?} is not a whole number")),
        }
    };
    let stepper = number(2, Settings::default().stepper as usize)
        .and_then(|code| Stepper::from_code(code as u32).ok_or(format!("no stepper {code}")));
    let kind = number(3, 0)
        .and_then(|code| Kind::from_code(code as u32).ok_or(format!("no scene {code}")));
    let (steps, runs, stepper, kind) = match (number(0, 120), number(1, 5), stepper, kind) {
        (Ok(steps), Ok(runs), Ok(stepper), Ok(kind)) if steps > 0 && runs > 0 => {
            (steps, runs, stepper, kind)
        }
        (steps, runs, stepper, kind) => {
            let problem = [steps.err(), runs.err(), stepper.err(), kind.err()]
                .into_iter()
                .flatten();
            let problem = problem.chain(["STEPS and RUNS must be positive".into()]);
            eprintln!(
                "web-timing: {}; usage: web-timing [STEPS] [RUNS] [STEPPER 0-3] [SCENE 0-1]",
                problem.take(1).collect::<String>()
            );
            return ExitCode::FAILURE;
        }
    };
    if let Ok(name) = std::env::var("SOFTFEM_MAX_WIDTH") {
        match softfem::simd::Width::from_name(&name) {
            Some(width) => softfem::simd::set_max_width(width),
            None => {
                eprintln!("web-timing: SOFTFEM_MAX_WIDTH={name:?} is not a width");
                return ExitCode::FAILURE;
            }
        }
    }
    println!("SIMD width {}", softfem::simd::active_width().name());
    let mut times = Vec::with_capacity(runs);
    for k in 1..=runs {
        match run(steps, stepper, kind) {
            Ok((ms, digest)) => {
                let stepper = kind
                    .admitted(Settings {
                        stepper,
                        ..Settings::default()
                    })
                    .stepper;
                println!(
                    "run {k}: {ms:.3} ms per step ({steps} steps, {kind:?}, {stepper:?}), \
                     positions {digest:016x}"
                );
                times.push(ms);
            }
            Err(message) => {
                eprintln!("web-timing: run {k}: {message}");
                return ExitCode::FAILURE;
            }
        }
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    println!("min {:.3} ms, median {median:.3} ms per step", times[0]);
    ExitCode::SUCCESS
}
