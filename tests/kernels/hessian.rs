//! Second derivatives and their SPD projection (`docs/math.md` section 6), in both precisions,
//! against independent references: central differences of the stress and of the nodal forces,
//! eigenvalues from nalgebra's symmetric eigensolver (in f64), the rotation identities of an
//! isotropic energy, and sums of element products for the mesh.

macro_rules! hessian_tests {
    ($precision:ident, $($api:ident)::+) => {
        #[allow(dead_code)] // `material_helpers!` brings helpers this suite does not use.
        mod $precision {
            use crate::common::{Rng, for_each_model, material_helpers};
            use nalgebra::{DMatrix, SymmetricEigen};
            use softfem::glam::{DMat3, DVec3};
            use softfem::{Buffer, MeshError};
            use $($api)::+::element::{TetHessian, TetRest, tet_vertex_force_and_block};
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::{
                Lame, Material, NeoHookean, StVK, StableNeoHookean, StressDerivative,
            };
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::types::{Mat3, Real, Vec3};

            material_helpers!();

            /// Central-difference step for `P` and the forces: near `eps^(1/3)`, where
            /// truncation (`h^2`) and rounding (`eps / h`) errors balance.
            const STEP: Real = if EPS > 1e-10 { 1e-2 } else { 1e-5 };
            /// Relative tolerance of those differences: truncation `h^2` times third derivatives
            /// of order the modulus (up to ~10 at stretches 0.6..1.6 for the stiffening models)
            /// plus rounding `eps / h`: 2e-3 in f32, 1e-7 in f64.
            const FD_TOLERANCE: Real = if EPS > 1e-10 { 2e-3 } else { 1e-7 };

            fn to_mat3(m: DMat3) -> Mat3 {
                Mat3::from_cols_array(&m.to_cols_array().map(|x| x as Real))
            }

            fn to_vec3(v: DVec3) -> Vec3 {
                Vec3::new(v.x as Real, v.y as Real, v.z as Real)
            }

            /// `r1 diag(s) r2^T`, rounded to `Real`.
            fn rotated(rng: &mut Rng, s: [f64; 3]) -> Mat3 {
                to_mat3(rng.rotated(DVec3::from_array(s)))
            }

            /// Stretches in `[0.6, 1.6]`, the last negated when `inverted`.
            fn moderate(rng: &mut Rng, inverted: bool) -> Mat3 {
                let sign = if inverted { -1.0 } else { 1.0 };
                let s = [rng.uniform(0.6, 1.6), rng.uniform(0.6, 1.6), sign * rng.uniform(0.6, 1.6)];
                rotated(rng, s)
            }

            /// The 9x9 matrix of `d` in f64 (`vec` order `3 * column + row`).
            fn matrix(d: &StressDerivative) -> DMatrix<f64> {
                DMatrix::from_fn(9, 9, |i, j| d.entry(i, j) as f64)
            }

            /// The 9x9 of the linear map `df -> apply(df)`, column `j` the image of unit `j`.
            fn matrix_of(apply: impl Fn(Mat3) -> Mat3) -> DMatrix<f64> {
                let mut out = DMatrix::zeros(9, 9);
                for j in 0..9 {
                    let mut unit = [0.0; 9];
                    unit[j] = 1.0;
                    let column = apply(Mat3::from_cols_array(&unit)).to_cols_array();
                    for i in 0..9 {
                        out[(i, j)] = column[i] as f64;
                    }
                }
                out
            }

            fn eigenvalues(m: &DMatrix<f64>) -> Vec<f64> {
                let symmetric = (m + m.transpose()) * 0.5;
                SymmetricEigen::new(symmetric).eigenvalues.iter().copied().collect()
            }

            fn largest_abs(m: &DMatrix<f64>) -> f64 {
                m.iter().fold(0.0, |a: f64, x| a.max(x.abs()))
            }

            fn norm_f64(m: Mat3) -> f64 {
                norm(m) as f64
            }

            /// StVK through the provided second-derivative methods of `Material` only: what a
            /// model defined outside the crate gets (finite-difference principal Hessian, pair
            /// eigenvalues as quotients with their limits).
            #[derive(Clone, Copy, Debug)]
            struct OutsideModel(StVK);

            impl Material for OutsideModel {
                fn energy_density(&self, f: Mat3) -> Real {
                    self.0.energy_density(f)
                }
                fn first_piola(&self, f: Mat3) -> Mat3 {
                    self.0.first_piola(f)
                }
                fn principal_energy(&self, s: Vec3) -> Real {
                    self.0.principal_energy(s)
                }
                fn principal_stress(&self, s: Vec3) -> Vec3 {
                    self.0.principal_stress(s)
                }
            }

            // ---- Material level --------------------------------------------------------------

            /// `dP/dF : dF` equals the central difference `(P(F + h dF) - P(F - h dF)) / 2h`.
            fn differential_matches_differences<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng::new(11);
                for i in 0..200 {
                    let f = moderate(&mut rng, i % 2 == 1);
                    let df = to_mat3(rng.entries());
                    let exact = model.first_piola_differential(f, df);
                    let difference = (model.first_piola(f + df * STEP) - model.first_piola(f - df * STEP))
                        * (1.0 / (2.0 * STEP));
                    let scale = modulus(lame) * norm(df) * (1.0 + norm(f) * norm(f));
                    assert!(
                        norm(exact - difference) <= FD_TOLERANCE * scale,
                        "{model:?} F = {f:?}: {exact:?} against {difference:?}"
                    );
                }
            }

            #[test]
            fn stress_differential_matches_central_differences_of_the_stress() {
                for_each_model!(differential_matches_differences);
            }

            /// The principal-frame assembly of the exact derivative (through the SVD) equals the
            /// direct differential, including at repeated and opposite stretches where the
            /// quotients of the twist and flip eigenvalues are 0/0.
            fn principal_assembly_matches_direct<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng::new(12);
                let special = [[1.2, 1.2, 0.9], [1.1, 1.1, 1.1], [1.0, 1.0, -1.0], [1.3, 0.8, -0.8], [1.0, 1.0, 1.0]];
                for i in 0..120 {
                    let s = if i < special.len() {
                        special[i]
                    } else {
                        let f = [rng.uniform(0.6, 1.6), rng.uniform(0.6, 1.6), rng.uniform(0.6, 1.6)];
                        if i % 2 == 0 { f } else { [f[0], f[1], -f[2]] }
                    };
                    let f = rotated(&mut rng, s);
                    let assembled = matrix(&model.stress_derivative(f));
                    let direct = matrix_of(|df| model.first_piola_differential(f, df));
                    // Both are exact up to rounding: the SVD's few eps, amplified by the
                    // condition of the modes (stretches >= 0.6), against the modulus times |F|^2.
                    let scale = modulus(lame) as f64 * (1.0 + norm_f64(f) * norm_f64(f));
                    let error = largest_abs(&(&assembled - &direct));
                    assert!(error <= 2e3 * EPS as f64 * scale, "{model:?} s = {s:?}: error {error:e} of {scale:e}");
                }
            }

            #[test]
            fn principal_assembly_equals_the_direct_differential() {
                for_each_model!(principal_assembly_matches_direct);
            }

            #[test]
            fn provided_methods_agree_with_the_closed_forms() {
                // The finite-difference principal Hessian has error of order eps^(2/3) relative
                // (6e-5 in f32, 4e-11 in f64) times third derivatives; the quotients near
                // repeated stretches lose sqrt(eps) (3e-4, 1.5e-8): tolerances with room.
                let tolerance = if EPS > 1e-10 { 1e-2 } else { 1e-6 };
                for lame in parameter_sets() {
                    let (inside, outside) = (StVK::new(lame), OutsideModel(StVK::new(lame)));
                    let mut rng = Rng::new(13);
                    for i in 0..100 {
                        let s = match i {
                            0 => [1.1, 1.1, 0.7],
                            1 => [1.0, 1.0, -1.0],
                            2 => [0.9, 0.9, 0.9],
                            _ => [rng.uniform(0.6, 1.6), rng.uniform(0.6, 1.6), rng.uniform(-1.6, 1.6)],
                        };
                        let f = rotated(&mut rng, s);
                        let scale = modulus(lame) as f64 * (1.0 + norm_f64(f) * norm_f64(f));
                        let a = matrix(&inside.projected_stress_derivative(f));
                        let b = matrix(&outside.projected_stress_derivative(f));
                        let error = largest_abs(&(&a - &b));
                        assert!(error <= tolerance * scale, "s = {s:?}: {error:e} of {scale:e}");
                        let direct = matrix_of(|df| outside.first_piola_differential(f, df));
                        let exact = matrix_of(|df| inside.first_piola_differential(f, df));
                        assert!(largest_abs(&(&direct - &exact)) <= tolerance * scale);
                    }
                }
            }

            /// Deformation classes for the projection: `(name, stretches)`.
            fn classes(rng: &mut Rng) -> Vec<(&'static str, [f64; 3])> {
                let mut out = Vec::new();
                for _ in 0..30 {
                    let mut u = || rng.uniform(0.3, 2.0);
                    let (a, b, c) = (u(), u(), u());
                    out.push(("random", [a, b, c]));
                    out.push(("inverted", [a, b, -c]));
                    out.push(("flat", [a, b, 0.0]));
                    out.push(("compressed 1e-3", [1e-3 * a, 1e-3 * b, 1e-3 * c]));
                    out.push(("squashed 1e-3", [a, b, 1e-3 * c]));
                    out.push(("stretched 1e3", [1e3 * a, b, c]));
                    out.push(("stretched 1e3 all", [1e3 * a, 1e3 * b, 1e3 * c]));
                    out.push(("repeated", [a, a, b]));
                    out.push(("repeated inverted", [a, a, -a]));
                    out.push(("triple", [a, a, a]));
                    out.push(("opposite", [a, b, -b]));
                }
                out
            }

            /// Symmetric, PSD to rounding and finite for every class (the isochoric neo-Hookean
            /// is not finite at J = 0 and is left out of the flat class).
            fn projection_is_psd<M: Material>(_lame: Lame, model: M) {
                let mut rng = Rng::new(14);
                let barrier = core::any::type_name::<M>().ends_with("::NeoHookean");
                for (class, s) in classes(&mut rng) {
                    if barrier && class == "flat" {
                        continue;
                    }
                    let f = rotated(&mut rng, s);
                    let d = model.projected_stress_derivative(f);
                    let m = matrix(&d);
                    assert!(m.iter().all(|x| x.is_finite()), "{model:?} {class} {s:?}: {d:?}");
                    // `apply` is the same matrix as `entry`.
                    let applied = matrix_of(|df| d.apply(df));
                    let scale = largest_abs(&m).max(f64::MIN_POSITIVE);
                    assert!(largest_abs(&(&applied - &m)) <= 64.0 * EPS as f64 * scale * 9.0);
                    let lowest = eigenvalues(&m).into_iter().fold(f64::INFINITY, f64::min);
                    // The entries are sums of nine rank-one terms with nonnegative weights,
                    // each rounded: a few eps of the largest entry.
                    assert!(
                        lowest >= -64.0 * EPS as f64 * scale,
                        "{model:?} {class} s = {s:?}: eigenvalue {lowest:e}, scale {scale:e}"
                    );
                }
            }

            #[test]
            fn projected_derivative_is_symmetric_positive_semi_definite_everywhere() {
                for_each_model!(projection_is_psd);
            }

            /// Where the exact derivative is SPD (stretched elements), the projection is it.
            fn projection_keeps_spd<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng::new(15);
                let mut spd = 0;
                for i in 0..100 {
                    // Half near rest, half stretched by up to 30 %; at rest itself the rotation
                    // modes have eigenvalue 0, slightly stretched ones a positive one.
                    let top = if i % 2 == 0 { 1.06 } else { 1.3 };
                    let mut u = || rng.uniform(1.01, top);
                    let s = [u(), u(), u()];
                    let f = rotated(&mut rng, s);
                    let exact = matrix_of(|df| model.first_piola_differential(f, df));
                    let scale = largest_abs(&exact);
                    let lowest = eigenvalues(&exact).into_iter().fold(f64::INFINITY, f64::min);
                    if lowest < 1e-6 * scale {
                        continue;
                    }
                    spd += 1;
                    let projected = matrix(&model.projected_stress_derivative(f));
                    let error = largest_abs(&(&projected - &exact));
                    assert!(error <= 2e3 * EPS as f64 * scale, "{model:?} s = {s:?}: {error:e} of {scale:e}");
                }
                // Stretching makes the exact derivative SPD for most samples (the isochoric
                // neo-Hookean least often): the comparison is not vacuous.
                assert!(spd >= 30, "{model:?} ({lame:?}): only {spd} SPD samples");
            }

            #[test]
            fn projection_is_the_exact_derivative_where_that_is_spd() {
                for_each_model!(projection_keeps_spd);
            }

            /// `D(Q F)[Q dF] = Q D(F)[dF]` and `D(F Q)[dF Q] = D(F)[dF] Q` for rotations `Q`.
            fn rotation_equivariance<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng::new(16);
                for i in 0..100 {
                    let f = moderate(&mut rng, i % 2 == 1);
                    let (q, r) = (to_mat3(rng.rotation()), to_mat3(rng.rotation()));
                    let df = to_mat3(rng.entries());
                    let base = model.projected_stress_derivative(f).apply(df);
                    let left = model.projected_stress_derivative(q * f).apply(q * df);
                    let right = model.projected_stress_derivative(f * r).apply(df * r);
                    let scale = modulus(lame) * norm(df) * (1.0 + norm(f) * norm(f));
                    assert!(norm(left - q * base) <= 2e3 * EPS * scale, "{model:?} left, F = {f:?}");
                    assert!(norm(right - base * r) <= 2e3 * EPS * scale, "{model:?} right, F = {f:?}");
                }
            }

            #[test]
            fn projection_is_rotation_equivariant() {
                for_each_model!(rotation_equivariance);
            }

            #[test]
            fn nan_only_from_nan_input_and_out_of_range_entries_are_zero() {
                let model = StableNeoHookean::from_young_poisson(1.0e6, 0.4).unwrap();
                let mut f = Mat3::IDENTITY;
                f.y_axis.z = Real::NAN;
                let d = model.projected_stress_derivative(f);
                assert!((0..81).any(|k| d.entry(k / 9, k % 9).is_nan()));
                assert!(model.first_piola_differential(f, Mat3::IDENTITY).is_nan());
                let d = model.projected_stress_derivative(Mat3::ZERO);
                assert!((0..81).all(|k| d.entry(k / 9, k % 9).is_finite()));
                assert_eq!(d.entry(9, 0), 0.0);
                assert_eq!(d.entry(0, usize::MAX), 0.0);
                assert_eq!(StressDerivative::default().apply(Mat3::IDENTITY), Mat3::ZERO);
            }

            // ---- Element level ---------------------------------------------------------------

            fn random_tet(rng: &mut Rng) -> (TetRest, [Vec3; 4]) {
                loop {
                    let rest = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z]
                        .map(|p| to_vec3(p + rng.vector() * 0.2));
                    if let Ok(tet) = TetRest::new(rest) {
                        if tet.volume > 0.05 {
                            return (tet, rest);
                        }
                    }
                }
            }

            /// The unprojected element product `H v` equals minus the central difference of the
            /// nodal forces, and the projected one equals it where no projection happens.
            fn element_product_matches_force_differences<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng::new(17);
                for i in 0..100 {
                    let (tet, rest) = random_tet(&mut rng);
                    let f = moderate(&mut rng, i % 2 == 1);
                    let x = rest.map(|p| f * p);
                    let v: [Vec3; 4] = core::array::from_fn(|_| to_vec3(rng.vector()));
                    let exact = TetHessian::exact(&model, &tet, x).product(&tet, v);
                    let plus = tet.elastic_forces(&model, core::array::from_fn(|k| x[k] + v[k] * STEP));
                    let minus = tet.elastic_forces(&model, core::array::from_fn(|k| x[k] - v[k] * STEP));
                    // |dF| <= |v| |G|: the scale of a force change.
                    let g = norm(tet.dm_inv) * 2.0;
                    let scale = tet.volume * modulus(lame) * g * g * (1.0 + norm(f) * norm(f));
                    for k in 0..4 {
                        let difference = (minus[k] - plus[k]) * (1.0 / (2.0 * STEP));
                        assert!((exact[k] - difference).length() <= FD_TOLERANCE * scale,
                            "{model:?} corner {k}: {:?} against {difference:?}", exact[k]);
                    }
                }
            }

            #[test]
            fn element_product_is_minus_the_derivative_of_the_nodal_forces() {
                for_each_model!(element_product_matches_force_differences);
            }

            /// The 12x12 of the projected element Hessian, probed with unit vectors.
            fn element_matrix(hessian: &TetHessian, tet: &TetRest) -> DMatrix<f64> {
                let mut out = DMatrix::zeros(12, 12);
                for j in 0..12 {
                    let mut v = [Vec3::ZERO; 4];
                    v[j / 3][j % 3] = 1.0;
                    let column = hessian.product(tet, v);
                    for i in 0..12 {
                        out[(i, j)] = column[i / 3][i % 3] as f64;
                    }
                }
                out
            }

            /// Projected element Hessians are symmetric PSD; their diagonal blocks are the 3x3
            /// blocks of the product, and the fused VBD call gives the same force and block.
            fn element_blocks<M: Material>(_lame: Lame, model: M) {
                let mut rng = Rng::new(18);
                let barrier = core::any::type_name::<M>().ends_with("::NeoHookean");
                for (class, s) in classes(&mut rng).into_iter().take(110) {
                    if barrier && class == "flat" {
                        continue;
                    }
                    let (tet, rest) = random_tet(&mut rng);
                    let f = rotated(&mut rng, s);
                    let x = rest.map(|p| f * p);
                    let hessian = TetHessian::new(&model, &tet, x);
                    let h = element_matrix(&hessian, &tet);
                    let scale = largest_abs(&h).max(f64::MIN_POSITIVE);
                    assert!(largest_abs(&(&h - h.transpose())) <= 1e3 * EPS as f64 * scale, "{class}");
                    let lowest = eigenvalues(&h).into_iter().fold(f64::INFINITY, f64::min);
                    assert!(lowest >= -1e3 * EPS as f64 * scale, "{model:?} {class}: {lowest:e} of {scale:e}");
                    for corner in 0..4 {
                        let block = hessian.vertex_block(&tet, corner);
                        for r in 0..3 {
                            for c in 0..3 {
                                let expected = h[(3 * corner + r, 3 * corner + c)];
                                let got = block.col(c)[r] as f64;
                                assert!((got - expected).abs() <= 1e3 * EPS as f64 * scale, "{class} corner {corner}");
                            }
                        }
                        let (force, fused) = tet_vertex_force_and_block(&model, &tet, x, corner);
                        assert_eq!(force, tet.elastic_forces(&model, x)[corner]);
                        let fused_error = (fused - block).to_cols_array().iter().fold(0.0 as Real, |a, x| a.max(x.abs()));
                        assert!(fused_error as f64 <= 1e3 * EPS as f64 * scale, "{class} corner {corner}: fused block");
                    }
                    assert_eq!(hessian.vertex_block(&tet, 4), Mat3::ZERO);
                }
            }

            #[test]
            fn element_hessian_is_psd_and_its_blocks_are_the_diagonal_of_the_product() {
                for_each_model!(element_blocks);
            }

            // ---- Mesh level ------------------------------------------------------------------

            struct Block {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
            }

            fn block() -> Block {
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, Vec3::new(0.2, 0.2, 0.1), (2, 2, 1), BoxSplit::Kuhn6);
                Block { rest, tets }
            }

            #[test]
            fn mesh_product_is_the_sum_of_element_products_and_the_force_derivative() {
                let block = block();
                let mut rest_data = vec![TetRest::default(); block.tets.len()];
                let mesh = TetMesh::new(&block.rest, &block.tets, &mut rest_data).unwrap();
                let model = StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
                let mut rng = Rng::new(19);
                // Stretched by 15 % with a wobble: every element's exact Hessian is SPD, so the
                // projection changes nothing and the product is the force derivative.
                let x: Vec<Vec3> = block.rest.iter().map(|p| *p * 1.15 + to_vec3(rng.vector()) * 1e-3).collect();
                let n = x.len();
                let mut cache = vec![TetHessian::default(); block.tets.len()];
                mesh.projected_hessians(&model, &x, &mut cache).unwrap();
                // Of the size of an element (0.1 m), so that `STEP d` is a strain of about STEP.
                let d: Vec<Vec3> = (0..n).map(|_| to_vec3(rng.vector() * 0.1)).collect();
                let mut out = vec![Vec3::ZERO; n];
                mesh.add_hessian_product(&cache, &d, &mut out).unwrap();
                // The sum of element products, in the same order.
                let mut sum = vec![Vec3::ZERO; n];
                for ((corners, rest), hessian) in block.tets.iter().zip(mesh.rest()).zip(&cache) {
                    let v = corners.map(|c| d[c as usize]);
                    for (k, f) in hessian.product(rest, v).into_iter().enumerate() {
                        sum[corners[k] as usize] += f;
                    }
                }
                assert_eq!(out, sum);
                // The force difference.
                let forces_at = |t: Real| {
                    let y: Vec<Vec3> = x.iter().zip(&d).map(|(x, d)| *x + *d * t).collect();
                    let mut f = vec![Vec3::ZERO; n];
                    mesh.add_elastic_forces(&model, &y, &mut f).unwrap();
                    f
                };
                let (plus, minus) = (forces_at(STEP), forces_at(-STEP));
                let scale = out.iter().fold(0.0 as Real, |a, f| a.max(f.length()));
                for i in 0..n {
                    let difference = (minus[i] - plus[i]) * (1.0 / (2.0 * STEP));
                    assert!((out[i] - difference).length() <= FD_TOLERANCE * scale, "vertex {i}");
                }
                // Diagonal blocks against the product probed with unit vectors at each vertex.
                let mut blocks = vec![Mat3::ZERO; n];
                mesh.add_vertex_hessian_blocks(&cache, &mut blocks).unwrap();
                let block_scale = blocks.iter().fold(0.0 as Real, |a, b| a.max(norm(*b)));
                for i in 0..n {
                    for axis in 0..3 {
                        let mut e = vec![Vec3::ZERO; n];
                        e[i][axis] = 1.0;
                        let mut column = vec![Vec3::ZERO; n];
                        mesh.add_hessian_product(&cache, &e, &mut column).unwrap();
                        let expected = column[i];
                        assert!((blocks[i].col(axis) - expected).length() <= 1e2 * EPS * block_scale,
                            "vertex {i} axis {axis}");
                    }
                }
            }

            /// The mesh product takes the elements in groups of the SIMD width's lanes: at every
            /// width this machine has (and each narrower one forced), for every element count
            /// from 1 to 40 (every tail of every group width), it is bit for bit the sum of the
            /// element products, element by element and corner by corner in order.
            #[test]
            fn mesh_product_is_bitwise_the_element_sum_at_every_width() {
                use softfem::simd::{self, Width};
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, Vec3::new(0.4, 0.2, 0.1), (4, 2, 1), BoxSplit::Kuhn6);
                let (nv, nt) = (rest.len(), tets.len());
                let model = NeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
                let mut rng = Rng::new(23);
                // Squashed and sheared with a wobble: indefinite exact Hessians, so the
                // projection is at work in the cache.
                let x: Vec<Vec3> = rest
                    .iter()
                    .map(|p| Vec3::new(p.x + 0.3 * p.z, p.y * 0.9, p.z * 0.7) + to_vec3(rng.vector()) * 2e-3)
                    .collect();
                let d: Vec<Vec3> = (0..nv).map(|_| to_vec3(rng.vector() * 0.1)).collect();
                let _guard = crate::common::lock_width();
                let widths: Vec<Width> =
                    Width::ALL.into_iter().filter(|w| *w <= simd::detected_width()).collect();
                for len in 1..=40.min(nt) {
                    let mut rest_data = vec![TetRest::default(); len];
                    let mesh = TetMesh::new(&rest, &tets[..len], &mut rest_data).unwrap();
                    let mut cache = vec![TetHessian::default(); len];
                    mesh.projected_hessians(&model, &x, &mut cache).unwrap();
                    let mut sum = vec![Vec3::ZERO; nv];
                    for ((corners, tet), hessian) in tets[..len].iter().zip(mesh.rest()).zip(&cache) {
                        let v = corners.map(|c| d[c as usize]);
                        for (k, f) in hessian.product(tet, v).into_iter().enumerate() {
                            sum[corners[k] as usize] += f;
                        }
                    }
                    for &width in &widths {
                        simd::set_max_width(width);
                        assert_eq!(simd::active_width(), width);
                        let mut out = vec![Vec3::ZERO; nv];
                        mesh.add_hessian_product(&cache, &d, &mut out).unwrap();
                        let bits = |v: &[Vec3]| -> Vec<[u64; 3]> {
                            v.iter().map(|p| [p.x, p.y, p.z].map(|c| f64::from(c).to_bits())).collect()
                        };
                        assert_eq!(bits(&out), bits(&sum), "{len} elements at {width:?}");
                    }
                }
                simd::set_max_width(Width::Avx512);
            }

            /// The grouped product gathers each group's cached entries through register
            /// transposes: on a mesh of many groups (432 tetrahedra, and lengths that end in
            /// every kind of tail), with every element's entries different, each width gives
            /// the bits of an element-by-element sum of `TetHessian::product`.
            #[test]
            fn mesh_product_of_many_groups_is_bitwise_the_element_sum_at_every_width() {
                use softfem::simd::{self, Width};
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, Vec3::new(0.6, 0.4, 0.3), (6, 4, 3), BoxSplit::Kuhn6);
                let (nv, nt) = (rest.len(), tets.len());
                let model = StableNeoHookean::from_young_poisson(1.0e6, 0.4).unwrap();
                let mut rng = Rng::new(71);
                let x: Vec<Vec3> = rest
                    .iter()
                    .map(|p| Vec3::new(p.x * 1.1 + 0.2 * p.y, p.y * 0.9, p.z * 0.8) + to_vec3(rng.vector()) * 1e-2)
                    .collect();
                let d: Vec<Vec3> = (0..nv).map(|_| to_vec3(rng.vector())).collect();
                let _guard = crate::common::lock_width();
                let widths: Vec<Width> =
                    Width::ALL.into_iter().filter(|w| *w <= simd::detected_width()).collect();
                for len in [nt, nt - 1, nt - 3, nt - 7, nt - 13] {
                    let mut rest_data = vec![TetRest::default(); len];
                    let mesh = TetMesh::new(&rest, &tets[..len], &mut rest_data).unwrap();
                    let mut cache = vec![TetHessian::default(); len];
                    mesh.projected_hessians(&model, &x, &mut cache).unwrap();
                    // No two elements alike (the box's cubes would otherwise repeat entries).
                    let distinct = cache.windows(2).filter(|pair| pair[0] != pair[1]).count();
                    assert_eq!(distinct, len - 1);
                    let mut sum = vec![Vec3::ZERO; nv];
                    for ((corners, tet), hessian) in tets[..len].iter().zip(mesh.rest()).zip(&cache) {
                        let v = corners.map(|c| d[c as usize]);
                        for (k, f) in hessian.product(tet, v).into_iter().enumerate() {
                            sum[corners[k] as usize] += f;
                        }
                    }
                    let bits = |v: &[Vec3]| -> Vec<[u64; 3]> {
                        v.iter().map(|p| [p.x, p.y, p.z].map(|c| f64::from(c).to_bits())).collect()
                    };
                    for &width in &widths {
                        simd::set_max_width(width);
                        let mut out = vec![Vec3::ZERO; nv];
                        mesh.add_hessian_product(&cache, &d, &mut out).unwrap();
                        assert_eq!(bits(&out), bits(&sum), "{len} elements at {width:?}");
                    }
                }
                simd::set_max_width(Width::Avx512);
            }

            #[test]
            fn mesh_kernels_refuse_bad_buffers_and_leave_outputs_untouched() {
                let block = block();
                let mut rest_data = vec![TetRest::default(); block.tets.len()];
                let mesh = TetMesh::new(&block.rest, &block.tets, &mut rest_data).unwrap();
                let model = StVK::from_young_poisson(1.0e6, 0.3).unwrap();
                let (n, m) = (block.rest.len(), block.tets.len());
                let mut cache = vec![TetHessian::default(); m];
                mesh.projected_hessians(&model, &block.rest, &mut cache).unwrap();
                let sentinel = Vec3::splat(SENTINEL);
                let mut short = vec![TetHessian::default(); m - 1];
                assert_eq!(
                    mesh.projected_hessians(&model, &block.rest, &mut short),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Hessians, expected: m, actual: m - 1 })
                );
                let mut bad = block.rest.clone();
                bad[3].y = Real::NAN;
                let before = cache.clone();
                assert_eq!(mesh.projected_hessians(&model, &bad, &mut cache), Err(MeshError::NonFinitePosition { vertex: 3 }));
                assert_eq!(cache, before);
                assert_eq!(
                    mesh.projected_hessians(&model, &block.rest[1..], &mut cache),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Positions, expected: n, actual: n - 1 })
                );

                let mut out = vec![sentinel; n];
                let mut direction = vec![Vec3::X; n];
                direction[5].z = Real::INFINITY;
                assert_eq!(mesh.add_hessian_product(&cache, &direction, &mut out), Err(MeshError::NonFiniteDirection { vertex: 5 }));
                assert_eq!(
                    mesh.add_hessian_product(&cache, &direction[1..], &mut out),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Direction, expected: n, actual: n - 1 })
                );
                assert_eq!(
                    mesh.add_hessian_product(&cache, &block.rest, &mut out[1..]),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Products, expected: n, actual: n - 1 })
                );
                assert_eq!(
                    mesh.add_hessian_product(&cache[1..], &block.rest, &mut out),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Hessians, expected: m, actual: m - 1 })
                );
                assert!(out.iter().all(|v| *v == sentinel));
                let mut blocks = vec![Mat3::from_diagonal(sentinel); n];
                assert_eq!(
                    mesh.add_vertex_hessian_blocks(&cache, &mut blocks[1..]),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Blocks, expected: n, actual: n - 1 })
                );
                assert_eq!(
                    mesh.add_vertex_hessian_blocks(&cache[1..], &mut blocks),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Hessians, expected: m, actual: m - 1 })
                );
                assert!(blocks.iter().all(|b| *b == Mat3::from_diagonal(sentinel)));
            }

            const SENTINEL: Real = 12345.0;
        }
    };
}

