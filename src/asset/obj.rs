//! Wavefront OBJ triangle surfaces: a reader and a per-frame writer (feature `std`).
//!
//! The reader takes the geometry a game asset needs for meshing and rendering: `v x y z [...]`
//! lines (extra fields such as `w` or vertex colours are checked to be numbers and dropped) and
//! `f` lines with vertex references `i`, `i/t`, `i//n` or `i/t/n` (only the vertex index `i` is
//! kept; negative indices count back from the last vertex defined so far). Polygons are
//! triangulated as fans around their first vertex, which is exact for the convex polygons
//! exporters write. Every other statement (`vt`, `vn`, `o`, `g`, `s`, `usemtl`, `mtllib`, `l`,
//! ...) is ignored; `#` starts a comment. Every error names the line ([`ObjFormatError`]).
//!
//! A hand parser rather than the `tobj` crate: `tobj` reports load errors without the line
//! they come from, and this format needs two statements.

use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;
use std::string::String;
use std::vec::Vec;

use super::super::types::{Real, Vec3};
pub use crate::error::{AssetFileError, ObjFormatError, ObjProblem};

/// A triangle surface read from an OBJ file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjSurface {
    /// Vertex positions in file order (units as written; metres for the simulation).
    pub positions: Vec<Vec3>,
    /// Triangles as 0-based indices, with the winding of the file (counter-clockwise seen from
    /// outside, by OBJ convention).
    pub triangles: Vec<[u32; 3]>,
}

/// Reads the vertices and faces of an OBJ text.
///
/// ```
/// use softfem::asset::obj::read_obj;
///
/// let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1 2/2 3/3 4/4  # a quad\n";
/// let surface = read_obj(text)?;
/// assert_eq!(surface.triangles, vec![[0, 1, 2], [0, 2, 3]]);
///
/// let error = read_obj("v 0 0 0\nf 1 2 3\n").unwrap_err();
/// assert_eq!(error.to_string(), "line 2: vertex index 2 is out of range (1 vertices)");
/// # Ok::<(), softfem::asset::obj::ObjFormatError>(())
/// ```
///
/// # Errors
/// An [`ObjFormatError`] with the line and problem: a vertex with fewer than three coordinates
/// or a field that is not a number, a non-finite coordinate, a face with fewer than three
/// vertices, index 0, an index out of range, or no faces at all.
pub fn read_obj(text: &str) -> Result<ObjSurface, ObjFormatError> {
    let mut surface = ObjSurface::default();
    // Faces may refer forward to vertices defined later (positive indices), so indices are
    // checked once every vertex is known; each face remembers its line for the message.
    let mut faces: Vec<(usize, usize, [i64; 3])> = Vec::new();
    let mut line_count = 0;
    for (number, raw) in text.lines().enumerate() {
        let line = number + 1;
        line_count = line;
        let content = raw.split('#').next().unwrap_or_default();
        let mut fields = content.split_whitespace();
        let error = |problem| ObjFormatError { line, problem };
        match fields.next() {
            Some("v") => {
                let mut coordinates = [0.0 as Real; 3];
                let mut count = 0;
                for (field, token) in fields.enumerate() {
                    let value: Real = token
                        .parse()
                        .map_err(|_| error(ObjProblem::BadField { field: field + 1 }))?;
                    if let Some(slot) = coordinates.get_mut(field) {
                        if !value.is_finite() {
                            return Err(error(ObjProblem::NonFiniteCoordinate));
                        }
                        *slot = value;
                    }
                    count += 1;
                }
                if count < 3 {
                    return Err(error(ObjProblem::MissingCoordinates));
                }
                surface.positions.push(Vec3::from_array(coordinates));
            }
            Some("f") => {
                let defined = surface.positions.len();
                let mut first = None;
                let mut previous = None;
                let mut vertices = 0;
                for (field, token) in fields.enumerate() {
                    let index: i64 = token
                        .split('/')
                        .next()
                        .and_then(|index| index.parse().ok())
                        .ok_or(error(ObjProblem::BadField { field: field + 1 }))?;
                    let index = match index {
                        0 => return Err(error(ObjProblem::ZeroIndex)),
                        // A negative index counts back from the vertices defined so far.
                        negative if negative < 0 => {
                            let resolved = defined as i64 + negative + 1;
                            if resolved < 1 {
                                return Err(error(ObjProblem::IndexOutOfRange {
                                    index: negative,
                                    vertices: defined,
                                }));
                            }
                            resolved
                        }
                        positive => positive,
                    };
                    vertices += 1;
                    match (first, previous) {
                        (None, _) => first = Some(index),
                        (Some(_), None) => previous = Some(index),
                        (Some(a), Some(b)) => {
                            faces.push((line, defined, [a, b, index]));
                            previous = Some(index);
                        }
                    }
                }
                if vertices < 3 {
                    return Err(error(ObjProblem::FaceTooSmall { vertices }));
                }
            }
            _ => {}
        }
    }
    if faces.is_empty() {
        return Err(ObjFormatError {
            line: line_count.max(1),
            problem: ObjProblem::NoFaces,
        });
    }
    let total = surface.positions.len();
    for (line, _, triangle) in faces {
        let mut resolved = [0u32; 3];
        for (slot, &index) in resolved.iter_mut().zip(&triangle) {
            match u32::try_from(index - 1) {
                Ok(zero_based) if (zero_based as usize) < total => *slot = zero_based,
                _ => {
                    return Err(ObjFormatError {
                        line,
                        problem: ObjProblem::IndexOutOfRange {
                            index,
                            vertices: total,
                        },
                    });
                }
            }
        }
        surface.triangles.push(resolved);
    }
    Ok(surface)
}

