//! The TetGen reader on arbitrary text (included once per precision by `lib.rs`).
//!
//! The input is the `.node` text, a zero byte, and the `.ele` text (invalid UTF-8 replaced).
//! Promises checked (`src/asset/tetgen.rs`): nothing panics, and the result is exactly what the
//! format documented in the module (one header, consecutive records, exact field counts,
//! numeric fields, finite coordinates, first index 0 or 1, references in range, 4-node
//! tetrahedra, no degenerate tetrahedron) gives, computed here by an independent reader: the same mesh, or an error naming
//! the same file, line and problem, whose message starts with `<file> file, line <n>:`.

use super::NAME;
use super::sf::asset::tetgen::{TetgenMesh, read_tetgen};
use super::sf::element::{TetRest, fix_orientation};
use super::sf::types::{Real, Vec3};
use super::sf::{ElementError, TetgenFile, TetgenFormatError, TetgenProblem};

/// Runs the reader checks on one fuzzer input.
pub fn check(data: &[u8]) {
    let (node, ele) = match data.iter().position(|&b| b == 0) {
        Some(split) => (&data[..split], &data[split + 1..]),
        None => (data, &[][..]),
    };
    let (node, ele) = (String::from_utf8_lossy(node), String::from_utf8_lossy(ele));
    let actual = read_tetgen(&node, &ele);
    let expected = reference(&node, &ele);
    match (&actual, &expected) {
        (Ok(mesh), Ok((positions, tets))) => {
            let same_positions = mesh.positions.len() == positions.len()
                && mesh.positions.iter().zip(positions).all(|(a, b)| {
                    a.to_array().map(Real::to_bits) == b.to_array().map(Real::to_bits)
                });
            assert!(
                same_positions && mesh.tets == *tets,
                "{NAME}: read_tetgen read {mesh:?}, the format gives {positions:?} {tets:?}"
            );
        }
        (Err(error), Err(failure)) => {
            let prefix = format!(
                "{} file, line {}:",
                match error.file {
                    TetgenFile::Node => ".node",
                    _ => ".ele",
                },
                error.line
            );
            assert!(
                error.to_string().starts_with(&prefix),
                "{NAME}: the message {error} does not start with {prefix}"
            );
            assert_eq!(
                summary(error),
                *failure,
                "{NAME}: read_tetgen reported {error:?} ({error}), the format gives {failure:?}"
            );
        }
        _ => panic!(
            "{NAME}: read_tetgen gave {}, the format gives {}",
            describe(&actual),
            match &expected {
                Ok(_) => "a mesh".to_string(),
                Err(failure) => format!("{failure:?}"),
            }
        ),
    }
}

fn describe(result: &Result<TetgenMesh, TetgenFormatError>) -> String {
    match result {
        Ok(mesh) => format!(
            "a mesh of {} points, {} tets",
            mesh.positions.len(),
            mesh.tets.len()
        ),
        Err(error) => format!("{error:?} ({error})"),
    }
}

/// A reported problem: which file (`true` for `.node`), which line, what.
#[derive(Debug, PartialEq)]
pub struct Failure {
    node_file: bool,
    line: usize,
    problem: Problem,
}

/// [`TetgenProblem`] without the explanatory strings.
#[derive(Debug, PartialEq)]
enum Problem {
    MissingHeader,
    BadHeader {
        field: usize,
    },
    UnsupportedElement {
        nodes_per_tet: usize,
    },
    TooManyNodes,
    WrongCount {
        declared: usize,
        found: usize,
    },
    FieldCount {
        expected: usize,
        found: usize,
    },
    NonNumeric {
        field: usize,
    },
    NonFinite {
        field: usize,
    },
    FirstIndex {
        found: i64,
    },
    NonConsecutiveIndex {
        expected: u64,
        found: i64,
    },
    IndexOutOfRange {
        index: i64,
        points: usize,
        first: u32,
    },
    DegenerateTet {
        index: i64,
    },
    Unknown,
}

