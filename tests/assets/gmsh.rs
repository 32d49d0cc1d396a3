//! The Gmsh 4.1 reader: a hand-written file with skipped sections, sparse node tags, a
//! parametric block, points and lines, triangles and tetrahedra; every malformed case with its
//! line and problem; file errors with their paths; a round trip through the generator's box.
#![cfg(feature = "std")]

use softfem::asset::gmsh::{read_gmsh, read_gmsh_file};
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::Vec3;
use softfem::{AssetFileError, GmshFormatError, GmshProblem, GmshSection};

/// Two tetrahedra sharing the face of nodes 20-30-40, the shared triangle as a surface element,
/// a point and a line element; node tags sparse and out of order. Line numbers matter.
const MESH: &str = "\
$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
1
3 1 \"jelly\"
$EndPhysicalNames
$Entities
0 0 0 1
1 0 0 0 1 1 1 0 0
$EndEntities
$Nodes
2 5 10 50
0 1 0 1
10
0 0 0
3 1 1 4
20
30
40
50
1 0 0 0.1 0.2 0.3
0 1 0 0.1 0.2 0.3
0 0 1 0.1 0.2 0.3
1 1 1.5 0.1 0.2 0.3
$EndNodes
$Elements
4 5 1 5
0 1 15 1
1 10
1 1 1 1
2 10 20
2 7 2 1
3 20 30 40
3 1 4 2
4 10 20 30 40
5 20 30 40 50
$EndElements
";

fn error(line: usize, problem: GmshProblem) -> GmshFormatError {
    GmshFormatError { line, problem }
}

#[test]
fn reads_tets_triangles_and_entities() {
    let mesh = read_gmsh(MESH).unwrap();
    assert_eq!(
        mesh.positions,
        vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(1.0, 1.0, 1.5)
        ]
    );
    assert_eq!(mesh.tets, vec![[0, 1, 2, 3], [1, 2, 3, 4]]);
    assert_eq!(mesh.tet_entities, vec![1, 1]);
    assert_eq!(mesh.triangles, vec![[1, 2, 3]]);
    assert_eq!(mesh.triangle_entities, vec![7]);
    // CRLF line ends and blank lines read the same.
    let crlf = MESH.replace('\n', "\r\n\r\n");
    assert_eq!(read_gmsh(&crlf).unwrap(), mesh);
    // The f64 API reads the same mesh.
    let double = softfem::f64::asset::gmsh::read_gmsh(MESH).unwrap();
    assert_eq!(double.tets, mesh.tets);
}