/// Reads an OBJ file (see [`read_obj`]).
///
/// # Errors
/// [`AssetFileError::Io`] with the path if it cannot be read as UTF-8 text,
/// [`AssetFileError::Obj`] with the path, line and problem if it is malformed.
pub fn read_obj_file(path: impl AsRef<Path>) -> Result<ObjSurface, AssetFileError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|source| AssetFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_obj(&text).map_err(|error| AssetFileError::Obj {
        path: path.to_path_buf(),
        error,
    })
}

/// Writes a triangle surface as OBJ text: `v` lines, `vn` lines when `normals` are given (one
/// per position), and `f` lines (1-based; `i//i` with normals). Coordinates are written with
/// Rust's shortest round-trip formatting, so reading the file back gives the same numbers.
///
/// # Errors
/// Any error of `out`; [`std::io::ErrorKind::InvalidInput`] if `normals` has a different length
/// than `positions` or a triangle index is out of range (nothing is written then).
pub fn write_obj(
    out: &mut impl Write,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    normals: Option<&[Vec3]>,
) -> std::io::Result<()> {
    let invalid = |message: &str| std::io::Error::new(std::io::ErrorKind::InvalidInput, message);
    if normals.is_some_and(|n| n.len() != positions.len()) {
        return Err(invalid("one normal per position is needed"));
    }
    if triangles
        .iter()
        .flatten()
        .any(|&v| v as usize >= positions.len())
    {
        return Err(invalid("a triangle index is out of range"));
    }
    // Formatted into one string and written at once: a file per frame is one system call.
    let mut text = String::with_capacity(positions.len() * 40 + triangles.len() * 24);
    for x in positions {
        let _ = writeln!(text, "v {} {} {}", x.x, x.y, x.z);
    }
    if let Some(normals) = normals {
        for n in normals {
            let _ = writeln!(text, "vn {} {} {}", n.x, n.y, n.z);
        }
    }
    for &[a, b, c] in triangles {
        let (a, b, c) = (a + 1, b + 1, c + 1);
        let _ = if normals.is_some() {
            writeln!(text, "f {a}//{a} {b}//{b} {c}//{c}")
        } else {
            writeln!(text, "f {a} {b} {c}")
        };
    }
    out.write_all(text.as_bytes())
}

/// Writes a triangle surface to an OBJ file (see [`write_obj`]), for example one file per frame
/// of a deformed render surface.
///
/// # Errors
/// [`AssetFileError::Io`] with the path.
pub fn write_obj_file(
    path: impl AsRef<Path>,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    normals: Option<&[Vec3]>,
) -> Result<(), AssetFileError> {
    let path = path.as_ref();
    let io_error = |source| AssetFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).map_err(io_error)?);
    write_obj(&mut file, positions, triangles, normals).map_err(io_error)?;
    file.flush().map_err(io_error)
}
