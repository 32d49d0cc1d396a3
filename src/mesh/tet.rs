//! Tetrahedral meshes.

use super::super::element::TetRest;
use super::super::lanes::LANES;
use super::super::material::Material;
use super::super::math::{BATCH_FORCES, BATCH_SVD};
use super::super::types::{Mat3, Real, Vec3};
use super::grouped::{
    ClampedStress, DirectForces, Energies, EnergyAndForces, FusedEnergy, Pass, PassJob,
    PrincipalStress, SvdForces, SvdStress, TetGroup, tet_groups,
};
use super::rest_blocks::{Rests, TetRestBlock, fill_rest_blocks};
use super::{check_length, check_positions, gather, validate};
use crate::error::{Buffer, MeshError};
use crate::simd::{WidthKernel, dispatch};

/// A validated tetrahedral mesh: the caller's index buffer and the rest data computed from the
/// rest positions, borrowed for `'a`. No heap.
///
/// Every element has vertex indices below [`vertex_count`](TetMesh::vertex_count), a positive,
/// non-degenerate rest volume and finite `Dm^-1`, so the kernels need no per-element checks.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::material::StVK;
/// use softfem::element::TetRest;
/// use softfem::mesh::TetMesh;
///
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
/// let tets = [[0, 1, 2, 3]];
/// let mut rest_data = [TetRest::default(); 1];
/// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
///
/// let squashed = rest.map(|x| x * Vec3::new(1.0, 1.0, 0.9));
/// let mut forces = [Vec3::ZERO; 4];
/// let stvk = StVK::from_young_poisson(1.0e6, 0.3).unwrap();
/// mesh.add_elastic_forces(&stvk, &squashed, &mut forces)?;
/// assert!(forces[3].z > 0.0); // the squashed apex is pushed back up
///
/// let mut masses = [0.0; 4];
/// mesh.lumped_masses(1000.0, &mut masses)?; // kg/m^3
/// assert!((masses.iter().sum::<f32>() - 1000.0 / 6.0).abs() < 1e-3);
/// # Ok::<(), softfem::MeshError>(())
/// ```
#[derive(Clone, Copy, Debug)]
pub struct TetMesh<'a> {
    tets: &'a [[u32; 4]],
    rest: &'a [TetRest],
    /// The rest data again in blocks of 16 ([`with_rest_blocks`](Self::with_rest_blocks)), or
    /// empty.
    blocks: &'a [TetRestBlock],
    vertex_count: usize,
    /// `max_e max_j sum_k |Dm^-1_kj|` (1/m): every entry of every element's `F` is at most this
    /// times the largest extent of the deformed positions along an axis.
    gradient_gain: Real,
}

