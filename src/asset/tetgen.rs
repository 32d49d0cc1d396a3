//! A reader for TetGen `.node` / `.ele` tetrahedral meshes (feature `std`).
//!
//! The format (TetGen user's manual, section "File formats"):
//! * `.node`: a header `<# points> <dimension (3)> <# attributes> <boundary markers (0 or 1)>`,
//!   then one record per point, `<index> <x> <y> <z> [attributes...] [marker]`.
//! * `.ele`: a header `<# tetrahedra> <nodes per tetrahedron (4)> <region attribute (0 or 1)>`,
//!   then one record per tetrahedron, `<index> <n1> <n2> <n3> <n4> [attribute]`.
//!
//! `#` starts a comment anywhere on a line and blank lines are skipped. Indices start at 0 or 1:
//! the first point's index decides, and the same base applies to every record index and every
//! point reference in the `.ele` file. Records must be numbered consecutively. Attributes,
//! markers and region attributes are checked to be numbers and then dropped. Coordinates are
//! read directly in this module's precision (metres, as written). 10-node (`-o2`) tetrahedra
//! are rejected. The reader is strict: every line must have exactly the fields its header
//! implies, and every error names the file, the line and the problem ([`TetgenFormatError`]).
//!
//! # Orientation
//! The format does not fix the orientation of a tetrahedron, so a file (TetGen's own output, or
//! a mesh such as the GAMES103 "house") may list tetrahedra with `det([x2 - x1, x3 - x1,
//! x4 - x1]) < 0`, some or all of them. This reader returns the tetrahedra exactly as written
//! and does not check their orientation. It does refuse a degenerate tetrahedron (zero or
//! near-zero volume, by the element module's test, in either orientation), naming the `.ele`
//! line, since no body could be built from it. Callers must not assume either sign: compute each rest volume and swap two
//! vertices (for example `n3` and `n4`) of every negatively oriented tetrahedron, with the
//! element module's orientation helper or by hand, before building rest data, which requires
//! positive volumes (`docs/math.md` section 1).

use std::path::Path;
use std::string::String;
use std::vec::Vec;

use super::super::element::{TetRest, fix_orientation};
use super::super::types::{Real, Vec3};
use crate::error::ElementError;
pub use crate::error::{TetgenError, TetgenFile, TetgenFormatError, TetgenProblem};

/// A tetrahedral mesh read from TetGen files.
#[derive(Clone, Debug, PartialEq)]
pub struct TetgenMesh {
    /// Point positions (metres, as written in the `.node` file), in file order.
    pub positions: Vec<Vec3>,
    /// Tetrahedra as 0-based indices into `positions`, in file order and with the vertex order
    /// of the file (whose orientation may be negative: see the [module documentation](self)).
    pub tets: Vec<[u32; 4]>,
}

/// Reads a mesh from the texts of a `.node` file and an `.ele` file.
///
/// # Errors
/// A [`TetgenFormatError`] naming the file, the 1-based line and the problem: a bad or missing
/// header, a record count different from the header's, a wrong number of fields, a field that
/// is not a number, a non-finite coordinate, a first index other than 0 or 1, a non-consecutive
/// (or duplicate) record index, a point reference out of range, 10-node tetrahedra, or a
/// degenerate tetrahedron ([`TetgenProblem::DegenerateTet`]).
///
/// ```
/// use softfem::asset::tetgen::read_tetgen;
///
/// // A single tetrahedron, 1-based, with a boundary marker per point.
/// let node = "\
/// 4 3 0 1   # points, dimension, attributes, markers
/// 1  0 0 0  1
/// 2  1 0 0  1
/// 3  0 1 0  1
/// 4  0 0 1  1
/// ";
/// let ele = "1 4 0\n1  1 2 3 4\n";
/// let mesh = read_tetgen(node, ele)?;
/// assert_eq!(mesh.positions.len(), 4);
/// assert_eq!(mesh.tets, vec![[0, 1, 2, 3]]);
///
/// let broken = "1 4 0\n1  1 2 3 5   # there is no point 5\n";
/// let error = read_tetgen(node, broken).unwrap_err();
/// assert_eq!(error.to_string(), ".ele file, line 2: point index 5 is out of range (4 points numbered from 1)");
/// # Ok::<(), softfem::asset::tetgen::TetgenFormatError>(())
/// ```
pub fn read_tetgen(node: &str, ele: &str) -> Result<TetgenMesh, TetgenFormatError> {
    let (positions, first) = read_node(node)?;
    let tets = read_ele(ele, &positions, first)?;
    Ok(TetgenMesh { positions, tets })
}

