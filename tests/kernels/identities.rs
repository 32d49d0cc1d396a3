//! The mesh kernels against the identities of `docs/math.md` section 5, in both precisions: zero
//! force and energy under rigid motion, balance of force and torque, forces as minus the energy
//! gradient, direct and principal paths agreeing, rotation invariance, and homogeneous
//! deformations of whole meshes against hand-derived closed forms (stress, boundary traction,
//! energy). Tetrahedra with every model; triangles (2D and membrane) with StVK.
//!
//! The test code is written once in `identity_tests!` and instantiated for the `f32` API at the
//! crate root and the `f64` API under `softfem::f64`. Tolerances are multiples of the
//! precision's `EPS` times the natural scale of the quantity, each with its reasoning.

use std::collections::HashMap;

/// The boundary faces of a set of elements with `N` corners: every face (the element minus one
/// corner) that belongs to exactly one element, with the corner it is opposite to.
fn boundary_faces<const N: usize>(elements: &[[u32; N]]) -> Vec<(Vec<u32>, u32)> {
    let mut faces: HashMap<Vec<u32>, (usize, Vec<u32>, u32)> = HashMap::new();
    for element in elements {
        for skip in 0..N {
            let face: Vec<u32> = (0..N).filter(|&k| k != skip).map(|k| element[k]).collect();
            let mut key = face.clone();
            key.sort_unstable();
            faces.entry(key).or_insert((0, face, element[skip])).0 += 1;
        }
    }
    faces
        .into_values()
        .filter(|(count, _, _)| *count == 1)
        .map(|(_, face, opposite)| (face, opposite))
        .collect()
}

