//! The elastic models the steppers advance: the traits a body implements ([`ElasticModel`] for
//! the explicit stepper, [`ElasticEnergy`] for the descent solvers' line search,
//! [`ElasticHessian`] for Newton and VBD) and the models the crate ships (tetrahedra with the
//! direct or the clamped stress, 2D triangles, membranes).

use super::super::element::{TetHessian, TriangleStVK, Vector};
use super::super::material::Material;
use super::super::mesh::{MembraneMesh, TetMesh, TriMesh};
use super::super::types::{Mat3, Real, Vec2, Vec3};
use super::explicit::stability;
use super::vertex_pass::{InOrder, VertexPass};
use crate::error::MeshError;

/// An elastic body the explicit stepper can advance: a validated mesh, a material and a force
/// path. Implement it to plug in other force models (extra springs, a different element).
pub trait ElasticModel {
    /// The position, velocity and force type (`Vec3`, or `Vec2` for 2D solids).
    type Vector: Vector;

    /// The number of vertices: the length of every per-vertex buffer.
    fn vertex_count(&self) -> usize;

    /// Adds the elastic forces (N) at `positions` (m) into `forces`.
    ///
    /// # Errors
    /// As the mesh kernels: length mismatch or non-finite positions; `forces` unchanged then.
    fn add_forces(
        &self,
        positions: &[Self::Vector],
        forces: &mut [Self::Vector],
    ) -> Result<(), MeshError>;

    /// Calls `visit(corners, stiffness, measure)` for every element: its vertex indices, an upper
    /// bound (N/m) on the largest eigenvalue of its small-strain stiffness matrix at rest, and its
    /// rest volume or area (m^3 or m^2). Used by [`stable_time_step`](super::stable_time_step) and
    /// by the relaxation's preconditioner; see `step/explicit/stability.rs` for the derivation.
    fn for_each_element_stiffness(&self, visit: impl FnMut(&[u32], Real, Real));

    /// Runs one of the steppers' passes over the vertices (integration, contact projection,
    /// trial points, residuals), split into blocks of [`VERTEX_BLOCK`](super::vertex_pass::VERTEX_BLOCK)
    /// vertices. The default runs it on the calling thread ([`InOrder`](super::vertex_pass::InOrder)); a model
    /// whose forces run on a thread pool (as `parallel::ParallelTetElastic`, feature `rayon`)
    /// returns `pass.run_with(&join)` with its pool's [`Join`](super::vertex_pass::Join), which gives the same
    /// bits.
    #[inline]
    fn run_vertex_pass<P: VertexPass>(&self, pass: P) -> P::Output {
        pass.run_with(&InOrder)
    }

    /// Whether [`limit_motion`](Self::limit_motion) acts: the explicit stepper then keeps each
    /// substep's start positions, in a fifth vector per vertex of its scratch
    /// ([`scratch_len::explicit_contact`](super::scratch_len::explicit_contact)). `false` by
    /// default.
    #[inline]
    fn limits_motion(&self) -> bool {
        false
    }

    /// The explicit stepper's contact between surfaces, after each substep's update: the
    /// vertices moved from `from` to `to` (m) and have the `velocities` (m/s), with `masses`
    /// (kg) and `pinned` (empty: none) over the substep `h` (s). A model whose surfaces must not
    /// pass through each other (the contact model of
    /// [`ContactModel`](super::contact::ContactModel)) changes `to` and `velocities` so that
    /// they do not, and returns whether it had to shorten the whole substep's motion (its
    /// failsafe). Called only where [`limits_motion`](Self::limits_motion); the default does
    /// nothing.
    ///
    /// # Errors
    /// The model's own (a contact buffer too small, say); the stepper then restores the state.
    #[inline]
    fn limit_motion(
        &self,
        from: &[Self::Vector],
        to: &mut [Self::Vector],
        velocities: &mut [Self::Vector],
        (masses, pinned): (&[Real], &[bool]),
        h: Real,
    ) -> Result<bool, MeshError> {
        let _ = (from, to, velocities, masses, pinned, h);
        Ok(false)
    }
}

