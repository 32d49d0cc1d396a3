//! The firmware check's workload, compiled twice: into the firmware (`src/main.rs`), where it
//! runs on the emulated Cortex-M4F, and into the host test (`tests/firmware.rs`), where the same
//! code computes the values the firmware must reproduce.
//!
//! [`run`] produces a list of named [`Record`]s: a 64-bit digest of every bit the computation
//! returned (singular vectors and values, every nodal force, every position and velocity after
//! stepping) and one representative value to print. A [`Meter`] wraps the calls worth measuring;
//! the host's does nothing, the firmware's counts instructions and stack.
//!
//! Everything here is `no_std` and allocation-free: the drop body lives in a caller-owned
//! `DropBody` of each precision and the descent solvers' scratch in a `DescentScratch`, the
//! collider scene's `softfem::body::Body` in a caller-owned `ColliderBody` (statics in the
//! firmware, `Body::empty` and rebuilt in place), Newton's cached element Hessians on the stack.

/// The most records one run produces (both precisions).
pub const MAX_RECORDS: usize = 128;

/// One named result: a digest of its bits and a value to show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// `"<precision> <what>"`, unique within a run.
    pub name: &'static str,
    /// FNV-1a over the little-endian bit patterns of every value (see [`Digest`]).
    pub digest: u64,
    /// A representative value (widened to f64 exactly), for the report.
    pub value: f64,
}

/// The records of one run, in order, in a fixed-capacity buffer.
pub struct Records {
    items: [Record; MAX_RECORDS],
    len: usize,
    /// Records that did not fit (a run with overflow must fail).
    pub overflow: usize,
}

impl Records {
    /// No records yet.
    pub const fn new() -> Self {
        const BLANK: Record = Record {
            name: "",
            digest: 0,
            value: 0.0,
        };
        Records {
            items: [BLANK; MAX_RECORDS],
            len: 0,
            overflow: 0,
        }
    }

    /// Appends `record`, or counts it in [`overflow`](Self::overflow) when full.
    pub fn push(&mut self, record: Record) {
        match self.items.get_mut(self.len) {
            Some(slot) => {
                *slot = record;
                self.len += 1;
            }
            None => self.overflow += 1,
        }
    }

    /// The records so far.
    pub fn as_slice(&self) -> &[Record] {
        self.items.get(..self.len).unwrap_or(&[])
    }
}

impl Default for Records {
    fn default() -> Self {
        Self::new()
    }
}

/// FNV-1a (64-bit) over bit patterns. Every NaN is hashed as the one quiet NaN of its width:
/// NaN payloads and signs are not portable (x86 produces `0xffc0_0000` where Arm produces
/// `0x7fc0_0000`) and carry no information here. Signed zeros stay distinct.
#[derive(Clone, Copy, Debug)]
pub struct Digest(u64);

impl Digest {
    /// The FNV-1a offset basis.
    pub const fn new() -> Self {
        Digest(0xcbf2_9ce4_8422_2325)
    }

