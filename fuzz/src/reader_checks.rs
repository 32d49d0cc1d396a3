//! The Gmsh and OBJ readers on arbitrary text (included once per precision by `lib.rs`).
//!
//! Promises checked (`src/asset/gmsh.rs`, `src/asset/obj.rs`): nothing panics or aborts; a mesh
//! that is read has finite positions, every element index in range and one entity tag per
//! element; an error names a line of the text (or one past its last) and its message starts
//! with `line <n>:`. An OBJ surface that is read, written back with `write_obj` and read again
//! is the same surface, bit for bit.

use super::NAME;
use super::sf::asset::gmsh::read_gmsh;
use super::sf::asset::obj::{read_obj, write_obj};
use super::sf::types::{Real, Vec3};

/// Runs the Gmsh reader checks on one fuzzer input.
pub fn check_gmsh(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let lines = text.lines().count();
    match read_gmsh(&text) {
        Ok(mesh) => {
            let n = mesh.positions.len();
            assert!(
                mesh.positions.iter().all(|x| x.is_finite()),
                "{NAME}: read_gmsh returned a non-finite position"
            );
            let in_range = |v: &u32| (*v as usize) < n;
            assert!(
                mesh.tets.iter().flatten().all(in_range)
                    && mesh.triangles.iter().flatten().all(in_range),
                "{NAME}: read_gmsh returned an element index out of range ({n} nodes)"
            );
            assert_eq!(
                mesh.tets.len(),
                mesh.tet_entities.len(),
                "{NAME}: tet entities"
            );
            assert_eq!(
                mesh.triangles.len(),
                mesh.triangle_entities.len(),
                "{NAME}: triangle entities"
            );
        }
        Err(error) => {
            assert!(
                (1..=lines + 1).contains(&error.line),
                "{NAME}: read_gmsh named line {} of a {lines}-line text ({error})",
                error.line
            );
            let prefix = format!("line {}:", error.line);
            assert!(
                error.to_string().starts_with(&prefix),
                "{NAME}: the message {error} does not start with {prefix}"
            );
        }
    }
}

/// Runs the OBJ reader checks on one fuzzer input.
pub fn check_obj(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let lines = text.lines().count();
    match read_obj(&text) {
        Ok(surface) => {
            let n = surface.positions.len();
            assert!(
                surface.positions.iter().all(|x| x.is_finite()),
                "{NAME}: read_obj returned a non-finite position"
            );
            assert!(
                surface
                    .triangles
                    .iter()
                    .flatten()
                    .all(|&v| (v as usize) < n),
                "{NAME}: read_obj returned a triangle index out of range ({n} vertices)"
            );
            let mut written = Vec::new();
            write_obj(&mut written, &surface.positions, &surface.triangles, None).unwrap_or_else(
                |error| panic!("{NAME}: write_obj refused a read surface: {error}"),
            );
            let again = read_obj(&String::from_utf8_lossy(&written))
                .unwrap_or_else(|error| panic!("{NAME}: write_obj's text does not read: {error}"));
            let bits = |x: &[Vec3]| -> Vec<[_; 3]> {
                x.iter().map(|x| x.to_array().map(Real::to_bits)).collect()
            };
            assert!(
                bits(&again.positions) == bits(&surface.positions)
                    && again.triangles == surface.triangles,
                "{NAME}: an OBJ surface written and read back changed"
            );
        }
        Err(error) => {
            // An empty text has no line to name: `NoFaces` names line 0 there.
            assert!(
                error.line <= lines.max(1) && (error.line >= 1 || lines == 0),
                "{NAME}: read_obj named line {} of a {lines}-line text ({error})",
                error.line
            );
            let prefix = format!("line {}:", error.line);
            assert!(
                error.to_string().starts_with(&prefix),
                "{NAME}: the message {error} does not start with {prefix}"
            );
        }
    }
}
