//! `svd3_batch` gives, matrix by matrix, exactly the bits of `svd3`, at every SIMD width this
//! machine has and with each narrower width forced (`softfem::simd::set_max_width`), in both
//! precisions: for thousands of matrices of every class of tests/kernels/svd.rs (random,
//! ill-conditioned, near-singular, exactly rank 1 and 2, repeated and clustered singular values,
//! reflections, zero, scales from 1e-30 to 1e30, subnormal, the largest safe magnitudes) mixed with
//! NaN and infinite ones, for every batch length from 0 to 40 (so every tail of every group width),
//! and for every sweep count from 0 to 6. An output of the wrong length is an error that names both
//! lengths and leaves the output untouched.
//!
//! The reference is the scalar `svd3` itself: the claim under test is bit-identity, and the
//! accuracy of `svd3` is tests/kernels/svd.rs's business.
//!
//! `SOFTFEM_MAX_WIDTH=sse` (or `scalar`, `avx2`) caps the widest width these tests try.

use crate::common::{Rng, lock_width};
use softfem::glam::{DMat3, DVec3};
use softfem::simd::{self, Width};

/// The widths to test: every one this machine has, up to `SOFTFEM_MAX_WIDTH` if set.
fn widths() -> Vec<Width> {
    let cap = std::env::var("SOFTFEM_MAX_WIDTH")
        .ok()
        .map(|name| {
            Width::from_name(&name).expect("SOFTFEM_MAX_WIDTH: scalar, sse, avx2 or avx512")
        })
        .unwrap_or(Width::Avx512);
    let detected = simd::detected_width();
    Width::ALL
        .into_iter()
        .filter(|&width| width <= detected && width <= cap)
        .collect()
}

/// Matrices per class.
const PER_CLASS: usize = 400;

/// Magnitudes at the edges of a precision's range (as in tests/kernels/svd.rs).
struct Extremes {
    subnormal: f64,
    tiniest: f64,
    huge: f64,
    max: f64,
}

const F32_EXTREMES: Extremes = Extremes {
    subnormal: 1e-39,
    tiniest: 1.401298464324817e-45,
    huge: 1e37,
    max: f32::MAX as f64,
};

const F64_EXTREMES: Extremes = Extremes {
    subnormal: 1e-310,
    tiniest: 5e-324,
    huge: 1e307,
    max: f64::MAX,
};

/// `u diag(1, m, ±1/cond) v^T`.
fn conditioned(rng: &mut Rng, cond: f64) -> DMat3 {
    let middle = rng.log_uniform(1.0 / cond, 1.0);
    let smallest = rng.sign() / cond;
    rng.rotated(DVec3::new(1.0, middle, smallest))
}

fn outer(x: DVec3, y: DVec3) -> DMat3 {
    DMat3::from_cols(x * y.x, x * y.y, x * y.z)
}

/// One matrix of class `class` (the classes of tests/kernels/svd.rs, in its order, then
/// non-finite).
fn class_matrix(class: usize, rng: &mut Rng, extremes: &Extremes) -> DMat3 {
    let short = |rng: &mut Rng, bits| DVec3::new(rng.short(bits), rng.short(bits), rng.short(bits));
    match class {
        0 => rng.entries(),
        1 => conditioned(rng, 1e3),
        2 => conditioned(rng, 1e6),
        3 => {
            let smallest = rng.sign() * 1e-9;
            rng.rotated(DVec3::new(1.0, 0.5, smallest))
        }
        // Exactly rank 2 and rank 1 (products of short mantissas are exact).
        4 => outer(short(rng, 8), short(rng, 8)) + outer(short(rng, 8), short(rng, 8)),
        5 => outer(short(rng, 12), short(rng, 12)),
        6 => {
            let middle = if rng.below(2) == 0 { 0.0 } else { 1.0 };
            rng.rotated(DVec3::new(1.0, middle, 0.0))
        }
        // Repeated singular values, plain and rotated.
        7 => {
            let d = DMat3::from_diagonal(
                [
                    DVec3::ONE,
                    DVec3::new(2.0, 1.0, 1.0),
                    DVec3::new(1.0, 1.0, 0.5),
                ][rng.below(3)],
            );
            match rng.below(3) {
                0 => d,
                1 => rng.rotation() * d,
                _ => {
                    let r = rng.rotation();
                    r * d * r.transpose()
                }
            }
        }
        8 => {
            if rng.below(2) == 0 {
                let delta = rng.log_uniform(1e-8, 1e-2);
                let middle = 1.0 - delta * rng.unit();
                rng.rotated(DVec3::new(1.0, middle, 1.0 - delta))
            } else {
                DMat3::IDENTITY + rng.entries() * rng.log_uniform(1e-8, 1e-3)
            }
        }
        // Reflections: det < 0.
        9 => match rng.below(3) {
            0 => -DMat3::IDENTITY,
            1 => DMat3::from_diagonal(DVec3::new(2.0, -2.0, 2.0)),
            _ => {
                let mut m = rng.entries();
                if m.determinant() > 0.0 {
                    m.x_axis = -m.x_axis;
                }
                m
            }
        },
        10 => DMat3::from_cols_array(&core::array::from_fn(|_| 0.0 * rng.sign())),
        11 => rng.entries() * 1e-30,
        12 => conditioned(rng, 1e3) * 1e30,
        13 => rng.entries() * extremes.subnormal,
        14 => DMat3::from_cols_array(&core::array::from_fn(|_| {
            (rng.below(9) as f64 - 4.0) * extremes.tiniest
        })),
        15 => {
            if rng.below(4) == 0 {
                DMat3::from_cols_array(&core::array::from_fn(|_| rng.sign() * extremes.max / 4.0))
            } else {
                rng.entries() * extremes.huge
            }
        }
        // Non-finite: one NaN or infinite entry, or entries beyond the range.
        _ => {
            let mut entries = rng.entries().to_cols_array();
            entries[rng.below(9)] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][rng.below(3)];
            DMat3::from_cols_array(&entries)
        }
    }
}

