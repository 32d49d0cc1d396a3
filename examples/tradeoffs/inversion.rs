//! Chart `inversion`: what each model does when elements are driven through inversion and
//! released (`docs/math.md` section 2), stepped explicitly in f32.
//!
//! * One tetrahedron: the base triangle is pinned, the apex is moved through the base plane to
//!   half its height on the other side (volume ratio `J = -0.5`) and released.
//! * A block of 2x2x2 cubes (48 tetrahedra): the bottom face is pinned, the top face is pushed
//!   down onto the bottom (flat) and released; the middle layer of vertices is free throughout.
//!
//! Models: StVK, the isochoric neo-Hookean, stable neo-Hookean (direct stress), and the
//! Irving–Teran–Fedkiw clamp (principal stress with stretches clamped at 0.3) on StVK and on
//! neo-Hookean. A run the stepper refuses (blow-up detected, state restored) stops there and says
//! so in its legend.

use std::path::Path;

use plotters::chart::SeriesLabelPosition;
use softfem::StepError;
use softfem::generate::BoxSplit;
use softfem::glam::Vec3;
use softfem::material::{NeoHookean, StVK, StableNeoHookean};
use softfem::step::{
    ElasticModel, ExplicitScratch, ExplicitSettings, Scene as StepScene, TetClamped, TetElastic,
    explicit_step, scratch_len, stable_time_step,
};

use crate::chart::{Axis, Figure, Panel, Series, Style, Table, num};
use crate::measure::progress;
use crate::single::body::{BoxMesh, masses, volume_ratios};
use crate::{Findings, Size};

const YOUNG: f32 = 1.0e5;
const POISSON: f32 = 0.3;
const DENSITY: f32 = 1000.0;
/// Mass-proportional damping (1/s), so that the released bodies settle within the run.
const DAMPING: f32 = 10.0;
/// The clamp's smallest stretch.
const THRESHOLD: f32 = 0.3;
/// The time step as a fraction of the stable bound at rest (compression stiffens the models).
const SAFETY: f32 = 0.5;

/// The five variants, by name.
pub const VARIANTS: [&str; 5] = [
    "StVK",
    "neo-Hookean",
    "stable neo-Hookean",
    "StVK + clamp",
    "neo-Hookean + clamp",
];

/// A scene: rest shape, the vertices held throughout, the vertices driven and then released,
/// and where the driven vertices go.
struct Scene {
    mesh: BoxMesh,
    held: Vec<bool>,
    driven: Vec<bool>,
    /// The displacement (m) of every driven vertex at the end of the drive.
    push: Vec3,
    drive_time: f32,
    release_time: f32,
}

/// The volume ratios over time of one run: `(t, smallest element ratio, total ratio)`, and the
/// failure if the stepper refused a step.
struct History {
    samples: Vec<(f64, f64, f64)>,
    failure: Option<(f64, StepError)>,
}

/// Steps `model` through the scene: the driven vertices move linearly to `push` over
/// `drive_time` (prescribed, pinned), then are released for `release_time`.
fn drive<F: ElasticModel<Vector = Vec3>>(
    model: &F,
    scene: &Scene,
    masses: &[f32],
    every: usize,
) -> Result<History, String> {
    let pinned_driving: Vec<bool> = scene
        .held
        .iter()
        .zip(&scene.driven)
        .map(|(a, b)| *a || *b)
        .collect();
    let mut stiffness = vec![0.0; masses.len()];
    let dt = SAFETY
        * stable_time_step(model, masses, &scene.held, &mut stiffness)
            .map_err(|e| e.to_string())?;
    // What each step acts on: the time step alone (no gravity, no ground).
    let step_scene = StepScene::new(dt);
    let settings = ExplicitSettings::new().with_damping(DAMPING);
    let rest = &scene.mesh.rest;
    let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; rest.len()]);
    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(rest.len())];
    let mut scratch = ExplicitScratch::new(&mut buffer);
    let mut rest_data = Vec::new();
    let mesh = scene.mesh.mesh(&mut rest_data)?;
    let drive_steps = (scene.drive_time / dt).ceil() as usize;
    let total = drive_steps + (scene.release_time / dt).ceil() as usize;
    let mut history = History {
        samples: vec![(0.0, 1.0, 1.0)],
        failure: None,
    };
    for step in 0..total {
        let driving = step < drive_steps;
        if driving {
            let s = (step + 1) as f32 / drive_steps as f32;
            for ((p, r), driven) in x.iter_mut().zip(rest).zip(&scene.driven) {
                if *driven {
                    *p = *r + scene.push * s;
                }
            }
            // The blow-up detector keeps its history: the prescribed moves are small per step
            // (under 1 % of an element), so only a real blow-up trips it.
        }
        let pinned = if driving {
            &pinned_driving
        } else {
            &scene.held
        };
        let t = f64::from(dt) * (step + 1) as f64;
        if let Err(error) = explicit_step(
            model,
            masses,
            pinned,
            &step_scene,
            &settings,
            &mut x,
            &mut v,
            &mut scratch,
        ) {
            history.failure = Some((t, error));
            break;
        }
        if step % every == 0 || step + 1 == total {
            let (smallest, whole) = volume_ratios(&mesh, &x);
            history.samples.push((t, smallest, whole));
        }
    }
    Ok(history)
}

