//! A reader for Gmsh `.msh` meshes, format version 4.1 ASCII (feature `std`).
//!
//! The format (Gmsh reference manual, section "MSH file format"): sections `$Name ... $EndName`.
//! This reader needs `$MeshFormat` (`4.1 0 <data size>`: version 4.1, file type 0 = ASCII),
//! `$Nodes` and `$Elements`, and skips every other section (`$Entities`, `$PhysicalNames`,
//! `$Periodic`, ...).
//! * `$Nodes`: `<blocks> <nodes> <min tag> <max tag>`, then per block
//!   `<entity dim> <entity tag> <parametric 0|1> <nodes in block>`, the block's node tags one
//!   per line, then their coordinates one per line (`x y z`, followed by `dim` parametric
//!   coordinates when `parametric` is 1).
//! * `$Elements`: `<blocks> <elements> <min tag> <max tag>`, then per block
//!   `<entity dim> <entity tag> <element type> <elements in block>` and one line per element,
//!   `<tag> <node tags...>`.
//!
//! Element type 2 (3-node triangle) and 4 (4-node tetrahedron) are read, with the entity tag of
//! their block; 15 (point), 1 (2-node line) and 8 (3-node line) are skipped; any other type
//! (quadrangles, hexahedra, prisms, second-order elements) is an error, so that volume is never
//! dropped silently. Node tags may be sparse and unordered: nodes are numbered 0, 1, ... in file
//! order and elements are translated. Coordinates are read in this module's precision. Every
//! error names the line and the problem ([`GmshFormatError`]).
//!
//! A hand parser rather than the `mshio` crate: `mshio`'s parse errors come from `nom` without
//! a line number, and the subset needed here is two sections.
//!
//! # Orientation
//! Gmsh writes tetrahedra positively oriented, but other tools writing MSH may not: like the
//! TetGen reader, this one returns tetrahedra as written; fix the orientation (for example with
//! the element module's `fix_orientation`) before building rest data.

use std::collections::HashMap;
use std::path::Path;
use std::vec::Vec;

use super::super::types::{Real, Vec3};
pub use crate::error::{AssetFileError, GmshFormatError, GmshProblem, GmshSection};

/// A mesh read from a Gmsh file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GmshMesh {
    /// Node positions in file order (units as written; metres for the simulation).
    pub positions: Vec<Vec3>,
    /// 4-node tetrahedra as 0-based indices into `positions`, in file order.
    pub tets: Vec<[u32; 4]>,
    /// The entity tag of each tetrahedron's block (the volume it belongs to).
    pub tet_entities: Vec<i32>,
    /// 3-node triangles as 0-based indices, in file order.
    pub triangles: Vec<[u32; 3]>,
    /// The entity tag of each triangle's block (the surface it belongs to).
    pub triangle_entities: Vec<i32>,
}

