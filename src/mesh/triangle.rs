//! Triangle meshes: 2D solids and membranes, with [`TriangleStVK`].

use super::super::element::{TriRest, TriangleStVK, Vector};
use super::super::types::{Real, Vec2, Vec3};
use super::{check_length, check_positions, gather, scatter_add, validate};
use crate::error::{Buffer, ElementError, MeshError};

/// The validated triangles of a [`TriMesh`] or [`MembraneMesh`], and the kernels written once
/// over the position type.
#[derive(Clone, Copy, Debug)]
struct Triangles<'a> {
    tris: &'a [[u32; 3]],
    rest: &'a [TriRest],
    vertex_count: usize,
}

impl<'a> Triangles<'a> {
    fn new<V: Vector>(
        rest_positions: &[V],
        tris: &'a [[u32; 3]],
        rest: &'a mut [TriRest],
        rest_data: fn([V; 3]) -> Result<TriRest, ElementError>,
    ) -> Result<Self, MeshError> {
        let vertex_count = validate(rest_positions, tris, rest, rest_data)?;
        Ok(Triangles {
            tris,
            rest,
            vertex_count,
        })
    }

    fn check_positions<V: Vector>(&self, positions: &[V]) -> Result<(), MeshError> {
        check_positions(self.vertex_count, positions)
    }

    fn add_elastic_forces<V: Vector>(
        &self,
        material: &TriangleStVK,
        positions: &[V],
        forces: &mut [V],
    ) -> Result<(), MeshError> {
        self.check_positions(positions)?;
        check_length(Buffer::Forces, self.vertex_count, forces.len())?;
        for (corners, rest) in self.tris.iter().zip(self.rest) {
            let f = rest.gradient(gather(positions, corners));
            scatter_add(forces, corners, rest.forces(material.piola(f)));
        }
        Ok(())
    }

    fn elastic_energy<V: Vector>(
        &self,
        material: &TriangleStVK,
        positions: &[V],
    ) -> Result<Real, MeshError> {
        self.check_positions(positions)?;
        Ok(self
            .tris
            .iter()
            .zip(self.rest)
            .map(|(corners, rest)| {
                rest.area * material.energy(rest.gradient(gather(positions, corners)))
            })
            .sum())
    }

    fn lumped_masses(&self, density: Real, masses: &mut [Real]) -> Result<(), MeshError> {
        super::lumped_masses(
            self.tris,
            self.rest.iter().map(|r| r.area),
            density,
            masses,
            self.vertex_count,
        )
    }
}

/// Generates a triangle mesh type over position type `$vector`.
macro_rules! triangle_mesh {
    (
        $(#[$doc:meta])*
        $mesh:ident, $vector:ident, $rest_data:path, $rest_doc:literal, $force_unit:literal,
        $energy_unit:literal, $density_unit:literal
    ) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug)]
        pub struct $mesh<'a> {
            triangles: Triangles<'a>,
        }

        impl<'a> $mesh<'a> {
            #[doc = concat!("Validates the mesh with rest positions `rest_positions` (m) and \
                vertex indices `tris`, filling `rest` (one entry per triangle) with ", $rest_doc,
                ".")]
            ///
            /// # Errors
            /// The first problem found, in this order: [`MeshError::LengthMismatch`] (`rest`
            /// must have `tris.len()` entries), [`MeshError::NonFiniteRestPosition`],
            /// [`MeshError::IndexOutOfRange`], [`MeshError::InvertedElement`] or
            /// [`MeshError::DegenerateElement`]. On error, `rest` may be partly written.
            pub fn new(
                rest_positions: &[$vector],
                tris: &'a [[u32; 3]],
                rest: &'a mut [TriRest],
            ) -> Result<Self, MeshError> {
                Triangles::new(rest_positions, tris, rest, $rest_data)
                    .map(|triangles| $mesh { triangles })
            }

            /// The number of vertices (the length of every position, force and mass buffer).
            #[inline]
            #[must_use]
            pub fn vertex_count(&self) -> usize {
                self.triangles.vertex_count
            }

            /// The number of triangles.
            #[inline]
            #[must_use]
            pub fn element_count(&self) -> usize {
                self.triangles.tris.len()
            }

            /// The vertex indices of every triangle.
            #[inline]
            #[must_use]
            pub fn tris(&self) -> &'a [[u32; 3]] {
                self.triangles.tris
            }

            /// The rest data of every triangle.
            #[inline]
            #[must_use]
            pub fn rest(&self) -> &'a [TriRest] {
                self.triangles.rest
            }

            #[doc = concat!("Adds the elastic forces (", $force_unit, ") of `material` at \
                deformed `positions` (m) into `forces`.")]
            ///
            /// # Errors
            /// [`MeshError::LengthMismatch`] if `positions` or `forces` does not have one entry
            /// per vertex; [`MeshError::NonFinitePosition`] naming the first non-finite vertex.
            /// On error, `forces` is unchanged.
            pub fn add_elastic_forces(
                &self,
                material: &TriangleStVK,
                positions: &[$vector],
                forces: &mut [$vector],
            ) -> Result<(), MeshError> {
                self.triangles.add_elastic_forces(material, positions, forces)
            }

            #[doc = concat!("The total elastic energy `sum A W(F)` (", $energy_unit, ") at \
                deformed `positions` (m).")]
            ///
            /// # Errors
            /// As [`add_elastic_forces`](Self::add_elastic_forces) for `positions`.
            pub fn elastic_energy(
                &self,
                material: &TriangleStVK,
                positions: &[$vector],
            ) -> Result<Real, MeshError> {
                self.triangles.elastic_energy(material, positions)
            }

            #[doc = concat!("Writes the lumped mass of every vertex into `masses` (overwriting): \
                each triangle gives `density * A / 3` to each corner, with `density` in ",
                $density_unit, ".")]
            ///
            /// # Errors
            /// [`MeshError::Density`] if `density` is not finite and positive;
            /// [`MeshError::LengthMismatch`] if `masses` does not have one entry per vertex. On
            /// error, `masses` is unchanged.
            pub fn lumped_masses(&self, density: Real, masses: &mut [Real]) -> Result<(), MeshError> {
                self.triangles.lumped_masses(density, masses)
            }
        }
    };
}