fn summary(error: &TetgenFormatError) -> Failure {
    let problem = match error.problem {
        TetgenProblem::MissingHeader => Problem::MissingHeader,
        TetgenProblem::BadHeader { field, .. } => Problem::BadHeader { field },
        TetgenProblem::UnsupportedElement { nodes_per_tet } => {
            Problem::UnsupportedElement { nodes_per_tet }
        }
        TetgenProblem::TooManyNodes => Problem::TooManyNodes,
        TetgenProblem::WrongCount { declared, found } => Problem::WrongCount { declared, found },
        TetgenProblem::FieldCount { expected, found } => Problem::FieldCount { expected, found },
        TetgenProblem::NonNumeric { field } => Problem::NonNumeric { field },
        TetgenProblem::NonFinite { field } => Problem::NonFinite { field },
        TetgenProblem::FirstIndex { found } => Problem::FirstIndex { found },
        TetgenProblem::NonConsecutiveIndex { expected, found } => {
            Problem::NonConsecutiveIndex { expected, found }
        }
        TetgenProblem::IndexOutOfRange {
            index,
            points,
            first,
        } => Problem::IndexOutOfRange {
            index,
            points,
            first,
        },
        TetgenProblem::DegenerateTet { index } => Problem::DegenerateTet { index },
        _ => Problem::Unknown,
    };
    Failure {
        node_file: matches!(error.file, TetgenFile::Node),
        line: error.line,
        problem,
    }
}

/// The non-blank records of a text: 1-based line number and fields, comments (`#` to the end
/// of the line) removed.
fn records(text: &str) -> Vec<(usize, Vec<&str>)> {
    text.lines()
        .enumerate()
        .filter_map(|(number, line)| {
            let content = line.find('#').map_or(line, |hash| &line[..hash]);
            let fields: Vec<&str> = content.split_whitespace().collect();
            (!fields.is_empty()).then_some((number + 1, fields))
        })
        .collect()
}

/// What the documented format gives for the two texts.
fn reference(node: &str, ele: &str) -> Result<(Vec<Vec3>, Vec<[u32; 4]>), Failure> {
    let (positions, first) = reference_node(node).map_err(|(line, problem)| Failure {
        node_file: true,
        line,
        problem,
    })?;
    let tets = reference_ele(ele, &positions, first).map_err(|(line, problem)| Failure {
        node_file: false,
        line,
        problem,
    })?;
    Ok((positions, tets))
}

type LineProblem = (usize, Problem);

/// Field `k` (1-based) of a record as an integer.
fn integer(line: usize, fields: &[&str], k: usize) -> Result<i64, LineProblem> {
    fields[k - 1]
        .parse::<i64>()
        .map_err(|_| (line, Problem::NonNumeric { field: k }))
}

/// A header count: a non-negative integer.
fn count(line: usize, fields: &[&str], k: usize) -> Result<usize, LineProblem> {
    let value = integer(line, fields, k)?;
    usize::try_from(value).map_err(|_| (line, Problem::BadHeader { field: k }))
}

/// A header flag: 0 or 1.
fn flag(line: usize, fields: &[&str], k: usize) -> Result<bool, LineProblem> {
    match integer(line, fields, k)? {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err((line, Problem::BadHeader { field: k })),
    }
}

fn field_count(line: usize, fields: &[&str], expected: usize) -> Result<(), LineProblem> {
    if fields.len() == expected {
        Ok(())
    } else {
        Err((
            line,
            Problem::FieldCount {
                expected,
                found: fields.len(),
            },
        ))
    }
}

/// The header record, or the missing-header problem one line past the end.
fn header<'r, 'a>(
    text: &str,
    records: &'r [(usize, Vec<&'a str>)],
) -> Result<&'r (usize, Vec<&'a str>), LineProblem> {
    records
        .first()
        .ok_or((text.lines().count() + 1, Problem::MissingHeader))
}

/// Exactly `declared` records after the header: the count problem is reported on the first extra
/// record, or on the header when records are missing.
fn check_record_count(records: &[(usize, Vec<&str>)], declared: usize) -> Result<(), LineProblem> {
    let found = records.len() - 1;
    if found > declared {
        Err((
            records[declared + 1].0,
            Problem::WrongCount { declared, found },
        ))
    } else if found < declared {
        Err((records[0].0, Problem::WrongCount { declared, found }))
    } else {
        Ok(())
    }
}