    /// Mixes in `bytes`.
    pub fn bytes(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.0 = (self.0 ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// Mixes in an `f32`.
    pub fn f32(&mut self, x: f32) {
        let bits = if x.is_nan() { 0x7fc0_0000 } else { x.to_bits() };
        self.bytes(&bits.to_le_bytes());
    }

    /// Mixes in an `f64`.
    pub fn f64(&mut self, x: f64) {
        let bits = if x.is_nan() {
            0x7ff8_0000_0000_0000
        } else {
            x.to_bits()
        };
        self.bytes(&bits.to_le_bytes());
    }

    /// Mixes in an integer.
    pub fn u64(&mut self, x: u64) {
        self.bytes(&x.to_le_bytes());
    }

    /// The digest.
    pub const fn finish(&self) -> u64 {
        self.0
    }
}

impl Default for Digest {
    fn default() -> Self {
        Self::new()
    }
}

/// Wraps the calls worth measuring. `name` identifies a measured section (calls to the same
/// section accumulate); [`units`](Meter::units) adds the work done (tetrahedra, vertices,
/// iterations) so that costs can be reported per unit.
pub trait Meter {
    /// Runs `work` as one call of section `name` and returns its result.
    fn measure<R>(&mut self, name: &'static str, work: impl FnOnce() -> R) -> R;

    /// Adds `units` units of work, named `unit`, to section `name`.
    fn units(&mut self, name: &'static str, unit: &'static str, units: u64);
}

/// A [`Meter`] that only runs the work: the host's.
#[cfg_attr(target_os = "none", allow(dead_code))]
pub struct NoMeter;

impl Meter for NoMeter {
    fn measure<R>(&mut self, _name: &'static str, work: impl FnOnce() -> R) -> R {
        work()
    }

    fn units(&mut self, _name: &'static str, _unit: &'static str, _units: u64) {}
}

/// A deterministic value in `[-1, 1]` with 1/1000 resolution from two integers, exact in any
/// precision (no floating-point function is involved).
fn jitter(i: u32, salt: u32) -> i32 {
    let mut h = i.wrapping_mul(0x9e37_79b9) ^ salt.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    (h % 2001) as i32 - 1000
}

/// The four force and energy pieces of one model: never-inlined, non-generic functions named
/// after the model, so that each is one symbol of its own in the firmware image (see
/// [`precision`]'s `pieces`). Expanded inside each precision's `pieces` module, whose imports
/// the types resolve to.
macro_rules! model_pieces {
    ($model:ident, $direct:ident, $principal:ident, $clamped:ident, $energy:ident) => {
        /// [`TetMesh::add_elastic_forces`] of this model.
        #[inline(never)]
        pub fn $direct(
            mesh: &TetMesh<'_>,
            material: &$model,
            positions: &[Vec3],
            forces: &mut [Vec3],
        ) -> Result<(), MeshError> {
            mesh.add_elastic_forces(material, positions, forces)
        }

        /// [`TetMesh::add_elastic_forces_principal`] of this model.
        #[inline(never)]
        pub fn $principal(
            mesh: &TetMesh<'_>,
            material: &$model,
            positions: &[Vec3],
            forces: &mut [Vec3],
        ) -> Result<(), MeshError> {
            mesh.add_elastic_forces_principal(material, positions, forces)
        }

        /// [`TetMesh::add_elastic_forces_clamped`] of this model.
        #[inline(never)]
        pub fn $clamped(
            mesh: &TetMesh<'_>,
            material: &$model,
            threshold: Real,
            positions: &[Vec3],
            forces: &mut [Vec3],
        ) -> Result<(), MeshError> {
            mesh.add_elastic_forces_clamped(material, threshold, positions, forces)
        }

        /// [`TetMesh::elastic_energy`] of this model.
        #[inline(never)]
        pub fn $energy(
            mesh: &TetMesh<'_>,
            material: &$model,
            positions: &[Vec3],
        ) -> Result<Real, MeshError> {
            mesh.elastic_energy(material, positions)
        }
    };
}

/// The workload, written once and instantiated per precision.
macro_rules! precision {
    ($module:ident, $prefix:literal, $($softfem:ident)::+) => {
        /// The workload in one precision.
        pub mod $module {
            use core::hint::black_box;

            use $($softfem)::+::body::{self as owning, FixedStorage, Solver, StepReport};
            use $($softfem)::+::element::{TetHessian, TetRest};
            use $($softfem)::+::generate::{BoxSplit, fill_box};
            use $($softfem)::+::MeshError;
            use $($softfem)::+::material::{Lame, NeoHookean, StVK, StableNeoHookean};
            use $($softfem)::+::mesh::TetMesh;
            use $($softfem)::+::step::{
                Collider, ExplicitScratch, ExplicitSettings, HalfSpace, NewtonReport, NewtonScratch,
                NewtonSettings, RelaxReport, RelaxScratch, RelaxSettings, Scene, TetElastic, VbdScratch, VbdSettings,
                scratch_len, stable_time_step,
            };
            use $($softfem)::+::svd::Svd3;
            use $($softfem)::+::types::{Mat3, Quat, Real, Vec3};
            use $($softfem)::+::step::{Attachment, Reaction};
            use $($softfem)::+::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};
            use $($softfem)::+::step::contact::boundary::ContactSurface;
            use $($softfem)::+::step::contact::model::{CandidateReuse, FrictionPair};
            use $($softfem)::+::step::contact::potential::{ContactBarrier, PairHessian};
            use $($softfem)::+::step::contact::{ContactBuffers, ContactModel, SUGGESTED_STICKING_SPEED};

            use super::{Digest, Meter, Record, Records, jitter};

            /// The library calls the workload makes, each in a function of its own that is never
            /// inlined and is not generic: in the firmware image each is exactly one symbol,
            /// `softfem_firmware::scenario::<single|double>::pieces::<name>`, whose code is the
            /// library function (checks included) inlined into it plus what it calls out of line.
            /// `tests/firmware.rs` reports their code size from the image.
            pub mod pieces {
                use $($softfem)::+::material::{NeoHookean, StVK, StableNeoHookean};
                use $($softfem)::+::mesh::TetMesh;
                use $($softfem)::+::step::{
                    ExplicitReport, ExplicitScratch, ExplicitSettings, NewtonReport,
                    NewtonScratch, NewtonSettings, RelaxReport, RelaxScratch, RelaxSettings,
                    Scene, TetElastic, VbdReport, VbdScratch, VbdSettings,
                };
                use $($softfem)::+::svd::Svd3;
                use $($softfem)::+::types::{Mat3, Real, Vec3};
                use $($softfem)::+::element::TetRest;
                use $($softfem)::+::{BodyError, MeshError, StepError};
                use $($softfem)::+::body::{CoupledReport, StepReport};
                use $($softfem)::+::step::{Attachment, Collider, Reaction};
                use $($softfem)::+::step::contact::ContactModel;

                use super::ColliderBody;

                /// [`svd3`](fn@$($softfem)::+::svd::svd3).
                #[inline(never)]
                pub fn svd3(a: Mat3) -> Svd3 {
                    $($softfem)::+::svd::svd3(a)
                }

                /// [`svd3_lanes`](fn@$($softfem)::+::svd::svd3_lanes).
                #[inline(never)]
                pub fn svd3_lanes(a: &[Mat3; 4]) -> [Svd3; 4] {
                    $($softfem)::+::svd::svd3_lanes(a)
                }

                /// [`TetMesh::new`]: mesh validation and rest data.
                #[inline(never)]
                pub fn mesh_new<'a>(
                    rest_positions: &[Vec3],
                    tets: &'a [[u32; 4]],
                    rest: &'a mut [TetRest],
                ) -> Result<TetMesh<'a>, MeshError> {
                    TetMesh::new(rest_positions, tets, rest)
                }

                model_pieces!(StVK, forces_stvk_direct, forces_stvk_principal, forces_stvk_clamped, energy_stvk);
                model_pieces!(NeoHookean, forces_neo_hookean_direct, forces_neo_hookean_principal, forces_neo_hookean_clamped, energy_neo_hookean);
                model_pieces!(StableNeoHookean, forces_stable_neo_hookean_direct, forces_stable_neo_hookean_principal, forces_stable_neo_hookean_clamped, energy_stable_neo_hookean);

                /// [`explicit_step`](fn@$($softfem)::+::step::explicit_step) of a stable
                /// neo-Hookean body.
                #[inline(never)]
                pub fn explicit_step(
                    model: &TetElastic<'_, StableNeoHookean>,
                    masses: &[Real],
                    scene: &Scene<'_, Vec3>,
                    settings: &ExplicitSettings,
                    positions: &mut [Vec3],
                    velocities: &mut [Vec3],
                    scratch: &mut ExplicitScratch<'_, Vec3>,
                ) -> Result<ExplicitReport, StepError> {
                    $($softfem)::+::step::explicit_step(model, masses, &[], scene, settings, positions, velocities, scratch)
                }

                /// [`relax_step`](fn@$($softfem)::+::step::relax_step) of a stable neo-Hookean
                /// body.
                #[inline(never)]
                pub fn relax_step(
                    model: &TetElastic<'_, StableNeoHookean>,
                    masses: &[Real],
                    scene: &Scene<'_, Vec3>,
                    settings: &RelaxSettings,
                    positions: &mut [Vec3],
                    velocities: &mut [Vec3],
                    scratch: &mut RelaxScratch<'_, Vec3>,
                ) -> Result<RelaxReport, StepError> {
                    $($softfem)::+::step::relax_step(model, masses, &[], scene, settings, positions, velocities, scratch)
                }

                /// [`newton_step`](fn@$($softfem)::+::step::newton_step) of a stable
                /// neo-Hookean body.
                #[inline(never)]
                pub fn newton_step(
                    model: &TetElastic<'_, StableNeoHookean>,
                    masses: &[Real],
                    scene: &Scene<'_, Vec3>,
                    settings: &NewtonSettings,
                    positions: &mut [Vec3],
                    velocities: &mut [Vec3],
                    scratch: &mut NewtonScratch<'_>,
                ) -> Result<NewtonReport, StepError> {
                    $($softfem)::+::step::newton_step(model, masses, &[], scene, settings, positions, velocities, scratch)
                }

                /// [`newton_step`](fn@$($softfem)::+::step::newton_step) of two stable
                /// neo-Hookean bodies in contact ([`ContactModel`] with friction).
                #[inline(never)]
                pub fn contact_newton_step(
                    model: &ContactModel<'_, TetElastic<'_, StableNeoHookean>>,
                    masses: &[Real],
                    scene: &Scene<'_, Vec3>,
                    settings: &NewtonSettings,
                    positions: &mut [Vec3],
                    velocities: &mut [Vec3],
                    scratch: &mut NewtonScratch<'_>,
                ) -> Result<NewtonReport, StepError> {
                    $($softfem)::+::step::newton_step(model, masses, &[], scene, settings, positions, velocities, scratch)
                }

                /// [`vbd_step`](fn@$($softfem)::+::step::vbd_step) of a stable neo-Hookean
                /// body.
                #[inline(never)]
                pub fn vbd_step(
                    model: &TetElastic<'_, StableNeoHookean>,
                    masses: &[Real],
                    scene: &Scene<'_, Vec3>,
                    settings: &VbdSettings,
                    positions: &mut [Vec3],
                    velocities: &mut [Vec3],
                    scratch: &mut VbdScratch<'_>,
                ) -> Result<VbdReport, StepError> {
                    $($softfem)::+::step::vbd_step(model, masses, &[], scene, settings, positions, velocities, scratch)
                }

                /// `Body::rebuild_from_box` of the body dropped onto the colliders, in place in
                /// `slot` (a static in the firmware).
                #[inline(never)]
                pub fn body_new(
                    slot: &mut ColliderBody,
                    min: Vec3,
                    max: Vec3,
                    density: Real,
                    material: StableNeoHookean,
                ) -> Result<(), BodyError> {
                    slot.set_material(material);
                    slot.rebuild_from_box(min, max, super::COLLIDER_CELLS, density)
                }

                /// `Body::step_with_reactions` of that body: the step and each collider's
                /// reaction.
                #[inline(never)]
                pub fn body_step_with_reactions(
                    body: &mut ColliderBody,
                    scene: &Scene<'_, Vec3>,
                    reactions: &mut [Reaction],
                ) -> Result<StepReport, StepError> {
                    body.step_with_reactions(scene, reactions)
                }

                /// `Body::step_with_rigid_bodies` of that body: the coupled step with its dynamic
                /// colliders.
                #[inline(never)]
                pub fn body_step_with_rigid_bodies(
                    body: &mut ColliderBody,
                    scene: &Scene<'_, Vec3>,
                    colliders: &mut [Collider<'_>],
                    reactions: &mut [Reaction],
                ) -> Result<CoupledReport, StepError> {
                    body.step_with_rigid_bodies(scene, colliders, reactions)
                }

                /// `Body::step_with_rigid_bodies_and_attachments` of that body.
                #[inline(never)]
                pub fn body_step_attached(
                    body: &mut ColliderBody,
                    scene: &Scene<'_, Vec3>,
                    colliders: &mut [Collider<'_>],
                    attachments: &[Attachment],
                    reactions: &mut [Reaction],
                ) -> Result<CoupledReport, StepError> {
                    body.step_with_rigid_bodies_and_attachments(scene, colliders, attachments, reactions)
                }

                /// `Body::step_with_colliders` of that body, whichever its solver.
                #[inline(never)]
                pub fn body_step(
                    body: &mut ColliderBody,
                    dt: Real,
                    colliders: &[Collider<'_>],
                ) -> Result<StepReport, StepError> {
                    body.step_with_colliders(dt, colliders)
                }
            }

            /// Everything one body needs, with capacity fixed at compile time: `V` vertices,
            /// `T` tetrahedra (as `tests/steppers/firmware_body.rs`).
            pub struct Body<const V: usize, const T: usize> {
                /// Rest positions (m).
                pub rest: [Vec3; V],
                /// Vertex indices.
                pub tets: [[u32; 4]; T],
                /// `Dm^-1` and volume per tetrahedron.
                pub rest_data: [TetRest; T],
                /// Positions (m).
                pub positions: [Vec3; V],
                /// Velocities (m/s).
                pub velocities: [Vec3; V],
                /// Lumped masses (kg).
                pub masses: [Real; V],
                /// Explicit scratch: forces of two substeps, position backup, velocity backup.
                pub explicit_scratch: [[Vec3; V]; 4],
                /// Relaxation scratch: five vectors per vertex.
                pub relax_vectors: [[Vec3; V]; 5],
                /// Relaxation scratch (and stiffness for the stable step): one scalar per
                /// vertex.
                pub relax_scalars: [Real; V],
            }

            impl<const V: usize, const T: usize> Body<V, T> {
                /// All zeros (filled by [`run`]).
                pub const EMPTY: Self = Body {
                    rest: [Vec3::ZERO; V],
                    tets: [[0; 4]; T],
                    rest_data: [TetRest {
                        dm_inv: Mat3::ZERO,
                        volume: 0.0,
                    }; T],
                    positions: [Vec3::ZERO; V],
                    velocities: [Vec3::ZERO; V],
                    masses: [0.0; V],
                    explicit_scratch: [[Vec3::ZERO; V]; 4],
                    relax_vectors: [[Vec3::ZERO; V]; 5],
                    relax_scalars: [0.0; V],
                };
            }

            /// Cells per side of the dropped cube.
            pub const DROP_CELLS: usize = 3;
            /// Vertices of the dropped cube: 4^3.
            pub const DROP_VERTICES: usize = (DROP_CELLS + 1) * (DROP_CELLS + 1) * (DROP_CELLS + 1);
            /// Tetrahedra of the dropped cube: 27 * 6.
            pub const DROP_TETS: usize = DROP_CELLS * DROP_CELLS * DROP_CELLS * 6;
            /// The dropped cube.
            pub type DropBody = Body<DROP_VERTICES, DROP_TETS>;

            /// The buffer lengths of Newton's method for the dropped cube.
            const NEWTON_LEN: scratch_len::NewtonScratchLen = scratch_len::newton(DROP_VERTICES, DROP_TETS);

            /// The scratch of the two descent solvers for the dropped cube, sized by softfem's
            /// `scratch_len::newton`, `scratch_len::vbd` and `scratch_len::vbd_indices` (const
            /// fns). The [`TetHessian`]s Newton's method caches are not here: `TetHessian` has no
            /// const value to initialise a static with, so they live on the stack of
            /// [`newton_drop`] (`NEWTON_LEN.hessians` of them).
            pub struct DescentScratch {
                /// Newton: vectors (start positions, gradients, trial point, direction, CG).
                pub newton_vectors: [Vec3; NEWTON_LEN.vectors],
                /// Newton: the inverted block-Jacobi preconditioner blocks.
                pub newton_blocks: [Mat3; NEWTON_LEN.blocks],
                /// VBD: vectors (start, gradient, the iterates of the last two sweeps, sweep).
                pub vbd_vectors: [Vec3; scratch_len::vbd(DROP_VERTICES)],
                /// VBD: vertex adjacency, colours and vertex order.
                pub vbd_indices: [u32; scratch_len::vbd_indices(DROP_VERTICES, DROP_TETS)],
            }

            impl DescentScratch {
                /// All zeros (the solvers never read what they did not write).
                pub const EMPTY: Self = DescentScratch {
                    newton_vectors: [Vec3::ZERO; NEWTON_LEN.vectors],
                    newton_blocks: [Mat3::ZERO; NEWTON_LEN.blocks],
                    vbd_vectors: [Vec3::ZERO; scratch_len::vbd(DROP_VERTICES)],
                    vbd_indices: [0; scratch_len::vbd_indices(DROP_VERTICES, DROP_TETS)],
                };
            }

            /// Cells along x, y and z of the cube dropped onto the colliders: one layer of 2 x 2
            /// cubes, the bottom face a 3 x 3 grid of vertices. (Built in place by
            /// `Body::rebuild_from_box`; `Body::from_box`, which returns the body by value,
            /// took about five times the body's size in stack here: 97 KB in f64.)
            pub const COLLIDER_CELLS: [usize; 3] = [2, 1, 2];
            /// Its vertices: 3 x 2 x 3.
            pub const COLLIDER_VERTICES: usize = (COLLIDER_CELLS[0] + 1) * (COLLIDER_CELLS[1] + 1) * (COLLIDER_CELLS[2] + 1);
            /// Its tetrahedra: five per cube (`Body::from_box` splits by `BoxSplit::Alternating5`).
            pub const COLLIDER_TETS: usize = COLLIDER_CELLS[0] * COLLIDER_CELLS[1] * COLLIDER_CELLS[2] * 5;
            /// softfem's owning body in fixed storage, sized for that cube. `FixedStorage` holds
            /// the scratch of every solver (Newton's `TetHessian`s included), so this is the
            /// largest static of the firmware per vertex.
            pub type ColliderBody = owning::Body<FixedStorage<COLLIDER_VERTICES, COLLIDER_TETS>, StableNeoHookean>;
            /// The jelly of the collider scene (E = 50 kPa, nu = 0.4) as a `const`, for the
            /// body's `static` (the run sets the same material again, computed at run time).
            pub const COLLIDER_MATERIAL: StableNeoHookean = match Lame::from_young_poisson(5.0e4, 0.4) {
                Ok(lame) => StableNeoHookean::new(lame),
                Err(_) => panic!("the collider jelly's parameters are valid"),
            };
            /// The collider scene's body before it is built: a `const`, so the firmware's body
            /// is a static in `.bss`, built in place (`Body::rebuild_from_box`).
            pub const COLLIDER_BODY: ColliderBody = ColliderBody::empty(COLLIDER_MATERIAL);
            /// Explicit steps (60 Hz) of the cube on the colliders.
            pub const COLLIDER_EXPLICIT_STEPS: u32 = 30;
            /// Implicit steps (60 Hz, the relaxation) of the cube on the colliders, from the same
            /// start.
            pub const COLLIDER_RELAX_STEPS: u32 = 20;

            /// Explicit steps of the drop.
            pub const EXPLICIT_STEPS: u32 = 300;
            /// Implicit (relaxation) steps of the drop.
            pub const RELAX_STEPS: u32 = 100;
            /// Implicit steps of each descent solver (Newton, VBD) in the drop.
            pub const DESCENT_STEPS: u32 = 20;
            /// The time step of the descent solvers' drop (s).
            pub const DESCENT_DT: Real = 1.0 / 60.0;
            /// The budget of sweeps of a VBD step in the drop (a fixed budget, as a game would
            /// set it: a sweep of this 64-vertex body costs about 33 million instructions in f64
            /// on the Cortex-M4F).
            pub const VBD_SWEEPS: u32 = 10;

            fn push(records: &mut Records, name: &'static str, digest: Digest, value: Real) {
                records.push(Record {
                    name,
                    digest: digest.finish(),
                    value: value as f64,
                });
            }

            fn real(digest: &mut Digest, x: Real) {
                #[allow(clippy::useless_conversion)]
                let wide = f64::from(x);
                if core::mem::size_of::<Real>() == 4 {
                    digest.f32(wide as f32);
                } else {
                    digest.f64(wide);
                }
            }

            fn vec3(digest: &mut Digest, v: Vec3) {
                real(digest, v.x);
                real(digest, v.y);
                real(digest, v.z);
            }

            fn mat3(digest: &mut Digest, m: Mat3) {
                vec3(digest, m.x_axis);
                vec3(digest, m.y_axis);
                vec3(digest, m.z_axis);
            }

            fn svd_digest(digest: &mut Digest, svd: &Svd3) {
                mat3(digest, svd.u);
                vec3(digest, svd.sigma);
                mat3(digest, svd.v);
            }

            /// The matrix with rows `r0`, `r1`, `r2`.
            fn rows(r0: [Real; 3], r1: [Real; 3], r2: [Real; 3]) -> Mat3 {
                Mat3::from_cols(Vec3::from(r0), Vec3::from(r1), Vec3::from(r2)).transpose()
            }

            /// The fixed matrices of the SVD section, with names.
            fn svd_cases() -> [(&'static str, Mat3); 12] {
                let general = rows([0.8, -0.3, 0.1], [0.2, 1.1, -0.4], [0.05, 0.3, 0.9]);
                // Rotations from Pythagorean triples (3, 4, 5) and (5, 12, 13): exact cosines.
                let rot_z = rows([0.6, -0.8, 0.0], [0.8, 0.6, 0.0], [0.0, 0.0, 1.0]);
                let rot_x = rows([1.0, 0.0, 0.0], [0.0, 5.0 / 13.0, -12.0 / 13.0], [0.0, 12.0 / 13.0, 5.0 / 13.0]);
                let u = Vec3::new(0.3, -1.2, 0.7);
                let v = Vec3::new(-0.4, 0.25, 1.5);
                let outer = |a: Vec3, b: Vec3| Mat3::from_cols(a * b.x, a * b.y, a * b.z);
                [
                    (concat!($prefix, " svd identity"), Mat3::IDENTITY),
                    (concat!($prefix, " svd reflection diag(3,-2,0.5)"), Mat3::from_diagonal(Vec3::new(3.0, -2.0, 0.5))),
                    (concat!($prefix, " svd general"), general),
                    (concat!($prefix, " svd shear+squash"), Mat3::from_cols(Vec3::X, Vec3::new(0.2, 1.0, 0.0), Vec3::new(0.0, 0.0, 0.9))),
                    (concat!($prefix, " svd rank 1"), outer(u, v)),
                    (concat!($prefix, " svd rank 2"), outer(u, v) + outer(Vec3::new(1.0, 0.5, -0.25), Vec3::new(0.5, 0.5, 0.1))),
                    (concat!($prefix, " svd zero"), Mat3::ZERO),
                    (concat!($prefix, " svd near-singular"), rot_z * Mat3::from_diagonal(Vec3::new(1.0, 0.5, 1e-9)) * rot_x.transpose()),
                    (concat!($prefix, " svd repeated (2,2,1) rotated"), rot_x * Mat3::from_diagonal(Vec3::new(2.0, 2.0, 1.0)) * rot_z),
                    (concat!($prefix, " svd general * 1e30"), general * 1e30),
                    (concat!($prefix, " svd general * 1e-30"), general * 1e-30),
                    (concat!($prefix, " svd NaN entry"), rows([1.0, 0.0, 0.0], [0.0, Real::NAN, 0.0], [0.0, 0.0, 1.0])),
                ]
            }

            /// SVDs of fixed matrices, one by one and four at a time.
            fn svds(meter: &mut impl Meter, records: &mut Records) {
                let cases = svd_cases();
                let mut scalar = [Svd3 { u: Mat3::ZERO, sigma: Vec3::ZERO, v: Mat3::ZERO }; 12];
                for ((name, a), out) in cases.iter().zip(&mut scalar) {
                    let a = black_box(*a);
                    *out = meter.measure(concat!($prefix, " svd3"), || pieces::svd3(a));
                    meter.units(concat!($prefix, " svd3"), "SVD", 1);
                    let mut digest = Digest::new();
                    svd_digest(&mut digest, out);
                    push(records, name, digest, out.sigma.x);
                }
                // svd3_lanes promises per-lane bit-identity with svd3; the record's value is the
                // number of lanes that differ (0) and its digest covers all twelve results.
                let mut digest = Digest::new();
                let mut differing = 0;
                for (group, expected) in cases.chunks_exact(4).zip(scalar.chunks_exact(4)) {
                    let mats: [Mat3; 4] = core::array::from_fn(|i| group.get(i).map_or(Mat3::ZERO, |c| c.1));
                    let mats = black_box(mats);
                    let lanes = meter.measure(concat!($prefix, " svd3_lanes"), || pieces::svd3_lanes(&mats));
                    meter.units(concat!($prefix, " svd3_lanes"), "SVD", 4);
                    for (got, want) in lanes.iter().zip(expected) {
                        let (mut a, mut b) = (Digest::new(), Digest::new());
                        svd_digest(&mut a, got);
                        svd_digest(&mut b, want);
                        differing += u32::from(a.finish() != b.finish());
                        svd_digest(&mut digest, got);
                    }
                }
                push(records, concat!($prefix, " svd3_lanes vs svd3 (lanes differing)"), digest, differing as Real);
            }

            /// The small box of the force section: 2 x 2 x 2 cells of 5 cm, 27 vertices,
            /// 48 tetrahedra.
            const FORCE_VERTICES: usize = 27;
            const FORCE_TETS: usize = 48;

            /// The [`pieces`] of one model.
            struct ModelPieces<M> {
                direct: fn(&TetMesh<'_>, &M, &[Vec3], &mut [Vec3]) -> Result<(), MeshError>,
                principal: fn(&TetMesh<'_>, &M, &[Vec3], &mut [Vec3]) -> Result<(), MeshError>,
                clamped: fn(&TetMesh<'_>, &M, Real, &[Vec3], &mut [Vec3]) -> Result<(), MeshError>,
                energy: fn(&TetMesh<'_>, &M, &[Vec3]) -> Result<Real, MeshError>,
            }

            /// Forces (direct, principal, clamped) and energy of one model on the box.
            fn model_forces<M>(
                meter: &mut impl Meter,
                records: &mut Records,
                names: [&'static str; 4],
                material: M,
                pieces: ModelPieces<M>,
                mesh: &TetMesh<'_>,
                deformed: &[Vec3; FORCE_VERTICES],
            ) {
                let [direct, principal, clamped, energy] = names;
                for (path, name) in [direct, principal, clamped].into_iter().enumerate() {
                    let mut forces = [Vec3::ZERO; FORCE_VERTICES];
                    let outcome = meter.measure(name, || match path {
                        0 => (pieces.direct)(mesh, &material, deformed, &mut forces),
                        1 => (pieces.principal)(mesh, &material, deformed, &mut forces),
                        _ => (pieces.clamped)(mesh, &material, 0.9, deformed, &mut forces),
                    });
                    meter.units(name, "tet", FORCE_TETS as u64);
                    let mut digest = Digest::new();
                    digest.u64(u64::from(outcome.is_ok()));
                    let mut largest: Real = 0.0;
                    for f in &forces {
                        vec3(&mut digest, *f);
                        largest = largest.max(f.abs().max_element());
                    }
                    push(records, name, digest, largest);
                }
                let total = meter.measure(energy, || (pieces.energy)(mesh, &material, deformed));
                meter.units(energy, "tet", FORCE_TETS as u64);
                let mut digest = Digest::new();
                let value = total.unwrap_or(Real::NAN);
                real(&mut digest, value);
                push(records, energy, digest, value);
            }

            /// Forces and energies of every model on a deformed box.
            fn forces(meter: &mut impl Meter, records: &mut Records) {
                let mut rest = [Vec3::ZERO; FORCE_VERTICES];
                let mut tets = [[0u32; 4]; FORCE_TETS];
                let mut rest_data = [TetRest::default(); FORCE_TETS];
                if fill_box(Vec3::ZERO, Vec3::splat(0.1), 2, 2, 2, BoxSplit::Kuhn6, &mut rest, &mut tets).is_err() {
                    push(records, concat!($prefix, " force box"), Digest::new(), Real::NAN);
                    return;
                }
                let Ok(mesh) = pieces::mesh_new(&rest, &tets, &mut rest_data) else {
                    push(records, concat!($prefix, " force box"), Digest::new(), Real::NAN);
                    return;
                };
                // An affine stretch, shear and squash (J = 1.2 * 0.85) plus up to 4 mm of jitter
                // per coordinate: element J from about 0.7 to 1.5.
                let affine = rows([1.2, 0.15, 0.0], [0.0, 1.0, -0.1], [0.05, 0.0, 0.85]);
                let mut deformed = rest;
                for (i, x) in deformed.iter_mut().enumerate() {
                    let i = i as u32;
                    let j = Vec3::new(jitter(i, 1) as Real, jitter(i, 2) as Real, jitter(i, 3) as Real);
                    *x = affine * *x + j * 4e-6;
                }
                let deformed = black_box(deformed);
                let mut digest = Digest::new();
                for r in mesh.rest() {
                    mat3(&mut digest, r.dm_inv);
                    real(&mut digest, r.volume);
                }
                push(records, concat!($prefix, " box rest data"), digest, mesh.rest_volume());

                let (e, nu) = (black_box(1.0e6), black_box(0.45));
                match (StVK::from_young_poisson(e, nu), NeoHookean::from_young_poisson(e, nu), StableNeoHookean::from_young_poisson(e, nu)) {
                    (Ok(stvk), Ok(neo), Ok(stable)) => {
                        model_forces(meter, records, [
                            concat!($prefix, " forces StVK direct"),
                            concat!($prefix, " forces StVK principal"),
                            concat!($prefix, " forces StVK clamped"),
                            concat!($prefix, " energy StVK"),
                        ], stvk, ModelPieces {
                            direct: pieces::forces_stvk_direct,
                            principal: pieces::forces_stvk_principal,
                            clamped: pieces::forces_stvk_clamped,
                            energy: pieces::energy_stvk,
                        }, &mesh, &deformed);
                        model_forces(meter, records, [
                            concat!($prefix, " forces neo-Hookean direct"),
                            concat!($prefix, " forces neo-Hookean principal"),
                            concat!($prefix, " forces neo-Hookean clamped"),
                            concat!($prefix, " energy neo-Hookean"),
                        ], neo, ModelPieces {
                            direct: pieces::forces_neo_hookean_direct,
                            principal: pieces::forces_neo_hookean_principal,
                            clamped: pieces::forces_neo_hookean_clamped,
                            energy: pieces::energy_neo_hookean,
                        }, &mesh, &deformed);
                        model_forces(meter, records, [
                            concat!($prefix, " forces stable neo-Hookean direct"),
                            concat!($prefix, " forces stable neo-Hookean principal"),
                            concat!($prefix, " forces stable neo-Hookean clamped"),
                            concat!($prefix, " energy stable neo-Hookean"),
                        ], stable, ModelPieces {
                            direct: pieces::forces_stable_neo_hookean_direct,
                            principal: pieces::forces_stable_neo_hookean_principal,
                            clamped: pieces::forces_stable_neo_hookean_clamped,
                            energy: pieces::energy_stable_neo_hookean,
                        }, &mesh, &deformed);
                    }
                    _ => push(records, concat!($prefix, " materials"), Digest::new(), Real::NAN),
                }
            }

            fn state_digest(positions: &[Vec3], velocities: &[Vec3]) -> Digest {
                let mut digest = Digest::new();
                for (x, v) in positions.iter().zip(velocities) {
                    vec3(&mut digest, *x);
                    vec3(&mut digest, *v);
                }
                digest
            }

            fn lowest<const V: usize>(positions: &[Vec3; V]) -> Real {
                positions.iter().fold(Real::INFINITY, |low, x| low.min(x.y))
            }

            /// A 6 cm jelly cube (stable neo-Hookean, E = 50 kPa) dropped from 3 cm onto the
            /// ground y = 0, stepped explicitly and, from the same start, implicitly.
            fn drop(meter: &mut impl Meter, records: &mut Records, body: &mut DropBody, descent: &mut DescentScratch) {
                let side = 0.06;
                let lift = Vec3::new(0.0, 0.03, 0.0);
                let filled = fill_box(lift, lift + Vec3::splat(side), DROP_CELLS, DROP_CELLS, DROP_CELLS, BoxSplit::Kuhn6, &mut body.rest, &mut body.tets);
                let material = StableNeoHookean::from_young_poisson(black_box(5.0e4), black_box(0.4));
                let (Ok(()), Ok(material)) = (filled, material) else {
                    push(records, concat!($prefix, " drop setup"), Digest::new(), Real::NAN);
                    return;
                };
                let Ok(mesh) = pieces::mesh_new(&body.rest, &body.tets, &mut body.rest_data) else {
                    push(records, concat!($prefix, " drop mesh"), Digest::new(), Real::NAN);
                    return;
                };
                let model = TetElastic::new(mesh, material);
                let masses_ok = mesh.lumped_masses(1000.0, &mut body.masses).is_ok();
                let dt = stable_time_step(&model, &body.masses, &[], &mut body.relax_scalars).unwrap_or(Real::NAN);
                let mut digest = Digest::new();
                digest.u64(u64::from(masses_ok));
                for m in &body.masses {
                    real(&mut digest, *m);
                }
                real(&mut digest, dt);
                push(records, concat!($prefix, " drop masses and stable dt"), digest, dt);

                let gravity = Vec3::new(0.0, -9.81, 0.0);
                let ground = HalfSpace::new(Vec3::Y, 0.0).with_restitution(0.3).with_friction(0.5);

                // Explicit: half the stable step, light damping.
                let scene = Scene::new(0.5 * dt).with_gravity(gravity).with_ground(ground);
                let settings = ExplicitSettings::new().with_damping(2.0);
                body.positions = body.rest;
                body.velocities = [Vec3::ZERO; DROP_VERTICES];
                let mut scratch = ExplicitScratch::new(body.explicit_scratch.as_flattened_mut());
                let mut failures = 0u64;
                let mut contacts = 0u64;
                let mut kinetic: Real = 0.0;
                for step in 1..=EXPLICIT_STEPS {
                    let (positions, velocities) = (&mut body.positions, &mut body.velocities);
                    let report = meter.measure(concat!($prefix, " explicit_step"), || {
                        pieces::explicit_step(&model, &body.masses, &scene, &settings, positions, velocities, &mut scratch)
                    });
                    meter.units(concat!($prefix, " explicit_step"), "vertex step", DROP_VERTICES as u64);
                    match report {
                        Ok(report) => {
                            contacts += report.ground_contacts as u64;
                            kinetic = report.kinetic_energy;
                        }
                        Err(_) => failures += 1,
                    }
                    if step % 100 == 0 {
                        let mut digest = state_digest(&body.positions, &body.velocities);
                        digest.u64(failures);
                        digest.u64(contacts);
                        real(&mut digest, kinetic);
                        let label = match step {
                            100 => concat!($prefix, " explicit drop, step 100 (lowest y)"),
                            200 => concat!($prefix, " explicit drop, step 200 (lowest y)"),
                            _ => concat!($prefix, " explicit drop, step 300 (lowest y)"),
                        };
                        push(records, label, digest, lowest(&body.positions));
                    }
                }

                // Implicit Euler at 240 Hz from the same start, Chebyshev-accelerated.
                let scene = Scene::new(1.0 / 240.0).with_gravity(gravity).with_ground(ground);
                let relax = RelaxSettings::new()
                    .with_tolerance(1e-3, 100)
                    .with_chebyshev(0.99, 2.0, 0);
                body.positions = body.rest;
                body.velocities = [Vec3::ZERO; DROP_VERTICES];
                let mut scratch = RelaxScratch::new(body.relax_vectors.as_flattened_mut(), &mut body.relax_scalars);
                let mut digest = Digest::new();
                let mut iterations = 0u64;
                for step in 1..=RELAX_STEPS {
                    let (positions, velocities) = (&mut body.positions, &mut body.velocities);
                    let report = meter.measure(concat!($prefix, " relax_step"), || {
                        pieces::relax_step(&model, &body.masses, &scene, &relax, positions, velocities, &mut scratch)
                    });
                    match report {
                        Ok(report) => {
                            iterations += u64::from(report.iterations);
                            meter.units(concat!($prefix, " relax_step"), "vertex iteration", DROP_VERTICES as u64 * u64::from(report.iterations));
                            relax_report(&mut digest, &report);
                        }
                        Err(_) => digest.u64(u64::MAX),
                    }
                    if step % 50 == 0 {
                        let state = state_digest(&body.positions, &body.velocities);
                        digest.u64(state.finish());
                        let label = match step {
                            50 => concat!($prefix, " relax drop, step 50 (lowest y)"),
                            _ => concat!($prefix, " relax drop, step 100 (lowest y)"),
                        };
                        push(records, label, digest, lowest(&body.positions));
                    }
                }
                let mut count = Digest::new();
                count.u64(iterations);
                push(records, concat!($prefix, " relax drop, iterations"), count, iterations as Real);

                // Implicit Euler at 60 Hz from the same start by Newton's method and by Vertex
                // Block Descent.
                let state = (&mut body.positions, &mut body.velocities);
                newton_drop(meter, records, &model, &body.masses, &body.rest, (&mut *state.0, &mut *state.1), descent, gravity, ground);
                vbd_drop(meter, records, &model, &body.masses, &body.rest, state, descent, gravity, ground);
            }

            /// Digests of one implicit drop's state after step 10 and 20, and its reports.
            struct DescentRecords {
                digest: Digest,
                labels: [&'static str; 2],
            }

            impl DescentRecords {
                /// Mixes in the state after `step` and pushes it at steps 10 and 20.
                fn after_step(&mut self, records: &mut Records, step: u32, positions: &[Vec3; DROP_VERTICES], velocities: &[Vec3; DROP_VERTICES]) {
                    let label = match step {
                        10 => self.labels[0],
                        20 => self.labels[1],
                        _ => return,
                    };
                    let state = state_digest(positions, velocities);
                    self.digest.u64(state.finish());
                    push(records, label, self.digest, lowest(positions));
                }
            }

            /// [`DESCENT_STEPS`] Newton steps of the drop from rest. Never inlined: its cached
            /// `TetHessian`s (58 KB in f64) must leave the stack when it returns, not stay in
            /// [`run`]'s frame while [`on_colliders`] builds its body.
            #[allow(clippy::too_many_arguments)]
            #[inline(never)]
            fn newton_drop(
                meter: &mut impl Meter,
                records: &mut Records,
                model: &TetElastic<'_, StableNeoHookean>,
                masses: &[Real; DROP_VERTICES],
                rest: &[Vec3; DROP_VERTICES],
                (positions, velocities): (&mut [Vec3; DROP_VERTICES], &mut [Vec3; DROP_VERTICES]),
                descent: &mut DescentScratch,
                gravity: Vec3,
                ground: HalfSpace<Vec3>,
            ) {
                let scene = Scene::new(DESCENT_DT).with_gravity(gravity).with_ground(ground);
                let settings = NewtonSettings::new().with_tolerance(1e-3, 20);
                *positions = *rest;
                *velocities = [Vec3::ZERO; DROP_VERTICES];
                let mut hessians = [TetHessian::default(); NEWTON_LEN.hessians];
                let mut scratch = NewtonScratch::new(&mut descent.newton_vectors, &mut descent.newton_blocks, &mut hessians);
                let mut out = DescentRecords {
                    digest: Digest::new(),
                    labels: [
                        concat!($prefix, " newton drop, step 10 (lowest y)"),
                        concat!($prefix, " newton drop, step 20 (lowest y)"),
                    ],
                };
                let (mut newton, mut cg) = (0u64, 0u64);
                for step in 1..=DESCENT_STEPS {
                    let report = meter.measure(concat!($prefix, " newton_step"), || {
                        pieces::newton_step(model, masses, &scene, &settings, &mut *positions, &mut *velocities, &mut scratch)
                    });
                    let digest = &mut out.digest;
                    match report {
                        Ok(report) => {
                            newton += u64::from(report.iterations);
                            cg += u64::from(report.details.cg_iterations);
                            meter.units(concat!($prefix, " newton_step"), "vertex Newton iteration", DROP_VERTICES as u64 * u64::from(report.iterations));
                            newton_report(digest, &report);
                        }
                        Err(_) => digest.u64(u64::MAX),
                    }
                    out.after_step(records, step, positions, velocities);
                }
                let mut count = Digest::new();
                count.u64(newton);
                push(records, concat!($prefix, " newton drop, Newton iterations"), count, newton as Real);
                let mut count = Digest::new();
                count.u64(cg);
                push(records, concat!($prefix, " newton drop, CG iterations"), count, cg as Real);
            }

            /// Mixes a relaxation step's report into `digest`: the fields it had before the
            /// implicit solvers shared one report type (all but `target` and `rho`).
            fn relax_report(digest: &mut Digest, report: &RelaxReport) {
                for count in [report.iterations, report.energy_evaluations, report.backtracks, report.restarts] {
                    digest.u64(u64::from(count));
                }
                digest.u64(u64::from(report.converged) | u64::from(report.stagnated) << 1);
                for value in [report.initial_residual, report.residual, report.phi, report.rounding_floor] {
                    real(digest, value);
                }
            }

            /// Mixes a Newton step's report into `digest`: the fields it had before the implicit
            /// solvers shared one report type (all but `restarts` and `rho`).
            fn newton_report(digest: &mut Digest, report: &NewtonReport) {
                for count in [report.iterations, report.details.cg_iterations, report.energy_evaluations, report.backtracks] {
                    digest.u64(u64::from(count));
                }
                digest.u64(u64::from(report.converged) | u64::from(report.stagnated) << 1);
                for value in [report.initial_residual, report.residual, report.target, report.rounding_floor, report.phi] {
                    real(digest, value);
                }
            }

            /// [`DESCENT_STEPS`] Vertex Block Descent steps of the drop from rest.
            #[allow(clippy::too_many_arguments)]
            fn vbd_drop(
                meter: &mut impl Meter,
                records: &mut Records,
                model: &TetElastic<'_, StableNeoHookean>,
                masses: &[Real; DROP_VERTICES],
                rest: &[Vec3; DROP_VERTICES],
                (positions, velocities): (&mut [Vec3; DROP_VERTICES], &mut [Vec3; DROP_VERTICES]),
                descent: &mut DescentScratch,
                gravity: Vec3,
                ground: HalfSpace<Vec3>,
            ) {
                let scene = Scene::new(DESCENT_DT).with_gravity(gravity).with_ground(ground);
                let settings = VbdSettings::new()
                    .with_tolerance(1e-3, VBD_SWEEPS)
                    .with_estimated_chebyshev(4);
                *positions = *rest;
                *velocities = [Vec3::ZERO; DROP_VERTICES];
                let mut scratch = VbdScratch::new(&mut descent.vbd_vectors, &mut descent.vbd_indices);
                let mut out = DescentRecords {
                    digest: Digest::new(),
                    labels: [
                        concat!($prefix, " vbd drop, step 10 (lowest y)"),
                        concat!($prefix, " vbd drop, step 20 (lowest y)"),
                    ],
                };
                let mut sweeps = 0u64;
                for step in 1..=DESCENT_STEPS {
                    let report = meter.measure(concat!($prefix, " vbd_step"), || {
                        pieces::vbd_step(model, masses, &scene, &settings, &mut *positions, &mut *velocities, &mut scratch)
                    });
                    let digest = &mut out.digest;
                    match report {
                        Ok(report) => {
                            sweeps += u64::from(report.iterations);
                            meter.units(concat!($prefix, " vbd_step"), "vertex sweep", DROP_VERTICES as u64 * u64::from(report.iterations));
                            // The fields the report had before the implicit solvers shared one
                            // report type (its `backtracks` were the per-vertex line search's,
                            // now `details.vertex_backtracks`).
                            let details = &report.details;
                            for count in [report.iterations, report.energy_evaluations, details.colours, report.restarts, details.vertex_backtracks, details.skipped, details.projected, details.redone_sweeps] {
                                digest.u64(u64::from(count));
                            }
                            digest.u64(u64::from(report.converged));
                            for value in [report.initial_residual, report.residual, report.phi, report.rho] {
                                real(digest, value);
                            }
                        }
                        Err(_) => digest.u64(u64::MAX),
                    }
                    out.after_step(records, step, positions, velocities);
                }
                let mut count = Digest::new();
                count.u64(sweeps);
                push(records, concat!($prefix, " vbd drop, sweeps"), count, sweeps as Real);
            }

            /// The sphere and the capsule the cube of [`on_colliders`] lands on: the sphere's top
            /// under the middle of the cube's bottom edge at x = -5 cm, the capsule (along z)
            /// under the whole edge at x = +5 cm, both tops at y = 5 cm, friction 0.5.
            fn colliders() -> [Collider<'static>; 2] {
                let (radius, top) = (0.02, 0.05);
                [
                    Collider::sphere(Vec3::new(-0.05, 0.0, 0.0), top).with_friction(0.5),
                    Collider::capsule(Vec3::new(0.05, top - radius, -0.1), Vec3::new(0.05, top - radius, 0.1), radius).with_friction(0.5),
                ]
            }

            /// The least signed distance (m) of any vertex to any collider: 0 for a body resting
            /// on them, negative inside one.
            pub fn clearance(positions: &[Vec3]) -> Real {
                let colliders = colliders();
                positions
                    .iter()
                    .flat_map(|&x| colliders.iter().map(move |c| c.distance(x)))
                    .fold(Real::INFINITY, Real::min)
            }

            /// One solver's run in [`on_colliders`]: what it measures and records.
            struct ColliderRun {
                solver: Solver,
                steps: u32,
                section: &'static str,
                unit: &'static str,
                /// The records of the state after half the steps and after all of them.
                labels: [&'static str; 2],
                /// The records of the summed substeps, or of the relaxation's iterations and
                /// converged steps ("": none).
                counts: [&'static str; 2],
            }

            /// A 10 cm jelly cube (stable neo-Hookean, E = 50 kPa; 18 vertices, 20 tetrahedra),
            /// softfem's owning `Body` in
            /// fixed storage ([`ColliderBody`], rebuilt in place), dropped from 5 cm onto a sphere
            /// and a capsule ([`colliders`]) and stepped at 60 Hz by `Body::step_with_colliders`:
            /// explicitly (substeps of half the stable step) and, rebuilt at rest, by implicit
            /// Euler (the relaxation, the stepper the README recommends for soft bodies at
            /// display rates).
            #[inline(never)]
            fn on_colliders(meter: &mut impl Meter, records: &mut Records, body: &mut ColliderBody) {
                let material = StableNeoHookean::from_young_poisson(black_box(5.0e4), black_box(0.4));
                let Ok(material) = material else {
                    push(records, concat!($prefix, " body setup"), Digest::new(), Real::NAN);
                    return;
                };
                let colliders = colliders();
                let (low, high) = (Vec3::new(-0.05, 0.1, -0.05), Vec3::new(0.05, 0.2, 0.05));
                let explicit = ColliderRun {
                    solver: Solver::Explicit {
                        settings: ExplicitSettings::new().with_damping(2.0),
                        stable_fraction: Some(0.5),
                    },
                    steps: COLLIDER_EXPLICIT_STEPS,
                    section: concat!($prefix, " body explicit step"),
                    unit: "vertex substep",
                    labels: [
                        concat!($prefix, " body explicit, step 15 (clearance)"),
                        concat!($prefix, " body explicit, step 30 (clearance)"),
                    ],
                    counts: [concat!($prefix, " body explicit, substeps"), ""],
                };
                // The drop's relaxation settings (Chebyshev-accelerated, tolerance 1e-3).
                let relax = ColliderRun {
                    solver: Solver::Relax(RelaxSettings::new().with_tolerance(1e-3, 100).with_chebyshev(0.99, 2.0, 0)),
                    steps: COLLIDER_RELAX_STEPS,
                    section: concat!($prefix, " body relax step"),
                    unit: "vertex iteration",
                    labels: [
                        concat!($prefix, " body relax, step 10 (clearance)"),
                        concat!($prefix, " body relax, step 20 (clearance)"),
                    ],
                    counts: [
                        concat!($prefix, " body relax, iterations"),
                        concat!($prefix, " body relax, converged steps"),
                    ],
                };
                for (index, run) in [explicit, relax].into_iter().enumerate() {
                    // Each run from rest: the body is built afresh.
                    let built = meter.measure(concat!($prefix, " Body::rebuild_from_box"), || {
                        pieces::body_new(body, low, high, 1000.0, material)
                    });
                    let Ok(()) = built else {
                        push(records, concat!($prefix, " body build"), Digest::new(), Real::NAN);
                        return;
                    };
                    body.set_gravity(Vec3::new(0.0, -9.81, 0.0));
                    if index == 0 {
                        let dt = body.stable_time_step().unwrap_or(Real::NAN);
                        let mut digest = Digest::new();
                        for m in body.masses() {
                            real(&mut digest, *m);
                        }
                        real(&mut digest, dt);
                        push(records, concat!($prefix, " body masses and stable dt"), digest, dt);
                    }
                    if body.set_solver(run.solver).is_err() {
                        push(records, concat!($prefix, " body solver"), Digest::new(), Real::NAN);
                        return;
                    }
                    let vertices = body.vertex_count() as u64;
                    let mut digest = Digest::new();
                    let mut counts = [0u64; 2];
                    for step in 1..=run.steps {
                        let report = meter.measure(run.section, || pieces::body_step(body, 1.0 / 60.0, &colliders));
                        let work = match report {
                            Ok(StepReport::Explicit(report)) => {
                                digest.u64(u64::from(report.substeps));
                                digest.u64(report.ground_contacts as u64);
                                real(&mut digest, report.kinetic_energy);
                                counts[0] += u64::from(report.substeps);
                                report.substeps
                            }
                            Ok(StepReport::Relax(report)) => {
                                relax_report(&mut digest, &report);
                                counts[0] += u64::from(report.iterations);
                                counts[1] += u64::from(report.converged);
                                report.iterations
                            }
                            Ok(_) => {
                                digest.u64(u64::MAX - 1);
                                0
                            }
                            Err(_) => {
                                digest.u64(u64::MAX);
                                0
                            }
                        };
                        meter.units(run.section, run.unit, vertices * u64::from(work));
                        if step == run.steps / 2 || step == run.steps {
                            let state = state_digest(body.positions(), body.velocities());
                            digest.u64(state.finish());
                            let label = if step == run.steps { run.labels[1] } else { run.labels[0] };
                            push(records, label, digest, clearance(body.positions()));
                        }
                    }
                    for (label, count) in run.counts.into_iter().zip(counts) {
                        if !label.is_empty() {
                            let mut digest = Digest::new();
                            digest.u64(count);
                            push(records, label, digest, count as Real);
                        }
                    }
                }
            }

            /// Vertices of the contact scene: two cubes of one Kuhn-split cell.
            const PAIR_VERTICES: usize = 16;
            /// Tetrahedra of the contact scene.
            const PAIR_TETS: usize = 12;
            /// Boundary triangles of the contact scene (12 per cube).
            const PAIR_TRIANGLES: usize = 24;
            /// Candidate pairs per list the contact scene's buffers hold.
            const PAIR_CANDIDATES: usize = 512;
            /// Active pairs the contact scene's Hessian and friction buffers hold (it has 6 at
            /// rest; cubes with aligned corners, 10 um apart, have 111).
            const PAIR_ACTIVE: usize = 32;
            /// Newton steps of the contact scene.
            const PAIR_STEPS: u32 = 10;
            /// The contact scene's broad-phase lengths.
            const PAIR_BROAD: scratch_len::BroadPhaseScratchLen = scratch_len::broad_phase(
                PAIR_VERTICES,
                scratch_len::boundary_edges(PAIR_TRIANGLES),
                PAIR_TRIANGLES,
            );
            /// Newton's lengths for the contact scene.
            const PAIR_NEWTON: scratch_len::NewtonScratchLen = scratch_len::newton(PAIR_VERTICES, PAIR_TETS);

            /// Body–body contact: a 1 cm cube dropped from 1 mm onto another standing on the
            /// ground, shifted by (3, 2) mm sideways so that no corner meets a corner (both of
            /// one Kuhn-split cell, stable neo-Hookean, E = 1e5 Pa), the
            /// barrier of `ContactModel` with dhat = 0.5 mm and friction 0.5 between them,
            /// [`PAIR_STEPS`] Newton steps at 100 Hz. Every buffer is a fixed array on the stack
            /// (about 55 KB of pair Hessians in f64); never inlined, so that they leave the stack
            /// with it.
            #[inline(never)]
            fn contact_pair(meter: &mut impl Meter, records: &mut Records) {
                let mut rest = [Vec3::ZERO; PAIR_VERTICES];
                let mut tets = [[0u32; 4]; PAIR_TETS];
                for (k, base) in [0.0, 0.011].into_iter().enumerate() {
                    let shift = k as Real;
                    let min = Vec3::new(0.003 * shift, base, 0.002 * shift);
                    let (Some(x), Some(t)) = (rest.get_mut(8 * k..8 * k + 8), tets.get_mut(6 * k..6 * k + 6)) else {
                        return;
                    };
                    if fill_box(min, min + Vec3::splat(0.01), 1, 1, 1, BoxSplit::Kuhn6, x, t).is_err() {
                        return;
                    }
                    for tet in t.iter_mut() {
                        for v in tet.iter_mut() {
                            *v += 8 * k as u32;
                        }
                    }
                }
                let mut faces = [BoundaryFace::default(); boundary_scratch_len(PAIR_TETS)];
                let mut triangles = [[0u32; 3]; PAIR_TRIANGLES];
                match boundary_faces(&tets, PAIR_VERTICES, &mut faces) {
                    Ok(found) if found.len() == PAIR_TRIANGLES => {
                        for (slot, face) in triangles.iter_mut().zip(found) {
                            *slot = face.triangle;
                        }
                    }
                    _ => return,
                }
                let mut surface_vertices = [0u32; scratch_len::boundary_vertices(PAIR_TRIANGLES)];
                let mut surface_edges = [[0u32; 2]; scratch_len::boundary_edges(PAIR_TRIANGLES)];
                let Ok(surface) = ContactSurface::from_triangles(&triangles, PAIR_VERTICES, &mut surface_vertices, &mut surface_edges) else {
                    return;
                };
                let mut rest_data = [TetRest::default(); PAIR_TETS];
                let Ok(mesh) = TetMesh::new(&rest, &tets, &mut rest_data) else {
                    return;
                };
                let mut masses = [0.0; PAIR_VERTICES];
                if mesh.lumped_masses(1000.0, &mut masses).is_err() {
                    return;
                }
                let Ok(material) = StableNeoHookean::from_young_poisson(1.0e5, 0.3) else {
                    return;
                };
                let mut slots = [0u32; PAIR_BROAD.slots];
                let mut entries = [0u32; PAIR_BROAD.entries];
                let mut vertex_triangle = [[0u32; 2]; PAIR_CANDIDATES];
                let mut edge_edge = [[0u32; 2]; PAIR_CANDIDATES];
                let mut pair_hessians = [PairHessian::default(); PAIR_ACTIVE];
                let mut friction = [FrictionPair::default(); PAIR_ACTIVE];
                // Candidate reuse (the motion's pairs kept for its line search).
                let mut reuse_bounds = [Vec3::ZERO; 2 * PAIR_VERTICES];
                let mut reuse_vertex_triangle = [[0u32; 2]; 2 * PAIR_CANDIDATES];
                let mut reuse_edge_edge = [[0u32; 2]; 2 * PAIR_CANDIDATES];
                let buffers = ContactBuffers {
                    slots: &mut slots,
                    entries: &mut entries,
                    vertex_triangle: &mut vertex_triangle,
                    edge_edge: &mut edge_edge,
                    hessians: &mut pair_hessians,
                    friction: &mut friction,
                    reuse: CandidateReuse {
                        bounds: &mut reuse_bounds,
                        vertex_triangle: &mut reuse_vertex_triangle,
                        edge_edge: &mut reuse_edge_edge,
                    },
                };
                // The upper cube's 0.13 N weight on its 4 bottom vertices: 0.05 N a pair at
                // half the gap.
                let Ok(barrier) = ContactBarrier::holding(5e-4, 0.05) else {
                    return;
                };
                let model = match ContactModel::new(TetElastic::new(mesh, material), surface, &rest, barrier, buffers) {
                    Ok(model) => match model.with_friction(0.5, SUGGESTED_STICKING_SPEED) {
                        Ok(model) => model,
                        Err(_) => return,
                    },
                    Err(_) => return,
                };
                let scene = Scene::new(0.01)
                    .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                    .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
                let settings = NewtonSettings::new().with_tolerance(1e-3, 30);
                let mut vectors = [Vec3::ZERO; PAIR_NEWTON.vectors];
                let mut blocks = [Mat3::ZERO; PAIR_NEWTON.blocks];
                let mut hessians = [TetHessian::default(); PAIR_NEWTON.hessians];
                let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
                let (mut positions, mut velocities) = (rest, [Vec3::ZERO; PAIR_VERTICES]);
                let mut digest = Digest::new();
                let (mut newton, mut failed) = (0u64, 0u64);
                for _ in 0..PAIR_STEPS {
                    let report = meter.measure(concat!($prefix, " contact_newton_step"), || {
                        pieces::contact_newton_step(&model, &masses, &scene, &settings, &mut positions, &mut velocities, &mut scratch)
                    });
                    match report {
                        Ok(report) => {
                            newton += u64::from(report.iterations);
                            meter.units(concat!($prefix, " contact_newton_step"), "vertex Newton iteration", PAIR_VERTICES as u64 * u64::from(report.iterations));
                            newton_report(&mut digest, &report);
                            failed += u64::from(!report.converged);
                        }
                        Err(_) => {
                            digest.u64(u64::MAX);
                            failed += 1;
                        }
                    }
                    let counts = model.counts();
                    for count in [counts.vertex_triangle, counts.edge_edge, counts.hessians, counts.friction] {
                        digest.u64(count as u64);
                    }
                    digest.u64(state_digest(&positions, &velocities).finish());
                }
                // The gap left between the cubes: the upper one's lowest vertex over the lower
                // one's highest.
                let upper = positions.get(8..).unwrap_or(&[]).iter().fold(Real::INFINITY, |low, p| low.min(p.y));
                let lower = positions.get(..8).unwrap_or(&[]).iter().fold(Real::NEG_INFINITY, |high, p| high.max(p.y));
                push(records, concat!($prefix, " contact pair, step 10 (gap)"), digest, upper - lower);
                let mut count = Digest::new();
                count.u64(newton);
                push(records, concat!($prefix, " contact pair, Newton iterations"), count, newton as Real);
                let mut count = Digest::new();
                count.u64(failed);
                push(records, concat!($prefix, " contact pair, steps failed or not converged"), count, failed as Real);
            }

            /// Steps of [`rigid_on_body`].
            const RIGID_STEPS: u32 = 30;

            /// Two-way coupling with a rigid body in firmware (issue #42): the owned 10 cm
            /// jelly cube ([`ColliderBody`], E = 50 kPa) standing on the ground as a half-space
            /// collider, a 1 kg rigid box (a cuboid collider wider than the cube) set on its
            /// top, stepped by Newton's method at 60 Hz with `Body::step_with_reactions`; the
            /// box is integrated here from the reaction (`v += J / m - g dt`, `y += v dt`), as a
            /// host engine would. Records the box's height and the floor's and box's reactions.
            /// The box is heavy enough for the staggered loop at 60 Hz: `2 sqrt(M / k)` = 28 ms
            /// with the cube's `k = E A / L` = 5 kN/m (a 0.2 kg box, 13 ms, is thrown off).
            #[inline(never)]
            fn rigid_on_body(meter: &mut impl Meter, records: &mut Records, body: &mut ColliderBody) {
                let Ok(material) = StableNeoHookean::from_young_poisson(black_box(5.0e4), black_box(0.4)) else {
                    push(records, concat!($prefix, " rigid on body setup"), Digest::new(), Real::NAN);
                    return;
                };
                let (low, high) = (Vec3::new(-0.05, 0.0, -0.05), Vec3::new(0.05, 0.1, 0.05));
                let built = pieces::body_new(body, low, high, 1000.0, material);
                if built.is_err() || body.set_solver(Solver::newton()).is_err() {
                    push(records, concat!($prefix, " rigid on body build"), Digest::new(), Real::NAN);
                    return;
                }
                body.set_gravity(Vec3::new(0.0, -9.81, 0.0));
                let (mass, half, dt) = (1.0, Vec3::new(0.08, 0.02, 0.08), 1.0 / 60.0);
                let (mut y, mut v) = (0.1 + half.y, 0.0);
                let mut reactions = [Reaction::ZERO; 2];
                let mut digest = Digest::new();
                for step in 1..=RIGID_STEPS {
                    let colliders = [
                        Collider::half_space(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0)),
                        Collider::cuboid(Vec3::new(0.0, y, 0.0), half, Quat::IDENTITY)
                            .with_velocity(Vec3::new(0.0, v, 0.0), Vec3::ZERO),
                    ];
                    let scene = body.scene(dt).with_colliders(&colliders);
                    let report = meter.measure(concat!($prefix, " body step with reactions"), || {
                        pieces::body_step_with_reactions(body, &scene, &mut reactions)
                    });
                    match report {
                        Ok(report) => digest.u64(u64::from(report.converged())),
                        Err(_) => digest.u64(u64::MAX),
                    }
                    for reaction in &reactions {
                        vec3(&mut digest, reaction.impulse);
                        vec3(&mut digest, reaction.angular_impulse);
                        digest.u64(u64::from(reaction.vertices));
                    }
                    let impulse = reactions.get(1).map_or(0.0, |r| r.impulse.y);
                    v += impulse / mass - 9.81 * dt;
                    y += v * dt;
                    real(&mut digest, y);
                    if step == RIGID_STEPS {
                        digest.u64(state_digest(body.positions(), body.velocities()).finish());
                        push(records, concat!($prefix, " rigid box on body, step 30 (height)"), digest, y);
                        // The floor carries both: the body's weight and the box's.
                        let floor = reactions.first().map_or(Real::NAN, |r| r.impulse.y) / dt;
                        let mut force = Digest::new();
                        real(&mut force, floor);
                        push(records, concat!($prefix, " rigid box on body, floor force (N)"), force, -floor);
                    }
                }
            }

            /// A dynamic rigid body solved with the soft body in firmware (issue #42 item 1): the
            /// cube of [`rigid_on_body`] with a 0.2 kg box on its top, a box the staggered loop
            /// throws off at 60 Hz, stepped by `Body::step_with_rigid_bodies` (Newton's method),
            /// the box's motion solved with the cube's. Records the box's height, the floor's
            /// force and the coupling iterations.
            #[inline(never)]
            fn dynamic_on_body(meter: &mut impl Meter, records: &mut Records, body: &mut ColliderBody) {
                let Ok(material) = StableNeoHookean::from_young_poisson(black_box(5.0e4), black_box(0.4)) else {
                    push(records, concat!($prefix, " dynamic on body setup"), Digest::new(), Real::NAN);
                    return;
                };
                let (low, high) = (Vec3::new(-0.05, 0.0, -0.05), Vec3::new(0.05, 0.1, 0.05));
                let built = pieces::body_new(body, low, high, 1000.0, material);
                if built.is_err() || body.set_solver(Solver::newton()).is_err() {
                    push(records, concat!($prefix, " dynamic on body build"), Digest::new(), Real::NAN);
                    return;
                }
                body.set_gravity(Vec3::new(0.0, -9.81, 0.0));
                let (mass, half, dt) = (0.2, Vec3::new(0.08, 0.02, 0.08), 1.0 / 60.0);
                let moments = Vec3::new(
                    half.y * half.y + half.z * half.z,
                    half.x * half.x + half.z * half.z,
                    half.x * half.x + half.y * half.y,
                ) * (mass / 3.0);
                let mut colliders = [
                    Collider::half_space(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0)),
                    Collider::cuboid(Vec3::new(0.0, 0.1 + half.y, 0.0), half, Quat::IDENTITY)
                        .with_mass(mass, moments),
                ];
                let mut reactions = [Reaction::ZERO; 2];
                let (mut digest, mut iterations) = (Digest::new(), 0);
                for step in 1..=RIGID_STEPS {
                    let scene = body.scene(dt);
                    let report = meter.measure(concat!($prefix, " body step with rigid bodies"), || {
                        pieces::body_step_with_rigid_bodies(body, &scene, &mut colliders, &mut reactions)
                    });
                    match report {
                        Ok(report) => {
                            digest.u64(u64::from(report.converged()));
                            iterations += report.coupling.iterations;
                        }
                        Err(_) => digest.u64(u64::MAX),
                    }
                    for reaction in &reactions {
                        vec3(&mut digest, reaction.impulse);
                        vec3(&mut digest, reaction.angular_impulse);
                        digest.u64(u64::from(reaction.vertices));
                    }
                    let y = colliders.get(1).map_or(Real::NAN, |c| c.position.y);
                    real(&mut digest, y);
                    if step == RIGID_STEPS {
                        digest.u64(state_digest(body.positions(), body.velocities()).finish());
                        digest.u64(u64::from(iterations));
                        push(records, concat!($prefix, " dynamic box on body, step 30 (height)"), digest, y);
                        let floor = reactions.first().map_or(Real::NAN, |r| r.impulse.y) / dt;
                        let mut force = Digest::new();
                        real(&mut force, floor);
                        push(records, concat!($prefix, " dynamic box on body, floor force (N)"), force, -floor);
                        let mut count = Digest::new();
                        count.u64(u64::from(iterations));
                        push(records, concat!($prefix, " dynamic box on body, coupling iterations"), count, iterations as Real);
                    }
                }
            }

            /// Attachments in firmware (issue #42 item 3): the owned jelly cube hangs from a
            /// static hook collider, its four top corners on hard attachments and the rest of
            /// its top face on springs (200 N/m) and dampers (2 N s/m), stepped by Newton's
            /// method at 60 Hz with `Body::step_with_rigid_bodies_and_attachments`. Records the
            /// hook's force after 30 steps and the state.
            #[inline(never)]
            fn hanging_body(meter: &mut impl Meter, records: &mut Records, body: &mut ColliderBody) {
                let Ok(material) = StableNeoHookean::from_young_poisson(black_box(5.0e4), black_box(0.4)) else {
                    push(records, concat!($prefix, " hanging body setup"), Digest::new(), Real::NAN);
                    return;
                };
                let (low, high) = (Vec3::new(-0.05, 0.0, -0.05), Vec3::new(0.05, 0.1, 0.05));
                let built = pieces::body_new(body, low, high, 1000.0, material);
                if built.is_err() || body.set_solver(Solver::newton()).is_err() {
                    push(records, concat!($prefix, " hanging body build"), Digest::new(), Real::NAN);
                    return;
                }
                body.set_gravity(Vec3::new(0.0, -9.81, 0.0));
                let hook = Collider::cuboid(Vec3::new(0.0, 0.12, 0.0), Vec3::new(0.06, 0.02, 0.06), Quat::IDENTITY);
                let mut attachments = [Attachment::new(0, 0, Vec3::ZERO); 9];
                let mut count = 0;
                for (i, &x) in body.positions().iter().enumerate() {
                    if x.y == 0.1 && count < attachments.len() {
                        let corner = x.x.abs() == 0.05 && x.z.abs() == 0.05;
                        let hold = Attachment::at(i as u32, 0, &hook, x);
                        attachments[count] = match corner {
                            true => hold,
                            false => hold.with_spring(200.0, 2.0),
                        };
                        count += 1;
                    }
                }
                let attached = attachments.get(..count).unwrap_or(&[]);
                let mut colliders = [hook];
                let mut reactions = [Reaction::ZERO];
                let (mut digest, dt) = (Digest::new(), 1.0 / 60.0);
                for step in 1..=RIGID_STEPS {
                    let scene = body.scene(dt);
                    let report = meter.measure(concat!($prefix, " body step with attachments"), || {
                        pieces::body_step_attached(body, &scene, &mut colliders, attached, &mut reactions)
                    });
                    match report {
                        Ok(report) => digest.u64(u64::from(report.converged())),
                        Err(_) => digest.u64(u64::MAX),
                    }
                    let reaction = reactions.first().copied().unwrap_or(Reaction::ZERO);
                    vec3(&mut digest, reaction.impulse);
                    vec3(&mut digest, reaction.angular_impulse);
                    if step == RIGID_STEPS {
                        digest.u64(state_digest(body.positions(), body.velocities()).finish());
                        let force = -reaction.impulse.y / dt;
                        push(records, concat!($prefix, " hanging body, hook force (N)"), digest, force);
                    }
                }
            }

            /// The whole workload in this precision.
            pub fn run(meter: &mut impl Meter, records: &mut Records, body: &mut DropBody, descent: &mut DescentScratch, owned: &mut ColliderBody) {
                svds(meter, records);
                forces(meter, records);
                drop(meter, records, body, descent);
                on_colliders(meter, records, owned);
                rigid_on_body(meter, records, owned);
                dynamic_on_body(meter, records, owned);
                hanging_body(meter, records, owned);
                contact_pair(meter, records);
            }
        }
    };
}

precision!(single, "f32", softfem);
precision!(double, "f64", softfem::f64);