/// Reads a mesh from a `.node` file and an `.ele` file (see [`read_tetgen`]).
///
/// # Errors
/// [`TetgenError::Io`] with the path if a file cannot be read as UTF-8 text;
/// [`TetgenError::Format`] with the path, line and problem if a file is malformed.
pub fn read_tetgen_files(
    node_path: impl AsRef<Path>,
    ele_path: impl AsRef<Path>,
) -> Result<TetgenMesh, TetgenError> {
    let (node_path, ele_path) = (node_path.as_ref(), ele_path.as_ref());
    let node = read_text(node_path)?;
    let ele = read_text(ele_path)?;
    let (positions, first) = read_node(&node).map_err(|error| TetgenError::Format {
        path: node_path.to_path_buf(),
        error,
    })?;
    let tets = read_ele(&ele, &positions, first).map_err(|error| TetgenError::Format {
        path: ele_path.to_path_buf(),
        error,
    })?;
    Ok(TetgenMesh { positions, tets })
}

fn read_text(path: &Path) -> Result<String, TetgenError> {
    std::fs::read_to_string(path).map_err(|source| TetgenError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The non-blank lines of a file, comments removed, split into fields, with 1-based numbers.
struct Records<'a> {
    file: TetgenFile,
    lines: core::iter::Enumerate<core::str::Lines<'a>>,
    lines_seen: usize,
}

/// One record: its line number and fields.
struct Record<'a> {
    file: TetgenFile,
    line: usize,
    fields: Vec<&'a str>,
}

impl<'a> Records<'a> {
    fn new(file: TetgenFile, text: &'a str) -> Self {
        Records {
            file,
            lines: text.lines().enumerate(),
            lines_seen: 0,
        }
    }

    fn error(&self, line: usize, problem: TetgenProblem) -> TetgenFormatError {
        TetgenFormatError {
            file: self.file,
            line,
            problem,
        }
    }
}

impl<'a> Iterator for Records<'a> {
    type Item = Record<'a>;

    fn next(&mut self) -> Option<Record<'a>> {
        for (number, line) in self.lines.by_ref() {
            self.lines_seen = number + 1;
            let content = line.split('#').next().unwrap_or("");
            let fields: Vec<&str> = content.split_whitespace().collect();
            if !fields.is_empty() {
                return Some(Record {
                    file: self.file,
                    line: number + 1,
                    fields,
                });
            }
        }
        None
    }
}

impl Record<'_> {
    fn error(&self, problem: TetgenProblem) -> TetgenFormatError {
        TetgenFormatError {
            file: self.file,
            line: self.line,
            problem,
        }
    }

    fn expect_fields(&self, expected: usize) -> Result<(), TetgenFormatError> {
        if self.fields.len() == expected {
            Ok(())
        } else {
            Err(self.error(TetgenProblem::FieldCount {
                expected,
                found: self.fields.len(),
            }))
        }
    }

    /// Field `field` (1-based) as text; the field count has been checked.
    fn text(&self, field: usize) -> Result<&str, TetgenFormatError> {
        field
            .checked_sub(1)
            .and_then(|i| self.fields.get(i))
            .copied()
            .ok_or(self.error(TetgenProblem::FieldCount {
                expected: field,
                found: self.fields.len(),
            }))
    }

    fn integer(&self, field: usize) -> Result<i64, TetgenFormatError> {
        self.text(field)?
            .parse()
            .map_err(|_| self.error(TetgenProblem::NonNumeric { field }))
    }

    /// A header count: a non-negative integer.
    fn count(&self, field: usize, expected: &'static str) -> Result<usize, TetgenFormatError> {
        usize::try_from(self.integer(field)?)
            .map_err(|_| self.error(TetgenProblem::BadHeader { field, expected }))
    }

    /// A header flag: 0 or 1.
    fn flag(&self, field: usize, expected: &'static str) -> Result<bool, TetgenFormatError> {
        match self.integer(field)? {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(self.error(TetgenProblem::BadHeader { field, expected })),
        }
    }

    /// An attribute: any number (TetGen writes them as reals); checked, then dropped.
    fn check_number(&self, field: usize) -> Result<(), TetgenFormatError> {
        self.text(field)?
            .parse::<f64>()
            .map(drop)
            .map_err(|_| self.error(TetgenProblem::NonNumeric { field }))
    }

    fn coordinate(&self, field: usize) -> Result<Real, TetgenFormatError> {
        let value: Real = self
            .text(field)?
            .parse()
            .map_err(|_| self.error(TetgenProblem::NonNumeric { field }))?;
        if value.is_finite() {
            Ok(value)
        } else {
            Err(self.error(TetgenProblem::NonFinite { field }))
        }
    }

    /// Checks that the record index (field 1) is `expected`.
    fn expect_index(&self, expected: u64) -> Result<(), TetgenFormatError> {
        let found = self.integer(1)?;
        if u64::try_from(found) == Ok(expected) {
            Ok(())
        } else {
            Err(self.error(TetgenProblem::NonConsecutiveIndex { expected, found }))
        }
    }
}

/// The header of a file, or [`TetgenProblem::MissingHeader`] past its last line.
fn header<'a>(records: &mut Records<'a>) -> Result<Record<'a>, TetgenFormatError> {
    match records.next() {
        Some(record) => Ok(record),
        None => Err(records.error(records.lines_seen + 1, TetgenProblem::MissingHeader)),
    }
}

