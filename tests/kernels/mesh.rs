//! Mesh validation and kernel errors: every [`MeshError`] and [`ElementError`] variant produced
//! by a concrete bad input and naming the right element, corner or vertex; output buffers
//! unchanged after an error; NaN and infinite positions never panic. Both precisions, written
//! once in `mesh_tests!`.

macro_rules! mesh_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use $($api)::+::element::{TetRest, TriRest, TriangleStVK, fix_orientation};
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::{Material, NeoHookean, StVK, StableNeoHookean};
            use $($api)::+::step::{ElasticEnergy, TetElastic};
            use $($api)::+::mesh::{MembraneMesh, TetMesh, TetRestBlock, TriMesh, rest_block_count};
            use $($api)::+::types::{Mat3, Real, Vec2, Vec3};
            use $($api)::+::{Buffer, ElementError, MeshError};

            /// The unit cube in 5 positively oriented tetrahedra.
            const CUBE: [[Real; 3]; 8] = [
                [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0],
            ];
            const TETS: [[u32; 4]; 5] =
                [[0, 1, 3, 4], [1, 2, 3, 6], [1, 4, 5, 6], [3, 4, 6, 7], [1, 3, 4, 6]];

            fn cube() -> [Vec3; 8] {
                CUBE.map(Vec3::from_array)
            }

            fn stvk() -> StVK {
                StVK::from_young_poisson(1.0e5, 0.3).unwrap()
            }

            /// A sentinel that no kernel would write.
            const SENTINEL: Real = 12345.0;

            /// StVK through the provided, one-lane-at-a-time group methods of `Material`: what a
            /// model defined outside the crate gets.
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

            /// The mesh kernels (which evaluate elements in groups where that is faster) against a
            /// plain loop over the elements in order: forces and energies bit for bit.
            fn kernels_match_the_element_loop<M: Material>(material: M) {
                // 3 x 1 x 1 cubes in 5 tetrahedra: 15 elements, three groups of four and three
                // elements left over.
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, Vec3::new(3.0, 1.0, 1.0), (3, 1, 1), BoxSplit::Alternating5);
                let (nv, nt) = (rest.len(), tets.len());
                let mut rest_data = vec![TetRest::default(); nt];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                // A general affine map plus a different wobble per vertex; vertex 5 pushed far
                // enough to invert the elements around it.
                let x: Vec<Vec3> = rest
                    .iter()
                    .enumerate()
                    .map(|(i, p)| {
                        let k = i as Real;
                        Vec3::new(1.1 * p.x + 0.2 * p.y, 0.9 * p.y - 0.1 * p.z, 1.05 * p.z + 0.05 * p.x)
                            + Vec3::new((0.7 * k).sin(), (1.3 * k).cos(), (2.1 * k).sin()) * 0.05
                    })
                    .enumerate()
                    .map(|(i, p)| if i == 5 { p + Vec3::new(0.0, 0.0, -1.5) } else { p })
                    .collect();
                let mut expected_forces = vec![Vec3::ZERO; nv];
                // The documented order: four partial sums over the whole groups of four, then
                // the elements left over.
                let whole = nt - nt % 4;
                let (mut partial, mut last) = ([0.0; 4], 0.0);
                for (i, (tet, rest)) in tets.iter().zip(mesh.rest()).enumerate() {
                    let corners = tet.map(|i| x[i as usize]);
                    let energy = rest.elastic_energy(&material, corners);
                    if i < whole {
                        partial[i % 4] += energy;
                    } else {
                        last += energy;
                    }
                    for (&i, f) in tet.iter().zip(rest.elastic_forces(&material, corners)) {
                        expected_forces[i as usize] += f;
                    }
                }
                let expected_energy = ((partial[0] + partial[1]) + (partial[2] + partial[3])) + last;
                let bits = |v: &[Vec3]| -> Vec<[u64; 3]> {
                    v.iter().map(|p| p.to_array().map(|c| f64::from(c).to_bits())).collect()
                };
                let mut forces = vec![Vec3::ZERO; nv];
                mesh.add_elastic_forces(&material, &x, &mut forces).unwrap();
                assert_eq!(bits(&forces), bits(&expected_forces), "{material:?}");
                let mut fused = vec![Vec3::ZERO; nv];
                let energy = TetElastic::new(mesh, material).energy_and_add_forces(&x, &mut fused).unwrap();
                assert_eq!(bits(&fused), bits(&expected_forces), "{material:?}");
                assert_eq!(f64::from(energy).to_bits(), f64::from(expected_energy).to_bits(), "{material:?}");
            }

            #[test]
            fn grouped_kernels_match_the_element_loop_bit_for_bit() {
                let (e, nu) = (1.0e5, 0.3);
                kernels_match_the_element_loop(StVK::from_young_poisson(e, nu).unwrap());
                kernels_match_the_element_loop(NeoHookean::from_young_poisson(e, nu).unwrap());
                kernels_match_the_element_loop(StableNeoHookean::from_young_poisson(e, nu).unwrap());
                kernels_match_the_element_loop(OutsideModel(StVK::from_young_poisson(e, nu).unwrap()));
            }

            #[test]
            fn the_cube_is_valid() {
                let mut rest = [TetRest::default(); 5];
                let mesh = TetMesh::new(&cube(), &TETS, &mut rest).unwrap();
                assert_eq!((mesh.vertex_count(), mesh.element_count()), (8, 5));
                assert_eq!(mesh.tets(), &TETS);
                assert!((mesh.rest_volume() - 1.0).abs() < 1e-6);
                for (tet, r) in TETS.iter().zip(mesh.rest()) {
                    assert_eq!(*tet, fix_orientation(*tet, tet.map(|i| cube()[i as usize])));
                    assert!(r.volume > 0.0);
                }
            }

            /// Rest blocks: one per 16 elements or part, filled from the mesh's rest data; a
            /// buffer of another length is refused and left as it was.
            #[test]
            fn rest_blocks_take_one_block_per_sixteen_elements() {
                assert_eq!([0, 1, 16, 17, 32, 33].map(rest_block_count), [0, 1, 1, 2, 2, 3]);
                let x = cube();
                let mut rest = [TetRest::default(); 5];
                let mesh = TetMesh::new(&x, &TETS, &mut rest).unwrap();
                assert!(mesh.rest_blocks().is_empty());
                for len in [0, 2] {
                    let mut blocks = vec![TetRestBlock::ZERO; len];
                    assert_eq!(
                        mesh.with_rest_blocks(&mut blocks).unwrap_err(),
                        MeshError::LengthMismatch { buffer: Buffer::RestBlocks, expected: 1, actual: len }
                    );
                    assert!(blocks.iter().all(|b| *b == TetRestBlock::ZERO));
                }
                let mut blocks = [TetRestBlock::ZERO; 1];
                let blocked = mesh.with_rest_blocks(&mut blocks).unwrap();
                assert_eq!(blocked.rest_blocks().len(), 1);
                assert_ne!(blocked.rest_blocks()[0], TetRestBlock::ZERO);
                let message = Buffer::RestBlocks.to_string();
                assert_eq!(message, "rest blocks");
            }

            #[test]
            fn construction_errors_name_the_offender() {
                let x = cube();
                let mut rest = [TetRest::default(); 5];
                // Rest data buffer of the wrong length.
                let mut short = [TetRest::default(); 4];
                assert_eq!(
                    TetMesh::new(&x, &TETS, &mut short).unwrap_err(),
                    MeshError::LengthMismatch { buffer: Buffer::RestData, expected: 5, actual: 4 }
                );
                // Non-finite rest positions, NaN and infinite.
                for bad in [Real::NAN, Real::INFINITY, Real::NEG_INFINITY] {
                    let mut x = cube();
                    x[6].y = bad;
                    assert_eq!(
                        TetMesh::new(&x, &TETS, &mut rest).unwrap_err(),
                        MeshError::NonFiniteRestPosition { vertex: 6 }
                    );
                }
                // An index out of range.
                let mut tets = TETS;
                tets[3][2] = 8;
                assert_eq!(
                    TetMesh::new(&x, &tets, &mut rest).unwrap_err(),
                    MeshError::IndexOutOfRange { element: 3, corner: 2, index: 8, vertex_count: 8 }
                );
                // An inverted element: two corners swapped.
                let mut tets = TETS;
                tets[2].swap(0, 1);
                assert_eq!(
                    TetMesh::new(&x, &tets, &mut rest).unwrap_err(),
                    MeshError::InvertedElement { element: 2 }
                );
                assert_eq!(fix_orientation(tets[2], tets[2].map(|i| x[i as usize])), [4, 5, 1, 6]);
                // A degenerate element: four coplanar corners (the bottom face).
                let mut tets = TETS;
                tets[4] = [0, 1, 2, 3];
                assert_eq!(
                    TetMesh::new(&x, &tets, &mut rest).unwrap_err(),
                    MeshError::DegenerateElement { element: 4 }
                );
                // A sliver just below the tolerance is degenerate, a flat-ish one above is not.
                let sliver = |height: Real| {
                    TetRest::new([Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.3, 0.3, height)])
                };
                // V = height / 6, longest edge sqrt(2): V <= ratio * 2^1.5 is degenerate.
                let ratio = $($api)::+::element::DEGENERACY_RATIO;
                assert_eq!(sliver(ratio).unwrap_err(), ElementError::Degenerate);
                assert!(sliver(1e-3).is_ok());
            }

            #[test]
            fn element_errors() {
                let good = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
                assert!(TetRest::new(good).is_ok());
                assert_eq!(
                    TetRest::new([Vec3::ZERO, Vec3::Y, Vec3::X, Vec3::Z]).unwrap_err(),
                    ElementError::Inverted
                );
                assert_eq!(
                    TetRest::new([Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X]).unwrap_err(),
                    ElementError::Degenerate
                );
                assert_eq!(TetRest::new([Vec3::ZERO; 4]).unwrap_err(), ElementError::Degenerate);
                assert_eq!(
                    TetRest::new([Vec3::ZERO, Vec3::X, Vec3::NAN, Vec3::Z]).unwrap_err(),
                    ElementError::NonFiniteRestPosition
                );
                // Finite but so large that the volume overflows: not representable.
                let huge = Vec3::splat(Real::MAX / 4.0);
                assert_eq!(
                    TetRest::new([-huge, huge, huge * Vec3::new(1.0, -1.0, 1.0), Vec3::Z]).unwrap_err(),
                    ElementError::Degenerate
                );
                assert!(TriRest::new([Vec2::ZERO, Vec2::X, Vec2::Y]).is_ok());
                assert_eq!(
                    TriRest::new([Vec2::ZERO, Vec2::Y, Vec2::X]).unwrap_err(),
                    ElementError::Inverted
                );
                assert_eq!(
                    TriRest::new([Vec2::ZERO, Vec2::X, Vec2::X * 2.0]).unwrap_err(),
                    ElementError::Degenerate
                );
                assert_eq!(
                    TriRest::new([Vec2::ZERO, Vec2::X, Vec2::INFINITY]).unwrap_err(),
                    ElementError::NonFiniteRestPosition
                );
                // Membranes have no rest orientation: both windings are valid, same area.
                let a = TriRest::membrane([Vec3::ZERO, Vec3::X, Vec3::Z]).unwrap();
                let b = TriRest::membrane([Vec3::ZERO, Vec3::Z, Vec3::X]).unwrap();
                assert_eq!((a.area, b.area), (0.5, 0.5));
                assert_eq!(
                    TriRest::membrane([Vec3::ZERO, Vec3::X, Vec3::X * 3.0]).unwrap_err(),
                    ElementError::Degenerate
                );
                assert_eq!(
                    TriRest::membrane([Vec3::NAN, Vec3::X, Vec3::Z]).unwrap_err(),
                    ElementError::NonFiniteRestPosition
                );
            }

            #[test]
            fn kernel_errors_leave_outputs_unchanged() {
                let x = cube();
                let mut rest = [TetRest::default(); 5];
                let mesh = TetMesh::new(&x, &TETS, &mut rest).unwrap();
                let model = stvk();
                let mut forces = [Vec3::splat(SENTINEL); 8];
                let mut energies = [SENTINEL; 5];
                let mut stresses = [Mat3::from_diagonal(Vec3::splat(SENTINEL)); 5];
                let mut masses = [SENTINEL; 8];
                let unchanged = |f: &[Vec3], e: &[Real], s: &[Mat3], m: &[Real]| {
                    f.iter().all(|v| *v == Vec3::splat(SENTINEL))
                        && e.iter().all(|v| *v == SENTINEL)
                        && s.iter().all(|v| v.x_axis.x == SENTINEL && v.y_axis.x == 0.0)
                        && m.iter().all(|v| *v == SENTINEL)
                };
                let mismatch = |buffer, expected, actual| MeshError::LengthMismatch {
                    buffer,
                    expected,
                    actual,
                };

                // Wrong lengths.
                assert_eq!(
                    mesh.add_elastic_forces(&model, &x[..7], &mut forces).unwrap_err(),
                    mismatch(Buffer::Positions, 8, 7)
                );
                assert_eq!(
                    mesh.add_elastic_forces_principal(&model, &x, &mut forces[..3]).unwrap_err(),
                    mismatch(Buffer::Forces, 8, 3)
                );
                assert_eq!(
                    mesh.add_elastic_forces_clamped(&model, 0.3, &x, &mut forces[..0]).unwrap_err(),
                    mismatch(Buffer::Forces, 8, 0)
                );
                assert_eq!(
                    mesh.element_energies(&model, &x, &mut energies[..4]).unwrap_err(),
                    mismatch(Buffer::Energies, 5, 4)
                );
                assert_eq!(
                    mesh.element_stresses(&model, &x, &mut stresses[..1]).unwrap_err(),
                    mismatch(Buffer::Stresses, 5, 1)
                );
                assert_eq!(
                    mesh.lumped_masses(1.0, &mut masses[..7]).unwrap_err(),
                    mismatch(Buffer::Masses, 8, 7)
                );
                assert_eq!(mesh.elastic_energy(&model, &[]).unwrap_err(), mismatch(Buffer::Positions, 8, 0));

                // Non-finite positions: the first bad vertex is named and nothing is written.
                for bad in [Real::NAN, Real::INFINITY, Real::NEG_INFINITY] {
                    let mut y = x;
                    y[5].z = bad;
                    y[7].x = bad;
                    let error = MeshError::NonFinitePosition { vertex: 5 };
                    assert_eq!(mesh.add_elastic_forces(&model, &y, &mut forces).unwrap_err(), error);
                    assert_eq!(mesh.add_elastic_forces_principal(&model, &y, &mut forces).unwrap_err(), error);
                    assert_eq!(mesh.add_elastic_forces_clamped(&model, 0.3, &y, &mut forces).unwrap_err(), error);
                    assert_eq!(mesh.elastic_energy(&model, &y).unwrap_err(), error);
                    assert_eq!(mesh.element_energies(&model, &y, &mut energies).unwrap_err(), error);
                    assert_eq!(mesh.element_stresses(&model, &y, &mut stresses).unwrap_err(), error);
                }

                // Bad densities.
                for density in [0.0, -1.0, Real::NAN, Real::INFINITY] {
                    assert_eq!(mesh.lumped_masses(density, &mut masses).unwrap_err(), MeshError::Density);
                }
                assert!(unchanged(&forces, &energies, &stresses, &masses));

                // And the kernels add (forces) or overwrite (the rest) on success.
                mesh.add_elastic_forces(&model, &x, &mut forces).unwrap();
                assert!(forces.iter().all(|v| *v == Vec3::splat(SENTINEL)));
                mesh.lumped_masses(6.0, &mut masses).unwrap();
                assert!((masses.iter().sum::<Real>() - 6.0).abs() < 1e-5);
            }

            #[test]
            fn triangle_mesh_errors() {
                let x = [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
                let tris = [[0, 1, 2], [0, 2, 3]];
                let mut rest = [TriRest::default(); 2];
                assert_eq!(
                    TriMesh::new(&x, &tris, &mut rest[..1]).unwrap_err(),
                    MeshError::LengthMismatch { buffer: Buffer::RestData, expected: 2, actual: 1 }
                );
                assert_eq!(
                    TriMesh::new(&x, &[[0, 1, 2], [0, 3, 2]], &mut rest).unwrap_err(),
                    MeshError::InvertedElement { element: 1 }
                );
                assert_eq!(
                    TriMesh::new(&x, &[[0, 1, 2], [0, 2, 4]], &mut rest).unwrap_err(),
                    MeshError::IndexOutOfRange { element: 1, corner: 2, index: 4, vertex_count: 4 }
                );
                let mut bad = x;
                bad[3].x = Real::NAN;
                assert_eq!(
                    TriMesh::new(&bad, &tris, &mut rest).unwrap_err(),
                    MeshError::NonFiniteRestPosition { vertex: 3 }
                );
                let mesh = TriMesh::new(&x, &tris, &mut rest).unwrap();
                let model = TriangleStVK::new(&stvk());
                let mut forces = [Vec2::splat(SENTINEL); 4];
                assert_eq!(
                    mesh.add_elastic_forces(&model, &bad, &mut forces).unwrap_err(),
                    MeshError::NonFinitePosition { vertex: 3 }
                );
                assert_eq!(
                    mesh.add_elastic_forces(&model, &x, &mut forces[..2]).unwrap_err(),
                    MeshError::LengthMismatch { buffer: Buffer::Forces, expected: 4, actual: 2 }
                );
                assert!(forces.iter().all(|f| *f == Vec2::splat(SENTINEL)));
                assert_eq!(mesh.elastic_energy(&model, &bad).unwrap_err(), MeshError::NonFinitePosition { vertex: 3 });

                let m = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0, Vec3::Z];
                let mut mrest = [TriRest::default(); 2];
                assert_eq!(
                    MembraneMesh::new(&m, &tris, &mut mrest).unwrap_err(),
                    MeshError::DegenerateElement { element: 0 }
                );
                let m = [Vec3::ZERO, Vec3::X, Vec3::ONE, Vec3::Z];
                let membrane = MembraneMesh::new(&m, &tris, &mut mrest).unwrap();
                let mut masses = [SENTINEL; 4];
                assert_eq!(membrane.lumped_masses(-2.0, &mut masses).unwrap_err(), MeshError::Density);
                assert!(masses.iter().all(|m| *m == SENTINEL));
                let mut forces = [Vec3::ZERO; 4];
                let mut bad = m;
                bad[2].y = Real::INFINITY;
                assert_eq!(
                    membrane.add_elastic_forces(&model, &bad, &mut forces).unwrap_err(),
                    MeshError::NonFinitePosition { vertex: 2 }
                );
            }

            /// The element-level functions have no error path: NaN and infinite positions give
            /// non-finite results and never panic, for every model and path.
            #[test]
            fn non_finite_positions_never_panic_at_element_level() {
                let rest = TetRest::new([Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]).unwrap();
                for bad in [Real::NAN, Real::INFINITY] {
                    let x = [Vec3::ZERO, Vec3::X, Vec3::new(0.0, bad, 0.0), Vec3::Z];
                    assert!(!rest.elastic_forces(&stvk(), x).iter().all(|f| f.is_finite()));
                    let nh = NeoHookean::from_young_poisson(1.0e5, 0.3).unwrap();
                    let snh = StableNeoHookean::from_young_poisson(1.0e5, 0.3).unwrap();
                    let _ = (rest.elastic_forces(&nh, x), rest.elastic_energy(&nh, x));
                    let _ = (rest.elastic_forces(&snh, x), rest.elastic_energy(&snh, x));
                }
                // A flat deformed state: NeoHookean's barrier gives non-finite values, no panic;
                // the mesh kernels accept it (the positions are finite).
                let mut tets_rest = [TetRest::default(); 5];
                let mesh = TetMesh::new(&cube(), &TETS, &mut tets_rest).unwrap();
                let flat = cube().map(|p| p * Vec3::new(1.0, 1.0, 0.0));
                let nh = NeoHookean::from_young_poisson(1.0e5, 0.3).unwrap();
                let mut forces = [Vec3::ZERO; 8];
                mesh.add_elastic_forces(&nh, &flat, &mut forces).unwrap();
                assert!(!mesh.elastic_energy(&nh, &flat).unwrap().is_finite());
                // The clamped path gives finite restoring forces there.
                let mut clamped = [Vec3::ZERO; 8];
                mesh.add_elastic_forces_clamped(&nh, 0.3, &flat, &mut clamped).unwrap();
                assert!(clamped.iter().all(|f| f.is_finite()));
                assert!(clamped[4].z > 0.0 && clamped[0].z < 0.0);
            }

            #[test]
            fn errors_display_the_index() {
                let text = MeshError::IndexOutOfRange { element: 3, corner: 2, index: 99, vertex_count: 8 }
                    .to_string();
                assert!(text.contains('3') && text.contains("99") && text.contains('8'), "{text}");
                assert!(MeshError::NonFinitePosition { vertex: 42 }.to_string().contains("42"));
                assert!(MeshError::LengthMismatch { buffer: Buffer::Masses, expected: 8, actual: 7 }
                    .to_string()
                    .contains("masses"));
                assert!(!ElementError::Degenerate.to_string().is_empty());
                let _: &dyn core::error::Error = &MeshError::Density;
                let _: &dyn core::error::Error = &ElementError::Inverted;
            }
        }
    };
}

mesh_tests!(single, softfem);
mesh_tests!(double, softfem::f64);
