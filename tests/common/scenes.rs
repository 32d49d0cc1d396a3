//! Scene set-ups the test suites repeat, written once.
//!
//! Each test suite is a macro instantiated once per precision, and the f32 and f64 APIs are
//! distinct types (`softfem::generate::BoxSplit` is not `softfem::f64::generate::BoxSplit`), so
//! the set-ups are macros too: the names they use (`box_counts`, `fill_box`, `Vec3`, `TetRest`,
//! `TetMesh`) resolve to the items of the precision in scope where they expand. Each does what
//! the suites did by hand, with the same numbers, so every test checks what it checked before.

/// `(rest, tets)`: the box from corner `$low` to corner `$high` in `($nx, $ny, $nz)` cells, each
/// split by `$split` (`generate::fill_box`), in buffers sized by `generate::box_counts`.
macro_rules! generated_box {
    ($low:expr, $high:expr, $cells:expr, $split:expr) => {{
        let (nx, ny, nz) = $cells;
        let split = $split;
        let (vertices, elements) = box_counts(nx, ny, nz, split).unwrap();
        let (mut rest, mut tets) = (vec![Vec3::ZERO; vertices], vec![[0; 4]; elements]);
        fill_box($low, $high, nx, ny, nz, split, &mut rest, &mut tets).unwrap();
        (rest, tets)
    }};
}
pub(crate) use generated_box;

/// Declares `$rest_data` (one `TetRest` per element), `$mesh` (`TetMesh::new` of `$rest`,
/// `$tets`) and `$masses` (the mesh's lumped masses at density `$density`, kg/m^3) where it
/// expands, with `TetRest` and `TetMesh` of the precision in scope there.
macro_rules! mesh_and_masses {
    ($rest_data:ident, $mesh:ident, $masses:ident; $rest:expr, $tets:expr, $density:expr) => {
        let mut $rest_data = vec![TetRest::default(); $tets.len()];
        let $mesh = TetMesh::new($rest, $tets, &mut $rest_data).unwrap();
        #[allow(unused_mut)]
        let mut $masses = vec![0.0; $mesh.vertex_count()];
        $mesh.lumped_masses($density, &mut $masses).unwrap();
    };
}
pub(crate) use mesh_and_masses;

/// Declares `Buffers` where it expands: owned scratch for Newton's method, sized by
/// `scratch_len::newton`, with `Vec3`, `Mat3`, `TetHessian`, `NewtonScratch` and `scratch_len`
/// of the precision in scope there.
macro_rules! newton_buffers {
    () => {
        /// Owned scratch buffers for Newton's method.
        struct Buffers {
            vectors: Vec<Vec3>,
            blocks: Vec<Mat3>,
            hessians: Vec<TetHessian>,
        }

        impl Buffers {
            fn new(vertices: usize, elements: usize) -> Self {
                let len = scratch_len::newton(vertices, elements);
                Buffers {
                    vectors: vec![Vec3::ZERO; len.vectors],
                    blocks: vec![Mat3::ZERO; len.blocks],
                    hessians: vec![TetHessian::default(); len.hessians],
                }
            }

            fn scratch(&mut self) -> NewtonScratch<'_> {
                NewtonScratch::new(&mut self.vectors, &mut self.blocks, &mut self.hessians)
            }
        }
    };
}
pub(crate) use newton_buffers;