/// Runs `variant` on `scene`.
fn run_variant(variant: &str, scene: &Scene) -> Result<History, String> {
    let mut rest_data = Vec::new();
    let mesh = scene.mesh.mesh(&mut rest_data)?;
    let masses = masses(&mesh, DENSITY)?;
    let every = 4;
    fn material<M>(made: Result<M, softfem::MaterialError>) -> Result<M, String> {
        made.map_err(|e| e.to_string())
    }
    match variant {
        "StVK" => drive(
            &TetElastic::new(mesh, material(StVK::from_young_poisson(YOUNG, POISSON))?),
            scene,
            &masses,
            every,
        ),
        "neo-Hookean" => drive(
            &TetElastic::new(
                mesh,
                material(NeoHookean::from_young_poisson(YOUNG, POISSON))?,
            ),
            scene,
            &masses,
            every,
        ),
        "stable neo-Hookean" => drive(
            &TetElastic::new(
                mesh,
                material(StableNeoHookean::from_young_poisson(YOUNG, POISSON))?,
            ),
            scene,
            &masses,
            every,
        ),
        "StVK + clamp" => drive(
            &TetClamped::new(
                mesh,
                material(StVK::from_young_poisson(YOUNG, POISSON))?,
                THRESHOLD,
            ),
            scene,
            &masses,
            every,
        ),
        _ => drive(
            &TetClamped::new(
                mesh,
                material(NeoHookean::from_young_poisson(YOUNG, POISSON))?,
                THRESHOLD,
            ),
            scene,
            &masses,
            every,
        ),
    }
}

/// One tetrahedron of edge 0.1 m on its pinned base; the apex goes to `J = -0.5`.
fn single_tet() -> Scene {
    let l = 0.1;
    let rest = vec![Vec3::ZERO, Vec3::X * l, Vec3::Y * l, Vec3::Z * l];
    Scene {
        mesh: BoxMesh {
            rest,
            tets: vec![[0, 1, 2, 3]],
        },
        held: vec![true, true, true, false],
        driven: vec![false, false, false, true],
        push: Vec3::Z * (-1.5 * l),
        drive_time: 0.1,
        release_time: 0.9,
    }
}

/// A 0.1 m block of 2x2x2 cubes; the top face is pushed onto the bottom face.
fn block() -> Result<Scene, String> {
    let h = 0.1;
    let mesh = BoxMesh::new(Vec3::splat(h), [2, 2, 2], BoxSplit::Kuhn6)?;
    let held = mesh.flags(|x| x.z == 0.0);
    let driven = mesh.flags(|x| x.z == h);
    Ok(Scene {
        mesh,
        held,
        driven,
        push: Vec3::Z * -h,
        drive_time: 0.2,
        release_time: 0.8,
    })
}