const CLASSES: usize = 17;

/// [`PER_CLASS`] matrices of every class, shuffled so that every group of lanes mixes classes,
/// then the same matrices class by class (groups of one class).
fn test_matrices(extremes: &Extremes) -> Vec<DMat3> {
    let mut rng = Rng::new(0x513d_2026);
    let by_class: Vec<DMat3> = (0..CLASSES)
        .flat_map(|class| {
            (0..PER_CLASS)
                .map(|_| class_matrix(class, &mut rng, extremes))
                .collect::<Vec<_>>()
        })
        .collect();
    let mut shuffled = by_class.clone();
    for i in (1..shuffled.len()).rev() {
        shuffled.swap(i, rng.below(i + 1));
    }
    shuffled.extend(by_class);
    shuffled
}

/// `run` at [`Width::Scalar`] and at every width, each result asserted equal to the scalar one,
/// which is returned.
fn same_at_every_width<T: PartialEq>(what: &str, run: impl Fn() -> T) -> T {
    let _guard = lock_width();
    simd::set_max_width(Width::Scalar);
    let scalar = run();
    for width in widths() {
        simd::set_max_width(width);
        let wide = run();
        simd::set_max_width(Width::Avx512);
        assert!(
            wide == scalar,
            "{what}, width {width:?}: the run differs from the scalar run"
        );
    }
    simd::set_max_width(Width::Avx512);
    scalar
}

macro_rules! precision_tests {
    ($name:ident, $($svd:ident)::+, $mat:ty, $round:expr, $extremes:expr, $lanes:ident) => {
        mod $name {
            use super::*;
            use $($svd)::+::{Svd3, svd3, svd3_batch, svd3_batch_sweeps, svd3_sweeps};

            type Mat = $mat;

            fn inputs() -> Vec<Mat> {
                test_matrices(&$extremes).into_iter().map($round).collect()
            }

            /// Every float of a decomposition as bits (NaN outputs compare equal to themselves).
            fn bits(svd: &Svd3) -> Vec<u64> {
                svd.u
                    .to_cols_array()
                    .into_iter()
                    .chain(svd.sigma.to_array())
                    .chain(svd.v.to_cols_array())
                    .map(|x| f64::from(x).to_bits())
                    .collect()
            }

            /// `svd3_batch_sweeps` of `matrices` gives `svd3_sweeps`'s bits for each.
            fn assert_batch_is_scalar(matrices: &[Mat], sweeps: u32, width: Width) {
                let placeholder = svd3_sweeps(Mat::IDENTITY, 0);
                let mut out = vec![placeholder; matrices.len()];
                svd3_batch_sweeps(matrices, &mut out, sweeps).unwrap();
                for (i, (a, from_batch)) in matrices.iter().zip(&out).enumerate() {
                    let scalar = svd3_sweeps(*a, sweeps);
                    assert_eq!(
                        bits(from_batch),
                        bits(&scalar),
                        "width {width:?}, {} lanes, sweeps {sweeps}, length {}, matrix {i} \
                         = {:?}:\n batch  {from_batch:?}\n scalar {scalar:?}",
                        width.$lanes(),
                        matrices.len(),
                        a.to_cols_array(),
                    );
                }
            }

            #[test]
            fn batch_is_bitwise_svd3_at_every_width() {
                let inputs = inputs();
                let _guard = lock_width();
                for width in widths() {
                    simd::set_max_width(width);
                    assert_eq!(simd::active_width(), width);
                    // The whole set in one call (long runs of full groups, then a tail).
                    assert_batch_is_scalar(&inputs, softfem::svd::DEFAULT_SWEEPS, width);
                    // Every length from 0 to 40, at varying offsets into the set.
                    for len in 0..=40 {
                        for start in [0, 7 * len + 1, inputs.len() / 2 + 13 * len] {
                            assert_batch_is_scalar(
                                &inputs[start..start + len],
                                softfem::svd::DEFAULT_SWEEPS,
                                width,
                            );
                        }
                    }
                }
                simd::set_max_width(Width::Avx512);
            }

            #[test]
            fn batch_sweeps_are_bitwise_svd3_sweeps_at_every_width() {
                let inputs = inputs();
                let sample: Vec<Mat> = inputs.iter().step_by(7).copied().collect();
                let _guard = lock_width();
                for width in widths() {
                    simd::set_max_width(width);
                    for sweeps in 0..=6 {
                        assert_batch_is_scalar(&sample, sweeps, width);
                    }
                }
                simd::set_max_width(Width::Avx512);
            }

            #[test]
            fn default_batch_is_default_sweeps() {
                let inputs = inputs();
                let mut out = vec![svd3_sweeps(Mat::IDENTITY, 0); 37];
                svd3_batch(&inputs[..37], &mut out).unwrap();
                for (a, svd) in inputs.iter().zip(&out) {
                    assert_eq!(bits(svd), bits(&svd3(*a)));
                }
            }

            #[test]
            fn mismatched_lengths_are_an_error_and_leave_the_output_alone() {
                let inputs = inputs();
                let marker = svd3_sweeps(Mat::from_diagonal([3.0, 2.0, 1.0].into()), 4);
                for (n_in, n_out) in [(0, 1), (1, 0), (5, 4), (16, 17), (40, 39)] {
                    let mut out = vec![marker; n_out];
                    assert_eq!(
                        svd3_batch(&inputs[..n_in], &mut out),
                        Err(softfem::SvdBatchError::OutputLength {
                            expected: n_in,
                            actual: n_out
                        })
                    );
                    assert!(out.iter().all(|svd| bits(svd) == bits(&marker)));
                }
                let message = softfem::SvdBatchError::OutputLength {
                    expected: 5,
                    actual: 4,
                }
                .to_string();
                assert!(message.contains('5') && message.contains('4'), "{message}");
            }
        }
    };
}

