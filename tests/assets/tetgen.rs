//! The TetGen reader: hand-written valid meshes (0- and 1-based, comments, attributes, markers,
//! region attributes, CRLF), every malformed case with its file, line and problem, file errors
//! with their paths, a round trip through the generator's box, and the shipped cube asset.
//!
//! Written once in `tetgen_tests!` and instantiated for the f32 API at the crate root and the
//! f64 API under `softfem::f64`.
#![cfg(feature = "std")]

use std::path::PathBuf;

use softfem::{TetgenFile, TetgenFormatError, TetgenProblem};

/// A tetrahedron and its mirror image sharing the face 1-2-3, 0-based, with one attribute and
/// a boundary marker per point, comments and blank lines. Line numbers matter to the tests.
const NODE_0: &str = "\
# two tetrahedra sharing a face
5 3 1 1   # points, dimension, attributes, markers

0  0.0 0.0 0.0   7.5  1
1  1.0 0.0 0.0   7.5  1
2  0.0 1.0 0.0  -1e3  0   # attribute in exponent form
3  0.0 0.0 1.0   7.5  1
4  1   1   1.5   7.5  1
";

const ELE_0: &str = "\
2 4 1   # tetrahedra, nodes per tetrahedron, region attribute
0  0 1 2 3  10
1  1 2 3 4  -2.5
";

/// The same mesh numbered from 1, without attributes or markers, with CRLF line ends.
const NODE_1: &str = "5 3 0 0\r\n1 0 0 0\r\n2 1 0 0\r\n3 0 1 0\r\n4 0 0 1\r\n5 1 1 1.5\r\n";
const ELE_1: &str = "2 4 0\r\n1 1 2 3 4\r\n2 2 3 4 5\r\n";

fn node_error(line: usize, problem: TetgenProblem) -> TetgenFormatError {
    TetgenFormatError {
        file: TetgenFile::Node,
        line,
        problem,
    }
}

fn ele_error(line: usize, problem: TetgenProblem) -> TetgenFormatError {
    TetgenFormatError {
        file: TetgenFile::Ele,
        line,
        problem,
    }
}

/// `NODE_0` with line `line` (1-based) replaced.
fn node_with(line: usize, replacement: &str) -> String {
    with_line(NODE_0, line, replacement)
}

fn ele_with(line: usize, replacement: &str) -> String {
    with_line(ELE_0, line, replacement)
}

fn with_line(text: &str, line: usize, replacement: &str) -> String {
    let mut lines: Vec<&str> = text.lines().collect();
    lines[line - 1] = replacement;
    lines.join("\n") + "\n"
}

/// The path of a file in the repository's `assets/meshes`.
fn asset(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/meshes")
        .join(name)
}