/// An [`ElasticModel`] whose forces are minus the gradient of an energy, as the relaxation
/// ([`relax_step`](super::relax_step), [`relax_quasi_static`](super::relax_quasi_static)) needs for
/// its line search.
pub trait ElasticEnergy: ElasticModel {
    /// Returns the elastic energy (J) at `positions` (m) and adds the elastic forces (N) into
    /// `forces`, in one pass. NaN or infinite positions give a non-finite energy (not an error).
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] if a buffer does not have one entry per vertex.
    fn energy_and_add_forces(
        &self,
        positions: &[Self::Vector],
        forces: &mut [Self::Vector],
    ) -> Result<Real, MeshError>;

    /// The largest fraction `t` in `[0, 1]` of the straight motion from `from` to `to` (m, one
    /// position per vertex) that the model admits: every point `from + s (to - from)` with
    /// `s <= t` keeps its surfaces apart. 1 (the default) for a model without contact; a
    /// [`ContactModel`](super::contact::model::ContactModel) answers by continuous collision
    /// detection. The descent solvers take no trial point or initial guess beyond it, so that no
    /// iterate is reached through an intersection.
    ///
    /// # Errors
    /// The model's (a contact model's buffers and inputs).
    #[inline]
    fn admissible_step(
        &self,
        from: &[Self::Vector],
        to: &[Self::Vector],
    ) -> Result<Real, MeshError> {
        let _ = (from, to);
        Ok(1.0)
    }

    /// Called once at the start of every implicit solve with the start positions `x_n` (m, in
    /// the solve's coordinates, which may be shifted by a constant from the caller's: see
    /// `step/descent/mod.rs`) and the step `h` (s; 0 for a quasi-static solve): where a model
    /// lags what it holds fixed over a step. Nothing by default; a
    /// [`ContactModel`](super::contact::model::ContactModel) with friction finds its
    /// frictional pairs and their normal forces there.
    ///
    /// # Errors
    /// The model's (a contact model's friction buffer too small); the step fails with it and
    /// the state is restored.
    #[inline]
    fn begin_solve(&self, start: &[Self::Vector], h: Real) -> Result<(), MeshError> {
        let _ = (start, h);
        Ok(())
    }
}

/// An [`ElasticEnergy`] with second derivatives, as Newton's method
/// ([`newton_step`](super::newton_step), [`newton_quasi_static`](super::newton_quasi_static))
/// needs: the projected (SPD) Hessian cached per element in a caller buffer, its product with a
/// direction and its 3x3 diagonal blocks (`docs/math.md` section 6).
pub trait ElasticHessian: ElasticEnergy<Vector = Vec3> {
    /// The number of elements: the length of the Hessian cache.
    fn element_count(&self) -> usize;

    /// Writes the projected Hessian data of every element at `positions` (m) into `cache`.
    ///
    /// # Errors
    /// As [`TetMesh::projected_hessians`]; `cache` unchanged then.
    fn projected_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError>;

    /// Writes the exact (unprojected, possibly indefinite) Hessian data of every element at
    /// `positions` (m) into `cache` and returns `true`, or returns `false` without writing
    /// anything where the model has none (the default): Newton's method then keeps the
    /// projected Hessian near the solution too (`docs/math.md` section 7.1.2).
    ///
    /// # Errors
    /// As [`TetMesh::exact_hessians`]; `cache` unchanged then.
    #[inline]
    fn exact_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<bool, MeshError> {
        let _ = (positions, cache);
        Ok(false)
    }

    /// Adds `H d` (N) into `out` for the Hessian in `cache` and the direction `direction` (m).
    ///
    /// # Errors
    /// As [`TetMesh::add_hessian_product`]; `out` unchanged then.
    fn add_hessian_product(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), MeshError>;

