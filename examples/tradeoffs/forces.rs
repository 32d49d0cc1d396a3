//! Chart `forces`: the elastic force kernels' error against their cost, for each model, by the
//! direct path (`first_piola`) and the principal (SVD) path, in f32 and f64.
//!
//! The reference is the f64 direct path (itself checked against finite differences of the
//! energy in `tests/kernels/identities.rs`) on the same inputs: the f32 mesh's rest and deformed
//! positions, converted exactly to f64, so that only the kernels' arithmetic is compared. The
//! error is `|f - f_ref| / |f_ref|` over the whole force vector.

use std::path::Path;

use softfem::generate::BoxSplit;

use crate::chart::{Axis, Figure, Panel, Series, Style, Table, num};
use crate::measure::{ns_per_item, progress};
use crate::{Findings, Size, double, single};

/// Young's modulus (Pa) and Poisson ratio of the material in every model.
const YOUNG: f64 = 1.0e6;
const POISSON: f64 = 0.45;

/// Where the f64 direct path (the reference, error 0) is drawn on the log error axis.
const REFERENCE_FLOOR: f64 = 1e-18;

/// A force path of `softfem::mesh::TetMesh`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForcePath {
    /// `add_elastic_forces`: `P` from `F` directly.
    Direct,
    /// `add_elastic_forces_principal`: `P = U diag(dW/ds) V^T` through `svd3_lanes`.
    Principal,
}

impl ForcePath {
    fn name(self) -> &'static str {
        match self {
            ForcePath::Direct => "direct",
            ForcePath::Principal => "SVD",
        }
    }
}

/// The three models, by name.
const MODELS: [&str; 3] = ["StVK", "neo-Hookean", "stable neo-Hookean"];

/// The forces (as f64) of model `model` by `path` on `mesh` at `x`, and the ns per tet of
/// computing them, in the precision of module `$p`.
macro_rules! measure_forces {
    ($p:ident, $model:expr, $path:expr, $mesh:expr, $x:expr, $repeats:expr) => {{
        use $p::api::material::{Material, NeoHookean, StVK, StableNeoHookean};
        use $p::api::mesh::TetMesh;
        use $p::api::types::{Real, Vec3};
        fn go<M: Material>(
            m: M,
            path: ForcePath,
            mesh: &TetMesh<'_>,
            x: &[Vec3],
            repeats: u32,
        ) -> (Vec<[f64; 3]>, f64) {
            let mut f = vec![Vec3::ZERO; x.len()];
            let evaluate = |f: &mut [Vec3]| {
                f.fill(Vec3::ZERO);
                match path {
                    ForcePath::Direct => mesh.add_elastic_forces(&m, x, f),
                    ForcePath::Principal => mesh.add_elastic_forces_principal(&m, x, f),
                }
                .map(|()| f[0].x)
            };
            let ns = ns_per_item(repeats, mesh.element_count(), || evaluate(&mut f).ok());
            let _ = evaluate(&mut f);
            ($p::body::to_f64(&f), ns)
        }
        let (e, nu) = (YOUNG as Real, POISSON as Real);
        let r = match $model {
            "StVK" => StVK::from_young_poisson(e, nu).map(|m| go(m, $path, $mesh, $x, $repeats)),
            "neo-Hookean" => {
                NeoHookean::from_young_poisson(e, nu).map(|m| go(m, $path, $mesh, $x, $repeats))
            }
            _ => StableNeoHookean::from_young_poisson(e, nu)
                .map(|m| go(m, $path, $mesh, $x, $repeats)),
        };
        r.map_err(|e| e.to_string())
    }};
}

/// `|a - b| / |b|` over whole force vectors.
pub fn relative_error(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let (mut diff, mut norm) = (0.0, 0.0);
    for (p, q) in a.iter().zip(b) {
        for i in 0..3 {
            diff += (p[i] - q[i]) * (p[i] - q[i]);
            norm += q[i] * q[i];
        }
    }
    (diff / norm).sqrt()
}

/// A deterministic smooth-plus-jitter deformation of `rest` (cell size `cell`): a rotation, a
/// stretch and shear, and a per-vertex jitter of 8 % of a cell, so that the elements see
/// volume ratios between about 0.7 and 1.6, none inverted.
fn deformed(rest: &[softfem::glam::Vec3], cell: f32) -> Vec<softfem::glam::Vec3> {
    use softfem::glam::{Mat3, Quat, Vec3};
    let rotation = Mat3::from_quat(Quat::from_axis_angle(
        Vec3::new(1.0, 2.0, 3.0).normalize(),
        0.7,
    ));
    let strain = Mat3::from_cols(
        Vec3::new(1.2, 0.1, 0.0),
        Vec3::new(0.05, 0.9, 0.1),
        Vec3::new(0.0, -0.1, 1.1),
    );
    rest.iter()
        .enumerate()
        .map(|(i, &x)| {
            let t = i as f32;
            let jitter =
                Vec3::new((t * 1.7).sin(), (t * 2.3).cos(), (t * 0.37).sin()) * (0.08 * cell);
            rotation * (strain * x) + jitter
        })
        .collect()
}

