//! The elastic model of a whole world: every body's tetrahedra over one vertex array, each body
//! with its own material, summed in body order (so the same bits on every target and thread
//! count). What the world's one solve advances, wrapped in the contact model.

use super::super::element::{TetHessian, TetRest};
use super::super::material::Material;
use super::super::mesh::TetMesh;
use super::super::step::contact::ContactModel;
use super::super::step::{
    Bodies, ContactBuffersVbd, ElasticEnergy, ElasticHessian, ElasticModel, SweepMesh, SweepRun,
    SweepSchedule, TetElastic, VertexBlockModel,
};
use super::super::types::{Mat3, Real, Vec3};
use super::Part;
#[cfg(feature = "rayon")]
use super::threads::Threads;
#[cfg(feature = "rayon")]
use super::super::step::vertex_pass::VertexPass;
use crate::error::{Buffer, MeshError, StepError};

/// Every body of a world as one [`ElasticHessian`]: body `k`'s tetrahedra are
/// `tets[part.first_tet..][..part.tet_count]` (global vertex indices), its rest data the same
/// range of `rest`, its material `part.material`. Forces, energies and Hessian products are
/// each body's, added in body order; the Hessian cache holds the bodies' elements in the same
/// order as `tets`.
///
/// With a thread pool (`threads`, feature `rayon`) the passes run body by body on the pool
/// (`world/threads.rs`), with the same bits.
#[derive(Clone, Copy, Debug)]
pub(crate) struct WorldElastic<'a, M: Material> {
    pub(crate) tets: &'a [[u32; 4]],
    pub(crate) rest: &'a [TetRest],
    pub(crate) parts: &'a [Part<M>],
    pub(crate) vertex_count: usize,
    #[cfg(feature = "rayon")]
    pub(crate) threads: Option<&'a Threads<M>>,
}

impl<'a, M: Material> WorldElastic<'a, M> {
    /// Body `part`'s tetrahedra as a model over all vertices, and their range in `tets`
    /// (empty views for a part beyond the lists, which the world never builds).
    fn body(&self, part: &Part<M>) -> (TetElastic<'a, M>, core::ops::Range<usize>) {
        let range = part.tet_range();
        let tets = self.tets.get(range.clone()).unwrap_or(&[]);
        let rest = self.rest.get(range.clone()).unwrap_or(&[]);
        let mesh = TetMesh::from_validated(tets, rest, self.vertex_count, part.gradient_gain);
        (TetElastic::new(mesh, part.material), range)
    }

    /// `each(model, range)` of every body in order; the first error stops it.
    fn each_body(
        &self,
        mut each: impl FnMut(TetElastic<'a, M>, core::ops::Range<usize>) -> Result<(), MeshError>,
    ) -> Result<(), MeshError> {
        for part in self.parts {
            let (model, range) = self.body(part);
            each(model, range)?;
        }
        Ok(())
    }

    /// [`ElasticModel::add_forces`] body after body on the calling thread.
    pub(crate) fn sequential_add_forces(
        &self,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<(), MeshError> {
        self.each_body(|model, _| model.add_forces(positions, forces))
    }

    /// [`ElasticEnergy::energy_and_add_forces`] body after body on the calling thread.
    pub(crate) fn sequential_energy_and_add_forces(
        &self,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, MeshError> {
        let mut total: Real = 0.0;
        self.each_body(|model, _| {
            total += model.energy_and_add_forces(positions, forces)?;
            Ok(())
        })?;
        Ok(total)
    }

    /// [`ElasticHessian::projected_hessians`] body after body on the calling thread.
    pub(crate) fn sequential_projected_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        check_cache(cache.len(), self.tets.len())?;
        self.each_body(|model, range| {
            let cache = cache.get_mut(range).unwrap_or(&mut []);
            model.projected_hessians(positions, cache)
        })
    }

    /// [`ElasticHessian::add_hessian_product`] body after body on the calling thread.
    pub(crate) fn sequential_add_hessian_product(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        check_cache(cache.len(), self.tets.len())?;
        self.each_body(|model, range| {
            let cache = cache.get(range).unwrap_or(&[]);
            model.add_hessian_product(cache, direction, out)
        })
    }

    /// [`ElasticHessian::add_vertex_hessian_blocks`] body after body on the calling thread.
    pub(crate) fn sequential_add_vertex_hessian_blocks(
        &self,
        cache: &[TetHessian],
        blocks: &mut [Mat3],
    ) -> Result<(), MeshError> {
        check_cache(cache.len(), self.tets.len())?;
        self.each_body(|model, range| {
            let cache = cache.get(range).unwrap_or(&[]);
            model.add_vertex_hessian_blocks(cache, blocks)
        })
    }
}

impl<M: Material> ElasticModel for WorldElastic<'_, M> {
    type Vector = Vec3;

    #[inline]
    fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    fn add_forces(&self, positions: &[Vec3], forces: &mut [Vec3]) -> Result<(), MeshError> {
        #[cfg(feature = "rayon")]
        if let Some(threads) = self.threads {
            return threads.add_forces(self, positions, forces);
        }
        self.sequential_add_forces(positions, forces)
    }

    fn for_each_element_stiffness(&self, mut visit: impl FnMut(&[u32], Real, Real)) {
        for part in self.parts {
            self.body(part).0.for_each_element_stiffness(&mut visit);
        }
    }

    #[cfg(feature = "rayon")]
    fn run_vertex_pass<P: VertexPass>(&self, pass: P) -> P::Output {
        match self.threads {
            Some(threads) => threads.run_vertex_pass(pass),
            None => pass.run_with(&super::super::step::vertex_pass::InOrder),
        }
    }
}

impl<M: Material> ElasticEnergy for WorldElastic<'_, M> {
    fn energy_and_add_forces(
        &self,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, MeshError> {
        #[cfg(feature = "rayon")]
        if let Some(threads) = self.threads {
            return threads.energy_and_add_forces(self, positions, forces);
        }
        self.sequential_energy_and_add_forces(positions, forces)
    }
}

impl<M: Material> ElasticHessian for WorldElastic<'_, M> {
    #[inline]
    fn element_count(&self) -> usize {
        self.tets.len()
    }