    /// Adds the 3x3 diagonal blocks (N/m) of the Hessian in `cache` into `blocks`.
    ///
    /// # Errors
    /// As [`TetMesh::add_vertex_hessian_blocks`]; `blocks` unchanged then.
    fn add_vertex_hessian_blocks(
        &self,
        cache: &[TetHessian],
        blocks: &mut [Mat3],
    ) -> Result<(), MeshError>;

    /// Calls `visit(corners, hessian)` for every tetrahedron in element order with its entry of
    /// `cache` and returns `true`, or returns `false` without a call where the model's Hessian is
    /// not a sum of tetrahedra over its vertices (the default). An assembled Hessian is built
    /// from it: Newton's multilevel preconditioner (feature `alloc`) needs it and falls back
    /// to block Jacobi where a model answers `false`.
    #[inline]
    fn for_each_element_hessian(
        &self,
        cache: &[TetHessian],
        visit: impl FnMut([u32; 4], &TetHessian),
    ) -> bool {
        let _ = (cache, visit);
        false
    }
}

/// A tetrahedral body with the direct stress [`Material::first_piola`]: the forces are the
/// exact gradient of [`TetMesh::elastic_energy`], so both steppers accept it.
#[derive(Clone, Copy, Debug)]
pub struct TetElastic<'a, M: Material> {
    /// The validated mesh.
    pub mesh: TetMesh<'a>,
    /// The material.
    pub material: M,
}

impl<'a, M: Material> TetElastic<'a, M> {
    /// `material` on `mesh`.
    #[inline]
    #[must_use]
    pub fn new(mesh: TetMesh<'a>, material: M) -> Self {
        TetElastic { mesh, material }
    }
}

/// A tetrahedral body with the clamped principal stress
/// ([`TetMesh::add_elastic_forces_clamped`]): inverted elements are pushed back. **Not an
/// energy gradient: explicit stepping only** (it does not implement [`ElasticEnergy`]).
#[derive(Clone, Copy, Debug)]
pub struct TetClamped<'a, M: Material> {
    /// The validated mesh.
    pub mesh: TetMesh<'a>,
    /// The material.
    pub material: M,
    /// The smallest stretch the stress sees (dimensionless, typically `0.2..0.5`).
    pub threshold: Real,
}

impl<'a, M: Material> TetClamped<'a, M> {
    /// `material` on `mesh`, stretches clamped from below at `threshold`. Not checked here: a
    /// `threshold` outside `(0, 1]` makes every force evaluation (and so every step) fail with
    /// [`MeshError::ClampThreshold`]; [`checked`](Self::checked) refuses it up front.
    #[inline]
    #[must_use]
    pub fn new(mesh: TetMesh<'a>, material: M, threshold: Real) -> Self {
        TetClamped {
            mesh,
            material,
            threshold,
        }
    }

    /// As [`new`](Self::new), checking `threshold`.
    ///
    /// # Errors
    /// [`MeshError::ClampThreshold`] if `threshold` is not in `(0, 1]`.
    #[inline]
    pub fn checked(mesh: TetMesh<'a>, material: M, threshold: Real) -> Result<Self, MeshError> {
        super::super::mesh::check_clamp_threshold(threshold)?;
        Ok(Self::new(mesh, material, threshold))
    }
}

/// A 2D triangle body (plane strain, per unit thickness) for the explicit stepper.
#[derive(Clone, Copy, Debug)]
pub struct TriElastic<'a> {
    /// The validated mesh.
    pub mesh: TriMesh<'a>,
    /// The material.
    pub material: TriangleStVK,
}

/// A membrane (triangles in space) for the explicit stepper.
#[derive(Clone, Copy, Debug)]
pub struct MembraneElastic<'a> {
    /// The validated mesh.
    pub mesh: MembraneMesh<'a>,
    /// The material (moduli in N/m for forces in N).
    pub material: TriangleStVK,
}