/// The record index (field 1) of the `position`-th record (0-based) for indices from `first`.
fn record_index(
    line: usize,
    fields: &[&str],
    first: u32,
    position: usize,
) -> Result<(), LineProblem> {
    let found = integer(line, fields, 1)?;
    let expected = u64::from(first) + position as u64;
    if found >= 0 && found as u64 == expected {
        Ok(())
    } else {
        Err((line, Problem::NonConsecutiveIndex { expected, found }))
    }
}

fn reference_node(text: &str) -> Result<(Vec<Vec3>, u32), LineProblem> {
    let records = records(text);
    let (line, fields) = header(text, &records)?;
    let line = *line;
    field_count(line, fields, 4)?;
    let declared = count(line, fields, 1)?;
    if integer(line, fields, 2)? != 3 {
        return Err((line, Problem::BadHeader { field: 2 }));
    }
    let attributes = count(line, fields, 3)?;
    let markers = flag(line, fields, 4)?;
    if declared > u32::MAX as usize {
        return Err((line, Problem::TooManyNodes));
    }
    let per_record = 4 + attributes + usize::from(markers);
    let mut positions = Vec::new();
    let mut first = 0;
    for (position, (line, fields)) in records.iter().skip(1).take(declared).enumerate() {
        let line = *line;
        field_count(line, fields, per_record)?;
        if position == 0 {
            first = match integer(line, fields, 1)? {
                0 => 0,
                1 => 1,
                found => return Err((line, Problem::FirstIndex { found })),
            };
        } else {
            record_index(line, fields, first, position)?;
        }
        let mut xyz = [0.0 as Real; 3];
        for (k, coordinate) in (2..=4).zip(&mut xyz) {
            let value: Real = fields[k - 1]
                .parse()
                .map_err(|_| (line, Problem::NonNumeric { field: k }))?;
            if !value.is_finite() {
                return Err((line, Problem::NonFinite { field: k }));
            }
            *coordinate = value;
        }
        for k in 5..=per_record {
            fields[k - 1]
                .parse::<f64>()
                .map_err(|_| (line, Problem::NonNumeric { field: k }))?;
        }
        positions.push(Vec3::from(xyz));
    }
    check_record_count(&records, declared)?;
    Ok((positions, first))
}

fn reference_ele(text: &str, positions: &[Vec3], first: u32) -> Result<Vec<[u32; 4]>, LineProblem> {
    let points = positions.len();
    let records = records(text);
    let (line, fields) = header(text, &records)?;
    let line = *line;
    field_count(line, fields, 3)?;
    let declared = count(line, fields, 1)?;
    match count(line, fields, 2)? {
        4 => {}
        10 => return Err((line, Problem::UnsupportedElement { nodes_per_tet: 10 })),
        _ => return Err((line, Problem::BadHeader { field: 2 })),
    }
    let region = flag(line, fields, 3)?;
    let per_record = 5 + usize::from(region);
    let mut tets = Vec::new();
    for (position, (line, fields)) in records.iter().skip(1).take(declared).enumerate() {
        let line = *line;
        field_count(line, fields, per_record)?;
        record_index(line, fields, first, position)?;
        let mut tet = [0u32; 4];
        for (k, vertex) in (2..=5).zip(&mut tet) {
            let index = integer(line, fields, k)?;
            match index.checked_sub(i64::from(first)) {
                Some(zero_based) if zero_based >= 0 && (zero_based as u128) < points as u128 => {
                    *vertex = zero_based as u32;
                }
                _ => {
                    return Err((
                        line,
                        Problem::IndexOutOfRange {
                            index,
                            points,
                            first,
                        },
                    ));
                }
            }
        }
        if region {
            fields[5]
                .parse::<f64>()
                .map_err(|_| (line, Problem::NonNumeric { field: 6 }))?;
        }
        // The documented degeneracy test: the element module's, on the tetrahedron oriented
        // positively (the reader accepts either orientation).
        let corners = |tet: [u32; 4]| tet.map(|v| positions[v as usize]);
        let oriented = fix_orientation(tet, corners(tet));
        if let Err(ElementError::Degenerate) = TetRest::new(corners(oriented)) {
            return Err((
                line,
                Problem::DegenerateTet {
                    index: integer(line, fields, 1)?,
                },
            ));
        }
        tets.push(tet);
    }
    check_record_count(&records, declared)?;
    Ok(tets)
}