    fn projected_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        #[cfg(feature = "rayon")]
        if let Some(threads) = self.threads {
            return threads.projected_hessians(self, positions, cache);
        }
        self.sequential_projected_hessians(positions, cache)
    }

    fn add_hessian_product(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        #[cfg(feature = "rayon")]
        if let Some(threads) = self.threads {
            return threads.add_hessian_product(self, cache, direction, out);
        }
        self.sequential_add_hessian_product(cache, direction, out)
    }

    fn add_vertex_hessian_blocks(
        &self,
        cache: &[TetHessian],
        blocks: &mut [Mat3],
    ) -> Result<(), MeshError> {
        #[cfg(feature = "rayon")]
        if let Some(threads) = self.threads {
            return threads.add_vertex_hessian_blocks(self, cache, blocks);
        }
        self.sequential_add_vertex_hessian_blocks(cache, blocks)
    }
}

/// The Hessian cache must hold one entry per tetrahedron of the world.
fn check_cache(actual: usize, expected: usize) -> Result<(), MeshError> {
    if actual == expected {
        Ok(())
    } else {
        Err(MeshError::LengthMismatch {
            buffer: Buffer::Hessians,
            expected,
            actual,
        })
    }
}

/// Vertex Block Descent over a world's bodies in contact: each sweep visits the bodies one
/// after the other, each with its own material, and takes the contact's terms at its start
/// ([`ContactModel::vertex_terms`]); the updates run in order on the calling thread, or, with
/// a thread pool (feature `rayon`), each body's colours in parallel on the pool: the contact's
/// terms are only read during a sweep, so the same bits.
impl<M: Material> SweepSchedule for ContactModel<'_, WorldElastic<'_, M>> {
    type Material = M;

    fn sweep_mesh(&self) -> SweepMesh<'_, M> {
        let world = self.model();
        SweepMesh {
            tets: world.tets,
            rest: world.rest,
            vertex_count: world.vertex_count,
            material: world.parts.first().map(|part| &part.material),
            bodies: Bodies::World(world.parts),
        }
    }

    fn vertex_contact(
        &self,
        positions: &[Vec3],
        buffers: &mut ContactBuffersVbd<'_>,
    ) -> Result<bool, StepError> {
        self.vertex_terms(positions, buffers.gradient, buffers.blocks, buffers.nearest)
            .map_err(|error| StepError::Mesh(MeshError::Contact(error)))?;
        Ok(true)
    }

    #[inline]
    fn run_sweep(&self, run: SweepRun<'_, '_, M>) {
        #[cfg(feature = "rayon")]
        if let Some(threads) = self.model().threads {
            return threads.run_sweep(run);
        }
        run.in_order();
    }
}

impl<M: Material> VertexBlockModel for ContactModel<'_, WorldElastic<'_, M>> {}