macro_rules! identity_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use super::boundary_faces;
            use crate::common::{Rng, for_each_model, material_helpers};
            use $($api)::+::element::{TetRest, TriRest, TriangleStVK, fix_orientation};
            use $($api)::+::material::{Lame, Material, NeoHookean, StVK, StableNeoHookean};
            use $($api)::+::mesh::{MembraneMesh, TetMesh, TriMesh};
            use $($api)::+::types::{Mat2, Mat3, Real, Vec2, Vec3};

            material_helpers!();

            fn random_vector(rng: &mut Rng, size: Real) -> Vec3 {
                Vec3::new(
                    uniform(rng, -size, size),
                    uniform(rng, -size, size),
                    uniform(rng, -size, size),
                )
            }

            fn random_rotation(rng: &mut Rng) -> Mat3 {
                let axis = (random_vector(rng, 1.0) + Vec3::new(0.0, 0.0, 2.0)).normalize();
                Mat3::from_axis_angle(axis, uniform(rng, 0.0, 6.0))
            }

            /// An `n`x`n`x`n` box of cubes of edge `h`, each split into 6 tetrahedra around its
            /// (0,0,0)-(1,1,1) diagonal (a conforming split, since every cube uses the same
            /// diagonal direction), oriented with `fix_orientation`.
            fn cube_box(n: u32, h: Real) -> (Vec<Vec3>, Vec<[u32; 4]>) {
                let m = n + 1;
                let id = |i: u32, j: u32, k: u32| i + m * (j + m * k);
                let mut x = Vec::new();
                for k in 0..m {
                    for j in 0..m {
                        for i in 0..m {
                            x.push(Vec3::new(i as Real, j as Real, k as Real) * h);
                        }
                    }
                }
                let mut tets = Vec::new();
                for k in 0..n {
                    for j in 0..n {
                        for i in 0..n {
                            let c = [
                                id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k),
                                id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1),
                                id(i, j + 1, k + 1),
                            ];
                            for t in [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6],
                                [0, 4, 5, 6], [0, 5, 1, 6]]
                            {
                                let tet = t.map(|a: usize| c[a]);
                                tets.push(fix_orientation(tet, tet.map(|v| x[v as usize])));
                            }
                        }
                    }
                }
                (x, tets)
            }

            /// The unit cube in 5 tetrahedra (4 corners and a central one): 5 is not a multiple
            /// of the SVD batch width, so the principal path's tail loop runs too.
            fn five_tet_cube() -> (Vec<Vec3>, Vec<[u32; 4]>) {
                let x = vec![
                    Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0),
                    Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0),
                    Vec3::new(1.0, 1.0, 1.0), Vec3::new(0.0, 1.0, 1.0),
                ];
                let tets = [[0, 1, 3, 4], [1, 2, 3, 6], [1, 4, 5, 6], [3, 4, 6, 7], [1, 3, 4, 6]];
                let tets = tets.iter().map(|&t| fix_orientation(t, t.map(|v| x[v as usize])));
                (x.clone(), tets.collect())
            }

            fn meshes() -> [(Vec<Vec3>, Vec<[u32; 4]>, Real); 2] {
                let (x, t) = five_tet_cube();
                let (bx, bt) = cube_box(2, 0.5);
                [(x, t, 1.0), (bx, bt, 0.5)]
            }

            /// Runs `check(mesh, x0, tets, h)` on each of [`meshes`], validated.
            fn for_each_mesh(mut check: impl FnMut(&TetMesh<'_>, &[Vec3], &[[u32; 4]], Real)) {
                for (x0, tets, h) in meshes() {
                    let mut rest = vec![TetRest::default(); tets.len()];
                    let mesh = TetMesh::new(&x0, &tets, &mut rest).unwrap();
                    check(&mesh, &x0, &tets, h);
                }
            }

            fn forces_of<M: Material>(
                mesh: &TetMesh, model: &M, x: &[Vec3],
            ) -> Vec<Vec3> {
                let mut forces = vec![Vec3::ZERO; x.len()];
                mesh.add_elastic_forces(model, x, &mut forces).unwrap();
                forces
            }

            // ---- Rigid motion ---------------------------------------------------------------

            fn rigid_motion_is_free<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng(7);
                for_each_mesh(|mesh, x0, _, h| {
                    assert_eq!(forces_of(mesh, &model, &x0), vec![Vec3::ZERO; x0.len()]);
                    assert_eq!(mesh.elastic_energy(&model, &x0).unwrap(), 0.0);
                    for _ in 0..10 {
                        let (r, t) = (random_rotation(&mut rng), random_vector(&mut rng, 3.0));
                        let x: Vec<Vec3> = x0.iter().map(|&p| r * p + t).collect();
                        // F = R to a few eps (the translation, up to 3 box sizes, costs a few
                        // eps of |t| / h each); P(R) is then a few dozen eps of the modulus
                        // (amplified up to lambda/mu), and a vertex sums up to ~20 elements'
                        // forces of size |P| h^2.
                        let tol = 4096.0 * EPS * modulus(lame) * h * h;
                        for f in forces_of(mesh, &model, &x) {
                            assert!(f.length() <= tol, "{model:?}: |f| = {:e}", f.length());
                        }
                        // W is quadratic in the strain error: far below the rounding of P.
                        let energy = mesh.elastic_energy(&model, &x).unwrap();
                        assert!(energy.abs() <= tol * h, "{model:?}: E = {energy:e}");
                    }
                });
            }

            #[test]
            fn rest_and_rigid_motion_give_zero_force_and_energy() {
                for_each_model!(rigid_motion_is_free);
            }

            // ---- Balance, torque, rotation invariance ---------------------------------------

            fn forces_balance<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng(11);
                for_each_mesh(|mesh, x0, tets, h| {
                    for _ in 0..5 {
                        // Random non-affine deformation, element stretches within ~[0.6, 1.5].
                        let g = random_rotation(&mut rng);
                        let x: Vec<Vec3> = x0
                            .iter()
                            .map(|&p| g * p + random_vector(&mut rng, 0.15 * h))
                            .collect();
                        let forces = forces_of(mesh, &model, &x);
                        // Per vertex forces of size ~modulus h^2; sums of a few dozen of them,
                        // each with a relative error of a few hundred eps (as in
                        // rigid_motion_is_free).
                        let tol = 4096.0 * EPS * modulus(lame) * h * h;
                        let net: Vec3 = forces.iter().sum();
                        let torque: Vec3 = x.iter().zip(&forces).map(|(p, f)| p.cross(*f)).sum();
                        assert!(net.length() <= tol, "{model:?}: net {net:?}");
                        assert!(torque.length() <= tol * 2.0, "{model:?}: torque {torque:?}");
                        // Per element, with the element-level API.
                        for (tet, rest) in tets.iter().zip(mesh.rest()) {
                            let xs = tet.map(|i| x[i as usize]);
                            let fs = rest.elastic_forces(&model, xs);
                            let net: Vec3 = fs.iter().sum();
                            let torque: Vec3 = xs.iter().zip(&fs).map(|(p, f)| p.cross(*f)).sum();
                            assert!(net.length() <= tol / 8.0, "{model:?}: net {net:?}");
                            assert!(torque.length() <= tol / 4.0, "{model:?}: {torque:?}");
                            // Rotation invariance: rotating the deformed element rotates its
                            // forces, f(Q x) = Q f(x) (from P(QF) = Q P(F)).
                            let q = random_rotation(&mut rng);
                            let rotated = rest.elastic_forces(&model, xs.map(|p| q * p));
                            for (fr, f) in rotated.iter().zip(&fs) {
                                assert!((*fr - q * *f).length() <= tol / 8.0, "{model:?}");
                            }
                        }
                    }
                });
            }

            #[test]
            fn forces_sum_to_zero_with_zero_torque_and_rotate_with_the_body() {
                for_each_model!(forces_balance);
            }

            // ---- Direct and principal paths -------------------------------------------------

            fn paths_agree<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng(13);
                for_each_mesh(|mesh, x0, _, h| {
                    let g = random_rotation(&mut rng) * Mat3::from_diagonal(Vec3::new(1.2, 0.9, 1.05));
                    let x: Vec<Vec3> =
                        x0.iter().map(|&p| g * p + random_vector(&mut rng, 0.1 * h)).collect();
                    let direct = forces_of(mesh, &model, &x);
                    let mut principal = vec![Vec3::ZERO; x.len()];
                    mesh.add_elastic_forces_principal(&model, &x, &mut principal).unwrap();
                    // Stretches here stay above 0.5, so a clamp at 0.1 changes nothing.
                    let mut clamped = vec![Vec3::ZERO; x.len()];
                    mesh.add_elastic_forces_clamped(&model, 0.1, &x, &mut clamped).unwrap();
                    assert_eq!(principal, clamped, "{model:?}");
                    // P agrees to 256 eps of the modulus per element (tests/kernels/material.rs); a
                    // vertex sums up to ~20 elements' forces of size |P| h^2.
                    let tol = 4096.0 * EPS * modulus(lame) * h * h;
                    for (a, b) in direct.iter().zip(&principal) {
                        assert!((*a - *b).length() <= tol, "{model:?}: {a:?} vs {b:?}");
                    }
                });
            }

            #[test]
            fn direct_and_principal_paths_give_the_same_forces() {
                for_each_model!(paths_agree);
            }

            // ---- Homogeneous deformations ---------------------------------------------------

            /// Closed forms of a model (`docs/math.md` section 2) written out by hand for diagonal
            /// `F = diag(s)` (where `P` is diagonal too) and for simple shear.
            trait ClosedForm: Material {
                /// The diagonal of `P(diag(s))`.
                fn diagonal_stress(&self, s: Vec3) -> Vec3;
                /// `W(diag(s))`.
                fn diagonal_energy(&self, s: Vec3) -> Real;
                /// `P` and `W` at `F = I + gamma e_x e_y^T`.
                fn shear(&self, gamma: Real) -> (Mat3, Real);
            }

            impl ClosedForm for StVK {
                fn diagonal_stress(&self, s: Vec3) -> Vec3 {
                    // G = diag(g), S = 2 mu G + lambda tr(G) I, P = F S.
                    let g = (s * s - Vec3::ONE) * 0.5;
                    s * (g * (2.0 * self.mu()) + Vec3::splat(self.lambda() * g.element_sum()))
                }
                fn diagonal_energy(&self, s: Vec3) -> Real {
                    let g = (s * s - Vec3::ONE) * 0.5;
                    0.5 * self.lambda() * g.element_sum().powi(2) + self.mu() * g.length_squared()
                }
                fn shear(&self, gamma: Real) -> (Mat3, Real) {
                    // F^T F = [[1, g, 0], [g, 1 + g^2, 0], [0, 0, 1]]: G has G_xy = g/2,
                    // G_yy = g^2/2, tr G = g^2/2. S = 2 mu G + lambda g^2/2 I, and P = F S
                    // adds g times row y of S to row x.
                    let (l, mu, g) = (self.lambda(), self.mu(), gamma);
                    let (sxx, sxy, syy) = (l * g * g / 2.0, mu * g, mu * g * g + l * g * g / 2.0);
                    let p = Mat3::from_cols(
                        Vec3::new(sxx + g * sxy, sxy, 0.0),
                        Vec3::new(sxy + g * syy, syy, 0.0),
                        Vec3::new(0.0, 0.0, sxx),
                    );
                    let w = l * g.powi(4) / 8.0 + mu * (g * g / 2.0 + g.powi(4) / 4.0);
                    (p, w)
                }
            }

            impl ClosedForm for NeoHookean {
                fn diagonal_stress(&self, s: Vec3) -> Vec3 {
                    let (mu, k) = (self.mu(), self.lame().bulk_modulus());
                    let (j, ic) = (s.x * s.y * s.z, s.length_squared());
                    let p = Vec3::new(s.y * s.z, s.z * s.x, s.x * s.y);
                    s * (mu * j.powf(-2.0 / 3.0))
                        + p * (-(mu / 3.0) * j.powf(-5.0 / 3.0) * ic + k * (j - 1.0))
                }
                fn diagonal_energy(&self, s: Vec3) -> Real {
                    let (mu, k) = (self.mu(), self.lame().bulk_modulus());
                    let (j, ic) = (s.x * s.y * s.z, s.length_squared());
                    mu / 2.0 * (j.powf(-2.0 / 3.0) * ic - 3.0) + k / 2.0 * (j - 1.0).powi(2)
                }
                fn shear(&self, gamma: Real) -> (Mat3, Real) {
                    // J = 1, I_C = 3 + g^2, cof F = F^-T = I - g e_y e_x^T.
                    let mu = self.mu();
                    let ic = 3.0 + gamma * gamma;
                    let f = Mat3::from_cols(Vec3::X, Vec3::new(gamma, 1.0, 0.0), Vec3::Z);
                    let cof = Mat3::from_cols(Vec3::new(1.0, -gamma, 0.0), Vec3::Y, Vec3::Z);
                    (f * mu - cof * (mu / 3.0 * ic), mu / 2.0 * gamma * gamma)
                }
            }

            impl ClosedForm for StableNeoHookean {
                fn diagonal_stress(&self, s: Vec3) -> Vec3 {
                    let (m, l, a) = snh_constants(self);
                    let (j, ic) = (s.x * s.y * s.z, s.length_squared());
                    let p = Vec3::new(s.y * s.z, s.z * s.x, s.x * s.y);
                    s * (m * (1.0 - 1.0 / (ic + 1.0))) + p * (l * (j - a))
                }
                fn diagonal_energy(&self, s: Vec3) -> Real {
                    let (m, l, a) = snh_constants(self);
                    let (j, ic) = (s.x * s.y * s.z, s.length_squared());
                    // Minus W(I) = l/2 (1-a)^2 - m/2 ln 4.
                    m / 2.0 * (ic - 3.0) + l / 2.0 * ((j - a).powi(2) - (1.0 - a).powi(2))
                        - m / 2.0 * ((ic + 1.0) / 4.0).ln()
                }
                fn shear(&self, gamma: Real) -> (Mat3, Real) {
                    // J = 1, I_C = 3 + g^2, cof F = I - g e_y e_x^T.
                    let (m, l, a) = snh_constants(self);
                    let ic = 3.0 + gamma * gamma;
                    let f = Mat3::from_cols(Vec3::X, Vec3::new(gamma, 1.0, 0.0), Vec3::Z);
                    let cof = Mat3::from_cols(Vec3::new(1.0, -gamma, 0.0), Vec3::Y, Vec3::Z);
                    let p = f * (m * (1.0 - 1.0 / (ic + 1.0))) + cof * (l * (1.0 - a));
                    (p, m / 2.0 * gamma * gamma - m / 2.0 * ((ic + 1.0) / 4.0).ln())
                }
            }

            /// `(m, l, a) = (4 mu / 3, lambda + 5 mu / 6, 1 + 3 m / (4 l))`.
            fn snh_constants(model: &StableNeoHookean) -> (Real, Real, Real) {
                let m = 4.0 * model.mu() / 3.0;
                let l = model.lambda() + 5.0 * model.mu() / 6.0;
                (m, l, 1.0 + 3.0 * m / (4.0 * l))
            }

            /// The lateral stretch `b` of uniaxial stress at axial stretch `a`: the root of
            /// `P_yy(diag(a, b, b)) = 0`, so that the lateral faces carry no traction. For StVK
            /// this is `g_b = -lambda g_a / (2 (lambda + mu))` (from
            /// `S_yy = 2 mu g_b + lambda (g_a + 2 g_b) = 0`); for the neo-Hookean models it has
            /// no simple closed form, so bisection on the closed-form `P_yy` (increasing in `b`)
            /// finds it to rounding.
            fn lateral_stretch<M: ClosedForm>(model: &M, a: Real) -> Real {
                let (mut lo, mut hi): (Real, Real) = (0.5, 1.5);
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if model.diagonal_stress(Vec3::new(a, mid, mid)).y > 0.0 {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                0.5 * (lo + hi)
            }

            /// Applies `x = F X` to the 2x2x2 box and checks: every per-element stress equals
            /// `p`, every vertex force equals minus the traction `P N A / 3` of the boundary
            /// faces around it (so interior vertices are in equilibrium), and the energy is
            /// `V W`.
            fn check_homogeneous<M: Material>(lame: Lame, model: &M, f: Mat3, p: Mat3, w: Real) {
                let h = 0.5;
                let (x0, tets) = cube_box(2, h);
                let mut rest = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&x0, &tets, &mut rest).unwrap();
                let x: Vec<Vec3> = x0.iter().map(|&p| f * p).collect();

                // The closed forms evaluate the same O(modulus) terms as the kernels in a
                // different order, with F from rounded positions: 256 eps of the modulus as
                // in tests/kernels/material.rs.
                let stress_tol = 256.0 * EPS * modulus(lame);
                let mut stresses = vec![Mat3::ZERO; tets.len()];
                mesh.element_stresses(model, &x, &mut stresses).unwrap();
                for s in &stresses {
                    assert!(norm(*s - p) <= stress_tol, "{model:?}: {s:?} vs {p:?}");
                }

                // Expected elastic force at vertex i: -sum over boundary faces (a, b, c) at i
                // of P (area-weighted outward normal) / 3. Interior faces cancel in pairs.
                let mut expected = vec![Vec3::ZERO; x0.len()];
                for (face, opposite) in boundary_faces(&tets) {
                    let [a, b, c] = [face[0], face[1], face[2]].map(|i| x0[i as usize]);
                    let mut normal = (b - a).cross(c - a) * 0.5;
                    if normal.dot(x0[opposite as usize] - a) > 0.0 {
                        normal = -normal;
                    }
                    for &i in &face {
                        expected[i as usize] -= p * normal / 3.0;
                    }
                }
                let forces = forces_of(&mesh, model, &x);
                // Up to ~20 elements' forces, each |P| h^2 with the stress tolerance above.
                let force_tol = 32.0 * stress_tol * h * h;
                for (i, (got, want)) in forces.iter().zip(&expected).enumerate() {
                    assert!((*got - *want).length() <= force_tol, "{model:?} v{i}: {got:?} vs {want:?}");
                }
                let interior = 1 + 3 * (1 + 3 * 1); // the vertex (1, 1, 1) h
                assert!(forces[interior].length() <= force_tol);

                // Total energy: V W with V = 1.
                let total_volume = mesh.rest_volume();
                assert!((total_volume - 1.0).abs() <= 16.0 * EPS);
                let energy = mesh.elastic_energy(model, &x).unwrap();
                let mut energies = vec![0.0; tets.len()];
                mesh.element_energies(model, &x, &mut energies).unwrap();
                let energy_tol = 256.0 * EPS * modulus(lame);
                assert!((energy - w).abs() <= energy_tol, "{model:?}: E = {energy} vs {w}");
                assert!((energies.iter().sum::<Real>() - w).abs() <= energy_tol);
            }

            fn homogeneous<M: ClosedForm>(lame: Lame, model: M) {
                // Uniaxial stress: stretch a along x, lateral stretch b with P_yy = P_zz = 0.
                for a in [1.15, 0.9] {
                    let b = lateral_stretch(&model, a);
                    let s = Vec3::new(a, b, b);
                    let p = Mat3::from_diagonal(model.diagonal_stress(s));
                    assert!(p.y_axis.y.abs() <= 64.0 * EPS * modulus(lame));
                    let p = Mat3::from_diagonal(Vec3::new(p.x_axis.x, 0.0, 0.0));
                    check_homogeneous(lame, &model, Mat3::from_diagonal(s), p, model.diagonal_energy(s));
                }
                // Volumetric: F = s I, P = p I.
                for s in [1.1, 0.92] {
                    let s = Vec3::splat(s);
                    let p = Mat3::from_diagonal(model.diagonal_stress(s));
                    check_homogeneous(lame, &model, Mat3::from_diagonal(s), p, model.diagonal_energy(s));
                }
                // Simple shear: F = I + gamma e_x e_y^T.
                let gamma = 0.3;
                let (p, w) = model.shear(gamma);
                let f = Mat3::from_cols(Vec3::X, Vec3::new(gamma, 1.0, 0.0), Vec3::Z);
                check_homogeneous(lame, &model, f, p, w);
            }

            #[test]
            fn homogeneous_deformations_match_closed_forms() {
                for_each_model!(homogeneous);
            }

            // ---- Triangles ------------------------------------------------------------------

            fn triangle_models() -> Vec<(Lame, TriangleStVK)> {
                parameter_sets()
                    .into_iter()
                    .map(|lame| (lame, TriangleStVK::new(&StVK::new(lame))))
                    .collect()
            }

            /// An `n`x`n` grid of squares of edge `h`, each split into two counter-clockwise
            /// triangles.
            fn square_grid(n: u32, h: Real) -> (Vec<Vec2>, Vec<[u32; 3]>) {
                let m = n + 1;
                let x = (0..m * m).map(|v| Vec2::new((v % m) as Real, (v / m) as Real) * h);
                let mut tris = Vec::new();
                for j in 0..n {
                    for i in 0..n {
                        let c = [i + m * j, i + 1 + m * j, i + 1 + m * (j + 1), i + m * (j + 1)];
                        tris.push([c[0], c[1], c[2]]);
                        tris.push([c[0], c[2], c[3]]);
                    }
                }
                (x.collect(), tris)
            }

            fn rotation_2d(angle: Real) -> Mat2 {
                Mat2::from_angle(angle)
            }

            /// The membrane embedding of a 2D grid: `(x, y) -> Q (x, y, 0)`.
            fn embed(q: Mat3, x: &[Vec2]) -> Vec<Vec3> {
                x.iter().map(|p| q * p.extend(0.0)).collect()
            }

            #[test]
            fn triangles_rest_and_rigid_motion_give_zero_force_and_energy() {
                let mut rng = Rng(17);
                let (x0, tris) = square_grid(3, 0.5);
                let mut rest = vec![TriRest::default(); tris.len()];
                let mesh = TriMesh::new(&x0, &tris, &mut rest).unwrap();
                let q = random_rotation(&mut rng);
                let m0 = embed(q, &x0);
                let mut membrane_rest = vec![TriRest::default(); tris.len()];
                let membrane = MembraneMesh::new(&m0, &tris, &mut membrane_rest).unwrap();
                for (lame, model) in triangle_models() {
                    // As for tetrahedra: F = R to a few eps, forces of size modulus h (per unit
                    // thickness) summed over ~6 triangles.
                    let tol = 1024.0 * EPS * modulus(lame) * 0.5;
                    for _ in 0..5 {
                        let r = rotation_2d(uniform(&mut rng, 0.0, 6.0));
                        let t = Vec2::new(uniform(&mut rng, -2.0, 2.0), 1.0);
                        let x: Vec<Vec2> = x0.iter().map(|&p| r * p + t).collect();
                        let mut forces = vec![Vec2::ZERO; x.len()];
                        mesh.add_elastic_forces(&model, &x, &mut forces).unwrap();
                        assert!(forces.iter().all(|f| f.length() <= tol), "{forces:?}");
                        assert!(mesh.elastic_energy(&model, &x).unwrap().abs() <= tol);

                        // A membrane can also rotate out of its plane.
                        let (r3, t3) = (random_rotation(&mut rng), random_vector(&mut rng, 2.0));
                        let x: Vec<Vec3> = m0.iter().map(|&p| r3 * p + t3).collect();
                        let mut forces = vec![Vec3::ZERO; x.len()];
                        membrane.add_elastic_forces(&model, &x, &mut forces).unwrap();
                        assert!(forces.iter().all(|f| f.length() <= tol), "{forces:?}");
                        assert!(membrane.elastic_energy(&model, &x).unwrap().abs() <= tol);
                    }
                }
            }

            #[test]
            fn triangle_forces_balance_and_exert_no_torque() {
                let mut rng = Rng(19);
                let (x0, tris) = square_grid(3, 0.5);
                let mut rest = vec![TriRest::default(); tris.len()];
                let mesh = TriMesh::new(&x0, &tris, &mut rest).unwrap();
                let q = random_rotation(&mut rng);
                let mut membrane_rest = vec![TriRest::default(); tris.len()];
                let membrane = MembraneMesh::new(&embed(q, &x0), &tris, &mut membrane_rest).unwrap();
                for (lame, model) in triangle_models() {
                    let tol = 1024.0 * EPS * modulus(lame) * 0.5;
                    let x: Vec<Vec2> = x0
                        .iter()
                        .map(|&p| rotation_2d(0.7) * p * 1.1 + Vec2::new(uniform(&mut rng, -0.1, 0.1), uniform(&mut rng, -0.1, 0.1)))
                        .collect();
                    let mut forces = vec![Vec2::ZERO; x.len()];
                    mesh.add_elastic_forces(&model, &x, &mut forces).unwrap();
                    let net: Vec2 = forces.iter().sum();
                    let torque: Real = x.iter().zip(&forces).map(|(p, f)| p.perp_dot(*f)).sum();
                    assert!(net.length() <= tol && torque.abs() <= 2.0 * tol, "{net:?} {torque}");

                    let x: Vec<Vec3> = x0
                        .iter()
                        .map(|p| q * p.extend(0.0) * 1.1 + random_vector(&mut rng, 0.1))
                        .collect();
                    let mut forces = vec![Vec3::ZERO; x.len()];
                    membrane.add_elastic_forces(&model, &x, &mut forces).unwrap();
                    let net: Vec3 = forces.iter().sum();
                    let torque: Vec3 = x.iter().zip(&forces).map(|(p, f)| p.cross(*f)).sum();
                    assert!(net.length() <= tol && torque.length() <= 4.0 * tol, "{net:?} {torque:?}");
                }
            }

            /// Plane strain StVK closed forms: `(P, W)` for `F = diag(a, b)` and for simple
            /// shear `F = [[1, g], [0, 1]]`.
            fn triangle_closed_form(lame: Lame, f: Mat2, shear: bool) -> (Mat2, Real) {
                let (l, mu) = (lame.lambda(), lame.mu());
                if shear {
                    // G = [[0, g/2], [g/2, g^2/2]], tr G = g^2/2, S = 2 mu G + lambda tr G I.
                    let g = f.y_axis.x;
                    let (s00, s01, s11) = (l * g * g / 2.0, mu * g, mu * g * g + l * g * g / 2.0);
                    let p = Mat2::from_cols(Vec2::new(s00 + g * s01, s01), Vec2::new(s01 + g * s11, s11));
                    (p, l * g.powi(4) / 8.0 + mu * (g * g / 2.0 + g.powi(4) / 4.0))
                } else {
                    let s = Vec2::new(f.x_axis.x, f.y_axis.y);
                    let g = (s * s - Vec2::ONE) * 0.5;
                    let p = s * (g * (2.0 * mu) + Vec2::splat(l * g.element_sum()));
                    (Mat2::from_diagonal(p), 0.5 * l * g.element_sum().powi(2) + mu * g.length_squared())
                }
            }

            #[test]
            fn triangle_homogeneous_deformations_match_closed_forms() {
                let mut rng = Rng(23);
                let (x0, tris) = square_grid(2, 0.5);
                let mut rest = vec![TriRest::default(); tris.len()];
                let mesh = TriMesh::new(&x0, &tris, &mut rest).unwrap();
                let q = random_rotation(&mut rng);
                let mut membrane_rest = vec![TriRest::default(); tris.len()];
                let membrane = MembraneMesh::new(&embed(q, &x0), &tris, &mut membrane_rest).unwrap();
                for (lame, model) in triangle_models() {
                    let (l, mu) = (lame.lambda(), lame.mu());
                    // Uniaxial stress in plane strain: S_yy = 2 mu g_b + lambda (g_a + g_b) = 0
                    // gives g_b = -lambda g_a / (lambda + 2 mu), i.e. b^2 = 1 + 2 g_b.
                    let a: Real = 1.15;
                    let g_b = -l * (a * a - 1.0) / 2.0 / (l + 2.0 * mu);
                    let uniaxial = Mat2::from_diagonal(Vec2::new(a, (1.0 + 2.0 * g_b).sqrt()));
                    let shear = Mat2::from_cols(Vec2::X, Vec2::new(0.3, 1.0));
                    let volumetric = Mat2::from_diagonal(Vec2::splat(0.9));
                    for (f, is_shear) in [(uniaxial, false), (shear, true), (volumetric, false)] {
                        let (p, w) = triangle_closed_form(lame, f, is_shear);
                        let stress_tol = 256.0 * EPS * modulus(lame);
                        // Every element's F is f, and its stress the closed form.
                        for (tri, rest) in tris.iter().zip(mesh.rest()) {
                            let corners = tri.map(|i| f * x0[i as usize]);
                            let got = model.first_piola(rest.deformation_gradient(corners));
                            assert!(got.abs_diff_eq(p, stress_tol), "{got:?} vs {p:?}");
                        }
                        if f == uniaxial {
                            assert!(p.y_axis.y.abs() <= stress_tol); // free lateral edges
                        }
                        // Expected force at vertex i: -sum over boundary edges (a, b) at i of
                        // P (length-weighted outward normal) / 2.
                        let mut expected = vec![Vec2::ZERO; x0.len()];
                        for (edge, opposite) in boundary_faces(&tris) {
                            let (a, b) = (x0[edge[0] as usize], x0[edge[1] as usize]);
                            let mut normal = (b - a).perp();
                            if normal.dot(x0[opposite as usize] - a) > 0.0 {
                                normal = -normal;
                            }
                            for &i in &edge {
                                expected[i as usize] -= p * normal / 2.0;
                            }
                        }
                        let x: Vec<Vec2> = x0.iter().map(|&p| f * p).collect();
                        let mut forces = vec![Vec2::ZERO; x.len()];
                        mesh.add_elastic_forces(&model, &x, &mut forces).unwrap();
                        let force_tol = 16.0 * stress_tol * 0.5;
                        for (got, want) in forces.iter().zip(&expected) {
                            assert!((*got - *want).length() <= force_tol, "{got:?} vs {want:?}");
                        }
                        assert!(forces[4].length() <= force_tol); // the centre vertex
                        let energy = mesh.elastic_energy(&model, &x).unwrap();
                        assert!((energy - w).abs() <= stress_tol, "{energy} vs {w}");

                        // The same sheet as a membrane, rotated into space by q and deformed in
                        // its plane: forces are the 2D forces rotated, energy the same.
                        let xm: Vec<Vec3> = embed(q, &x);
                        let mut mforces = vec![Vec3::ZERO; x.len()];
                        membrane.add_elastic_forces(&model, &xm, &mut mforces).unwrap();
                        for (got, want) in mforces.iter().zip(&expected) {
                            assert!((*got - q * want.extend(0.0)).length() <= force_tol);
                        }
                        let energy = membrane.elastic_energy(&model, &xm).unwrap();
                        assert!((energy - w).abs() <= stress_tol, "{energy} vs {w}");
                    }
                }
            }

            #[test]
            fn lumped_masses_distribute_the_total_mass() {
                for_each_mesh(|mesh, x0, tets, _| {
                    let mut masses = vec![-1.0; x0.len()];
                    mesh.lumped_masses(1000.0, &mut masses).unwrap();
                    // The boxes have volume 1: the total is rho exactly up to rounding.
                    let total: Real = masses.iter().sum();
                    assert!((total - 1000.0).abs() <= 64.0 * EPS * 1000.0);
                    // Each vertex gets rho/4 of the volume of the tets around it.
                    let mut volume_around = vec![0.0; x0.len()];
                    for (t, r) in tets.iter().zip(mesh.rest()) {
                        for &i in t {
                            volume_around[i as usize] += r.volume;
                        }
                    }
                    for (m, v) in masses.iter().zip(&volume_around) {
                        assert!((m - 250.0 * v).abs() <= 64.0 * EPS * 1000.0);
                    }
                });
                let (x0, tris) = square_grid(2, 0.5);
                let mut rest = vec![TriRest::default(); tris.len()];
                let mesh = TriMesh::new(&x0, &tris, &mut rest).unwrap();
                let mut masses = vec![0.0; x0.len()];
                mesh.lumped_masses(3.0, &mut masses).unwrap();
                assert!((masses.iter().sum::<Real>() - 3.0).abs() <= 16.0 * EPS);
                // The centre vertex touches 6 triangles of area 1/8 (the grid's diagonals
                // meet there in the (0,0)-(1,1) direction): 3 * 6/8 / 3.
                assert!((masses[4] - 0.75).abs() <= 16.0 * EPS);
            }
        }
    };
}