precision_tests!(
    f32,
    softfem::svd,
    softfem::glam::Mat3,
    |m: DMat3| m.as_mat3(),
    F32_EXTREMES,
    lanes_f32
);
precision_tests!(
    f64,
    softfem::f64::svd,
    softfem::glam::DMat3,
    |m: DMat3| m,
    F64_EXTREMES,
    lanes_f64
);

/// The detected width is consistent with what the standard library detects (an independent
/// implementation of the same CPUID and XCR0 checks), and the cap works and is undone.
#[test]
fn detection_agrees_with_std_and_the_cap_applies() {
    #[cfg(target_arch = "x86_64")]
    {
        let expected = if std::arch::is_x86_feature_detected!("avx512f") {
            Width::Avx512
        } else if std::arch::is_x86_feature_detected!("avx2") {
            Width::Avx2
        } else {
            Width::Sse
        };
        assert_eq!(simd::detected_width(), expected);
    }
    let _guard = lock_width();
    for width in Width::ALL {
        simd::set_max_width(width);
        assert_eq!(simd::max_width(), width);
        assert_eq!(simd::active_width(), width.min(simd::detected_width()));
    }
    simd::set_max_width(Width::Avx512);
    assert_eq!(simd::active_width(), simd::detected_width());
}

#[test]
fn width_names_round_trip() {
    for width in Width::ALL {
        assert_eq!(Width::from_name(width.name()), Some(width));
        assert_eq!(Width::from_name(&width.name().to_uppercase()), Some(width));
    }
    assert_eq!(Width::from_name("avx"), None);
    assert_eq!(Width::ALL.map(Width::lanes_f32), [1, 4, 8, 16],);
    assert_eq!(Width::ALL.map(Width::lanes_f64), [1, 4, 4, 8]);
}

// The mesh kernels: forces (direct, principal, clamped), energies (per element, total, fused
// with the forces) and whole explicit and relaxation runs give, at every width, the bits of the
// scalar path (`Width::Scalar`) and of an independent element-by-element loop over the public
// per-element functions (`TetRest::elastic_forces` and friends) in element order. Mesh sizes
// from 0 to 40 elements and a few larger ones cover every tail of every group width (4, 8, 16
// and, in pairs, 32); the deformations include strong stretches (the logarithm's exact branch of
// stable neo-Hookean), flat and inverted elements (the clamped path).