hessian_tests!(single, softfem);
hessian_tests!(double, softfem::f64);

macro_rules! triangle_hessian_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use crate::common::Rng;
            use nalgebra::{DMatrix, SymmetricEigen};
            use softfem::{Buffer, MeshError};
            use $($api)::+::element::{MembraneHessian, SymmetricMatrix, TriHessian, TriRest, TriangleStVK};
            use $($api)::+::generate::{fill_rectangle, fill_rectangle_3d, rectangle_counts};
            use $($api)::+::material::StVK;
            use $($api)::+::mesh::{MembraneMesh, TriMesh};
            use $($api)::+::types::{Mat2, Mat3, Real, Vec2, Vec3};

            const EPS: Real = Real::EPSILON;
            const STEP: Real = if EPS > 1e-10 { 1e-2 } else { 1e-5 };
            /// As in the tetrahedron tests: truncation `h^2` plus rounding `eps / h`.
            const FD_TOLERANCE: Real = if EPS > 1e-10 { 2e-3 } else { 1e-7 };

            fn model() -> TriangleStVK {
                TriangleStVK::new(&StVK::from_young_poisson(1.0e6, 0.3).unwrap())
            }

            fn modulus() -> Real {
                let m = StVK::from_young_poisson(1.0e6, 0.3).unwrap();
                m.lambda() + 2.0 * m.mu()
            }

            fn r(rng: &mut Rng, lo: f64, hi: f64) -> Real {
                rng.uniform(lo, hi) as Real
            }

            fn rotation2(angle: Real) -> Mat2 {
                Mat2::from_angle(angle)
            }

            /// `R1 diag(s) R2^T` in 2D (`inverted`: `s_1 < 0`), stretches in `[lo, hi]`.
            fn f2(rng: &mut Rng, lo: f64, hi: f64, inverted: bool) -> Mat2 {
                let s = Vec2::new(r(rng, lo, hi), r(rng, lo, hi) * if inverted { -1.0 } else { 1.0 });
                rotation2(r(rng, 0.0, 6.3)) * Mat2::from_diagonal(s) * rotation2(r(rng, 0.0, 6.3)).transpose()
            }

            /// A membrane gradient: the 2D one rotated into space by a random rotation.
            fn f3(rng: &mut Rng, lo: f64, hi: f64) -> [Vec3; 2] {
                let f = f2(rng, lo, hi, false);
                let q = Mat3::from_axis_angle(Vec3::new(r(rng, -1.0, 1.0), r(rng, -1.0, 1.0), 1.0).normalize(), r(rng, 0.0, 6.3));
                [q * f.x_axis.extend(0.0), q * f.y_axis.extend(0.0)]
            }

            fn matrix<const N: usize>(m: &SymmetricMatrix<N>) -> DMatrix<f64> {
                DMatrix::from_fn(N, N, |i, j| m.entry(i, j) as f64)
            }

            fn lowest(m: &DMatrix<f64>) -> f64 {
                SymmetricEigen::new(m.clone()).eigenvalues.iter().copied().fold(f64::INFINITY, f64::min)
            }

            fn largest_abs(m: &DMatrix<f64>) -> f64 {
                m.iter().fold(0.0, |a: f64, x| a.max(x.abs()))
            }

            fn norm2(m: Mat2) -> Real {
                (m.x_axis.length_squared() + m.y_axis.length_squared()).sqrt()
            }

            fn norm3(m: [Vec3; 2]) -> Real {
                (m[0].length_squared() + m[1].length_squared()).sqrt()
            }

            #[test]
            fn differentials_match_central_differences_of_the_stress() {
                let model = model();
                let mut rng = Rng::new(21);
                for i in 0..200 {
                    let f = f2(&mut rng, 0.5, 1.6, i % 2 == 1);
                    let df = Mat2::from_cols_array(&core::array::from_fn(|_| r(&mut rng, -1.0, 1.0)));
                    let exact = model.first_piola_differential(f, df);
                    let difference = (model.first_piola(f + df * STEP) - model.first_piola(f - df * STEP)) * (1.0 / (2.0 * STEP));
                    let scale = modulus() * norm2(df) * (1.0 + norm2(f) * norm2(f));
                    assert!(norm2(exact - difference) <= FD_TOLERANCE * scale, "2D {f:?}");
                    let f = f3(&mut rng, 0.5, 1.6);
                    let df = [Vec3::new(r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0)), Vec3::new(r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0))];
                    let exact = model.membrane_first_piola_differential(f, df);
                    let plus = model.membrane_first_piola([f[0] + df[0] * STEP, f[1] + df[1] * STEP]);
                    let minus = model.membrane_first_piola([f[0] - df[0] * STEP, f[1] - df[1] * STEP]);
                    let difference = [(plus[0] - minus[0]) * (1.0 / (2.0 * STEP)), (plus[1] - minus[1]) * (1.0 / (2.0 * STEP))];
                    let scale = modulus() * norm3(df) * (1.0 + norm3(f) * norm3(f));
                    assert!(norm3([exact[0] - difference[0], exact[1] - difference[1]]) <= FD_TOLERANCE * scale, "membrane {f:?}");
                }
            }

            #[test]
            fn projections_are_psd_and_exact_where_the_derivative_is_spd() {
                let model = model();
                let mut rng = Rng::new(22);
                let (mut spd2, mut spd3) = (0, 0);
                for i in 0..300 {
                    // Compressed (StVK softens below 1/sqrt 3), stretched, inverted, flat.
                    let (lo, hi) = match i % 3 { 0 => (0.05, 0.7), 1 => (1.02, 1.5), _ => (0.3, 2.0) };
                    let f = f2(&mut rng, lo, hi, i % 4 == 3);
                    let f = if i % 10 == 9 { Mat2::from_cols(f.x_axis, f.x_axis * 0.5) } else { f };
                    let exact = matrix(&model.stress_derivative(f));
                    let projected = matrix(&model.projected_stress_derivative(f));
                    let scale = largest_abs(&exact).max(f64::MIN_POSITIVE);
                    assert!(projected.iter().all(|x| x.is_finite()));
                    assert!(lowest(&projected) >= -64.0 * EPS as f64 * scale, "2D {f:?}: {}", lowest(&projected));
                    if lowest(&exact) > 1e-6 * scale {
                        spd2 += 1;
                        assert!(largest_abs(&(&projected - &exact)) <= 1e2 * EPS as f64 * scale);
                    }
                    let f = f3(&mut rng, lo, hi);
                    let exact = matrix(&model.membrane_stress_derivative(f));
                    let projected = matrix(&model.membrane_projected_stress_derivative(f));
                    let scale = largest_abs(&exact).max(f64::MIN_POSITIVE);
                    assert!(lowest(&projected) >= -64.0 * EPS as f64 * scale, "membrane {f:?}: {}", lowest(&projected));
                    if lowest(&exact) > 1e-6 * scale {
                        spd3 += 1;
                        assert!(largest_abs(&(&projected - &exact)) <= 1e2 * EPS as f64 * scale);
                    }
                }
                // A membrane's out-of-plane modes carry the in-plane stress: SPD only in tension.
                assert!(spd2 >= 50 && spd3 >= 50, "{spd2} {spd3}");
            }

            #[test]
            fn element_products_match_force_differences_and_blocks_the_product() {
                let model = model();
                let mut rng = Rng::new(23);
                let tri = TriRest::new([Vec2::ZERO, Vec2::new(1.0, 0.1), Vec2::new(0.2, 0.9)]).unwrap();
                let rest3 = [Vec3::ZERO, Vec3::new(1.0, 0.1, 0.3), Vec3::new(0.2, 0.9, -0.2)];
                let membrane = TriRest::membrane(rest3).unwrap();
                for _ in 0..50 {
                    let x: [Vec2; 3] = core::array::from_fn(|_| Vec2::new(r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0)));
                    let v: [Vec2; 3] = core::array::from_fn(|_| Vec2::new(r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0)));
                    let hv = TriHessian::exact(&model, &tri, x).product(v);
                    let plus = tri.elastic_forces(&model, core::array::from_fn(|k| x[k] + v[k] * STEP));
                    let minus = tri.elastic_forces(&model, core::array::from_fn(|k| x[k] - v[k] * STEP));
                    let scale = modulus() * 50.0;
                    for k in 0..3 {
                        let difference = (minus[k] - plus[k]) * (1.0 / (2.0 * STEP));
                        assert!((hv[k] - difference).length() <= FD_TOLERANCE * scale, "2D corner {k}");
                    }
                    let projected = TriHessian::new(&model, &tri, x);
                    for corner in 0..3 {
                        let block = projected.vertex_block(corner);
                        for axis in 0..2 {
                            let mut e = [Vec2::ZERO; 3];
                            e[corner][axis] = 1.0;
                            let column = projected.product(e)[corner];
                            assert!((block.col(axis) - column).length() <= 1e2 * EPS * scale);
                        }
                    }
                    let y: [Vec3; 3] = core::array::from_fn(|_| Vec3::new(r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0)));
                    let w: [Vec3; 3] = core::array::from_fn(|_| Vec3::new(r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0), r(&mut rng, -1.0, 1.0)));
                    let hw = MembraneHessian::exact(&model, &membrane, y).product(w);
                    let plus = membrane.membrane_elastic_forces(&model, core::array::from_fn(|k| y[k] + w[k] * STEP));
                    let minus = membrane.membrane_elastic_forces(&model, core::array::from_fn(|k| y[k] - w[k] * STEP));
                    for k in 0..3 {
                        let difference = (minus[k] - plus[k]) * (1.0 / (2.0 * STEP));
                        assert!((hw[k] - difference).length() <= FD_TOLERANCE * scale, "membrane corner {k}");
                    }
                    let projected = MembraneHessian::new(&model, &membrane, y);
                    for corner in 0..3 {
                        let block = projected.vertex_block(corner);
                        for axis in 0..3 {
                            let mut e = [Vec3::ZERO; 3];
                            e[corner][axis] = 1.0;
                            let column = projected.product(e)[corner];
                            assert!((block.col(axis) - column).length() <= 1e2 * EPS * scale);
                        }
                    }
                }
            }

            #[test]
            fn mesh_kernels_sum_the_elements_and_refuse_bad_buffers() {
                let model = model();
                let (nv, nt) = rectangle_counts(3, 2).unwrap();
                let (mut rest, mut tris) = (vec![Vec2::ZERO; nv], vec![[0; 3]; nt]);
                fill_rectangle(Vec2::ZERO, Vec2::new(0.3, 0.2), 3, 2, &mut rest, &mut tris).unwrap();
                let mut rest_data = vec![TriRest::default(); nt];
                let mesh = TriMesh::new(&rest, &tris, &mut rest_data).unwrap();
                let mut rng = Rng::new(24);
                let x: Vec<Vec2> = rest.iter().map(|p| *p * 1.1 + Vec2::new(r(&mut rng, -1e-3, 1e-3), r(&mut rng, -1e-3, 1e-3))).collect();
                let d: Vec<Vec2> = (0..nv).map(|_| Vec2::new(r(&mut rng, -0.1, 0.1), r(&mut rng, -0.1, 0.1))).collect();
                let mut cache = vec![TriHessian::default(); nt];
                mesh.projected_hessians(&model, &x, &mut cache).unwrap();
                let mut out = vec![Vec2::ZERO; nv];
                mesh.add_hessian_product(&cache, &d, &mut out).unwrap();
                let mut sum = vec![Vec2::ZERO; nv];
                for (corners, h) in tris.iter().zip(&cache) {
                    for (k, f) in h.product(corners.map(|c| d[c as usize])).into_iter().enumerate() {
                        sum[corners[k] as usize] += f;
                    }
                }
                assert_eq!(out, sum);
                let mut blocks = vec![Mat2::ZERO; nv];
                mesh.add_vertex_hessian_blocks(&cache, &mut blocks).unwrap();
                let mut expected = vec![Mat2::ZERO; nv];
                for (corners, h) in tris.iter().zip(&cache) {
                    for (k, &c) in corners.iter().enumerate() {
                        expected[c as usize] += h.vertex_block(k);
                    }
                }
                assert_eq!(blocks, expected);
                let mut bad = d.clone();
                bad[2].x = Real::NAN;
                let before = out.clone();
                assert_eq!(mesh.add_hessian_product(&cache, &bad, &mut out), Err(MeshError::NonFiniteDirection { vertex: 2 }));
                assert_eq!(out, before);
                assert_eq!(
                    mesh.projected_hessians(&model, &x, &mut cache[1..]),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Hessians, expected: nt, actual: nt - 1 })
                );

                // The membrane version of the same sheet, lifted into space.
                let mut rest3 = vec![Vec3::ZERO; nv];
                let mut tris3 = vec![[0; 3]; nt];
                fill_rectangle_3d(Vec3::ZERO, Vec3::new(0.3, 0.0, 0.0), Vec3::new(0.0, 0.2, 0.0), 3, 2, &mut rest3, &mut tris3).unwrap();
                let mut rest_data3 = vec![TriRest::default(); nt];
                let membrane = MembraneMesh::new(&rest3, &tris3, &mut rest_data3).unwrap();
                let y: Vec<Vec3> = rest3.iter().map(|p| *p * 1.1 + Vec3::new(0.0, 0.0, r(&mut rng, -1e-3, 1e-3))).collect();
                let mut cache3 = vec![MembraneHessian::default(); nt];
                membrane.projected_hessians(&model, &y, &mut cache3).unwrap();
                let mut blocks3 = vec![Mat3::ZERO; nv];
                membrane.add_vertex_hessian_blocks(&cache3, &mut blocks3).unwrap();
                // Probe the diagonal with unit directions.
                let scale = blocks3.iter().fold(0.0 as Real, |a, b| a.max(b.x_axis.length().max(b.y_axis.length()).max(b.z_axis.length())));
                for i in 0..nv {
                    for axis in 0..3 {
                        let mut e = vec![Vec3::ZERO; nv];
                        e[i][axis] = 1.0;
                        let mut column = vec![Vec3::ZERO; nv];
                        membrane.add_hessian_product(&cache3, &e, &mut column).unwrap();
                        assert!((blocks3[i].col(axis) - column[i]).length() <= 1e2 * EPS * scale);
                    }
                }
                assert_eq!(
                    membrane.add_vertex_hessian_blocks(&cache3, &mut blocks3[1..]),
                    Err(MeshError::LengthMismatch { buffer: Buffer::Blocks, expected: nv, actual: nv - 1 })
                );
            }
        }
    };
}

mod triangles {
    triangle_hessian_tests!(single, softfem);
    triangle_hessian_tests!(double, softfem::f64);
}
