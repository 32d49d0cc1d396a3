//! Legacy VTK files of several tetrahedral bodies in one unstructured grid, with a `body` cell
//! field telling them apart.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use softfem::glam::Vec3;

/// Writes the bodies (`positions[k]` and `tets[k]` of body `k`) at `time` (s) into `path`.
pub fn write(
    path: &Path,
    time: f64,
    positions: &[&[Vec3]],
    tets: &[&[[u32; 4]]],
) -> io::Result<()> {
    let mut out = BufWriter::new(File::create(path)?);
    let points: usize = positions.iter().map(|p| p.len()).sum();
    let cells: usize = tets.iter().map(|t| t.len()).sum();
    writeln!(out, "# vtk DataFile Version 3.0")?;
    writeln!(out, "softfem playground")?;
    writeln!(out, "ASCII")?;
    writeln!(out, "DATASET UNSTRUCTURED_GRID")?;
    writeln!(out, "FIELD FieldData 1")?;
    writeln!(out, "TIME 1 1 double")?;
    writeln!(out, "{time}")?;
    writeln!(out, "POINTS {points} float")?;
    for p in positions.iter().flat_map(|p| p.iter()) {
        writeln!(out, "{} {} {}", p.x, p.y, p.z)?;
    }
    writeln!(out, "CELLS {cells} {}", cells * 5)?;
    let mut offset = 0;
    for (body, cells) in positions.iter().zip(tets) {
        for [a, b, c, d] in cells.iter().map(|t| t.map(|i| i as usize + offset)) {
            writeln!(out, "4 {a} {b} {c} {d}")?;
        }
        offset += body.len();
    }
    writeln!(out, "CELL_TYPES {cells}")?;
    for _ in 0..cells {
        writeln!(out, "10")?; // VTK_TETRA
    }
    writeln!(out, "CELL_DATA {cells}")?;
    writeln!(out, "SCALARS body int 1")?;
    writeln!(out, "LOOKUP_TABLE default")?;
    for (k, cells) in tets.iter().enumerate() {
        for _ in cells.iter() {
            writeln!(out, "{k}")?;
        }
    }
    out.flush()
}