/// Reads a mesh from the text of a `.msh` file (version 4.1, ASCII).
///
/// ```
/// use softfem::asset::gmsh::read_gmsh;
///
/// let text = "\
/// $MeshFormat
/// 4.1 0 8
/// $EndMeshFormat
/// $Nodes
/// 1 4 1 4
/// 3 1 0 4
/// 1
/// 2
/// 3
/// 4
/// 0 0 0
/// 1 0 0
/// 0 1 0
/// 0 0 1
/// $EndNodes
/// $Elements
/// 1 1 1 1
/// 3 1 4 1
/// 1 1 2 3 4
/// $EndElements
/// ";
/// let mesh = read_gmsh(text)?;
/// assert_eq!(mesh.tets, vec![[0, 1, 2, 3]]);
///
/// let broken = text.replace("1 1 2 3 4", "1 1 2 3 9");
/// assert_eq!(read_gmsh(&broken).unwrap_err().to_string(), "line 19: node tag 9 does not exist");
/// # Ok::<(), softfem::asset::gmsh::GmshFormatError>(())
/// ```
///
/// # Errors
/// A [`GmshFormatError`] with the line and problem: a missing or unterminated section, a
/// version other than 4.1 or a binary file, a wrong number of fields or a field that is not a
/// number, a non-finite coordinate, a duplicate or unknown node tag, a header count that does not
/// match its records, an unsupported element type, or a second `$MeshFormat`, `$Nodes` or
/// `$Elements` section (named on the line that opens it).
pub fn read_gmsh(text: &str) -> Result<GmshMesh, GmshFormatError> {
    let mut lines = Lines::new(text);
    let mut mesh = GmshMesh::default();
    let mut seen_format = false;
    let mut node_tags: Option<HashMap<u64, u32>> = None;
    let mut seen_elements = false;
    while let Some((line, content)) = lines.next_line() {
        match content {
            "$MeshFormat" => {
                refuse_repeat(seen_format, GmshSection::MeshFormat, line)?;
                let (line, fields) = lines.record(GmshSection::MeshFormat)?;
                let error = |problem| GmshFormatError { line, problem };
                let [version, file_type, ..] = fields.as_slice() else {
                    return Err(error(GmshProblem::FieldCount {
                        expected: 3,
                        found: fields.len(),
                    }));
                };
                if *version != "4.1" {
                    return Err(error(GmshProblem::UnsupportedVersion));
                }
                if *file_type != "0" {
                    return Err(error(GmshProblem::Binary));
                }
                lines.end(GmshSection::MeshFormat)?;
                seen_format = true;
            }
            "$Nodes" => {
                require_format(seen_format, line)?;
                refuse_repeat(node_tags.is_some(), GmshSection::Nodes, line)?;
                node_tags = Some(read_nodes(&mut lines, &mut mesh)?);
            }
            "$Elements" => {
                require_format(seen_format, line)?;
                refuse_repeat(seen_elements, GmshSection::Elements, line)?;
                let tags = node_tags.as_ref().ok_or(GmshFormatError {
                    line,
                    problem: GmshProblem::MissingSection(GmshSection::Nodes),
                })?;
                read_elements(&mut lines, tags, &mut mesh)?;
                seen_elements = true;
            }
            other if !other.starts_with("$End") => {
                if let Some(name) = other.strip_prefix('$') {
                    lines.skip_section(name)?;
                }
            }
            _ => {}
        }
    }
    let end = lines.past_end();
    if !seen_format {
        return Err(GmshFormatError {
            line: end,
            problem: GmshProblem::MissingSection(GmshSection::MeshFormat),
        });
    }
    if node_tags.is_none() {
        return Err(GmshFormatError {
            line: end,
            problem: GmshProblem::MissingSection(GmshSection::Nodes),
        });
    }
    if !seen_elements {
        return Err(GmshFormatError {
            line: end,
            problem: GmshProblem::MissingSection(GmshSection::Elements),
        });
    }
    Ok(mesh)
}

/// Reads a `.msh` file (see [`read_gmsh`]).
///
/// # Errors
/// [`AssetFileError::Io`] with the path if it cannot be read as UTF-8 text,
/// [`AssetFileError::Gmsh`] with the path, line and problem if it is malformed.
pub fn read_gmsh_file(path: impl AsRef<Path>) -> Result<GmshMesh, AssetFileError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|source| AssetFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_gmsh(&text).map_err(|error| AssetFileError::Gmsh {
        path: path.to_path_buf(),
        error,
    })
}

fn require_format(seen: bool, line: usize) -> Result<(), GmshFormatError> {
    if seen {
        Ok(())
    } else {
        Err(GmshFormatError {
            line,
            problem: GmshProblem::MissingSection(GmshSection::MeshFormat),
        })
    }
}

/// A second `$MeshFormat`, `$Nodes` or `$Elements` section (at `line`) is refused: elements
/// would refer to the nodes of one of two sections, and which is a guess.
fn refuse_repeat(seen: bool, section: GmshSection, line: usize) -> Result<(), GmshFormatError> {
    if seen {
        Err(GmshFormatError {
            line,
            problem: GmshProblem::RepeatedSection(section),
        })
    } else {
        Ok(())
    }
}