triangle_mesh!(
    /// A validated mesh of 2D triangles (positions in the plane, counter-clockwise at rest), for
    /// [`TriangleStVK`] in plane strain. No heap.
    ///
    /// With moduli in Pa, energies and forces are per unit thickness (J/m, N/m) and masses per
    /// unit thickness (kg/m) for a density in kg/m^3; see [`TriangleStVK`] for thickness.
    ///
    /// ```
    /// use softfem::element::{TriRest, TriangleStVK};
    /// use softfem::glam::Vec2;
    /// use softfem::material::StVK;
    /// use softfem::mesh::TriMesh;
    ///
    /// // A unit square in two triangles.
    /// let rest = [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
    /// let tris = [[0, 1, 2], [0, 2, 3]];
    /// let mut rest_data = [TriRest::default(); 2];
    /// let mesh = TriMesh::new(&rest, &tris, &mut rest_data)?;
    /// let stvk = TriangleStVK::new(&StVK::from_lame(1.0e5, 1.0e5).unwrap());
    /// let stretched = rest.map(|x| x * Vec2::new(1.1, 1.0));
    /// let mut forces = [Vec2::ZERO; 4];
    /// mesh.add_elastic_forces(&stvk, &stretched, &mut forces)?;
    /// assert!(forces[1].x < 0.0 && forces[0].x > 0.0);
    /// # Ok::<(), softfem::MeshError>(())
    /// ```
    TriMesh, Vec2, TriRest::new, "each triangle's rest data ([`TriRest::new`])", "N/m",
    "J/m", "kg/m^3 (masses in kg/m)"
);

triangle_mesh!(
    /// A validated mesh of membrane triangles (cloth, sheets): positions in space, each
    /// triangle's rest shape measured in its own plane. [`TriangleStVK`] only; no bending
    /// stiffness. No heap.
    ///
    /// For energies in J and forces in N, build the material with moduli times thickness (N/m;
    /// see [`TriangleStVK`]) and give the density per unit area (kg/m^2).
    ///
    /// ```
    /// use softfem::element::{TriRest, TriangleStVK};
    /// use softfem::glam::Vec3;
    /// use softfem::material::StVK;
    /// use softfem::mesh::MembraneMesh;
    ///
    /// let rest = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z];
    /// let tris = [[0, 1, 2], [0, 2, 3]];
    /// let mut rest_data = [TriRest::default(); 2];
    /// let mesh = MembraneMesh::new(&rest, &tris, &mut rest_data)?;
    /// let mut masses = [0.0; 4];
    /// mesh.lumped_masses(0.2, &mut masses)?; // kg/m^2
    /// assert!((masses.iter().sum::<f32>() - 0.2).abs() < 1e-6);
    /// # Ok::<(), softfem::MeshError>(())
    /// ```
    MembraneMesh, Vec3, TriRest::membrane,
    "each triangle's rest data in its own plane ([`TriRest::membrane`])", "N, with moduli in N/m",
    "J, with moduli in N/m", "kg/m^2"
);