identity_tests!(single, softfem);
identity_tests!(double, softfem::f64);

/// Forces are minus the gradient of the energy, in f64 (`docs/math.md` section 5), for every model
/// on tetrahedra and StVK on 2D triangles and membranes.
///
/// Central differences with step `d = 1e-6` (box size 1) have a truncation error of order
/// `d^2 |E'''| ~ 1e-12` and a rounding error of order `eps |E| / d ~ 1e-10`, both relative to the
/// force scale `modulus * h^2`; the tolerance `sqrt(eps) ~ 1.5e-8` of that scale sits well above
/// both and far below any error a wrong formula would make.
mod gradient {
    use crate::common::Rng;
    use softfem::f64::element::{TetRest, TriRest, TriangleStVK, fix_orientation};
    use softfem::f64::material::{Lame, Material, NeoHookean, StVK, StableNeoHookean};
    use softfem::f64::mesh::{MembraneMesh, TetMesh, TriMesh};
    use softfem::f64::types::{Vec2, Vec3};

    const STEP: f64 = 1e-6;

    fn tolerance(lame: Lame) -> f64 {
        f64::EPSILON.sqrt() * (lame.lambda() + 2.0 * lame.mu())
    }

    /// `-dE/dx` by central differences, one coordinate at a time, for positions with `D`
    /// coordinates stored as arrays.
    fn minus_gradient<const D: usize>(
        x: &[[f64; D]],
        energy: impl Fn(&[[f64; D]]) -> f64,
    ) -> Vec<[f64; D]> {
        let mut out = vec![[0.0; D]; x.len()];
        let mut probe = x.to_vec();
        for (i, slot) in out.iter_mut().enumerate() {
            for d in 0..D {
                let original = probe[i][d];
                probe[i][d] = original + STEP;
                let plus = energy(&probe);
                probe[i][d] = original - STEP;
                let minus = energy(&probe);
                probe[i][d] = original;
                slot[d] = -(plus - minus) / (2.0 * STEP);
            }
        }
        out
    }

