//! Legacy VTK (ASCII) unstructured grids, the format ParaView and VisIt open directly.
//!
//! One file per output frame, `frame_0000.vtk`, `frame_0001.vtk`, ... (ParaView groups them
//! into a time series), each holding the simulated time as `TIME` field data, the positions,
//! the cells (tetrahedra, VTK cell type 10, or triangles, type 5), the per-vertex velocity and
//! the per-cell volume ratio (current / rest volume). A `frames.vtk.series` file lists the
//! frames with their times for ParaView's file-series reader.
//! Format: "The VTK User's Guide", section "VTK File Formats", legacy format.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use softfem::glam::Vec3;

/// VTK cell type of a linear tetrahedron (`VTK_TETRA`).
pub const VTK_TETRA: u8 = 10;
/// VTK cell type of a linear triangle (`VTK_TRIANGLE`).
pub const VTK_TRIANGLE: u8 = 5;

/// The cells of one frame, as vertex indices into its positions.
#[derive(Clone, Copy, Debug)]
pub enum Cells<'a> {
    /// Tetrahedra (the whole mesh).
    Tets(&'a [[u32; 4]]),
    /// Triangles (the boundary surface).
    Triangles(&'a [[u32; 3]]),
}

impl Cells<'_> {
    fn len(&self) -> usize {
        match self {
            Cells::Tets(tets) => tets.len(),
            Cells::Triangles(triangles) => triangles.len(),
        }
    }
}

/// Everything one VTK file holds.
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    /// A one-line description (the VTK header's title line; newlines are replaced).
    pub title: &'a str,
    /// Simulated time (s).
    pub time: f64,
    /// Vertex positions (m).
    pub positions: &'a [Vec3],
    /// Velocities (m/s), one per vertex.
    pub velocities: &'a [Vec3],
    /// Cells indexing `positions`.
    pub cells: Cells<'a>,
    /// Current over rest volume, one per cell (for triangles: of the tetrahedron they bound).
    pub volume_ratios: &'a [f32],
}

/// The file name of output frame `index`: `frame_0000.vtk`, ...
pub fn frame_file_name(index: usize) -> String {
    format!("frame_{index:04}.vtk")
}

/// Whether `name` is one of [`frame_file_name`]'s names: `frame_`, four or more digits, `.vtk`.
pub fn is_frame_file_name(name: &str) -> bool {
    name.strip_prefix("frame_")
        .and_then(|rest| rest.strip_suffix(".vtk"))
        .is_some_and(|digits| digits.len() >= 4 && digits.bytes().all(|b| b.is_ascii_digit()))
}