impl<'a> TetMesh<'a> {
    /// Validates the mesh with rest positions `rest_positions` (m) and vertex indices `tets`,
    /// filling `rest` (one entry per tetrahedron) with each element's rest data.
    ///
    /// # Errors
    /// The first problem found, in this order: [`MeshError::LengthMismatch`] (`rest` must have
    /// `tets.len()` entries), [`MeshError::NonFiniteRestPosition`] (first such vertex),
    /// [`MeshError::IndexOutOfRange`] (first element and corner),
    /// [`MeshError::InvertedElement`] or [`MeshError::DegenerateElement`] (first such element;
    /// see [`TetRest::new`] and [`fix_orientation`](super::super::element::fix_orientation)). On
    /// error, `rest` may be partly written.
    pub fn new(
        rest_positions: &[Vec3],
        tets: &'a [[u32; 4]],
        rest: &'a mut [TetRest],
    ) -> Result<TetMesh<'a>, MeshError> {
        let vertex_count = validate(rest_positions, tets, rest, TetRest::new)?;
        let gradient_gain = rest.iter().fold(0.0, |gain: Real, r| {
            let column_sum = |c: Vec3| c.abs().element_sum();
            let m = r.dm_inv;
            gain.max(column_sum(m.x_axis))
                .max(column_sum(m.y_axis))
                .max(column_sum(m.z_axis))
        });
        Ok(TetMesh {
            tets,
            rest,
            blocks: &[],
            vertex_count,
            gradient_gain,
        })
    }

    /// The mesh over `tets` and `rest` as [`new`](Self::new) built it before, without validating
    /// again: `vertex_count` and `gradient_gain` must be those of a mesh that [`new`](Self::new)
    /// accepted with exactly these buffers (its [`vertex_count`](Self::vertex_count) and
    /// [`gradient_gain`](Self::gradient_gain)). For owners of already validated data (the
    /// [`Body`](super::super::body::Body)) that rebuild the view every step. Nothing unsound
    /// follows from wrong arguments (every access stays checked), only wrong results.
    #[inline]
    #[must_use]
    pub(crate) fn from_validated(
        tets: &'a [[u32; 4]],
        rest: &'a [TetRest],
        vertex_count: usize,
        gradient_gain: Real,
    ) -> TetMesh<'a> {
        TetMesh {
            tets,
            rest,
            blocks: &[],
            vertex_count,
            gradient_gain,
        }
    }

    /// This mesh with its rest data also in `blocks`, which it fills: 16 elements per block,
    /// field by field, which the wide SIMD lanes load without transposing (1.00x to 1.23x the
    /// direct force pass at 105k tetrahedra with AVX-512 in eight runs, 1.18x and 1.44x at 1M
    /// in two, where the pass prefetches the blocks ahead; see [`TetRestBlock`] and the
    /// docs/guide/10-performance.md). The results
    /// of every kernel are bit for bit those without blocks; only the passes that form
    /// deformation gradients a group at a time use them. Costs 40 bytes per element in f32
    /// (80 in f64), in [`rest_block_count`](super::rest_block_count) blocks.
    ///
    /// Unoptimised (debug) builds fill the blocks but run every pass on the per-element
    /// records: a second inlined loop made the passes' stack frames too large for small test
    /// threads. The bits are the same either way; only release builds gain the speed.
    ///
    /// ```
    /// use softfem::element::TetRest;
    /// use softfem::glam::Vec3;
    /// use softfem::mesh::{TetMesh, TetRestBlock, rest_block_count};
    ///
    /// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    /// let tets = [[0, 1, 2, 3]];
    /// let mut rest_data = [TetRest::ZERO; 1];
    /// let mut blocks = [TetRestBlock::ZERO; rest_block_count(1)];
    /// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?.with_rest_blocks(&mut blocks)?;
    /// assert_eq!(mesh.rest_blocks().len(), 1);
    /// # Ok::<(), softfem::error::MeshError>(())
    /// ```
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] naming [`Buffer::RestBlocks`] unless `blocks` has
    /// [`rest_block_count`](super::rest_block_count)`(element_count)` entries; `blocks` is then
    /// unchanged.
    pub fn with_rest_blocks(
        self,
        blocks: &'a mut [TetRestBlock],
    ) -> Result<TetMesh<'a>, MeshError> {
        fill_rest_blocks(self.rest, blocks)?;
        Ok(TetMesh { blocks, ..self })
    }

    /// The rest data in blocks that [`with_rest_blocks`](Self::with_rest_blocks) filled
    /// (empty without).
    #[inline]
    #[must_use]
    pub fn rest_blocks(&self) -> &'a [TetRestBlock] {
        self.blocks
    }

    /// This mesh with `blocks`, which must be what [`with_rest_blocks`](Self::with_rest_blocks)
    /// filled for it (or empty): for owners of already validated data, as
    /// [`from_validated`](Self::from_validated). Wrong blocks give wrong results, nothing
    /// unsound.
    #[inline]
    #[must_use]
    pub(crate) fn with_filled_blocks(self, blocks: &'a [TetRestBlock]) -> TetMesh<'a> {
        TetMesh { blocks, ..self }
    }

    /// The largest column sum of any element's `Dm^-1` (1/m), computed by [`new`](Self::new):
    /// what [`from_validated`](Self::from_validated) needs back.
    #[inline]
    #[must_use]
    pub(crate) fn gradient_gain(&self) -> Real {
        self.gradient_gain
    }

    /// The number of vertices (the length every position, force and mass buffer must have).
    #[inline]
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The number of tetrahedra.
    #[inline]
    #[must_use]
    pub fn element_count(&self) -> usize {
        self.tets.len()
    }

    /// The vertex indices of every tetrahedron.
    #[inline]
    #[must_use]
    pub fn tets(&self) -> &'a [[u32; 4]] {
        self.tets
    }

    /// The rest data of every tetrahedron.
    #[inline]
    #[must_use]
    pub fn rest(&self) -> &'a [TetRest] {
        self.rest
    }

    /// The total rest volume (m^3).
    #[must_use]
    pub fn rest_volume(&self) -> Real {
        self.rest.iter().map(|r| r.volume).sum()
    }

    /// Adds the elastic forces (N) of `material` at deformed `positions` (m) into `forces`,
    /// using the direct stress [`Material::first_piola`].
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] if `positions` or `forces` does not have
    /// [`vertex_count`](TetMesh::vertex_count) entries; [`MeshError::NonFinitePosition`] naming
    /// the first non-finite vertex; [`MeshError::DeformationRange`] naming the first element
    /// whose deformation gradient has an entry beyond the material's
    /// [`deformation_limit`](Material::deformation_limit), where its stress would overflow. On
    /// error, `forces` is unchanged.
    pub fn add_elastic_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<(), MeshError> {
        let out = (Buffer::Forces, self.vertex_count, forces.len());
        self.check_output(material, positions, out)?;
        self.pass(material, positions, DirectForces(forces), BATCH_FORCES);
        Ok(())
    }

    /// As [`add_elastic_forces`](TetMesh::add_elastic_forces), through the principal
    /// (SVD) stress `P = U diag(dW/ds) V^T` ([`Material::first_piola_from_svd`]). Equal to the
    /// direct path to rounding wherever the model is defined. On targets with SIMD (x86_64,
    /// aarch64) the SVDs of consecutive tetrahedra are computed a group at a time, at the widest
    /// SIMD width the CPU has ([`simd`](crate::simd)), elsewhere one by one ([`svd3`](super::super::svd::svd3)): the same
    /// bits either way.
    ///
    /// # Errors
    /// As [`add_elastic_forces`](TetMesh::add_elastic_forces); on error, `forces` is unchanged.
    pub fn add_elastic_forces_principal<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<(), MeshError> {
        self.check_positions(positions)?;
        self.check_deformation(material, positions)?;
        self.add_svd_forces(material, positions, forces, PrincipalStress(material))
    }

    /// **Not the gradient of any energy: for explicit time stepping only.** As
    /// [`add_elastic_forces_principal`](TetMesh::add_elastic_forces_principal), with the
    /// stretches clamped from below at `threshold` (dimensionless, typically `0.2..0.5`) so that
    /// inverted elements get a restoring force: see
    /// [`Material::first_piola_principal_clamped`]. Energy-based solvers (implicit Euler as
    /// minimisation, relaxation, line searches) must not use these forces.
    ///
    /// # Errors
    /// [`MeshError::ClampThreshold`] if `threshold` is not in `(0, 1]` (NaN, infinite, zero,
    /// negative or above the rest stretch); otherwise as
    /// [`add_elastic_forces`](TetMesh::add_elastic_forces). On error, `forces` is unchanged.
    pub fn add_elastic_forces_clamped<M: Material>(
        &self,
        material: &M,
        threshold: Real,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<(), MeshError> {
        check_clamp_threshold(threshold)?;
        self.check_positions(positions)?;
        self.check_deformation(material, positions)?;
        let stress = ClampedStress {
            material,
            threshold,
        };
        self.add_svd_forces(material, positions, forces, stress)
    }

    /// The total elastic energy (J) and, added into `forces`, the elastic forces (N) of
    /// `material` at `positions` (m), from one deformation gradient per element: the fused pass
    /// of the energy-based steppers. Lengths are checked; finiteness is not (a non-finite
    /// position gives a non-finite energy, which a line search rejects).
    ///
    /// The energy is summed in a fixed order on every target, grouped or not: element `i` of
    /// the first `n - n % LANES` adds to partial sum `i % LANES`, the partial sums are added as
    /// `(s0 + s1) + (s2 + s3)`, then the last `n % LANES` elements in order. Four independent
    /// sums instead of one chain: the chain cost the grouped stable neo-Hookean pass 5 %.
    pub(crate) fn energy_and_add_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, MeshError> {
        check_length(Buffer::Positions, self.vertex_count, positions.len())?;
        check_length(Buffer::Forces, self.vertex_count, forces.len())?;
        // Beyond the material's range the energy is reported as infinite, which the line
        // searches reject, and the forces are left alone. (Non-finite positions fail the range
        // check too.)
        if self.check_deformation(material, positions).is_err() {
            return Ok(Real::INFINITY);
        }
        let job = EnergyAndForces {
            forces,
            energy: FusedEnergy::new(self.tets.len()),
        };
        Ok(self
            .pass(material, positions, job, BATCH_FORCES)
            .energy
            .total())
    }

    /// The total elastic energy `sum V W(F)` (J) of `material` at deformed `positions` (m),
    /// summed element by element in order. Infinite or NaN if the material is (e.g.
    /// [`NeoHookean`](super::super::material::NeoHookean) with a flat element). The steppers'
    /// fused energy-and-force pass sums the same terms in four interleaved partial sums, so the
    /// two totals can differ in the last bits.
    ///
    /// # Errors
    /// As [`add_elastic_forces`](TetMesh::add_elastic_forces) for `positions`.
    pub fn elastic_energy<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
    ) -> Result<Real, MeshError> {
        self.check_positions(positions)?;
        self.check_deformation(material, positions)?;
        // In element order from the neutral element of `Sum`, as `Iterator::sum` adds.
        let mut total: Real = core::iter::empty::<Real>().sum();
        let job = Energies(|_, energy| total += energy);
        self.pass(material, positions, job, BATCH_FORCES);
        Ok(total)
    }

    /// Writes the energy `V W(F)` (J) of every tetrahedron into `out`.
    ///
    /// # Errors
    /// As [`add_elastic_forces`](TetMesh::add_elastic_forces), and
    /// [`MeshError::LengthMismatch`] if `out` does not have one entry per element. On error,
    /// `out` is unchanged.
    pub fn element_energies<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        out: &mut [Real],
    ) -> Result<(), MeshError> {
        self.check_output(material, positions, (Buffer::Energies, self.tets.len(), out.len()))?;
        let job = Energies(|i, energy| {
            if let Some(slot) = out.get_mut(i) {
                *slot = energy;
            }
        });
        self.pass(material, positions, job, BATCH_FORCES);
        Ok(())
    }

    /// Writes the first Piola–Kirchhoff stress `P` (Pa, direct path) of every tetrahedron into
    /// `out`.
    ///
    /// # Errors
    /// As [`add_elastic_forces`](TetMesh::add_elastic_forces), and
    /// [`MeshError::LengthMismatch`] if `out` does not have one entry per element. On error,
    /// `out` is unchanged.
    pub fn element_stresses<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        out: &mut [Mat3],
    ) -> Result<(), MeshError> {
        self.check_output(material, positions, (Buffer::Stresses, self.tets.len(), out.len()))?;
        for ((corners, rest), stress) in self.tets.iter().zip(self.rest).zip(out) {
            *stress = material.first_piola(rest.deformation_gradient(gather(positions, corners)));
        }
        Ok(())
    }

    /// Writes the lumped mass (kg) of every vertex into `masses` (overwriting): each
    /// tetrahedron gives `density * V / 4` to each of its corners (`docs/math.md` section 4).
    /// Vertices in no element get zero.
    ///
    /// # Errors
    /// [`MeshError::Density`] if `density` (kg/m^3) is not finite and positive;
    /// [`MeshError::LengthMismatch`] if `masses` does not have one entry per vertex;
    /// [`MeshError::MassRange`] naming the first element whose share `density * V / 4` is below
    /// `Real::MIN_POSITIVE` or above `Real::MAX / element_count` (so that every vertex mass is a
    /// normal number the steppers accept). On error, `masses` is unchanged.
    pub fn lumped_masses(&self, density: Real, masses: &mut [Real]) -> Result<(), MeshError> {
        super::lumped_masses(
            self.tets,
            self.rest.iter().map(|r| r.volume),
            density,
            masses,
            self.vertex_count,
        )
    }

    /// The elements to evaluate [`LANES`] at a time (all whole groups when `batch`, none
    /// otherwise) and the rest, to evaluate one at a time.
    #[allow(clippy::type_complexity)]
    pub(crate) fn groups_and_tail(
        &self,
        batch: bool,
    ) -> (
        impl Iterator<Item = TetGroup<'a>>,
        impl Iterator<Item = (&'a [u32; 4], &'a TetRest)>,
    ) {
        let grouped = if batch {
            self.tets.len() - self.tets.len() % LANES
        } else {
            0
        };
        let (tets, single_tets) = self
            .tets
            .split_at_checked(grouped)
            .unwrap_or((&[], self.tets));
        let (rest, single_rest) = self
            .rest
            .split_at_checked(grouped)
            .unwrap_or((&[], self.rest));
        (tet_groups(tets, rest), single_tets.iter().zip(single_rest))
    }

    /// `Ok` if every element's deformation gradient at `positions` (one per vertex) has all
    /// entries finite and within `material`'s [`deformation_limit`](Material::deformation_limit);
    /// else [`MeshError::DeformationRange`] naming the first element that does not. A single
    /// pass over the positions settles the common case: no entry of any `F` exceeds the largest
    /// extent of the positions along an axis times `gradient_gain`. Only when that bound is
    /// above the limit (or not finite) are the elements' gradients computed one by one.
    pub(crate) fn check_deformation<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
    ) -> Result<(), MeshError> {
        let limit = material.deformation_limit();
        if limit == Real::INFINITY {
            return Ok(());
        }
        let first = positions.first().copied().unwrap_or(Vec3::ZERO);
        let (low, high) = positions
            .iter()
            .fold((first, first), |(low, high), &p| (low.min(p), high.max(p)));
        if self.extent_within(limit, low, high) {
            return Ok(());
        }
        self.check_each_deformation(limit, positions)
    }

    /// Whether positions spanning the box `low..=high` keep every entry of every element's
    /// deformation gradient within `limit` by the bound of
    /// [`check_deformation`](Self::check_deformation) (largest extent times `gradient_gain`):
    /// `true` settles the check, `false` decides nothing. A limit below 1 never passes: it
    /// refuses every element (the bound behind it is on `max(1, |F_ij|)`), which only the
    /// element-by-element path reports.
    #[inline]
    pub(crate) fn extent_within(&self, limit: Real, low: Vec3, high: Vec3) -> bool {
        limit == Real::INFINITY
            || (limit >= 1.0 && (high - low).max_element() * self.gradient_gain <= limit)
    }

    /// The slow path of [`check_deformation`](Self::check_deformation), element by element:
    /// kept out of line so that its frame does not add to the stack of every force call.
    #[cold]
    #[inline(never)]
    fn check_each_deformation(&self, limit: Real, positions: &[Vec3]) -> Result<(), MeshError> {
        // `max(1, largest entry)`: the energy bound behind the limit grows like
        // `max(1, |F_ij|)^power`, so that a limit below 1 (a modulus with no headroom) refuses
        // even `F = 0`, whose energy density is of the order of the modulus.
        let within = |f: Mat3| {
            let largest = f.x_axis.abs().max(f.y_axis.abs()).max(f.z_axis.abs());
            largest.max_element().max(1.0) <= limit && f.is_finite()
        };
        let outside = self.tets.iter().zip(self.rest).position(|(corners, rest)| {
            !within(rest.deformation_gradient(gather(positions, corners)))
        });
        outside.map_or(Ok(()), |element| {
            Err(MeshError::DeformationRange { element })
        })
    }

    /// Runs `job` over every element: at the width [`simd`](crate::simd) picks where `batch`,
    /// else one element at a time.
    #[inline(always)]
    fn pass<M: Material, J: PassJob>(
        &self,
        material: &M,
        positions: &[Vec3],
        job: J,
        batch: bool,
    ) -> J {
        let pass = Pass {
            material,
            positions,
            tets: self.tets,
            rests: Rests::new(self.rest, self.blocks, 0),
            job,
        };
        if batch { dispatch(pass) } else { pass.scalar() }
    }

    /// Length and finiteness of a deformed position buffer.
    fn check_positions(&self, positions: &[Vec3]) -> Result<(), MeshError> {
        check_positions(self.vertex_count, positions)
    }

    /// The checks of a pass that writes an output buffer, in their order: `positions` (length,
    /// finite), the output's `(buffer, expected, actual)` length, then the deformation range of
    /// `material` ([`check_deformation`](Self::check_deformation)).
    fn check_output<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        (buffer, expected, actual): (Buffer, usize, usize),
    ) -> Result<(), MeshError> {
        self.check_positions(positions)?;
        check_length(buffer, expected, actual)?;
        self.check_deformation(material, positions)
    }

    /// The principal-path force loop, with `stress` mapping an SVD of `F` to `P`.
    fn add_svd_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &mut [Vec3],
        stress: impl SvdStress,
    ) -> Result<(), MeshError> {
        self.check_positions(positions)?;
        check_length(Buffer::Forces, self.vertex_count, forces.len())?;
        let job = SvdForces { forces, stress };
        self.pass(material, positions, job, BATCH_SVD);
        Ok(())
    }
}

/// `Ok` if `threshold` is a stretch in `(0, 1]`, the range in which the clamped stress is
/// finite for every model and leaves undeformed elements unclamped.
#[inline]
pub(crate) fn check_clamp_threshold(threshold: Real) -> Result<(), MeshError> {
    if threshold > 0.0 && threshold <= 1.0 {
        Ok(())
    } else {
        Err(MeshError::ClampThreshold)
    }
}