/// Replaces line `line` (1-based) of `MESH` with `with`.
fn with_line(line: usize, with: &str) -> String {
    MESH.lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == line { with } else { l })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn malformed_files_name_line_and_problem() {
    let cases: Vec<(String, GmshFormatError)> = vec![
        (
            with_line(2, "2.2 0 8"),
            error(2, GmshProblem::UnsupportedVersion),
        ),
        (with_line(2, "4.1 1 8"), error(2, GmshProblem::Binary)),
        (
            with_line(2, "4.1"),
            error(
                2,
                GmshProblem::FieldCount {
                    expected: 3,
                    found: 1,
                },
            ),
        ),
        (
            with_line(3, "$EndFormat"),
            error(3, GmshProblem::ExpectedEnd(GmshSection::MeshFormat)),
        ),
        (
            with_line(13, "2 6 10 50"),
            error(
                13,
                GmshProblem::CountMismatch {
                    expected: 6,
                    found: 5,
                },
            ),
        ),
        (
            with_line(13, "2 5 10"),
            error(
                13,
                GmshProblem::FieldCount {
                    expected: 4,
                    found: 3,
                },
            ),
        ),
        (
            with_line(15, "x"),
            error(15, GmshProblem::BadField { field: 1 }),
        ),
        (
            with_line(16, "0 0"),
            error(
                16,
                GmshProblem::FieldCount {
                    expected: 3,
                    found: 2,
                },
            ),
        ),
        (
            with_line(16, "0 nan 0"),
            error(16, GmshProblem::NonFiniteCoordinate),
        ),
        (
            with_line(16, "0 zero 0"),
            error(16, GmshProblem::BadField { field: 2 }),
        ),
        (
            with_line(19, "10"),
            error(19, GmshProblem::DuplicateNode { tag: 10 }),
        ),
        (
            with_line(23, "1 0 0 0.1 0.2"),
            error(
                23,
                GmshProblem::FieldCount {
                    expected: 6,
                    found: 5,
                },
            ),
        ),
        (
            with_line(26, "$EndNode"),
            error(26, GmshProblem::ExpectedEnd(GmshSection::Nodes)),
        ),
        (
            with_line(33, "3 7 3 1"),
            error(33, GmshProblem::UnsupportedElement { element_type: 3 }),
        ),
        (
            with_line(35, "3 1 11 2"),
            error(35, GmshProblem::UnsupportedElement { element_type: 11 }),
        ),
        (
            with_line(34, "3 20 30 41"),
            error(34, GmshProblem::UnknownNode { tag: 41 }),
        ),
        (
            with_line(36, "4 10 20 30"),
            error(
                36,
                GmshProblem::FieldCount {
                    expected: 5,
                    found: 4,
                },
            ),
        ),
        (
            with_line(37, "5 20 30 x 50"),
            error(37, GmshProblem::BadField { field: 4 }),
        ),
        (
            with_line(37, "q 20 30 40 50"),
            error(37, GmshProblem::BadField { field: 1 }),
        ),
        (
            with_line(28, "4 6 1 5"),
            error(
                28,
                GmshProblem::CountMismatch {
                    expected: 6,
                    found: 5,
                },
            ),
        ),
        (
            with_line(38, ""),
            error(38, GmshProblem::UnterminatedSection(GmshSection::Elements)),
        ),
    ];
    for (text, expected) in cases {
        assert_eq!(read_gmsh(&text), Err(expected), "{expected}");
    }
    // Missing sections.
    let no_elements: String = MESH.lines().take(26).collect::<Vec<_>>().join("\n");
    assert_eq!(
        read_gmsh(&no_elements),
        Err(error(
            27,
            GmshProblem::MissingSection(GmshSection::Elements)
        ))
    );
    let no_format: String = MESH.lines().skip(3).collect::<Vec<_>>().join("\n");
    assert_eq!(
        read_gmsh(&no_format),
        Err(error(
            9,
            GmshProblem::MissingSection(GmshSection::MeshFormat)
        ))
    );
    assert_eq!(
        read_gmsh("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Elements\n0 0 0 0\n$EndElements\n"),
        Err(error(4, GmshProblem::MissingSection(GmshSection::Nodes)))
    );
    assert_eq!(
        read_gmsh(""),
        Err(error(
            1,
            GmshProblem::MissingSection(GmshSection::MeshFormat)
        ))
    );
    assert_eq!(
        read_gmsh(&with_line(34, "3 20 30 41"))
            .unwrap_err()
            .to_string(),
        "line 34: node tag 41 does not exist"
    );
}

#[test]
fn file_errors_name_the_path() {
    let dir = std::env::temp_dir().join(format!("softfem-gmsh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let missing = dir.join("missing.msh");
    let error = read_gmsh_file(&missing).unwrap_err();
    assert!(matches!(error, AssetFileError::Io { ref path, .. } if *path == missing));
    let bad = dir.join("bad.msh");
    std::fs::write(&bad, with_line(2, "2.2 0 8")).unwrap();
    let error = read_gmsh_file(&bad).unwrap_err();
    assert_eq!(
        error.to_string(),
        format!("{}:2: only MSH version 4.1 is read", bad.display())
    );
    std::fs::write(&bad, MESH).unwrap();
    assert_eq!(read_gmsh_file(&bad).unwrap(), read_gmsh(MESH).unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The generator's box written as MSH 4.1 (one node block, one element block, tags offset by
/// 100 to exercise the translation) reads back as the same mesh.
#[test]
fn generated_box_round_trips() {
    let max = Vec3::new(0.2, 0.3, 0.1);
    let (positions, tets) =
        crate::common::scenes::generated_box!(Vec3::ZERO, max, (2, 3, 1), BoxSplit::Alternating5);
    let (vertex_count, tet_count) = (positions.len(), tets.len());
    let mut text = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n");
    text += &format!(
        "1 {vertex_count} 100 {}\n3 1 0 {vertex_count}\n",
        99 + vertex_count
    );
    for i in 0..vertex_count {
        text += &format!("{}\n", 100 + i);
    }
    for x in &positions {
        text += &format!("{} {} {}\n", x.x, x.y, x.z);
    }
    text += &format!("$EndNodes\n$Elements\n1 {tet_count} 1 {tet_count}\n3 1 4 {tet_count}\n");
    for (i, t) in tets.iter().enumerate() {
        text += &format!(
            "{} {} {} {} {}\n",
            i + 1,
            t[0] + 100,
            t[1] + 100,
            t[2] + 100,
            t[3] + 100
        );
    }
    text += "$EndElements\n";
    let mesh = read_gmsh(&text).unwrap();
    assert_eq!(mesh.positions, positions);
    assert_eq!(mesh.tets, tets);
    assert!(mesh.triangles.is_empty());
}