/// Removes from `dir` every frame file ([`is_frame_file_name`]) not named in `keep`: the frames
/// a longer earlier run left there, which ParaView would otherwise show after the new series.
/// Nothing else is touched. Returns how many files were removed.
pub fn remove_stale_frames(dir: &Path, keep: &[&str]) -> io::Result<usize> {
    let mut removed = 0;
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        if is_frame_file_name(name) && !keep.contains(&name) && entry.file_type()?.is_file() {
            std::fs::remove_file(entry.path())?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// Writes `frame` to the file `path` (replacing it).
pub fn write_frame_file(path: &Path, frame: &Frame<'_>) -> io::Result<()> {
    let mut out = BufWriter::new(File::create(path)?);
    write_frame(&mut out, frame)?;
    out.flush()
}

/// Writes `frame` as a legacy ASCII VTK unstructured grid.
///
/// # Errors
/// `InvalidInput` if a per-vertex or per-cell array has the wrong length or a cell indexes past
/// the positions; any error of `out`.
pub fn write_frame(out: &mut impl Write, frame: &Frame<'_>) -> io::Result<()> {
    let (vertex_count, cell_count) = (frame.positions.len(), frame.cells.len());
    check(
        frame.velocities.len() == vertex_count,
        "one velocity per vertex",
    )?;
    check(
        frame.volume_ratios.len() == cell_count,
        "one volume ratio per cell",
    )?;
    let in_range = |v: &u32| (*v as usize) < vertex_count;
    check(
        match frame.cells {
            Cells::Tets(tets) => tets.iter().flatten().all(in_range),
            Cells::Triangles(triangles) => triangles.iter().flatten().all(in_range),
        },
        "cell vertex index out of range",
    )?;

    writeln!(out, "# vtk DataFile Version 3.0")?;
    writeln!(out, "{}", frame.title.replace(['\n', '\r'], " "))?;
    writeln!(out, "ASCII")?;
    writeln!(out, "DATASET UNSTRUCTURED_GRID")?;
    writeln!(out, "FIELD FieldData 1")?;
    writeln!(out, "TIME 1 1 double")?;
    writeln!(out, "{}", frame.time)?;
    writeln!(out, "POINTS {vertex_count} float")?;
    for p in frame.positions {
        writeln!(out, "{} {} {}", p.x, p.y, p.z)?;
    }
    match frame.cells {
        Cells::Tets(tets) => {
            writeln!(out, "CELLS {cell_count} {}", cell_count * 5)?;
            for [a, b, c, d] in tets {
                writeln!(out, "4 {a} {b} {c} {d}")?;
            }
        }
        Cells::Triangles(triangles) => {
            writeln!(out, "CELLS {cell_count} {}", cell_count * 4)?;
            for [a, b, c] in triangles {
                writeln!(out, "3 {a} {b} {c}")?;
            }
        }
    }
    let cell_type = match frame.cells {
        Cells::Tets(_) => VTK_TETRA,
        Cells::Triangles(_) => VTK_TRIANGLE,
    };
    writeln!(out, "CELL_TYPES {cell_count}")?;
    for _ in 0..cell_count {
        writeln!(out, "{cell_type}")?;
    }
    writeln!(out, "POINT_DATA {vertex_count}")?;
    writeln!(out, "VECTORS velocity float")?;
    for v in frame.velocities {
        writeln!(out, "{} {} {}", v.x, v.y, v.z)?;
    }
    writeln!(out, "CELL_DATA {cell_count}")?;
    writeln!(out, "SCALARS volume_ratio float 1")?;
    writeln!(out, "LOOKUP_TABLE default")?;
    for ratio in frame.volume_ratios {
        writeln!(out, "{ratio}")?;
    }
    Ok(())
}

/// Writes ParaView's file-series description (`*.vtk.series`, JSON) of the frames `files`
/// (file name, simulated time in s), so that ParaView shows the simulated time.
pub fn write_series_file(path: &Path, files: &[(String, f64)]) -> io::Result<()> {
    let mut out = BufWriter::new(File::create(path)?);
    writeln!(
        out,
        "{{\n  \"file-series-version\": \"1.0\",\n  \"files\": ["
    )?;
    for (i, (name, time)) in files.iter().enumerate() {
        let comma = if i + 1 < files.len() { "," } else { "" };
        writeln!(
            out,
            "    {{ \"name\": \"{name}\", \"time\": {time} }}{comma}"
        )?;
    }
    writeln!(out, "  ]\n}}")?;
    out.flush()
}

fn check(condition: bool, what: &str) -> io::Result<()> {
    if condition {
        Ok(())
    } else {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            what.to_string(),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minimal reader for what [`write_frame`] writes: sections keyed by their header line.
    struct Parsed {
        header: Vec<String>,
        time: f64,
        points: Vec<[f32; 3]>,
        cells: Vec<Vec<u32>>,
        cell_types: Vec<u8>,
        velocities: Vec<[f32; 3]>,
        ratios: Vec<f32>,
    }

    fn parse(text: &str) -> Parsed {
        let mut lines = text.lines();
        let header: Vec<String> = lines.by_ref().take(4).map(str::to_string).collect();
        let mut next = || lines.next().expect("file ends early");
        let numbers = |line: &str| -> Vec<f64> {
            line.split_whitespace()
                .map(|f| f.parse().unwrap())
                .collect()
        };
        let count_after = |line: &str, keyword: &str| -> usize {
            let fields: Vec<&str> = line.split_whitespace().collect();
            assert_eq!(fields[0], keyword, "{line}");
            fields[1].parse().unwrap()
        };
        assert_eq!(next(), "FIELD FieldData 1");
        assert_eq!(next(), "TIME 1 1 double");
        let time = numbers(next())[0];
        let n = count_after(next(), "POINTS");
        let vec3 = |v: Vec<f64>| [v[0] as f32, v[1] as f32, v[2] as f32];
        let points = (0..n).map(|_| vec3(numbers(next()))).collect();
        let cells_line = next();
        let m = count_after(cells_line, "CELLS");
        let cells: Vec<Vec<u32>> = (0..m)
            .map(|_| numbers(next()).iter().map(|&x| x as u32).collect())
            .collect();
        let total: usize = cells.iter().map(Vec::len).sum();
        assert!(cells_line.ends_with(&format!(" {total}")), "{cells_line}");
        assert_eq!(count_after(next(), "CELL_TYPES"), m);
        let cell_types = (0..m).map(|_| next().parse().unwrap()).collect();
        assert_eq!(count_after(next(), "POINT_DATA"), n);
        assert_eq!(next(), "VECTORS velocity float");
        let velocities = (0..n).map(|_| vec3(numbers(next()))).collect();
        assert_eq!(count_after(next(), "CELL_DATA"), m);
        assert_eq!(next(), "SCALARS volume_ratio float 1");
        assert_eq!(next(), "LOOKUP_TABLE default");
        let ratios = (0..m).map(|_| next().parse().unwrap()).collect();
        assert_eq!(lines.next(), None);
        Parsed {
            header,
            time,
            points,
            cells,
            cell_types,
            velocities,
            ratios,
        }
    }

    const X: [Vec3; 5] = [
        Vec3::ZERO,
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        Vec3::new(0.25, 0.5, -1.5),
    ];
    const V: [Vec3; 5] = [
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, -2.5),
        Vec3::ZERO,
        Vec3::ZERO,
        Vec3::new(1e-7, 3.0, 0.0),
    ];

    #[test]
    fn tets_round_trip() {
        let tets = [[0, 1, 2, 3], [0, 2, 1, 4]];
        let frame = Frame {
            title: "two tets\nsecond line",
            time: 0.125,
            positions: &X,
            velocities: &V,
            cells: Cells::Tets(&tets),
            volume_ratios: &[1.0, 0.875],
        };
        let mut bytes = Vec::new();
        write_frame(&mut bytes, &frame).unwrap();
        let parsed = parse(&String::from_utf8(bytes).unwrap());
        assert_eq!(parsed.header[0], "# vtk DataFile Version 3.0");
        assert_eq!(parsed.header[1], "two tets second line");
        assert_eq!(parsed.header[2..], ["ASCII", "DATASET UNSTRUCTURED_GRID"]);
        assert_eq!(parsed.time, 0.125);
        // Rust prints the shortest string that parses back to the same f32: exact round trip.
        assert_eq!(parsed.points, X.map(|p| p.to_array()));
        assert_eq!(parsed.velocities, V.map(|v| v.to_array()));
        assert_eq!(parsed.cells, [vec![4, 0, 1, 2, 3], vec![4, 0, 2, 1, 4]]);
        assert_eq!(parsed.cell_types, [VTK_TETRA; 2]);
        assert_eq!(parsed.ratios, [1.0, 0.875]);
    }

    #[test]
    fn triangles_round_trip() {
        let triangles = [[0, 2, 1], [1, 2, 3], [0, 1, 3]];
        let frame = Frame {
            title: "surface",
            time: 2.0,
            positions: &X,
            velocities: &V,
            cells: Cells::Triangles(&triangles),
            volume_ratios: &[1.0, 1.5, 0.5],
        };
        let mut bytes = Vec::new();
        write_frame(&mut bytes, &frame).unwrap();
        let parsed = parse(&String::from_utf8(bytes).unwrap());
        assert_eq!(parsed.cells.len(), 3);
        assert!(parsed.cells.iter().all(|c| c.len() == 4 && c[0] == 3));
        assert_eq!(parsed.cell_types, [VTK_TRIANGLE; 3]);
        assert_eq!(parsed.ratios, [1.0, 1.5, 0.5]);
    }

    #[test]
    fn inconsistent_frames_are_refused() {
        let tets = [[0, 1, 2, 5]];
        let frame = Frame {
            title: "bad",
            time: 0.0,
            positions: &X,
            velocities: &V,
            cells: Cells::Tets(&tets),
            volume_ratios: &[1.0],
        };
        let error = write_frame(&mut Vec::new(), &frame).unwrap_err();
        assert_eq!(error.kind(), io::ErrorKind::InvalidInput);
        let short = Frame {
            velocities: &V[..2],
            cells: Cells::Tets(&[[0, 1, 2, 3]]),
            ..frame
        };
        assert!(write_frame(&mut Vec::new(), &short).is_err());
    }

    #[test]
    fn file_names_and_series() {
        assert_eq!(frame_file_name(7), "frame_0007.vtk");
        assert_eq!(frame_file_name(12345), "frame_12345.vtk");
        let dir = std::env::temp_dir().join(format!("bouncy-vtk-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("frames.vtk.series");
        write_series_file(
            &path,
            &[(frame_file_name(0), 0.0), (frame_file_name(1), 0.5)],
        )
        .unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("{ \"name\": \"frame_0001.vtk\", \"time\": 0.5 }\n"));
        assert!(text.contains("\"time\": 0 },\n"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn stale_frames_of_a_longer_run_are_removed_and_nothing_else() {
        assert!(is_frame_file_name("frame_0000.vtk") && is_frame_file_name("frame_12345.vtk"));
        for name in [
            "frame_000.vtk",
            "frame_00a0.vtk",
            "frame_0000.vtu",
            "frames.vtk.series",
        ] {
            assert!(!is_frame_file_name(name), "{name}");
        }
        let dir = std::env::temp_dir().join(format!("bouncy-stale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let names = [
            "frame_0000.vtk",
            "frame_0001.vtk",
            "frame_0002.vtk",
            "frame_0003.vtk",
        ];
        for name in names
            .iter()
            .chain(&["notes.txt", "frame_7.vtk", "filmstrip.svg"])
        {
            std::fs::write(dir.join(name), "x").unwrap();
        }
        assert_eq!(remove_stale_frames(&dir, &names[..2]).unwrap(), 2);
        let mut left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        left.sort();
        let expected = [
            "filmstrip.svg",
            "frame_0000.vtk",
            "frame_0001.vtk",
            "frame_7.vtk",
        ];
        assert_eq!(left, [&expected[..], &["notes.txt"]].concat());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