pub fn run(size: Size, out: &Path) -> Result<Findings, String> {
    let (cells, repeats) = match size {
        Size::Quick => (4, 3),
        Size::Full => (14, 15),
    };
    let edge = 0.5f32;
    let box32 = single::body::BoxMesh::new(
        softfem::glam::Vec3::splat(edge),
        [cells; 3],
        BoxSplit::Kuhn6,
    )?;
    let x32 = deformed(&box32.rest, edge / cells as f32);
    let box64 = double::body::BoxMesh {
        rest: box32.rest.iter().map(|p| p.as_dvec3()).collect(),
        tets: box32.tets.clone(),
    };
    let x64: Vec<_> = x32.iter().map(|p| p.as_dvec3()).collect();
    let (mut rest32, mut rest64) = (Vec::new(), Vec::new());
    let mesh32 = box32.mesh(&mut rest32)?;
    let mesh64 = box64.mesh(&mut rest64)?;
    let (smallest, _) = single::body::volume_ratios(&mesh32, &x32);
    if smallest <= 0.0 {
        return Err(format!(
            "the test deformation inverts an element (volume ratio {smallest})"
        ));
    }
    progress(
        "forces",
        &format!(
            "{} tets, smallest volume ratio {smallest:.2}, E = {YOUNG} Pa, nu = {POISSON}",
            mesh32.element_count()
        ),
    );

    let mut table = Table::new(&[
        "model",
        "path",
        "precision",
        "ns_per_tet",
        "relative_error",
        "tets",
    ]);
    let mut series = Vec::new();
    let mut findings = Findings::new("forces");
    for (color, model) in MODELS.into_iter().enumerate() {
        let (reference, ns_ref) =
            measure_forces!(double, model, ForcePath::Direct, &mesh64, &x64, repeats)?;
        let mut points = vec![(ns_ref, REFERENCE_FLOOR)];
        let mut labels = vec!["direct f64 (reference)".to_owned()];
        table.push(vec![
            model.into(),
            "direct".into(),
            "f64".into(),
            num(ns_ref),
            num(0.0),
            mesh32.element_count().to_string(),
        ]);
        let mut line = format!("{model}: direct f64 {ns_ref:.1} ns/tet (reference)");
        for (path, precision) in [
            (ForcePath::Direct, "f32"),
            (ForcePath::Principal, "f32"),
            (ForcePath::Principal, "f64"),
        ] {
            let (forces, ns) = if precision == "f32" {
                measure_forces!(single, model, path, &mesh32, &x32, repeats)?
            } else {
                measure_forces!(double, model, path, &mesh64, &x64, repeats)?
            };
            let error = relative_error(&forces, &reference);
            table.push(vec![
                model.into(),
                path.name().into(),
                precision.into(),
                num(ns),
                num(error),
                mesh32.element_count().to_string(),
            ]);
            points.push((ns, error));
            labels.push(format!("{} {precision}", path.name()));
            line += &format!(
                "; {} {precision} {ns:.1} ns/tet error {error:.1e}",
                path.name()
            );
        }
        progress("forces", &line);
        findings.line(line);
        series.push(Series::new(model, Style::Points, color, points).with_labels(labels));
    }
    table.write(&out.join("forces.csv"))?;
    Figure {
        title: "Elastic forces: error against cost per tetrahedron".into(),
        panels: vec![Panel::new(
            &format!(
                "{} tets, volume ratios {smallest:.2}..; error vs f64 direct (drawn at {REFERENCE_FLOOR:.0e})",
                mesh32.element_count()
            ),
            Axis::log("ns per tetrahedron (one thread, zeroing and checks included)"),
            Axis::log("relative force error |f - f_ref| / |f_ref|"),
            series,
        )],
    }
    .write(&out.join("forces.svg"))?;
    Ok(findings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_error_of_force_vectors() {
        let reference = [[3.0, 0.0, 0.0], [0.0, 4.0, 0.0]];
        assert_eq!(relative_error(&reference, &reference), 0.0);
        let off = [[3.0, 0.0, 0.5], [0.0, 4.0, 0.0]];
        assert!((relative_error(&off, &reference) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn the_test_deformation_keeps_every_element_upright() {
        let boxed =
            single::body::BoxMesh::new(softfem::glam::Vec3::splat(0.5), [3; 3], BoxSplit::Kuhn6)
                .unwrap();
        let mut rest = Vec::new();
        let mesh = boxed.mesh(&mut rest).unwrap();
        let (smallest, total) =
            single::body::volume_ratios(&mesh, &deformed(&boxed.rest, 0.5 / 3.0));
        assert!(
            smallest > 0.5 && (total - 1.17).abs() < 0.1,
            "{smallest} {total}"
        );
    }
}