/// Checks that a file had exactly `declared` records once `found` have been read and the
/// iterator is exhausted or holds an extra record.
fn check_count(
    records: &mut Records<'_>,
    header_line: usize,
    declared: usize,
    found: usize,
) -> Result<(), TetgenFormatError> {
    if let Some(extra) = records.next() {
        let found = found + 1 + records.count();
        return Err(extra.error(TetgenProblem::WrongCount { declared, found }));
    }
    if found < declared {
        return Err(records.error(header_line, TetgenProblem::WrongCount { declared, found }));
    }
    Ok(())
}

/// The positions of a `.node` text and the index of its first point (0 or 1).
fn read_node(text: &str) -> Result<(Vec<Vec3>, u32), TetgenFormatError> {
    let mut records = Records::new(TetgenFile::Node, text);
    let head = header(&mut records)?;
    head.expect_fields(4)?;
    let declared = head.count(1, "a number of points")?;
    if head.integer(2)? != 3 {
        return Err(head.error(TetgenProblem::BadHeader {
            field: 2,
            expected: "the dimension 3",
        }));
    }
    let attributes = head.count(3, "a number of attributes")?;
    let marker = head.flag(4, "0 or 1 (boundary markers)")?;
    if u32::try_from(declared).is_err() {
        return Err(head.error(TetgenProblem::TooManyNodes));
    }
    let fields = attributes
        .checked_add(4 + usize::from(marker))
        .ok_or(head.error(TetgenProblem::BadHeader {
            field: 3,
            expected: "a number of attributes",
        }))?;

    // The header is not trusted with the allocation size: a record takes at least 8 bytes.
    let mut positions = Vec::with_capacity(declared.min(text.len() / 8));
    let mut first = 0;
    for record in records.by_ref().take(declared) {
        record.expect_fields(fields)?;
        if positions.is_empty() {
            first = match record.integer(1)? {
                0 => 0,
                1 => 1,
                found => return Err(record.error(TetgenProblem::FirstIndex { found })),
            };
        } else {
            record.expect_index(u64::from(first) + positions.len() as u64)?;
        }
        let position = Vec3::new(
            record.coordinate(2)?,
            record.coordinate(3)?,
            record.coordinate(4)?,
        );
        for field in 5..=fields {
            record.check_number(field)?;
        }
        positions.push(position);
    }
    check_count(&mut records, head.line, declared, positions.len())?;
    Ok((positions, first))
}

/// The tetrahedra of an `.ele` text as 0-based indices into `positions`, numbered from `first`
/// in the file; a degenerate tetrahedron is refused on its line.
fn read_ele(
    text: &str,
    positions: &[Vec3],
    first: u32,
) -> Result<Vec<[u32; 4]>, TetgenFormatError> {
    let points = positions.len();
    let mut records = Records::new(TetgenFile::Ele, text);
    let head = header(&mut records)?;
    head.expect_fields(3)?;
    let declared = head.count(1, "a number of tetrahedra")?;
    match head.count(2, "4 (nodes per tetrahedron)")? {
        4 => {}
        10 => {
            return Err(head.error(TetgenProblem::UnsupportedElement { nodes_per_tet: 10 }));
        }
        _ => {
            return Err(head.error(TetgenProblem::BadHeader {
                field: 2,
                expected: "4 (nodes per tetrahedron)",
            }));
        }
    }
    let region = head.flag(3, "0 or 1 (region attribute)")?;
    let fields = 5 + usize::from(region);

    let mut tets = Vec::with_capacity(declared.min(text.len() / 10));
    for record in records.by_ref().take(declared) {
        record.expect_fields(fields)?;
        record.expect_index(u64::from(first) + tets.len() as u64)?;
        let mut tet = [0u32; 4];
        for (field, vertex) in (2..).zip(tet.iter_mut()) {
            let index = record.integer(field)?;
            *vertex = index
                .checked_sub(i64::from(first))
                .and_then(|zero_based| u32::try_from(zero_based).ok())
                .filter(|&zero_based| (zero_based as usize) < points)
                .ok_or(record.error(TetgenProblem::IndexOutOfRange {
                    index,
                    points,
                    first,
                }))?;
        }
        if region {
            record.check_number(6)?;
        }
        // The test a body applies when built from this mesh: positively oriented first (the
        // reader accepts either orientation), then `TetRest::new`'s degeneracy test.
        let corners = tet.map(|v| positions.get(v as usize).copied().unwrap_or(Vec3::ZERO));
        let oriented = fix_orientation(tet, corners);
        let oriented_corners =
            oriented.map(|v| positions.get(v as usize).copied().unwrap_or(Vec3::ZERO));
        if let Err(ElementError::Degenerate) = TetRest::new(oriented_corners) {
            return Err(record.error(TetgenProblem::DegenerateTet {
                index: record.integer(1)?,
            }));
        }
        tets.push(tet);
    }
    check_count(&mut records, head.line, declared, tets.len())?;
    Ok(tets)
}