pub fn run(_size: Size, out: &Path) -> Result<Findings, String> {
    // Both scenes are tiny: the quick run is the full run.
    let mut table = Table::new(&[
        "scene",
        "variant",
        "t_s",
        "smallest_volume_ratio",
        "total_volume_ratio",
        "failure",
    ]);
    let mut findings = Findings::new("inversion");
    let mut panels_series: [Vec<Series>; 3] = Default::default();
    for (scene_name, scene) in [("tet", single_tet()), ("block", block()?)] {
        for (color, variant) in VARIANTS.into_iter().enumerate() {
            let history = run_variant(variant, &scene)?;
            let failure = history
                .failure
                .map(|(t, e)| format!("{e:?} at t = {t:.3} s"));
            for &(t, smallest, whole) in &history.samples {
                table.push(vec![
                    scene_name.into(),
                    variant.into(),
                    num(t),
                    num(smallest),
                    num(whole),
                    String::new(),
                ]);
            }
            if let Some(text) = &failure {
                table.push(vec![
                    scene_name.into(),
                    variant.into(),
                    num(history.failure.map_or(f64::NAN, |f| f.0)),
                    String::new(),
                    String::new(),
                    text.clone(),
                ]);
            }
            let &(t_end, smallest_end, whole_end) =
                history.samples.last().unwrap_or(&(0.0, f64::NAN, f64::NAN));
            let worst = history
                .samples
                .iter()
                .map(|s| s.1)
                .fold(f64::INFINITY, f64::min);
            let outcome = failure
                .clone()
                .unwrap_or_else(|| format!("ran to t = {t_end:.2} s"));
            let line = format!(
                "{scene_name}, {variant}: smallest element volume ratio {worst:.2} during the run; at the end smallest {smallest_end:.3}, total {whole_end:.3} ({outcome})"
            );
            progress("inversion", &line);
            findings.line(line);
            let name = match history.failure {
                Some((t, error)) => format!(
                    "{variant} (stepper refused at t = {t:.2} s: {})",
                    short(error)
                ),
                None => variant.to_owned(),
            };
            let style = if variant.contains("clamp") {
                Style::Dashed
            } else {
                Style::Line
            };
            if scene_name == "tet" {
                panels_series[0].push(Series::new(
                    &name,
                    style,
                    color,
                    history.samples.iter().map(|s| (s.0, s.1)).collect(),
                ));
            } else {
                panels_series[1].push(Series::new(
                    &name,
                    style,
                    color,
                    history.samples.iter().map(|s| (s.0, s.2)).collect(),
                ));
                panels_series[2].push(Series::new(
                    &name,
                    style,
                    color,
                    history.samples.iter().map(|s| (s.0, s.1)).collect(),
                ));
            }
        }
    }
    table.write(&out.join("inversion.csv"))?;
    let [tet, block_total, block_smallest] = panels_series;
    let released = |what: &str, at: f32| format!("{what} (released at t = {at} s)");
    Figure {
        title: format!("Inversion: driven through J = 0 and released (E = {YOUNG:.0e} Pa, nu = {POISSON}, explicit, f32)"),
        panels: vec![
            Panel::new(&released("one tetrahedron, apex pushed through its pinned base to J = -0.5", 0.1), Axis::linear("time (s)"), Axis::linear("volume ratio J").with_range(-1.5, 1.5), tet)
                .with_legend(SeriesLabelPosition::LowerRight),
            Panel::new(&released("block of 48 tets squashed flat: total volume / rest volume", 0.2), Axis::linear("time (s)"), Axis::linear("total volume ratio").with_range(-0.5, 1.5), block_total)
                .with_legend(SeriesLabelPosition::LowerRight),
            Panel::new(&released("the same block: smallest element volume ratio", 0.2), Axis::linear("time (s)"), Axis::linear("smallest element volume ratio").with_range(-1.5, 1.5), block_smallest)
                .with_legend(SeriesLabelPosition::LowerRight),
        ],
    }
    .write(&out.join("inversion.svg"))?;
    Ok(findings)
}

/// A short name of a step error for a legend.
fn short(error: StepError) -> String {
    match error {
        StepError::NonFiniteState { .. } => "non-finite state".into(),
        StepError::EnergyBlowUp => "energy blow-up".into(),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scenes_hold_and_drive_what_they_say() {
        let tet = single_tet();
        assert_eq!(tet.held.iter().filter(|h| **h).count(), 3);
        // The apex ends at half the tet's height below its base: J = -0.5.
        let apex = tet.mesh.rest[3] + tet.push;
        assert!((apex.z / tet.mesh.rest[3].z + 0.5).abs() < 1e-6);
        let block = block().unwrap();
        assert_eq!(block.held.iter().filter(|h| **h).count(), 9);
        assert_eq!(block.driven.iter().filter(|h| **h).count(), 9);
    }

    #[test]
    fn stable_neo_hookean_brings_the_tet_back() {
        let history = run_variant("stable neo-Hookean", &single_tet()).unwrap();
        assert!(history.failure.is_none());
        let (_, end, _) = *history.samples.last().unwrap();
        assert!((end - 1.0).abs() < 0.1, "{end}");
    }
}