/// The [`ElasticModel`] of a shipped model whose `mesh` counts the vertices: its forces from
/// `add_forces` (with `model` the model) and the per-element stiffness bounds of the
/// explicit stepper from `stiffness`.
macro_rules! shipped_model {
    (
        impl[$($generics:tt)*] for $model_type:ty, $vector:ident,
        add_forces: |$model:ident, $positions:ident, $forces:ident| $add_forces:expr,
        stiffness: |$visit:ident| $stiffness:expr $(,)?
    ) => {
        impl<$($generics)*> ElasticModel for $model_type {
            type Vector = $vector;
            #[inline]
            fn vertex_count(&self) -> usize {
                self.mesh.vertex_count()
            }
            #[inline]
            fn add_forces(
                &self,
                $positions: &[$vector],
                $forces: &mut [$vector],
            ) -> Result<(), MeshError> {
                let $model = self;
                $add_forces
            }
            fn for_each_element_stiffness(&self, $visit: impl FnMut(&[u32], Real, Real)) {
                let $model = self;
                $stiffness
            }
        }
    };
}

shipped_model! {
    impl[M: Material] for TetElastic<'_, M>, Vec3,
    add_forces: |model, positions, forces| {
        model.mesh.add_elastic_forces(&model.material, positions, forces)
    },
    stiffness: |visit| stability::tet_stiffness(&model.mesh, &model.material, visit),
}

impl<M: Material> ElasticEnergy for TetElastic<'_, M> {
    fn energy_and_add_forces(
        &self,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, MeshError> {
        self.mesh
            .energy_and_add_forces(&self.material, positions, forces)
    }
}

impl<M: Material> ElasticHessian for TetElastic<'_, M> {
    #[inline]
    fn element_count(&self) -> usize {
        self.mesh.element_count()
    }
    fn projected_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        self.mesh
            .projected_hessians(&self.material, positions, cache)
    }
    fn exact_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<bool, MeshError> {
        self.mesh
            .exact_hessians(&self.material, positions, cache)
            .map(|()| true)
    }
    fn add_hessian_product(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        self.mesh.add_hessian_product(cache, direction, out)
    }
    fn add_vertex_hessian_blocks(
        &self,
        cache: &[TetHessian],
        blocks: &mut [Mat3],
    ) -> Result<(), MeshError> {
        self.mesh.add_vertex_hessian_blocks(cache, blocks)
    }
    fn for_each_element_hessian(
        &self,
        cache: &[TetHessian],
        mut visit: impl FnMut([u32; 4], &TetHessian),
    ) -> bool {
        for (&corners, hessian) in self.mesh.tets().iter().zip(cache) {
            visit(corners, hessian);
        }
        true
    }
}

shipped_model! {
    impl[M: Material] for TetClamped<'_, M>, Vec3,
    add_forces: |model, positions, forces| {
        let (material, threshold) = (&model.material, model.threshold);
        model.mesh.add_elastic_forces_clamped(material, threshold, positions, forces)
    },
    stiffness: |visit| stability::tet_stiffness(&model.mesh, &model.material, visit),
}

shipped_model! {
    impl[] for TriElastic<'_>, Vec2,
    add_forces: |model, positions, forces| {
        model.mesh.add_elastic_forces(&model.material, positions, forces)
    },
    stiffness: |visit| {
        let (mesh, material) = (&model.mesh, &model.material);
        stability::triangle_stiffness(mesh.tris(), mesh.rest(), material, visit);
    },
}

shipped_model! {
    impl[] for MembraneElastic<'_>, Vec3,
    add_forces: |model, positions, forces| {
        model.mesh.add_elastic_forces(&model.material, positions, forces)
    },
    stiffness: |visit| {
        let (mesh, material) = (&model.mesh, &model.material);
        stability::triangle_stiffness(mesh.tris(), mesh.rest(), material, visit);
    },
}