    /// `x0` scaled by 1.1 and moved by up to 0.15 per coordinate: a general deformation with
    /// stretches well clear of inversion.
    fn deformed<const D: usize>(rng: &mut Rng, x0: &[[f64; D]]) -> Vec<[f64; D]> {
        x0.iter()
            .map(|p| core::array::from_fn(|d| p[d] * 1.1 + rng.uniform(-0.15, 0.15)))
            .collect()
    }

    /// Asserts that `forces(x)` is `-dE/dx` for `E = energy(x)`, to [`tolerance`]; `V` is the
    /// position type of the mesh, `D` its number of coordinates.
    fn assert_forces_are_minus_gradient<V, const D: usize>(
        what: &str,
        lame: Lame,
        x: &[[f64; D]],
        energy: impl Fn(&[V]) -> f64,
        forces: impl Fn(&[V]) -> Vec<V>,
    ) where
        V: Copy + From<[f64; D]> + Into<[f64; D]>,
    {
        let vectors = |x: &[[f64; D]]| -> Vec<V> { x.iter().map(|&p| V::from(p)).collect() };
        let expected = minus_gradient(x, |x| energy(&vectors(x)));
        for (f, e) in forces(&vectors(x)).into_iter().zip(&expected) {
            let f: [f64; D] = f.into();
            let error = f.iter().zip(e).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
            assert!(error.sqrt() <= tolerance(lame), "{what}: {f:?} vs {e:?}");
        }
    }