fn read_nodes(
    lines: &mut Lines<'_>,
    mesh: &mut GmshMesh,
) -> Result<HashMap<u64, u32>, GmshFormatError> {
    let section = GmshSection::Nodes;
    let (header_line, header) = lines.record(section)?;
    let [blocks, total, _, _] = numbers::<u64, 4>(header_line, &header)?;
    let mut tags: HashMap<u64, u32> = HashMap::new();
    let mut order = Vec::new();
    for _ in 0..blocks {
        let (line, fields) = lines.record(section)?;
        let [dimension, _, parametric, count] = numbers::<u64, 4>(line, &fields)?;
        if parametric > 1 || dimension > 3 {
            return Err(GmshFormatError {
                line,
                problem: GmshProblem::BadField {
                    field: if dimension > 3 { 1 } else { 3 },
                },
            });
        }
        order.clear();
        for _ in 0..count {
            let (line, fields) = lines.record(section)?;
            let [tag] = numbers::<u64, 1>(line, &fields)?;
            let index = u32::try_from(tags.len()).map_err(|_| GmshFormatError {
                line,
                problem: GmshProblem::CountMismatch {
                    expected: total as usize,
                    found: tags.len(),
                },
            })?;
            if tags.insert(tag, index).is_some() {
                return Err(GmshFormatError {
                    line,
                    problem: GmshProblem::DuplicateNode { tag },
                });
            }
            order.push(tag);
        }
        let fields_per_node = 3 + if parametric == 1 {
            dimension as usize
        } else {
            0
        };
        for _ in 0..count {
            let (line, fields) = lines.record(section)?;
            if fields.len() != fields_per_node {
                return Err(GmshFormatError {
                    line,
                    problem: GmshProblem::FieldCount {
                        expected: fields_per_node,
                        found: fields.len(),
                    },
                });
            }
            let mut x = [0.0 as Real; 3];
            for (field, (slot, token)) in x.iter_mut().zip(&fields).enumerate() {
                let value: Real = token.parse().map_err(|_| GmshFormatError {
                    line,
                    problem: GmshProblem::BadField { field: field + 1 },
                })?;
                if !value.is_finite() {
                    return Err(GmshFormatError {
                        line,
                        problem: GmshProblem::NonFiniteCoordinate,
                    });
                }
                *slot = value;
            }
            mesh.positions.push(Vec3::from_array(x));
        }
    }
    if tags.len() as u64 != total {
        return Err(GmshFormatError {
            line: header_line,
            problem: GmshProblem::CountMismatch {
                expected: total as usize,
                found: tags.len(),
            },
        });
    }
    lines.end(section)?;
    Ok(tags)
}

fn read_elements(
    lines: &mut Lines<'_>,
    tags: &HashMap<u64, u32>,
    mesh: &mut GmshMesh,
) -> Result<(), GmshFormatError> {
    let section = GmshSection::Elements;
    let (header_line, header) = lines.record(section)?;
    let [blocks, total, _, _] = numbers::<u64, 4>(header_line, &header)?;
    let mut found = 0u64;
    for _ in 0..blocks {
        let (line, fields) = lines.record(section)?;
        let [_, entity, element_type, count] = numbers::<i64, 4>(line, &fields)?;
        let nodes = match element_type {
            15 => 1,
            1 => 2,
            8 => 3,
            2 => 3,
            4 => 4,
            other => {
                return Err(GmshFormatError {
                    line,
                    problem: GmshProblem::UnsupportedElement {
                        element_type: u32::try_from(other).unwrap_or(u32::MAX),
                    },
                });
            }
        };
        let entity = i32::try_from(entity).map_err(|_| GmshFormatError {
            line,
            problem: GmshProblem::BadField { field: 2 },
        })?;
        for _ in 0..count.max(0) {
            let (line, fields) = lines.record(section)?;
            if fields.len() != nodes + 1 {
                return Err(GmshFormatError {
                    line,
                    problem: GmshProblem::FieldCount {
                        expected: nodes + 1,
                        found: fields.len(),
                    },
                });
            }
            let mut indices = [0u32; 4];
            for (field, (slot, token)) in indices.iter_mut().zip(fields.iter().skip(1)).enumerate()
            {
                let tag: u64 = token.parse().map_err(|_| GmshFormatError {
                    line,
                    problem: GmshProblem::BadField { field: field + 2 },
                })?;
                *slot = *tags.get(&tag).ok_or(GmshFormatError {
                    line,
                    problem: GmshProblem::UnknownNode { tag },
                })?;
            }
            // The element tag must be a number too.
            numbers::<u64, 1>(line, fields.get(..1).unwrap_or_default())?;
            let [a, b, c, d] = indices;
            match element_type {
                4 => {
                    mesh.tets.push([a, b, c, d]);
                    mesh.tet_entities.push(entity);
                }
                2 => {
                    mesh.triangles.push([a, b, c]);
                    mesh.triangle_entities.push(entity);
                }
                _ => {}
            }
            found += 1;
        }
    }
    if found != total {
        return Err(GmshFormatError {
            line: header_line,
            problem: GmshProblem::CountMismatch {
                expected: total as usize,
                found: found as usize,
            },
        });
    }
    lines.end(section)
}