macro_rules! mesh_tests {
    ($name:ident, $($crate_path:ident)::+, $real:ty, $vec:ident) => {
        mod $name {
            use super::*;
            use softfem::glam::$vec as V;
            use $($crate_path)::+::element::TetRest;
            use $($crate_path)::+::material::{Material, NeoHookean, StVK, StableNeoHookean};
            use $($crate_path)::+::mesh::{TetMesh, TetRestBlock, rest_block_count};
            use $($crate_path)::+::types::Mat3 as M3;
            use $($crate_path)::+::step::{
                ElasticEnergy, ExplicitScratch, ExplicitSettings, RelaxScratch, RelaxSettings, Scene,
                TetElastic, scratch_len, explicit_step, relax_step,
            };

            type Real = $real;

            /// A box of `cells^3` Kuhn cubes (6 tets each) and its deformed positions: a general
            /// affine map plus jitter of `jitter` grid spacings, with every `wild`-th vertex
            /// (if any) thrown far off, which flattens and inverts the elements around it.
            fn deformed_box(cells: usize, jitter: f64, wild: usize) -> (Vec<V>, Vec<V>, Vec<[u32; 4]>) {
                use softfem::generate::{BoxSplit, box_counts, fill_box};
                let (nv, nt) = box_counts(cells, cells, cells, BoxSplit::Kuhn6).unwrap();
                let mut rest = vec![softfem::glam::Vec3::ZERO; nv];
                let mut tets = vec![[0u32; 4]; nt];
                fill_box(
                    softfem::glam::Vec3::ZERO,
                    softfem::glam::Vec3::ONE,
                    cells,
                    cells,
                    cells,
                    BoxSplit::Kuhn6,
                    &mut rest,
                    &mut tets,
                )
                .unwrap();
                let affine = DMat3::from_cols(
                    DVec3::new(1.10, -0.10, 0.05),
                    DVec3::new(0.15, 0.95, -0.12),
                    DVec3::new(-0.05, 0.20, 1.05),
                );
                let mut rng = Rng::new(0x51d_2026);
                let amplitude = jitter / cells as f64;
                let to_v = |x: DVec3| V::new(x.x as Real, x.y as Real, x.z as Real);
                let deformed = rest
                    .iter()
                    .enumerate()
                    .map(|(i, x)| {
                        let x = x.as_dvec3();
                        let mut y = affine * x + rng.vector() * amplitude;
                        if wild > 0 && i % wild == 3 {
                            y += rng.vector() * 0.8;
                        }
                        to_v(y)
                    })
                    .collect();
                let rest = rest.iter().map(|x| to_v(x.as_dvec3())).collect();
                (rest, deformed, tets)
            }

            fn bits(values: &[V]) -> Vec<u64> {
                values
                    .iter()
                    .flat_map(|v| v.to_array())
                    .map(|x| f64::from(x).to_bits())
                    .collect()
            }

            /// Runs `kernel` at every width and checks each result against `reference`.
            fn at_every_width<T: PartialEq + std::fmt::Debug>(
                what: &str,
                reference: &T,
                mut kernel: impl FnMut() -> T,
            ) {
                let _guard = lock_width();
                for width in std::iter::once(Width::Scalar).chain(widths()) {
                    simd::set_max_width(width);
                    let result = kernel();
                    simd::set_max_width(Width::Avx512);
                    assert!(result == *reference, "{what}: width {width:?} differs from the element loop");
                }
            }

            /// Forces of every element `per_element(rest, corners' positions)`, added in element
            /// and corner order.
            fn element_loop(
                tets: &[[u32; 4]],
                rest: &[TetRest],
                x: &[V],
                per_element: impl Fn(&TetRest, [V; 4]) -> [V; 4],
            ) -> Vec<u64> {
                let mut forces = vec![V::ZERO; x.len()];
                for (tet, r) in tets.iter().zip(rest) {
                    let f = per_element(r, tet.map(|i| x[i as usize]));
                    for (&i, f) in tet.iter().zip(f) {
                        forces[i as usize] += f;
                    }
                }
                bits(&forces)
            }

            fn check_forces<M: Material>(material: &M, mesh: &TetMesh<'_>, x: &[V], label: &str) {
                let (tets, rest) = (mesh.tets(), mesh.rest());
                let kernel = |run: &dyn Fn(&mut [V])| {
                    // A nonzero start checks that the kernels add.
                    let mut forces = vec![V::splat(0.25); x.len()];
                    run(&mut forces);
                    forces.iter().map(|f| *f - V::splat(0.25)).collect::<Vec<V>>()
                };
                let reference = |per: &dyn Fn(&TetRest, [V; 4]) -> [V; 4]| {
                    let mut forces = vec![V::splat(0.25); x.len()];
                    for (tet, r) in tets.iter().zip(rest) {
                        let f = per(r, tet.map(|i| x[i as usize]));
                        for (&i, f) in tet.iter().zip(f) {
                            forces[i as usize] += f;
                        }
                    }
                    bits(&forces.iter().map(|f| *f - V::splat(0.25)).collect::<Vec<V>>())
                };
                let n = tets.len();
                at_every_width(&format!("{label} direct, {n} tets"), &reference(&|r, p| r.elastic_forces(material, p)), || {
                    bits(&kernel(&|f| mesh.add_elastic_forces(material, x, f).unwrap()))
                });
                at_every_width(
                    &format!("{label} principal, {n} tets"),
                    &reference(&|r, p| r.nodal_forces(material.first_piola_principal(r.deformation_gradient(p)))),
                    || bits(&kernel(&|f| mesh.add_elastic_forces_principal(material, x, f).unwrap())),
                );
                at_every_width(
                    &format!("{label} clamped, {n} tets"),
                    &reference(&|r, p| {
                        r.nodal_forces(material.first_piola_principal_clamped(r.deformation_gradient(p), 0.3))
                    }),
                    || bits(&kernel(&|f| mesh.add_elastic_forces_clamped(material, 0.3, x, f).unwrap())),
                );
            }

            fn check_energies<M: Material>(material: &M, mesh: &TetMesh<'_>, x: &[V], label: &str) {
                let (tets, rest) = (mesh.tets(), mesh.rest());
                let n = tets.len();
                let energies: Vec<Real> = tets
                    .iter()
                    .zip(rest)
                    .map(|(tet, r)| r.elastic_energy(material, tet.map(|i| x[i as usize])))
                    .collect();
                let energy_bits = |e: &[Real]| e.iter().map(|e| f64::from(*e).to_bits()).collect::<Vec<_>>();
                at_every_width(&format!("{label} element energies, {n} tets"), &energy_bits(&energies), || {
                    let mut out = vec![0.0; n];
                    mesh.element_energies(material, x, &mut out).unwrap();
                    energy_bits(&out)
                });
                let total: Real = energies.iter().sum();
                at_every_width(&format!("{label} total energy, {n} tets"), &f64::from(total).to_bits(), || {
                    f64::from(mesh.elastic_energy(material, x).unwrap()).to_bits()
                });
                // The fused pass: documented order (partial sum i % 4 for the whole groups of
                // four, added pairwise, then the rest in order) and the direct forces.
                let whole = n - n % 4;
                let mut partial = [0.0 as Real; 4];
                let mut last = 0.0 as Real;
                for (i, e) in energies.iter().enumerate() {
                    if i < whole {
                        partial[i % 4] += e;
                    } else {
                        last += e;
                    }
                }
                let fused_total = ((partial[0] + partial[1]) + (partial[2] + partial[3])) + last;
                let forces = element_loop(tets, rest, x, |r, p| r.elastic_forces(material, p));
                let model = TetElastic::new(*mesh, *material);
                at_every_width(
                    &format!("{label} fused energy and forces, {n} tets"),
                    &(f64::from(fused_total).to_bits(), forces),
                    || {
                        let mut f = vec![V::ZERO; x.len()];
                        let e = model.energy_and_add_forces(x, &mut f).unwrap();
                        (f64::from(e).to_bits(), bits(&f))
                    },
                );
            }

            fn check_all(cells: usize, jitter: f64, wild: usize, lengths: &[usize]) {
                let (rest_x, x, tets) = deformed_box(cells, jitter, wild);
                for &len in lengths {
                    let tets = &tets[..len.min(tets.len())];
                    let mut rest = vec![TetRest::default(); tets.len()];
                    let mesh = TetMesh::new(&rest_x, tets, &mut rest).unwrap();
                    // The same mesh with its rest data also in blocks: the same bits.
                    let mut blocks = vec![TetRestBlock::ZERO; rest_block_count(tets.len())];
                    let blocked = mesh.with_rest_blocks(&mut blocks).unwrap();
                    assert_eq!(blocked.rest_blocks().len(), tets.len().div_ceil(16));
                    let stvk = StVK::from_young_poisson(1.0e6, 0.45).unwrap();
                    let nh = NeoHookean::from_young_poisson(1.0e6, 0.45).unwrap();
                    let snh = StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap();
                    for (mesh, layout) in [(mesh, "records"), (blocked, "blocks")] {
                        check_forces(&stvk, &mesh, &x, &format!("StVK ({layout})"));
                        check_forces(&snh, &mesh, &x, &format!("stable neo-Hookean ({layout})"));
                        check_energies(&stvk, &mesh, &x, &format!("StVK ({layout})"));
                        check_energies(&snh, &mesh, &x, &format!("stable neo-Hookean ({layout})"));
                        if wild == 0 {
                            // Not defined at J <= 0.
                            check_forces(&nh, &mesh, &x, &format!("neo-Hookean ({layout})"));
                            check_energies(&nh, &mesh, &x, &format!("neo-Hookean ({layout})"));
                        }
                    }
                }
            }

            #[test]
            fn mesh_kernels_are_bitwise_the_element_loop_at_every_width_for_every_tail() {
                let lengths: Vec<usize> = (0..=40).chain([63, 64, 65, 97, 162]).collect();
                check_all(3, 0.08, 0, &lengths);
            }

            #[test]
            fn mesh_kernels_are_bitwise_on_strong_and_inverting_deformations() {
                check_all(4, 0.3, 0, &[384]);
                check_all(4, 0.3, 7, &[33, 384]);
            }

            /// Elements collapsed to a point (`F = 0`, which `svd3` does not decompose: it returns
            /// `u = v = I`, `sigma = 0`) in lanes of a group whose other lanes are decomposed: the
            /// principal and clamped passes (the clamped stress of `F = 0` is not zero) keep the
            /// bits of the element loop at every width.
            #[test]
            fn principal_paths_are_bitwise_with_collapsed_elements_in_a_group() {
                let (rest_x, mut x, tets) = deformed_box(3, 0.08, 0);
                // Elements at different lanes of 4-, 8- and 16-wide groups.
                for &e in &[5usize, 22, 43, 60] {
                    let point = x[tets[e][0] as usize];
                    for &i in &tets[e] {
                        x[i as usize] = point;
                    }
                }
                let mut rest = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&rest_x, &tets, &mut rest).unwrap();
                let collapsed = tets
                    .iter()
                    .zip(mesh.rest())
                    .filter(|(tet, r)| r.deformation_gradient(tet.map(|i| x[i as usize])) == M3::ZERO)
                    .count();
                assert!(collapsed >= 4, "only {collapsed} collapsed elements");
                check_forces(&StVK::from_young_poisson(1.0e6, 0.45).unwrap(), &mesh, &x, "StVK");
                check_forces(&StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap(), &mesh, &x, "stable neo-Hookean");
            }

            /// A model from outside the crate, with only the required methods: the provided lane
            /// methods (one lane at a time through the scalar ones) keep every width's bits.
            #[test]
            fn a_model_with_only_the_required_methods_is_bitwise_at_every_width() {
                #[derive(Clone, Copy, Debug)]
                struct Outside(StVK);
                impl Material for Outside {
                    fn energy_density(&self, f: M3) -> Real {
                        self.0.energy_density(f)
                    }
                    fn first_piola(&self, f: M3) -> M3 {
                        self.0.first_piola(f)
                    }
                    fn principal_energy(&self, s: V) -> Real {
                        self.0.principal_energy(s)
                    }
                    fn principal_stress(&self, s: V) -> V {
                        // Not the lane form of StVK: a different, exact-at-rest grouping.
                        self.0.principal_stress(s) * 0.5 + self.0.principal_stress(s) * 0.5
                    }
                }
                let (rest_x, x, tets) = deformed_box(3, 0.3, 7);
                let mut rest = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&rest_x, &tets, &mut rest).unwrap();
                check_forces(&Outside(StVK::from_young_poisson(1.0e6, 0.45).unwrap()), &mesh, &x, "outside model");
            }

            /// Explicit steps (stable neo-Hookean, gravity, half the stable step) and relaxation
            /// steps at every width end in the bits of the scalar run.
            #[test]
            fn explicit_and_relaxation_runs_are_bitwise_the_scalar_run_at_every_width() {
                let (rest_x, _, tets) = deformed_box(4, 0.0, 0);
                crate::common::scenes::mesh_and_masses!(rest, mesh, masses; &rest_x, &tets, 1000.0);
                let model = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap());
                let n = mesh.vertex_count();
                // The bottom layer is pinned.
                let pinned: Vec<bool> = rest_x.iter().map(|x| x.y == 0.0).collect();
                let gravity = V::new(0.0, -9.81, 0.0);
                let run = || {
                    let scene = Scene::new(2.0e-5).with_gravity(gravity);
                    let settings = ExplicitSettings::new();
                    let (mut x, mut v) = (rest_x.clone(), vec![V::ZERO; n]);
                    let mut buffer = vec![V::ZERO; scratch_len::explicit(n)];
                    for _ in 0..20 {
                        let mut scratch = ExplicitScratch::new(&mut buffer);
                        explicit_step(&model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    }
                    let explicit = (bits(&x), bits(&v));
                    let scene = Scene::new(1.0 / 60.0).with_gravity(gravity);
                    let settings = RelaxSettings::new().with_tolerance(0.0, 30);
                    let (mut vectors, mut scalars) = (vec![V::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                    for _ in 0..3 {
                        let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                        relax_step(&model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    }
                    (explicit, bits(&x), bits(&v))
                };
                let scalar = same_at_every_width("explicit and relaxation", run);
                // The runs moved: the comparison is not of two rest states.
                assert_ne!(scalar.0.0, bits(&rest_x));
            }

            /// Explicit steps onto a ground (restitution, friction, damping, pinned vertices;
            /// external forces) at every width end in the bits of the scalar run, the reports too (kinetic
            /// energy and contacts): the update runs each width's groups, then narrower ones,
            /// then one vertex at a time (125 vertices: groups of 16, 8 and 4 and a tail).
            #[test]
            fn explicit_ground_contacts_are_bitwise_the_scalar_run_at_every_width() {
                use $($crate_path)::+::step::{HalfSpace, stable_time_step};
                let (rest_x, deformed, tets) = deformed_box(4, 0.1, 0);
                crate::common::scenes::mesh_and_masses!(rest, mesh, masses; &rest_x, &tets, 1000.0);
                let model = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap());
                let n = mesh.vertex_count();
                let pinned: Vec<bool> = (0..n).map(|i| i % 11 == 4).collect();
                let mut stiffness = vec![0.0; n];
                let dt = 0.5 * stable_time_step(&model, &masses, &[], &mut stiffness).unwrap();
                // The plane cuts the lowest layer: some vertices start inside, the rest fall.
                let normal = V::new(0.1, 1.0, -0.05).normalize();
                let lowest = deformed.iter().map(|&x| normal.dot(x)).fold(Real::INFINITY, Real::min);
                let ground = HalfSpace::new(normal, lowest + 0.03)
                    .with_restitution(0.5)
                    .with_friction(0.4);
                // Pushed sideways and up, every vertex differently.
                let pushes: Vec<V> = (0..n).map(|i| V::new(0.5 * i as Real, 2.0, -1.0) * masses[i]).collect();
                let run = || {
                    let mut results = Vec::new();
                    for (ground, pushed) in [(ground, false), (ground.with_friction(0.0), false), (ground, true)] {
                        let scene = Scene::new(dt)
                            .with_gravity(V::new(0.0, -9.81, 0.0))
                            .with_ground(ground)
                            .with_external_forces(if pushed { &pushes[..] } else { &[] });
                        let settings = ExplicitSettings::new().with_damping(0.5);
                        let mut x = deformed.clone();
                        let mut v: Vec<V> = (0..n).map(|i| V::new(0.0, -0.5 - 0.01 * i as Real, 0.1)).collect();
                        let mut buffer = vec![V::ZERO; scratch_len::explicit(n)];
                        let mut reports = Vec::new();
                        for _ in 0..8 {
                            let mut scratch = ExplicitScratch::new(&mut buffer);
                            let report =
                                explicit_step(&model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                            reports.push((f64::from(report.kinetic_energy).to_bits(), report.ground_contacts));
                        }
                        results.push((bits(&x), bits(&v), reports));
                    }
                    results
                };
                let scalar = same_at_every_width("explicit onto the ground", run);
                // Vertices hit the ground in both runs, and the runs moved.
                assert!(scalar.iter().all(|r| r.2.iter().any(|&(_, contacts)| contacts > 0)));
                assert_ne!(scalar[0].0, bits(&deformed));
            }

            /// Relaxation steps and quasi-static solves onto a tilted ground, in each of the
            /// relaxation's modes (Chebyshev with a given and an estimated `rho`, heavy ball), with
            /// friction, pinned vertices, external forces, fixed axes and a sphere collider, at
            /// every width end in the bits of the scalar run, reports included: the vertex passes
            /// run each width's groups, then narrower ones, then one vertex at a time (125
            /// vertices: groups of 16, 8 and 4 and a tail in f32; of 8 and 4 and a tail in f64).
            #[test]
            fn relaxation_contacts_are_bitwise_the_scalar_run_at_every_width() {
                use $($crate_path)::+::step::{
                    Collider, FIXED_X, HalfSpace, SUGGESTED_STICKING_SPEED, relax_quasi_static,
                };
                let (rest_x, deformed, tets) = deformed_box(4, 0.1, 0);
                crate::common::scenes::mesh_and_masses!(rest, mesh, masses; &rest_x, &tets, 1000.0);
                let model = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.45).unwrap());
                let n = mesh.vertex_count();
                assert_eq!(n, 125);
                let pinned: Vec<bool> = (0..n).map(|i| i % 11 == 4).collect();
                // The plane cuts the lowest layer: some vertices start inside, the rest fall.
                let normal = V::new(0.1, 1.0, -0.05).normalize();
                let lowest = deformed.iter().map(|&x| normal.dot(x)).fold(Real::INFINITY, Real::min);
                // Friction in the objective (a sticking speed): the direction passes damp the
                // tangential direction at the vertices in contact.
                let ground = HalfSpace::new(normal, lowest + 0.03)
                    .with_friction(0.4)
                    .with_sticking_speed(SUGGESTED_STICKING_SPEED);
                // Pushed sideways and up, every vertex differently; every seventh vertex moves
                // in y and z only.
                let pushes: Vec<V> = (0..n).map(|i| V::new(0.5 * i as Real, 2.0, -1.0) * masses[i]).collect();
                let fixed: Vec<u8> = (0..n).map(|i| if i % 7 == 3 { FIXED_X } else { 0 }).collect();
                // A sphere pressing into the top of the box.
                let highest = deformed.iter().map(|x| x.y).fold(Real::NEG_INFINITY, Real::max);
                let colliders = [Collider::sphere(V::new(0.5, highest + 0.3, 0.5), 0.4)];
                let scene = Scene::new(1.0 / 60.0)
                    .with_gravity(V::new(0.0, -9.81, 0.0))
                    .with_ground(ground);
                let base = RelaxSettings::new().with_tolerance(0.0, 12);
                let run = || {
                    let mut results = Vec::new();
                    let modes = [
                        (scene, base),
                        (scene, base.with_chebyshev(0.9, 1.5, 2)),
                        (scene, base.with_estimated_chebyshev(2.0, 3)),
                        (scene, base.with_momentum(0.3)),
                        (scene.with_ground(ground.with_friction(0.0)), base),
                    ];
                    for (k, (scene, settings)) in modes.into_iter().enumerate() {
                        let scene = scene.with_colliders(&colliders);
                        let loaded = scene.with_external_forces(&pushes).with_fixed_axes(&fixed);
                        let scene = if k % 2 == 0 { scene } else { loaded };
                        let (mut x, mut v) = (deformed.clone(), vec![V::new(0.0, -0.5, 0.1); n]);
                        let (mut vectors, mut scalars) = (vec![V::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                        let mut reports = Vec::new();
                        for _ in 0..2 {
                            let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                            let report =
                                relax_step(&model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                            reports.push((report.iterations, report.backtracks, f64::from(report.phi).to_bits()));
                        }
                        let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                        let mut settled = x.clone();
                        let report =
                            relax_quasi_static(&model, &masses, &pinned, &scene, &settings, &mut settled, &mut scratch).unwrap();
                        reports.push((report.iterations, report.backtracks, f64::from(report.phi).to_bits()));
                        results.push((bits(&x), bits(&v), bits(&settled), reports));
                    }
                    results
                };
                let scalar = same_at_every_width("relaxation onto the ground", run);
                // Every run moved, and friction, the loads and the modes changed the result.
                for result in &scalar {
                    assert_ne!(result.0, bits(&deformed));
                    assert_ne!(result.2, result.0);
                }
                for (k, a) in scalar.iter().enumerate() {
                    for b in &scalar[k + 1..] {
                        assert_ne!(a.0, b.0);
                    }
                }
            }

            /// Vertex Block Descent steps at every width end in the bits of the scalar run: the
            /// sweep sums the elements around several vertices of one colour at once, one vertex
            /// per lane (`src/step/descent/vbd/sums.rs`), with the vertex line search (energies too)
            /// and without, for every model, from deformed positions with the bottom pinned.
            #[test]
            fn vbd_runs_are_bitwise_the_scalar_run_at_every_width() {
                use $($crate_path)::+::step::{
                    HalfSpace, SUGGESTED_STICKING_SPEED, Scene, VbdScratch, VbdSettings, scratch_len, vbd_step,
                };
                fn check<M: Material>(material: M, label: &str) {
                    let (rest_x, deformed, tets) = deformed_box(3, 0.05, 0);
                    crate::common::scenes::mesh_and_masses!(rest, mesh, masses; &rest_x, &tets, 1000.0);
                    let model = TetElastic::new(mesh, material);
                    let n = mesh.vertex_count();
                    let pinned: Vec<bool> = rest_x.iter().map(|x| x.y == 0.0).collect();
                    let start: Vec<V> = deformed
                        .iter()
                        .zip(&rest_x)
                        .zip(&pinned)
                        .map(|((&d, &r), &p)| if p { r } else { d })
                        .collect();
                    let gravity = V::new(0.0, -9.81, 0.0);
                    let scene = Scene::new(1.0 / 60.0).with_gravity(gravity);
                    let base = VbdSettings::new().with_tolerance(0.0, 12);
                    // A frictionless tilted ground through the lower layers, loads on some
                    // vertices and one axis fixed on others: the lanes of the sweep's vertex
                    // updates left to the one-vertex update (fixed axes, steps into the ground)
                    // among lanes updated together (`src/step/descent/vbd/lanes.rs`).
                    let forces: Vec<V> = (0..n)
                        .map(|i| if i % 5 == 0 { V::new(30.0, 0.0, -20.0) } else { V::ZERO })
                        .collect();
                    let axes: Vec<u8> = (0..n).map(|i| if i % 7 == 3 { 0b001 } else { 0 }).collect();
                    let ground = HalfSpace::new(V::new(0.1, 1.0, -0.05).normalize(), 0.4);
                    let loaded = scene
                        .with_ground(ground)
                        .with_external_forces(&forces)
                        .with_fixed_axes(&axes);
                    // The same with friction: the lanes of vertices in contact are left to the
                    // one-vertex update, the others are updated together.
                    let rough = loaded.with_ground(ground.with_friction(0.5).with_sticking_speed(SUGGESTED_STICKING_SPEED));
                    let run = || {
                        let mut results = Vec::new();
                        // With and without the packed sweep layout (the same bits either way).
                        for (scene, settings, packed, falling) in [
                            (scene, base.with_estimated_chebyshev(3), false, false),
                            (scene, base.with_line_search(0).with_chebyshev(0.9, 2), false, false),
                            (loaded, base.with_line_search(0).with_chebyshev(0.9, 2), false, true),
                            (loaded, base.with_line_search(0).with_estimated_chebyshev(3).with_tolerance(1e-5, 60), false, true),
                            (rough, base.with_line_search(0).with_chebyshev(0.9, 2), false, true),
                            (scene, base.with_estimated_chebyshev(3), true, false),
                            (scene, base.with_line_search(0).with_chebyshev(0.9, 2), true, false),
                            (loaded, base.with_line_search(0).with_chebyshev(0.9, 2), true, true),
                            (loaded, base.with_line_search(0).with_estimated_chebyshev(3).with_tolerance(1e-5, 60), true, true),
                            (rough, base.with_line_search(0).with_chebyshev(0.9, 2), true, true),
                        ] {
                            // Falling onto the ground at 3 m/s: steps into it.
                            let fall = if falling { V::new(0.0, -3.0, 0.0) } else { V::ZERO };
                            let velocities: Vec<V> =
                                pinned.iter().map(|&p| if p { V::ZERO } else { fall }).collect();
                            let (mut x, mut v) = (start.clone(), velocities);
                            let mut vectors = vec![V::ZERO; scratch_len::vbd(n)];
                            let mut indices = vec![0; scratch_len::vbd_indices(n, tets.len())];
                            let mut values = vec![0.0; scratch_len::vbd_layout(tets.len())];
                            let mut corners = vec![0; scratch_len::vbd_layout_corners(n, tets.len())];
                            let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                            if packed {
                                scratch = scratch.with_layout(&mut values, &mut corners);
                            }
                            // The reports too: the counts of skipped and projected vertex
                            // updates, and the Chebyshev estimate, which the sweeps' Gauss-Seidel
                            // residual sets.
                            let mut reports = Vec::new();
                            for _ in 0..2 {
                                let report = vbd_step(&model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch)
                                    .unwrap();
                                reports.push(format!(
                                    "{} {} {} {} {:?}",
                                    report.iterations,
                                    report.energy_evaluations,
                                    report.details.skipped,
                                    report.details.projected,
                                    report.rho.to_bits()
                                ));
                            }
                            assert_eq!(scratch.layout_in_use(), packed);
                            results.push((bits(&x), bits(&v), reports));
                        }
                        results
                    };
                    let scalar = same_at_every_width(&format!("{label} VBD"), run);
                    assert_ne!(scalar[0].0, bits(&start), "{label}: the run moved");
                    assert!(scalar[..5] == scalar[5..], "{label}: the packed layout changed the bits");
                    assert_ne!(scalar[2].0, scalar[4].0, "{label}: friction changed the run");
                }
                check(StVK::from_young_poisson(1.0e6, 0.45).unwrap(), "StVK");
                check(NeoHookean::from_young_poisson(1.0e6, 0.45).unwrap(), "neo-Hookean");
                check(StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap(), "stable neo-Hookean");
            }
        }
    };
}

mesh_tests!(mesh_f32, softfem, f32, Vec3);
mesh_tests!(mesh_f64, softfem::f64, f64, DVec3);

// The explicit step of a 2D body (triangles) at every width, against the scalar run: the same
// update in groups of 2D lanes.
macro_rules! planar_tests {
    ($name:ident, $($crate_path:ident)::+, $real:ty, $vec:ident) => {
        mod $name {
            use super::*;
            use softfem::glam::$vec as V;
            use $($crate_path)::+::element::{TriRest, TriangleStVK};
            use $($crate_path)::+::generate::{fill_rectangle, rectangle_counts};
            use $($crate_path)::+::material::StVK;
            use $($crate_path)::+::mesh::TriMesh;
            use $($crate_path)::+::step::{
                ExplicitScratch, ExplicitSettings, HalfSpace, Scene, TriElastic, scratch_len,
                explicit_step, stable_time_step,
            };

            type Real = $real;

            /// A 2D rectangle (110 vertices: groups of 16, 8 and 4 and a tail) thrown onto a
            /// tilted ground, with restitution, friction, damping and pinned vertices: every
            /// width ends in the bits of the scalar run, reports included.
            #[test]
            fn explicit_2d_ground_contacts_are_bitwise_the_scalar_run_at_every_width() {
                let (nv, nt) = rectangle_counts(10, 9).unwrap();
                let mut rest = vec![V::ZERO; nv];
                let mut tris = vec![[0; 3]; nt];
                fill_rectangle(V::new(0.0, 0.05), V::new(0.1, 0.15), 10, 9, &mut rest, &mut tris)
                    .unwrap();
                let mut rest_data = vec![TriRest::default(); nt];
                let mesh = TriMesh::new(&rest, &tris, &mut rest_data).unwrap();
                let material = TriangleStVK::new(&StVK::from_young_poisson(1.0e5, 0.3).unwrap());
                let body = TriElastic { mesh, material };
                let mut masses = vec![0.0; nv];
                mesh.lumped_masses(1000.0, &mut masses).unwrap();
                let mut stiffness = vec![0.0; nv];
                let dt = 0.5 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                let pinned: Vec<bool> = (0..nv).map(|i| i % 13 == 6).collect();
                let ground = HalfSpace::new(V::new(0.05, 1.0), 0.06)
                    .with_restitution(0.3)
                    .with_friction(0.5);
                let scene = Scene::new(dt).with_gravity(V::new(0.0, -9.81)).with_ground(ground);
                let settings = ExplicitSettings::new().with_damping(1.0);
                let run = || {
                    let mut x = rest.clone();
                    let mut v: Vec<V> = (0..nv).map(|i| V::new(0.2, -1.0 - 0.01 * i as Real)).collect();
                    let mut buffer = vec![V::ZERO; scratch_len::explicit(nv)];
                    let mut reports = Vec::new();
                    for _ in 0..20 {
                        let mut scratch = ExplicitScratch::new(&mut buffer);
                        let report =
                            explicit_step(&body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch)
                                .unwrap();
                        reports.push((f64::from(report.kinetic_energy).to_bits(), report.ground_contacts));
                    }
                    let bits = |values: &[V]| -> Vec<u64> {
                        values.iter().flat_map(|v| v.to_array()).map(|x| f64::from(x).to_bits()).collect()
                    };
                    (bits(&x), bits(&v), reports)
                };
                let scalar = same_at_every_width("the 2D explicit run", run);
                // The body reached the ground.
                assert!(scalar.2.iter().any(|&(_, contacts)| contacts > 0));
            }
        }
    };
}

planar_tests!(planar_f32, softfem, f32, Vec2);
planar_tests!(planar_f64, softfem::f64, f64, DVec2);