    fn check_tets<M: Material>(lame: Lame, model: M) {
        let mut rng = Rng(29);
        let corners = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ];
        let x0 = corners.map(Vec3::from_array);
        let tets = [
            [0, 1, 3, 4],
            [1, 2, 3, 6],
            [1, 4, 5, 6],
            [3, 4, 6, 7],
            [1, 3, 4, 6],
        ]
        .map(|t: [u32; 4]| fix_orientation(t, t.map(|v| x0[v as usize])));
        let mut rest = [TetRest::default(); 5];
        let mesh = TetMesh::new(&x0, &tets, &mut rest).unwrap();
        assert_forces_are_minus_gradient(
            &format!("{model:?}"),
            lame,
            &deformed(&mut rng, &corners),
            |x: &[Vec3]| mesh.elastic_energy(&model, x).unwrap(),
            |x| {
                let mut forces = vec![Vec3::ZERO; x.len()];
                mesh.add_elastic_forces(&model, x, &mut forces).unwrap();
                forces
            },
        );
    }

    #[test]
    fn tet_forces_are_minus_the_energy_gradient() {
        for lame in [
            Lame::from_young_poisson(1.0e5, 0.3).unwrap(),
            Lame::from_young_poisson(1.0e6, 0.45).unwrap(),
            Lame::from_young_poisson(2.0e3, -0.3).unwrap(),
        ] {
            check_tets(lame, StVK::new(lame));
            check_tets(lame, NeoHookean::new(lame));
            check_tets(lame, StableNeoHookean::new(lame));
        }
    }

    #[test]
    fn triangle_forces_are_minus_the_energy_gradient() {
        let mut rng = Rng(31);
        let lame = Lame::from_young_poisson(1.0e6, 0.45).unwrap();
        let model = TriangleStVK::new(&StVK::new(lame));
        let corners = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let x0 = corners.map(Vec2::from_array);
        let tris = [[0, 1, 2], [0, 2, 3]];
        let mut rest = [TriRest::default(); 2];
        let mesh = TriMesh::new(&x0, &tris, &mut rest).unwrap();
        assert_forces_are_minus_gradient(
            "triangles",
            lame,
            &deformed(&mut rng, &corners),
            |x: &[Vec2]| mesh.elastic_energy(&model, x).unwrap(),
            |x| {
                let mut forces = vec![Vec2::ZERO; 4];
                mesh.add_elastic_forces(&model, x, &mut forces).unwrap();
                forces
            },
        );

        // A membrane, tilted at rest and bent out of plane when deformed.
        let corners = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.2],
            [1.0, 1.0, 0.5],
            [0.0, 1.0, 0.1],
        ];
        let m0 = corners.map(Vec3::from_array);
        let mut membrane_rest = [TriRest::default(); 2];
        let membrane = MembraneMesh::new(&m0, &tris, &mut membrane_rest).unwrap();
        assert_forces_are_minus_gradient(
            "membrane",
            lame,
            &deformed(&mut rng, &corners),
            |x: &[Vec3]| membrane.elastic_energy(&model, x).unwrap(),
            |x| {
                let mut forces = vec![Vec3::ZERO; 4];
                membrane.add_elastic_forces(&model, x, &mut forces).unwrap();
                forces
            },
        );
    }
}