/// Exactly `N` whitespace-separated numbers.
fn numbers<T: core::str::FromStr + Default + Copy, const N: usize>(
    line: usize,
    fields: &[&str],
) -> Result<[T; N], GmshFormatError> {
    if fields.len() != N {
        return Err(GmshFormatError {
            line,
            problem: GmshProblem::FieldCount {
                expected: N,
                found: fields.len(),
            },
        });
    }
    let mut values = [T::default(); N];
    for (field, (slot, token)) in values.iter_mut().zip(fields).enumerate() {
        *slot = token.parse().map_err(|_| GmshFormatError {
            line,
            problem: GmshProblem::BadField { field: field + 1 },
        })?;
    }
    Ok(values)
}

/// The lines of the file, trimmed, with 1-based numbers; blank lines are skipped.
struct Lines<'a> {
    lines: core::iter::Enumerate<core::str::Lines<'a>>,
    last: usize,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str) -> Lines<'a> {
        Lines {
            lines: text.lines().enumerate(),
            last: 0,
        }
    }

    fn next_line(&mut self) -> Option<(usize, &'a str)> {
        for (number, raw) in self.lines.by_ref() {
            self.last = number + 1;
            let content = raw.trim();
            if !content.is_empty() {
                return Some((number + 1, content));
            }
        }
        None
    }

    /// One past the last line (where a missing line is reported).
    fn past_end(&self) -> usize {
        self.last + 1
    }

    /// The next line of `section` as fields; the end of the file or a `$` line is an error.
    fn record(&mut self, section: GmshSection) -> Result<(usize, Vec<&'a str>), GmshFormatError> {
        match self.next_line() {
            Some((line, content)) if !content.starts_with('$') => {
                Ok((line, content.split_whitespace().collect()))
            }
            Some((line, _)) => Err(GmshFormatError {
                line,
                problem: GmshProblem::UnterminatedSection(section),
            }),
            None => Err(GmshFormatError {
                line: self.past_end(),
                problem: GmshProblem::UnterminatedSection(section),
            }),
        }
    }

    /// The `$End...` line of `section`.
    fn end(&mut self, section: GmshSection) -> Result<(), GmshFormatError> {
        let expected = match section {
            GmshSection::MeshFormat => "$EndMeshFormat",
            GmshSection::Nodes => "$EndNodes",
            GmshSection::Elements => "$EndElements",
        };
        match self.next_line() {
            Some((_, content)) if content == expected => Ok(()),
            Some((line, _)) => Err(GmshFormatError {
                line,
                problem: GmshProblem::ExpectedEnd(section),
            }),
            None => Err(GmshFormatError {
                line: self.past_end(),
                problem: GmshProblem::UnterminatedSection(section),
            }),
        }
    }

    /// Skips an unknown section up to its `$End<name>` line (or the end of the file).
    fn skip_section(&mut self, name: &str) -> Result<(), GmshFormatError> {
        while let Some((_, content)) = self.next_line() {
            if content.strip_prefix("$End") == Some(name) {
                return Ok(());
            }
        }
        Ok(())
    }
}