macro_rules! tetgen_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use super::*;
            use std::fmt::Write as _;
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::asset::tetgen::{TetgenError, TetgenMesh, read_tetgen, read_tetgen_files};
            use $($api)::+::types::{Real, Vec3};

            /// What `read_tetgen` must return for `NODE_0` / `ELE_0` and `NODE_1` / `ELE_1`.
            fn two_tets() -> TetgenMesh {
                TetgenMesh {
                    positions: vec![
                        Vec3::ZERO,
                        Vec3::X,
                        Vec3::Y,
                        Vec3::Z,
                        Vec3::new(1.0, 1.0, 1.5),
                    ],
                    tets: vec![[0, 1, 2, 3], [1, 2, 3, 4]],
                }
            }

            /// The TetGen text of a mesh, numbered from `first`; with `extras`, every point
            /// gets two attributes and a marker and every tetrahedron a region attribute.
            fn to_tetgen(positions: &[Vec3], tets: &[[u32; 4]], first: u32, extras: bool) -> (String, String) {
                let flag = u32::from(extras);
                let mut node = format!("# written by tests/tetgen.rs\n{} 3 {} {flag}\n", positions.len(), 2 * flag);
                for (index, p) in (first..).zip(positions) {
                    // `{}` prints the shortest decimal that reads back to the same value.
                    write!(node, "{index} {} {} {}", p.x, p.y, p.z).unwrap();
                    if extras {
                        write!(node, "  0.25 -3  {}", index % 2).unwrap();
                    }
                    node.push('\n');
                }
                let mut ele = format!("{} 4 {flag}\n", tets.len());
                for (index, tet) in (first..).zip(tets) {
                    let [a, b, c, d] = tet.map(|v| v + first);
                    write!(ele, "{index}  {a} {b} {c} {d}").unwrap();
                    if extras {
                        write!(ele, "  {}", index % 3).unwrap();
                    }
                    ele.push('\n');
                }
                (node, ele)
            }

            fn generated_box(cells: [usize; 3], min: Vec3, max: Vec3) -> TetgenMesh {
                let [nx, ny, nz] = cells;
                let (positions, tets) = crate::common::scenes::generated_box!(min, max, (nx, ny, nz), BoxSplit::Kuhn6);
                TetgenMesh { positions, tets }
            }

            /// The mesh shipped as `assets/meshes/cube.node` / `cube.ele`.
            fn unit_cube() -> TetgenMesh {
                generated_box([2, 2, 2], Vec3::ZERO, Vec3::ONE)
            }

            #[test]
            fn reads_a_zero_based_mesh_with_comments_attributes_and_markers() {
                assert_eq!(read_tetgen(NODE_0, ELE_0), Ok(two_tets()));
            }

            #[test]
            fn reads_a_one_based_mesh_with_crlf_line_ends() {
                assert_eq!(read_tetgen(NODE_1, ELE_1), Ok(two_tets()));
            }

            #[test]
            fn reads_an_empty_mesh() {
                let mesh = read_tetgen("0 3 0 0\n", "0 4 0\n").unwrap();
                assert!(mesh.positions.is_empty() && mesh.tets.is_empty());
            }

            #[test]
            fn node_header_errors() {
                use TetgenProblem::*;
                let cases: Vec<(String, TetgenFormatError)> = vec![
                    (String::new(), node_error(1, MissingHeader)),
                    ("# only\n\n  # comments\n".into(), node_error(4, MissingHeader)),
                    (node_with(2, "5 3 1"), node_error(2, FieldCount { expected: 4, found: 3 })),
                    (node_with(2, "five 3 1 1"), node_error(2, NonNumeric { field: 1 })),
                    (node_with(2, "-5 3 1 1"), node_error(2, BadHeader { field: 1, expected: "a number of points" })),
                    (node_with(2, "5 2 1 1"), node_error(2, BadHeader { field: 2, expected: "the dimension 3" })),
                    (node_with(2, "5 3 -1 1"), node_error(2, BadHeader { field: 3, expected: "a number of attributes" })),
                    (node_with(2, "5 3 1 2"), node_error(2, BadHeader { field: 4, expected: "0 or 1 (boundary markers)" })),
                    (node_with(2, "5 3 1 1.0"), node_error(2, NonNumeric { field: 4 })),
                    (node_with(2, "5000000000 3 1 1"), node_error(2, TooManyNodes)),
                ];
                for (node, expected) in cases {
                    assert_eq!(read_tetgen(&node, ELE_0), Err(expected), "{node:?}");
                }
            }

            #[test]
            fn node_record_errors() {
                use TetgenProblem::*;
                let cases: Vec<(String, TetgenFormatError)> = vec![
                    // Counts: missing records are reported on the header line, extra ones on
                    // the first extra record.
                    (node_with(2, "6 3 1 1"), node_error(2, WrongCount { declared: 6, found: 5 })),
                    (node_with(2, "3 3 1 1"), node_error(7, WrongCount { declared: 3, found: 5 })),
                    (node_with(5, "1  1.0 0.0 0.0  7.5"), node_error(5, FieldCount { expected: 6, found: 5 })),
                    (node_with(5, "1  1.0 0.0 0.0  7.5 1 0"), node_error(5, FieldCount { expected: 6, found: 7 })),
                    (node_with(5, "1  1.0 0,0 0.0  7.5 1"), node_error(5, NonNumeric { field: 3 })),
                    (node_with(5, "1  1.0 0.0 0.0  x 1"), node_error(5, NonNumeric { field: 5 })),
                    (node_with(5, "1  1.0 0.0 0.0  7.5 one"), node_error(5, NonNumeric { field: 6 })),
                    (node_with(5, "1  NaN 0.0 0.0  7.5 1"), node_error(5, NonFinite { field: 2 })),
                    (node_with(5, "1  1.0 inf 0.0  7.5 1"), node_error(5, NonFinite { field: 3 })),
                    // Overflows both precisions.
                    (node_with(5, "1  1.0 0.0 1e400  7.5 1"), node_error(5, NonFinite { field: 4 })),
                    (node_with(4, "2  0.0 0.0 0.0   7.5  1"), node_error(4, FirstIndex { found: 2 })),
                    (node_with(4, "-1  0.0 0.0 0.0   7.5  1"), node_error(4, FirstIndex { found: -1 })),
                    (node_with(5, "0  1.0 0.0 0.0  7.5  1"), node_error(5, NonConsecutiveIndex { expected: 1, found: 0 })),
                    (node_with(5, "2  1.0 0.0 0.0  7.5  1"), node_error(5, NonConsecutiveIndex { expected: 1, found: 2 })),
                    (node_with(5, "1.0  1.0 0.0 0.0  7.5  1"), node_error(5, NonNumeric { field: 1 })),
                ];
                for (node, expected) in cases {
                    assert_eq!(read_tetgen(&node, ELE_0), Err(expected), "{node:?}");
                }
            }

            #[test]
            fn ele_errors() {
                use TetgenProblem::*;
                let cases: Vec<(String, TetgenFormatError)> = vec![
                    ("\n# nothing\n".into(), ele_error(3, MissingHeader)),
                    (ele_with(1, "2 4"), ele_error(1, FieldCount { expected: 3, found: 2 })),
                    (ele_with(1, "2 10 1"), ele_error(1, UnsupportedElement { nodes_per_tet: 10 })),
                    (ele_with(1, "2 3 1"), ele_error(1, BadHeader { field: 2, expected: "4 (nodes per tetrahedron)" })),
                    (ele_with(1, "2 4 3"), ele_error(1, BadHeader { field: 3, expected: "0 or 1 (region attribute)" })),
                    (ele_with(1, "x 4 1"), ele_error(1, NonNumeric { field: 1 })),
                    (ele_with(1, "3 4 1"), ele_error(1, WrongCount { declared: 3, found: 2 })),
                    (ele_with(1, "1 4 1"), ele_error(3, WrongCount { declared: 1, found: 2 })),
                    (ele_with(3, "1  1 2 3 4"), ele_error(3, FieldCount { expected: 6, found: 5 })),
                    (ele_with(3, "1  1 2 3 4 5 6"), ele_error(3, FieldCount { expected: 6, found: 7 })),
                    (ele_with(3, "1  1 2 3 5 0"), ele_error(3, IndexOutOfRange { index: 5, points: 5, first: 0 })),
                    (ele_with(3, "1  1 -1 3 4 0"), ele_error(3, IndexOutOfRange { index: -1, points: 5, first: 0 })),
                    (ele_with(3, "1  1 2 3 4x 0"), ele_error(3, NonNumeric { field: 5 })),
                    (ele_with(3, "1  1 2 3 4 region"), ele_error(3, NonNumeric { field: 6 })),
                    (ele_with(3, "0  1 2 3 4 0"), ele_error(3, NonConsecutiveIndex { expected: 1, found: 0 })),
                    (ele_with(2, "1  0 1 2 3 0"), ele_error(2, NonConsecutiveIndex { expected: 0, found: 1 })),
                ];
                for (ele, expected) in cases {
                    assert_eq!(read_tetgen(NODE_0, &ele), Err(expected), "{ele:?}");
                }
                // With 1-based points, 0 and 6 are out of range and the first tetrahedron must
                // be numbered 1.
                let one_based = |ele: &str| read_tetgen(NODE_1, ele);
                assert_eq!(
                    one_based("1 4 0\n1 0 1 2 3\n"),
                    Err(ele_error(2, IndexOutOfRange { index: 0, points: 5, first: 1 }))
                );
                assert_eq!(
                    one_based("1 4 0\n1 2 3 4 6\n"),
                    Err(ele_error(2, IndexOutOfRange { index: 6, points: 5, first: 1 }))
                );
                assert_eq!(
                    one_based("1 4 0\n0 1 2 3 4\n"),
                    Err(ele_error(2, NonConsecutiveIndex { expected: 1, found: 0 }))
                );
            }

            #[test]
            fn errors_say_where_and_what() {
                let error = read_tetgen(&node_with(5, "1  1.0 0.0 0.0  7.5"), ELE_0).unwrap_err();
                assert_eq!(error.to_string(), ".node file, line 5: expected 6 fields, found 5");
            }

            #[test]
            fn file_errors_name_the_path() {
                let dir = std::env::temp_dir().join(format!("softfem-tetgen-{}-{}", std::process::id(), stringify!($precision)));
                std::fs::create_dir_all(&dir).unwrap();
                let (node_path, ele_path) = (dir.join("m.node"), dir.join("m.ele"));
                std::fs::write(&node_path, NODE_0).unwrap();
                std::fs::write(&ele_path, ele_with(3, "1  1 2 3 9 0")).unwrap();

                let missing = dir.join("missing.ele");
                match read_tetgen_files(&node_path, &missing) {
                    Err(TetgenError::Io { path, source }) => {
                        assert_eq!(path, missing);
                        assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
                    }
                    other => panic!("expected an I/O error, got {other:?}"),
                }
                match read_tetgen_files(&node_path, &ele_path) {
                    Err(error @ TetgenError::Format { .. }) => {
                        assert_eq!(
                            error.to_string(),
                            format!("{}:3: point index 9 is out of range (5 points numbered from 0)", ele_path.display())
                        );
                        let TetgenError::Format { path, error } = error else { unreachable!() };
                        assert_eq!(path, ele_path);
                        assert_eq!(error.file, TetgenFile::Ele);
                        assert_eq!(error.line, 3);
                    }
                    other => panic!("expected a format error, got {other:?}"),
                }
                std::fs::write(&ele_path, ELE_0).unwrap();
                assert_eq!(read_tetgen_files(&node_path, &ele_path).unwrap(), two_tets());
                std::fs::remove_dir_all(&dir).unwrap();
            }

            #[test]
            fn generated_box_round_trips_through_tetgen_text() {
                // Irregular spacing (thirds, fifths) so that coordinates are not short decimals.
                let mesh = generated_box([3, 2, 5], Vec3::new(-0.3, 0.1, 2.0), Vec3::new(1.0, 0.7, 2.9));
                for first in [0, 1] {
                    for extras in [false, true] {
                        let (node, ele) = to_tetgen(&mesh.positions, &mesh.tets, first, extras);
                        assert_eq!(read_tetgen(&node, &ele).as_ref(), Ok(&mesh), "first {first}, extras {extras}");
                    }
                }
            }

            #[test]
            fn shipped_cube_is_the_generators_unit_cube() {
                let cube = unit_cube();
                let read = read_tetgen_files(asset("cube.node"), asset("cube.ele")).unwrap();
                assert_eq!(read, cube);
                let volume: Real = read
                    .tets
                    .iter()
                    .map(|t| t.map(|v| read.positions[v as usize]))
                    .map(|[x0, x1, x2, x3]| (x1 - x0).cross(x2 - x0).dot(x3 - x0) / 6.0)
                    .inspect(|&v| assert!(v > 0.0))
                    .sum();
                // 48 volumes of exactly 1/48 (dyadic corners): only the rounding of the sum.
                assert!((volume - 1.0).abs() <= 64.0 * Real::EPSILON);
            }

            /// `SOFTFEM_BLESS_ASSETS=1 cargo test --features std --test assets tetgen::` rewrites
            /// the shipped cube from the generator; otherwise the files must match what it writes.
            #[test]
            fn shipped_cube_text_is_up_to_date() {
                let cube = unit_cube();
                let (node, ele) = to_tetgen(&cube.positions, &cube.tets, 1, false);
                let node = node.replace(
                    "# written by tests/tetgen.rs\n",
                    "# The unit cube [0, 1]^3 as 2 x 2 x 2 cubes of 6 tetrahedra (BoxSplit::Kuhn6),\n\
                     # written by tests/tetgen.rs from softfem::generate::fill_box. Metres, 1-based.\n",
                );
                // Written by one precision only: the tests run in parallel and the text is the same.
                if stringify!($precision) == "single" && std::env::var_os("SOFTFEM_BLESS_ASSETS").is_some() {
                    std::fs::create_dir_all(asset("")).unwrap();
                    std::fs::write(asset("cube.node"), &node).unwrap();
                    std::fs::write(asset("cube.ele"), &ele).unwrap();
                }
                assert_eq!(std::fs::read_to_string(asset("cube.node")).unwrap(), node);
                assert_eq!(std::fs::read_to_string(asset("cube.ele")).unwrap(), ele);
            }
        }
    };
}

tetgen_tests!(single, softfem);
tetgen_tests!(double, softfem::f64);
