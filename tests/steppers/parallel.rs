//! Determinism of the partitioned passes (`mesh::TetPartition`) and of their rayon runs
//! (`softfem::parallel`, feature `rayon`): the forces, energies and whole explicit runs must have
//! the bits of the sequential code for every piece count, thread count and piece order, in both
//! precisions. The reference is the sequential kernel itself: the claim tested is equality of
//! bits, not accuracy.

/// The tests of one precision, over its `softfem` module path.
macro_rules! precision_tests {
    ($name:ident, $root:path, $real:ty) => {
        mod $name {
            use sf::element::{TetHessian, TetRest};
            use sf::generate::{BoxSplit, box_counts, fill_box};
            use sf::material::{Material, StVK, StableNeoHookean};
            use sf::mesh::{
                ElementForces, TetMesh, TetPartition, TetRestBlock, element_forces_len,
                partition_incident_len, partition_offsets_len, rest_block_count,
            };
            use sf::step::{ElasticEnergy, TetElastic};
            use sf::types::{Mat3, Vec3};
            use $root as sf;

            type Real = $real;

            /// A box of `cells^3` Kuhn cells (6 tets each), its rest positions and tets.
            pub(super) fn box_mesh(cells: usize) -> (Vec<Vec3>, Vec<[u32; 4]>) {
                let (low, high) = (Vec3::ZERO, Vec3::splat(0.1) + Vec3::Y * 0.05);
                let (rest, elements) = crate::common::scenes::generated_box!(low, high, (cells, cells, cells), BoxSplit::Kuhn6);
                (rest, elements)
            }

            /// Deformed positions: an affine map plus a deterministic jitter (LCG), so that
            /// every element has its own `F`.
            fn deformed(rest: &[Vec3]) -> Vec<Vec3> {
                let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
                let mut next = || {
                    state = state
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    ((state >> 40) as Real / (1u64 << 24) as Real - 0.5) * 2.0e-3
                };
                rest.iter()
                    .map(|p| {
                        Vec3::new(
                            1.1 * p.x + 0.05 * p.y + next(),
                            0.92 * p.y - 0.03 * p.z + next(),
                            0.97 * p.z + 0.02 * p.x + next(),
                        )
                    })
                    .collect()
            }

            /// Non-zero starting forces, so the gather must add to the caller's values.
            fn initial_forces(n: usize) -> Vec<Vec3> {
                (0..n)
                    .map(|i| Vec3::new(0.5, -0.25, 0.125) * (i % 7) as Real)
                    .collect()
            }

            fn bits(v: &[Vec3]) -> Vec<[u64; 3]> {
                v.iter()
                    .map(|p| p.to_array().map(|c| (c as f64).to_bits()))
                    .collect()
            }

            /// A permutation of `0..n` from a seed (Fisher-Yates on an LCG).
            fn shuffled(n: usize, seed: u64) -> Vec<usize> {
                let mut order: Vec<usize> = (0..n).collect();
                let mut state = seed;
                for i in (1..n).rev() {
                    state = state
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    order.swap(i, (state >> 33) as usize % (i + 1));
                }
                order
            }

            /// Forces, energy and fused pass of `material` through partitions of several piece
            /// counts, pieces in shuffled order on one thread, against the sequential kernels.
            fn shuffled_matches<M: Material>(material: &M, cells: usize) {
                let (rest, tets) = box_mesh(cells);
                let mut rest_data = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let x = deformed(&rest);
                let (nv, ne) = (mesh.vertex_count(), mesh.element_count());

                let mut expected = initial_forces(nv);
                mesh.add_elastic_forces(material, &x, &mut expected)
                    .unwrap();
                let expected_energy = mesh.elastic_energy(material, &x).unwrap();
                let body = TetElastic::new(mesh, *material);
                let mut expected_fused = initial_forces(nv);
                let expected_fused_energy =
                    body.energy_and_add_forces(&x, &mut expected_fused).unwrap();
                assert!(expected_energy > 0.0 && expected_fused_energy > 0.0);

                // The mesh as built, and with its rest data also in blocks (which pieces
                // starting inside a block use only from the next block on): the same bits.
                let mut blocks = vec![TetRestBlock::ZERO; rest_block_count(ne)];
                let blocked = mesh.with_rest_blocks(&mut blocks).unwrap();
                let runs = [(1, 1), (2, 2), (3, 3), (7, 4), (64, 5), (ne + 5, 6)];
                for ((pieces, seed), mesh) in runs
                    .into_iter()
                    .flat_map(|run| [(run, mesh), (run, blocked)])
                {
                    let mut offsets = vec![0; partition_offsets_len(nv)];
                    let mut incident = vec![0; partition_incident_len(ne)];
                    let partition =
                        TetPartition::new(mesh, pieces, &mut offsets, &mut incident).unwrap();
                    assert_eq!(partition.element_chunk() % sf::lanes::LANES, 0);

                    let mut element_forces: Vec<ElementForces> =
                        vec![[Vec3::ZERO; 4]; element_forces_len(ne)];
                    let mut forces = initial_forces(nv);
                    partition
                        .check_forces(material, &x, &forces, &element_forces)
                        .unwrap();
                    // The slices as a caller hands them out: `chunks_mut`, run shuffled.
                    let mut slices: Vec<_> = element_forces
                        .chunks_mut(partition.element_chunk())
                        .enumerate()
                        .map(Some)
                        .collect();
                    assert_eq!(slices.len(), partition.element_piece_count());
                    for slot in shuffled(slices.len(), seed) {
                        let (piece, out) = slices[slot].take().unwrap();
                        assert_eq!(out.len(), partition.element_piece(piece).len());
                        partition.element_forces(material, &x, piece, out).unwrap();
                    }
                    let mut slices: Vec<_> = forces
                        .chunks_mut(partition.vertex_chunk())
                        .enumerate()
                        .map(Some)
                        .collect();
                    assert_eq!(slices.len(), partition.vertex_piece_count());
                    for slot in shuffled(slices.len(), seed ^ 0x5555) {
                        let (piece, out) = slices[slot].take().unwrap();
                        partition
                            .gather_forces(&element_forces, piece, out)
                            .unwrap();
                    }
                    assert_eq!(bits(&forces), bits(&expected), "forces, {pieces} pieces");

                    let mut one_thread = initial_forces(nv);
                    partition
                        .add_elastic_forces(material, &x, &mut one_thread, &mut element_forces)
                        .unwrap();
                    assert_eq!(bits(&one_thread), bits(&expected));

                    // The owner-computes form, pieces shuffled.
                    let mut forces = initial_forces(nv);
                    shuffled_pieces(
                        &mut forces,
                        partition.vertex_chunk(),
                        seed + 41,
                        |k, out| partition.add_forces_owned(material, &x, k, out).unwrap(),
                    );
                    assert_eq!(
                        bits(&forces),
                        bits(&expected),
                        "owner form, {pieces} pieces"
                    );

                    let mut energies = vec![0.0; ne];
                    partition.check_energy(material, &x, &energies).unwrap();
                    for piece in shuffled(partition.element_piece_count(), seed + 10) {
                        let range = partition.element_piece(piece);
                        partition
                            .element_energies(material, &x, piece, &mut energies[range])
                            .unwrap();
                    }
                    let energy = partition.total_energy(&energies).unwrap();
                    assert_eq!(
                        energy.to_bits(),
                        expected_energy.to_bits(),
                        "{pieces} pieces"
                    );

                    let mut forces = initial_forces(nv);
                    assert!(
                        partition
                            .check_fused(material, &x, &forces, &element_forces, &energies)
                            .unwrap()
                    );
                    for piece in shuffled(partition.element_piece_count(), seed + 20) {
                        let range = partition.element_piece(piece);
                        partition
                            .element_energies_and_forces(
                                material,
                                &x,
                                piece,
                                &mut energies[range.clone()],
                                &mut element_forces[range],
                            )
                            .unwrap();
                    }
                    for piece in shuffled(partition.vertex_piece_count(), seed + 30) {
                        let range = partition.vertex_piece(piece);
                        partition
                            .gather_forces(&element_forces, piece, &mut forces[range])
                            .unwrap();
                    }
                    assert_eq!(
                        bits(&forces),
                        bits(&expected_fused),
                        "fused, {pieces} pieces"
                    );
                    let fused = partition.fused_total_energy(&energies).unwrap();
                    assert_eq!(fused.to_bits(), expected_fused_energy.to_bits());

                    // The owner-computes fused form, pieces shuffled: every element's energy
                    // written once (NaN where none was) and the forces of the sequential pass.
                    let mut owned_energies = vec![Real::NAN; ne];
                    let mut forces = initial_forces(nv);
                    let covered: usize = (0..partition.vertex_piece_count())
                        .map(|k| partition.energy_piece(k).len())
                        .sum();
                    assert_eq!(covered, ne, "energy pieces cover the elements once");
                    for piece in shuffled(partition.vertex_piece_count(), seed + 40) {
                        let vertices = partition.vertex_piece(piece);
                        let elements = partition.energy_piece(piece);
                        partition
                            .energy_and_add_forces_owned(
                                material,
                                &x,
                                piece,
                                &mut forces[vertices],
                                &mut owned_energies[elements],
                            )
                            .unwrap();
                    }
                    assert_eq!(
                        bits(&forces),
                        bits(&expected_fused),
                        "owner fused, {pieces} pieces"
                    );
                    let energy_bits =
                        |e: &[Real]| e.iter().map(|e| e.to_bits()).collect::<Vec<_>>();
                    assert_eq!(energy_bits(&owned_energies), energy_bits(&energies));
                    let mut forces = initial_forces(nv);
                    let fused = partition
                        .energy_and_add_forces(
                            material,
                            &x,
                            &mut forces,
                            &element_forces,
                            &mut owned_energies,
                        )
                        .unwrap();
                    assert_eq!(bits(&forces), bits(&expected_fused));
                    assert_eq!(fused.to_bits(), expected_fused_energy.to_bits());
                }
            }

            #[test]
            fn shuffled_pieces_on_one_thread_give_the_sequential_bits() {
                // 5^3 cells: 750 tets (750 % 4 = 2, so the scalar tail after the last group
                // is exercised), odd vertex count 216.
                let snh = StableNeoHookean::from_young_poisson(1.0e5, 0.45).unwrap();
                shuffled_matches(&snh, 5);
                shuffled_matches(&StVK::from_young_poisson(1.0e6, 0.3).unwrap(), 4);
            }

            #[test]
            fn partition_refuses_bad_buffers_and_pieces() {
                let (rest, tets) = box_mesh(2);
                let mut rest_data = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let (nv, ne) = (mesh.vertex_count(), mesh.element_count());
                let mut short = vec![0; partition_offsets_len(nv) - 1];
                let mut incident = vec![0; partition_incident_len(ne)];
                assert_eq!(
                    TetPartition::new(mesh, 2, &mut short, &mut incident).unwrap_err(),
                    sf::MeshError::LengthMismatch {
                        buffer: sf::Buffer::AdjacencyOffsets,
                        expected: nv + 1,
                        actual: nv,
                    }
                );
                let mut offsets = vec![0; partition_offsets_len(nv)];
                let partition = TetPartition::new(mesh, 2, &mut offsets, &mut incident).unwrap();
                let material = StVK::from_young_poisson(1.0e6, 0.3).unwrap();
                let mut out = vec![[Vec3::ZERO; 4]; partition.element_chunk()];
                let pieces = partition.element_piece_count();
                assert_eq!(
                    partition.element_forces(&material, &rest, pieces, &mut out),
                    Err(sf::MeshError::PieceIndex {
                        piece: pieces,
                        pieces
                    })
                );
                let element_forces = vec![[Vec3::ZERO; 4]; ne - 1];
                let forces = vec![Vec3::ZERO; nv];
                assert!(matches!(
                    partition.check_forces(&material, &rest, &forces, &element_forces),
                    Err(sf::MeshError::LengthMismatch {
                        buffer: sf::Buffer::ElementForces,
                        ..
                    })
                ));
                let mut bad = rest.clone();
                bad[3].y = Real::NAN;
                let element_forces = vec![[Vec3::ZERO; 4]; ne];
                assert_eq!(
                    partition.check_forces(&material, &bad, &forces, &element_forces),
                    Err(sf::MeshError::NonFinitePosition { vertex: 3 })
                );
            }

            fn mat_bits(m: &[Mat3]) -> Vec<[u64; 9]> {
                m.iter()
                    .map(|a| a.to_cols_array().map(|c| (c as f64).to_bits()))
                    .collect()
            }

            /// Non-zero starting blocks, so the gather must add to the caller's values.
            fn initial_blocks(n: usize) -> Vec<Mat3> {
                (0..n)
                    .map(|i| Mat3::from_diagonal(Vec3::new(1.0, 2.0, 3.0) * (i % 5) as Real))
                    .collect()
            }

            /// A direction with its own value at every vertex (the Hessian product's input).
            fn direction(rest: &[Vec3]) -> Vec<Vec3> {
                rest.iter()
                    .enumerate()
                    .map(|(i, p)| Vec3::new(p.y, -p.z, p.x) + Vec3::splat((i % 11) as Real * 1e-3))
                    .collect()
            }

            /// The sequential results of every pass these tests split: principal and clamped
            /// forces, projected Hessians, their product and diagonal blocks.
            struct SvdAndHessianReference {
                principal: Vec<[u64; 3]>,
                clamped: Vec<[u64; 3]>,
                cache: Vec<TetHessian>,
                product: Vec<[u64; 3]>,
                blocks: Vec<[u64; 9]>,
            }

            const CLAMP: Real = 0.95;

            impl SvdAndHessianReference {
                fn new<M: Material>(
                    mesh: TetMesh<'_>,
                    material: &M,
                    x: &[Vec3],
                    d: &[Vec3],
                ) -> Self {
                    let nv = mesh.vertex_count();
                    let mut principal = initial_forces(nv);
                    mesh.add_elastic_forces_principal(material, x, &mut principal)
                        .unwrap();
                    let mut clamped = initial_forces(nv);
                    mesh.add_elastic_forces_clamped(material, CLAMP, x, &mut clamped)
                        .unwrap();
                    let mut cache = vec![TetHessian::default(); mesh.element_count()];
                    mesh.projected_hessians(material, x, &mut cache).unwrap();
                    let mut product = initial_forces(nv);
                    mesh.add_hessian_product(&cache, d, &mut product).unwrap();
                    let mut blocks = initial_blocks(nv);
                    mesh.add_vertex_hessian_blocks(&cache, &mut blocks).unwrap();
                    // The clamp acts (y is squashed to 0.92), so the two paths differ.
                    assert_ne!(bits(&principal), bits(&clamped));
                    SvdAndHessianReference {
                        principal: bits(&principal),
                        clamped: bits(&clamped),
                        cache,
                        product: bits(&product),
                        blocks: mat_bits(&blocks),
                    }
                }
            }

            /// Runs `piece(k, slice)` on the `chunk`-long slices of `buffer` in shuffled order.
            fn shuffled_pieces<T>(
                buffer: &mut [T],
                chunk: usize,
                seed: u64,
                mut piece: impl FnMut(usize, &mut [T]),
            ) {
                let mut slices: Vec<_> = buffer.chunks_mut(chunk).enumerate().map(Some).collect();
                for slot in shuffled(slices.len(), seed) {
                    let (k, out) = slices[slot].take().unwrap();
                    piece(k, out);
                }
            }

            /// Principal and clamped forces, Hessians, products and blocks of `material`
            /// through partitions of several piece counts, pieces in shuffled order on one
            /// thread, against the sequential kernels.
            fn shuffled_svd_and_hessian_matches<M: Material>(material: &M, cells: usize) {
                let (rest, tets) = box_mesh(cells);
                let mut rest_data = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let (x, d) = (deformed(&rest), direction(&rest));
                let (nv, ne) = (mesh.vertex_count(), mesh.element_count());
                let reference = SvdAndHessianReference::new(mesh, material, &x, &d);
                for (pieces, seed) in [(1, 11), (2, 12), (3, 13), (7, 14), (64, 15), (ne + 5, 16)] {
                    let mut offsets = vec![0; partition_offsets_len(nv)];
                    let mut incident = vec![0; partition_incident_len(ne)];
                    let p = TetPartition::new(mesh, pieces, &mut offsets, &mut incident).unwrap();
                    let (ec, vc) = (p.element_chunk(), p.vertex_chunk());
                    let mut element_forces = vec![[Vec3::ZERO; 4]; element_forces_len(ne)];

                    let mut forces = initial_forces(nv);
                    p.check_principal(material, &x, &forces, &element_forces)
                        .unwrap();
                    shuffled_pieces(&mut element_forces, ec, seed, |k, out| {
                        p.element_forces_principal(material, &x, k, out).unwrap()
                    });
                    shuffled_pieces(&mut forces, vc, seed + 1, |k, out| {
                        p.gather_forces(&element_forces, k, out).unwrap()
                    });
                    assert_eq!(
                        bits(&forces),
                        reference.principal,
                        "principal, {pieces} pieces"
                    );

                    let mut forces = initial_forces(nv);
                    p.check_clamped(material, CLAMP, &x, &forces, &element_forces)
                        .unwrap();
                    shuffled_pieces(&mut element_forces, ec, seed + 2, |k, out| {
                        p.element_forces_clamped(material, CLAMP, &x, k, out)
                            .unwrap()
                    });
                    shuffled_pieces(&mut forces, vc, seed + 3, |k, out| {
                        p.gather_forces(&element_forces, k, out).unwrap()
                    });
                    assert_eq!(bits(&forces), reference.clamped, "clamped, {pieces} pieces");

                    let mut cache = vec![TetHessian::default(); ne];
                    p.check_hessians(&x, &cache).unwrap();
                    shuffled_pieces(&mut cache, ec, seed + 4, |k, out| {
                        p.element_hessians(material, &x, k, out).unwrap()
                    });
                    assert!(cache == reference.cache, "Hessians, {pieces} pieces");

                    let mut product = initial_forces(nv);
                    p.check_hessian_product(&cache, &d, &product, &element_forces)
                        .unwrap();
                    shuffled_pieces(&mut element_forces, ec, seed + 5, |k, out| {
                        p.element_hessian_products(&cache, &d, k, out).unwrap()
                    });
                    shuffled_pieces(&mut product, vc, seed + 6, |k, out| {
                        p.gather_forces(&element_forces, k, out).unwrap()
                    });
                    assert_eq!(
                        bits(&product),
                        reference.product,
                        "product, {pieces} pieces"
                    );

                    // The owner-computes forms, pieces shuffled.
                    let mut forces = initial_forces(nv);
                    shuffled_pieces(&mut forces, vc, seed + 8, |k, out| {
                        p.add_forces_principal_owned(material, &x, k, out).unwrap()
                    });
                    assert_eq!(bits(&forces), reference.principal, "owner principal");
                    let mut forces = initial_forces(nv);
                    shuffled_pieces(&mut forces, vc, seed + 9, |k, out| {
                        p.add_forces_clamped_owned(material, CLAMP, &x, k, out)
                            .unwrap()
                    });
                    assert_eq!(bits(&forces), reference.clamped, "owner clamped");
                    let mut product = initial_forces(nv);
                    shuffled_pieces(&mut product, vc, seed + 10, |k, out| {
                        p.add_hessian_product_owned(&cache, &d, k, out).unwrap()
                    });
                    assert_eq!(bits(&product), reference.product, "owner product");

                    let mut blocks = initial_blocks(nv);
                    p.check_vertex_blocks(&cache, &blocks).unwrap();
                    shuffled_pieces(&mut blocks, vc, seed + 7, |k, out| {
                        p.gather_vertex_blocks(&cache, k, out).unwrap()
                    });
                    assert_eq!(
                        mat_bits(&blocks),
                        reference.blocks,
                        "blocks, {pieces} pieces"
                    );
                }
            }

            #[test]
            fn shuffled_svd_and_hessian_pieces_on_one_thread_give_the_sequential_bits() {
                // 750 tets: a scalar tail after the last group of four.
                let snh = StableNeoHookean::from_young_poisson(1.0e5, 0.45).unwrap();
                shuffled_svd_and_hessian_matches(&snh, 5);
                shuffled_svd_and_hessian_matches(&StVK::from_young_poisson(1.0e6, 0.3).unwrap(), 4);
            }

            #[test]
            fn svd_and_hessian_pieces_check_as_the_sequential_kernels() {
                let (rest, tets) = box_mesh(2);
                let mut rest_data = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let (nv, ne) = (mesh.vertex_count(), mesh.element_count());
                let mut offsets = vec![0; partition_offsets_len(nv)];
                let mut incident = vec![0; partition_incident_len(ne)];
                let p = TetPartition::new(mesh, 3, &mut offsets, &mut incident).unwrap();
                let material = StVK::from_young_poisson(1.0e6, 0.3).unwrap();
                let element_forces = vec![[Vec3::ZERO; 4]; ne];
                let forces = vec![Vec3::ZERO; nv];
                let mut sequential = forces.clone();
                for threshold in [0.0, 1.5, Real::NAN] {
                    assert_eq!(
                        p.check_clamped(&material, threshold, &rest, &forces, &element_forces),
                        mesh.add_elastic_forces_clamped(
                            &material,
                            threshold,
                            &rest,
                            &mut sequential
                        )
                    );
                }
                let mut bad = rest.clone();
                bad[5].z = Real::INFINITY;
                assert_eq!(
                    p.check_principal(&material, &bad, &forces, &element_forces),
                    mesh.add_elastic_forces_principal(&material, &bad, &mut sequential)
                );
                let cache = vec![TetHessian::default(); ne];
                let mut out = vec![Vec3::ZERO; nv];
                assert_eq!(
                    p.check_hessian_product(&cache, &bad, &out, &element_forces),
                    mesh.add_hessian_product(&cache, &bad, &mut out)
                );
                assert_eq!(
                    p.check_hessians(&bad, &cache),
                    Err(sf::MeshError::NonFinitePosition { vertex: 5 })
                );
                let mut blocks = vec![Mat3::ZERO; nv - 1];
                assert_eq!(
                    p.check_vertex_blocks(&cache, &blocks),
                    mesh.add_vertex_hessian_blocks(&cache, &mut blocks)
                );
                let pieces = p.vertex_piece_count();
                assert_eq!(
                    p.gather_vertex_blocks(&cache, pieces, &mut blocks),
                    Err(sf::MeshError::PieceIndex {
                        piece: pieces,
                        pieces
                    })
                );
                let mut short = vec![TetHessian::default(); p.element_chunk() - 1];
                assert!(matches!(
                    p.element_hessians(&material, &rest, 0, &mut short),
                    Err(sf::MeshError::LengthMismatch {
                        buffer: sf::Buffer::Hessians,
                        ..
                    })
                ));
            }

            #[cfg(feature = "rayon")]
            mod threads {
                use super::*;
                use sf::parallel::{self, ParallelTetClamped, ParallelTetElastic};
                use sf::step::{
                    ElasticHessian, ElasticModel, ExplicitScratch, ExplicitSettings, HalfSpace, NewtonScratch, NewtonSettings,
                    Preconditioner, RelaxScratch, RelaxSettings, Scene, scratch_len, explicit_step,
                    newton_step, relax_step, stable_time_step, TetClamped,
                };

                const THREADS: [usize; 4] = [1, 2, 3, 8];

                fn pool(threads: usize) -> rayon::ThreadPool {
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap()
                }

                #[test]
                fn forces_and_energies_on_1_2_3_8_threads_give_the_sequential_bits() {
                    let (rest, tets) = box_mesh(8); // 3072 tets
                    let mut rest_data = vec![TetRest::default(); tets.len()];
                    let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                    let (nv, ne) = (mesh.vertex_count(), mesh.element_count());
                    let material = StableNeoHookean::from_young_poisson(1.0e5, 0.45).unwrap();
                    let x = deformed(&rest);
                    let mut expected = initial_forces(nv);
                    mesh.add_elastic_forces(&material, &x, &mut expected)
                        .unwrap();
                    let expected_energy = mesh.elastic_energy(&material, &x).unwrap();
                    let mut expected_fused = initial_forces(nv);
                    let expected_fused_energy = TetElastic::new(mesh, material)
                        .energy_and_add_forces(&x, &mut expected_fused)
                        .unwrap();
                    // Many pieces per thread: work stealing reorders them, and the pool runs
                    // them in spans of consecutive pieces (all of them on one thread; past the
                    // 64 pieces whose element ranges the partition keeps, with 100).
                    for (threads, pieces) in THREADS.map(|t| (t, 4 * t + 1)).into_iter().chain(
                        THREADS.map(|t| (t, 100)),
                    ) {
                        let mut offsets = vec![0; partition_offsets_len(nv)];
                        let mut incident = vec![0; partition_incident_len(ne)];
                        let partition =
                            TetPartition::new(mesh, pieces, &mut offsets, &mut incident).unwrap();
                        let mut element_forces = vec![[Vec3::ZERO; 4]; ne];
                        let mut energies = vec![0.0; ne];
                        let pool = pool(threads);
                        let mut forces = initial_forces(nv);
                        pool.install(|| {
                            parallel::add_elastic_forces(
                                &partition,
                                &material,
                                &x,
                                &mut forces,
                                &mut element_forces,
                            )
                        })
                        .unwrap();
                        assert_eq!(bits(&forces), bits(&expected), "{threads} threads, {pieces} pieces");
                        let energy = pool
                            .install(|| {
                                parallel::elastic_energy(&partition, &material, &x, &mut energies)
                            })
                            .unwrap();
                        assert_eq!(energy.to_bits(), expected_energy.to_bits());
                        let mut forces = initial_forces(nv);
                        let fused = pool
                            .install(|| {
                                parallel::energy_and_add_forces(
                                    &partition,
                                    &material,
                                    &x,
                                    &mut forces,
                                    &mut element_forces,
                                    &mut energies,
                                )
                            })
                            .unwrap();
                        assert_eq!(bits(&forces), bits(&expected_fused), "{threads} threads");
                        assert_eq!(fused.to_bits(), expected_fused_energy.to_bits());
                    }
                }

                /// A slab of 127 x 127 x 1 Kuhn cells: 32 768 vertices, enough that on two or more
                /// threads the direct and fused passes check the positions in a chunk per
                /// thread (`parallel::positions_pass`) instead of on the calling thread. Forces,
                /// fused energy and forces against the sequential kernels, bit for bit; then a
                /// NaN and an infinite position, and a vertex so far out that the deformation
                /// bound fails, each in the last chunk of the vertices (another thread's): the
                /// sequential kernels' results (the force pass's errors with the forces as they
                /// were; the fused pass's energy, infinite out of range, and forces).
                #[test]
                fn passes_past_the_parallel_position_check_give_the_sequential_bits_and_errors() {
                    let (cells, layers) = (127, 1);
                    let (vertices, tets) =
                        box_counts(cells, cells, layers, BoxSplit::Kuhn6).unwrap();
                    assert!(vertices >= 32_768);
                    let (mut rest, mut elements) =
                        (vec![Vec3::ZERO; vertices], vec![[0; 4]; tets]);
                    let high = Vec3::new(1.0, 1.0, 1.0 / cells as Real);
                    fill_box(
                        Vec3::ZERO,
                        high,
                        cells,
                        cells,
                        layers,
                        BoxSplit::Kuhn6,
                        &mut rest,
                        &mut elements,
                    )
                    .unwrap();
                    let mut rest_data = vec![TetRest::default(); tets];
                    let mesh = TetMesh::new(&rest, &elements, &mut rest_data).unwrap();
                    let (nv, ne) = (mesh.vertex_count(), mesh.element_count());
                    let stvk = StVK::from_young_poisson(1.0e6, 0.45).unwrap();
                    let body = TetElastic::new(mesh, stvk);
                    let mut offsets = vec![0; partition_offsets_len(nv)];
                    let mut incident = vec![0; partition_incident_len(ne)];
                    let partition =
                        TetPartition::new(mesh, 4, &mut offsets, &mut incident).unwrap();
                    let mut element_forces = vec![[Vec3::ZERO; 4]; ne];
                    let mut energies = vec![0.0; ne];
                    let far = nv - 3 * cells; // in the last chunk of any pool here
                    let mut nan = deformed(&rest);
                    nan[far].y = Real::NAN;
                    let mut infinite = deformed(&rest);
                    infinite[far].z = Real::NEG_INFINITY;
                    let mut out_of_range = deformed(&rest);
                    out_of_range[far].x = Real::MAX.sqrt();
                    let inputs = [deformed(&rest), nan, infinite, out_of_range];
                    for (case, x) in inputs.iter().enumerate() {
                        let mut expected = initial_forces(nv);
                        let expected_result = mesh.add_elastic_forces(&stvk, x, &mut expected);
                        let mut expected_fused = initial_forces(nv);
                        let expected_energy = body.energy_and_add_forces(x, &mut expected_fused);
                        // The fused pass checks no finiteness: on NaN it computes NaN, as
                        // the sequential pass does.
                        assert_eq!(expected_result.is_err(), case > 0, "case {case}");
                        for threads in [2, 3] {
                            let pool = pool(threads);
                            let mut forces = initial_forces(nv);
                            let result = pool.install(|| {
                                parallel::add_elastic_forces(
                                    &partition,
                                    &stvk,
                                    x,
                                    &mut forces,
                                    &mut element_forces,
                                )
                            });
                            assert_eq!(result, expected_result, "case {case}, {threads} threads");
                            assert_eq!(bits(&forces), bits(&expected), "case {case}, {threads}");
                            let mut forces = initial_forces(nv);
                            let energy = pool.install(|| {
                                parallel::energy_and_add_forces(
                                    &partition,
                                    &stvk,
                                    x,
                                    &mut forces,
                                    &mut element_forces,
                                    &mut energies,
                                )
                            });
                            assert_eq!(
                                energy.map(Real::to_bits),
                                expected_energy.map(Real::to_bits),
                                "case {case}, {threads} threads: fused energy"
                            );
                            assert_eq!(
                                bits(&forces),
                                bits(&expected_fused),
                                "case {case}, {threads} threads: fused forces"
                            );
                        }
                    }
                }

                #[test]
                fn svd_forces_and_hessians_on_1_2_3_8_threads_give_the_sequential_bits() {
                    let (rest, tets) = box_mesh(7); // 2058 tets (2058 % 4 = 2)
                    let mut rest_data = vec![TetRest::default(); tets.len()];
                    let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                    let (nv, ne) = (mesh.vertex_count(), mesh.element_count());
                    let material = StableNeoHookean::from_young_poisson(1.0e5, 0.45).unwrap();
                    let (x, d) = (deformed(&rest), direction(&rest));
                    let reference = SvdAndHessianReference::new(mesh, &material, &x, &d);
                    let body = TetElastic::new(mesh, material);
                    // As above: spans of pieces, also past the 64 kept ranges (100 pieces).
                    for (threads, pieces) in THREADS.map(|t| (t, 4 * t + 1)).into_iter().chain(
                        THREADS.map(|t| (t, 100)),
                    ) {
                        let mut offsets = vec![0; partition_offsets_len(nv)];
                        let mut incident = vec![0; partition_incident_len(ne)];
                        let p = TetPartition::new(mesh, pieces, &mut offsets, &mut incident)
                            .unwrap();
                        let mut element_forces = vec![[Vec3::ZERO; 4]; ne];
                        let pool = pool(threads);
                        pool.install(|| {
                            let mut forces = initial_forces(nv);
                            parallel::add_elastic_forces_principal(
                                &p,
                                &material,
                                &x,
                                &mut forces,
                                &mut element_forces,
                            )
                            .unwrap();
                            assert_eq!(bits(&forces), reference.principal, "{threads} threads");
                            let mut forces = initial_forces(nv);
                            parallel::add_elastic_forces_clamped(
                                &p,
                                &material,
                                CLAMP,
                                &x,
                                &mut forces,
                                &mut element_forces,
                            )
                            .unwrap();
                            assert_eq!(bits(&forces), reference.clamped, "{threads} threads");
                        });
                        // The Hessian passes through the body the Newton solver takes.
                        let mut energies = vec![0.0; ne];
                        let parallel_body =
                            ParallelTetElastic::new(body, p, &mut element_forces, &mut energies)
                                .unwrap()
                                .with_pool(&pool);
                        assert_eq!(ElasticHessian::element_count(&parallel_body), ne);
                        let mut cache = vec![TetHessian::default(); ne];
                        parallel_body.projected_hessians(&x, &mut cache).unwrap();
                        assert!(cache == reference.cache, "{threads} threads: Hessians");
                        let mut product = initial_forces(nv);
                        parallel_body
                            .add_hessian_product(&cache, &d, &mut product)
                            .unwrap();
                        assert_eq!(bits(&product), reference.product, "{threads} threads");
                        let mut blocks = initial_blocks(nv);
                        parallel_body
                            .add_vertex_hessian_blocks(&cache, &mut blocks)
                            .unwrap();
                        assert_eq!(mat_bits(&blocks), reference.blocks, "{threads} threads");
                    }
                }

                /// Owner passes over a mesh whose element order is partly scrambled (every 29th
                /// element swapped with one far away), so that each piece's element range holds
                /// runs of elements that all touch it between elements that do not: the passes
                /// run the runs without the test of whether a group touches the piece, the rest
                /// with it. Direct, fused, principal and clamped forces, Hessian products and
                /// blocks on 1 and 2 threads and piece by piece on this thread, against the
                /// sequential kernels, bit for bit.
                #[test]
                fn owner_passes_on_a_scrambled_element_order_give_the_sequential_bits() {
                    let (rest, mut tets) = box_mesh(7); // 2058 tets
                    let ne = tets.len();
                    for i in (0..ne).step_by(29) {
                        tets.swap(i, (i * 7 + ne / 2) % ne);
                    }
                    let mut rest_data = vec![TetRest::default(); ne];
                    let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                    let nv = mesh.vertex_count();
                    let material = StableNeoHookean::from_young_poisson(1.0e5, 0.45).unwrap();
                    let (x, d) = (deformed(&rest), direction(&rest));
                    let reference = SvdAndHessianReference::new(mesh, &material, &x, &d);
                    let mut expected = initial_forces(nv);
                    mesh.add_elastic_forces(&material, &x, &mut expected)
                        .unwrap();
                    let body = TetElastic::new(mesh, material);
                    let mut expected_fused = initial_forces(nv);
                    let expected_energy =
                        body.energy_and_add_forces(&x, &mut expected_fused).unwrap();
                    for (threads, pieces) in [(1, 3), (2, 2), (2, 7), (1, 100), (2, 100)] {
                        let mut offsets = vec![0; partition_offsets_len(nv)];
                        let mut incident = vec![0; partition_incident_len(ne)];
                        let p =
                            TetPartition::new(mesh, pieces, &mut offsets, &mut incident).unwrap();
                        let mut element_forces = vec![[Vec3::ZERO; 4]; ne];
                        let mut energies = vec![0.0; ne];
                        let label = format!("{threads} threads, {pieces} pieces");
                        // Piece by piece on this thread.
                        let mut forces = initial_forces(nv);
                        p.add_elastic_forces(&material, &x, &mut forces, &mut element_forces)
                            .unwrap();
                        assert_eq!(bits(&forces), bits(&expected), "{label}");
                        let mut forces = initial_forces(nv);
                        let energy = p
                            .energy_and_add_forces(
                                &material,
                                &x,
                                &mut forces,
                                &element_forces,
                                &mut energies,
                            )
                            .unwrap();
                        assert_eq!(bits(&forces), bits(&expected_fused), "{label}");
                        assert_eq!(energy.to_bits(), expected_energy.to_bits(), "{label}");
                        // On the pool, in spans.
                        let pool = pool(threads);
                        pool.install(|| {
                            let mut forces = initial_forces(nv);
                            parallel::add_elastic_forces(
                                &p,
                                &material,
                                &x,
                                &mut forces,
                                &mut element_forces,
                            )
                            .unwrap();
                            assert_eq!(bits(&forces), bits(&expected), "{label}");
                            let mut forces = initial_forces(nv);
                            let energy = parallel::energy_and_add_forces(
                                &p,
                                &material,
                                &x,
                                &mut forces,
                                &mut element_forces,
                                &mut energies,
                            )
                            .unwrap();
                            assert_eq!(bits(&forces), bits(&expected_fused), "{label}");
                            assert_eq!(energy.to_bits(), expected_energy.to_bits(), "{label}");
                            let mut forces = initial_forces(nv);
                            parallel::add_elastic_forces_principal(
                                &p,
                                &material,
                                &x,
                                &mut forces,
                                &mut element_forces,
                            )
                            .unwrap();
                            assert_eq!(bits(&forces), reference.principal, "{label}");
                            let mut forces = initial_forces(nv);
                            parallel::add_elastic_forces_clamped(
                                &p,
                                &material,
                                CLAMP,
                                &x,
                                &mut forces,
                                &mut element_forces,
                            )
                            .unwrap();
                            assert_eq!(bits(&forces), reference.clamped, "{label}");
                            let mut product = initial_forces(nv);
                            parallel::add_hessian_product(
                                &p,
                                &reference.cache,
                                &d,
                                &mut product,
                                &mut element_forces,
                            )
                            .unwrap();
                            assert_eq!(bits(&product), reference.product, "{label}");
                            let mut blocks = initial_blocks(nv);
                            parallel::add_vertex_hessian_blocks(&p, &reference.cache, &mut blocks)
                                .unwrap();
                            assert_eq!(mat_bits(&blocks), reference.blocks, "{label}");
                        });
                    }
                }

                /// A box of `cells^3` Kuhn cells lifted 2 mm above the ground: rest positions,
                /// tets.
                fn lifted_box(cells: usize) -> (Vec<Vec3>, Vec<[u32; 4]>) {
                    let (rest, tets) = box_mesh(cells);
                    (rest.iter().map(|p| *p + Vec3::Y * 0.002).collect(), tets)
                }

                /// A partition of `mesh` into `pieces` over fresh adjacency buffers.
                fn partition<'a>(
                    mesh: TetMesh<'a>,
                    pieces: usize,
                    offsets: &'a mut Vec<u32>,
                    incident: &'a mut Vec<u32>,
                ) -> TetPartition<'a> {
                    offsets.resize(partition_offsets_len(mesh.vertex_count()), 0);
                    incident.resize(partition_incident_len(mesh.element_count()), 0);
                    TetPartition::new(mesh, pieces, offsets, incident).unwrap()
                }

                /// `run` of `body` made parallel: partitioned into `pieces`, on a pool of
                /// `threads` threads.
                fn on_parallel_body<M: Material + Sync, R>(
                    body: TetElastic<'_, M>,
                    pieces: usize,
                    threads: usize,
                    run: impl FnOnce(&ParallelTetElastic<'_, M>) -> R,
                ) -> R {
                    let (mut offsets, mut incident) = (Vec::new(), Vec::new());
                    let p = partition(body.mesh, pieces, &mut offsets, &mut incident);
                    let ne = body.mesh.element_count();
                    let (mut element_forces, mut energies) =
                        (vec![[Vec3::ZERO; 4]; ne], vec![0.0; ne]);
                    let pool = pool(threads);
                    let parallel_body =
                        ParallelTetElastic::new(body, p, &mut element_forces, &mut energies)
                            .unwrap()
                            .with_pool(&pool);
                    run(&parallel_body)
                }

                type RunBits = (Vec<[u64; 3]>, Vec<[u64; 3]>, String);

                /// `steps` explicit steps of `model` from `start` at rest, onto the ground:
                /// the final state's bits and the contact count.
                fn explicit_run<F: ElasticModel<Vector = Vec3>>(
                    model: &F,
                    masses: &[Real],
                    scene: &Scene<'_, Vec3>,
                    settings: &ExplicitSettings,
                    start: &[Vec3],
                    steps: usize,
                ) -> RunBits {
                    let n = start.len();
                    let (mut x, mut v) = (start.to_vec(), vec![Vec3::ZERO; n]);
                    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                    let mut scratch = ExplicitScratch::new(&mut buffer);
                    let mut contacts = 0;
                    for _ in 0..steps {
                        let report = explicit_step(
                            model,
                            masses,
                            &[],
                            scene,
                            settings,
                            &mut x,
                            &mut v,
                            &mut scratch,
                        )
                        .unwrap();
                        contacts += report.ground_contacts;
                    }
                    (bits(&x), bits(&v), format!("{contacts} contacts"))
                }

                /// 60 explicit steps of a box on the ground with the clamped principal forces, sequential
                /// against `ParallelTetClamped` on 1, 2, 3 and 8 threads: every bit.
                #[test]
                fn clamped_explicit_run_on_1_2_3_8_threads_gives_the_sequential_bits() {
                    // Resting on the ground from the start (60 steps are 1 ms): contacts at once.
                    let (start, tets) = box_mesh(5);
                    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &start, &tets, 1000.0);
                    let (nv, ne) = (mesh.vertex_count(), mesh.element_count());
                    let material = StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap();
                    let body = TetClamped::checked(mesh, material, 0.3).unwrap();
                    let mut stiffness = vec![0.0; nv];
                    let dt = 0.5 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                    let scene = Scene::new(dt)
                        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                        .with_ground(HalfSpace::new(Vec3::Y, 0.0));
                    let settings = ExplicitSettings::new();
                    let expected = explicit_run(&body, &masses, &scene, &settings, &start, 60);
                    assert_ne!(expected.2, "0 contacts", "the box must touch the ground");
                    for threads in THREADS {
                        let (mut offsets, mut incident) = (Vec::new(), Vec::new());
                        let p = partition(mesh, 3 * threads, &mut offsets, &mut incident);
                        let mut element_forces = vec![[Vec3::ZERO; 4]; ne];
                        let pool = pool(threads);
                        let parallel_body = ParallelTetClamped::new(body, p, &mut element_forces)
                            .unwrap()
                            .with_pool(&pool);
                        let got = explicit_run(&parallel_body, &masses, &scene, &settings, &start, 60);
                        assert!(got == expected, "{threads} threads: clamped run differs");
                    }
                }

                /// `steps` relaxation steps of 1/60 s (Chebyshev, the defaults) of `model`
                /// from `start` at rest, onto the ground with the sticking speed
                /// `sticking_speed` (m/s; positive puts friction into the objective): the
                /// final state's bits and every step's report.
                fn relax_run<F: ElasticEnergy<Vector = Vec3>>(
                    model: &F,
                    masses: &[Real],
                    start: &[Vec3],
                    (steps, sticking_speed): (usize, Real),
                ) -> RunBits {
                    let n = start.len();
                    let ground = HalfSpace::new(Vec3::Y, 0.0)
                        .with_friction(0.5)
                        .with_sticking_speed(sticking_speed);
                    let scene = Scene::new(1.0 / 60.0)
                        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                        .with_ground(ground);
                    let settings = RelaxSettings::new().with_tolerance(1.0e-3, 300);
                    let (mut x, mut v) = (start.to_vec(), vec![Vec3::ZERO; n]);
                    let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
                    let mut scalars = vec![0.0; n];
                    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                    let mut reports = String::new();
                    for _ in 0..steps {
                        let report = relax_step(
                            model,
                            masses,
                            &[],
                            &scene,
                            &settings,
                            &mut x,
                            &mut v,
                            &mut scratch,
                        )
                        .unwrap();
                        reports += &format!("{report:?}\n");
                    }
                    (bits(&x), bits(&v), reports)
                }

                /// `steps` Newton steps of 1/30 s of `model` from `start` at rest, onto the
                /// ground, as [`relax_run`], with `preconditioner`.
                fn newton_run<F: ElasticHessian>(
                    model: &F,
                    masses: &[Real],
                    start: &[Vec3],
                    (steps, sticking_speed, preconditioner): (usize, Real, Preconditioner),
                ) -> RunBits {
                    let (n, ne) = (start.len(), model.element_count());
                    let ground = HalfSpace::new(Vec3::Y, 0.0)
                        .with_friction(0.5)
                        .with_sticking_speed(sticking_speed);
                    let scene = Scene::new(1.0 / 30.0)
                        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                        .with_ground(ground);
                    let settings = NewtonSettings::new()
                        .with_tolerance(1.0e-4, 30)
                        .with_preconditioner(preconditioner);
                    let (mut x, mut v) = (start.to_vec(), vec![Vec3::ZERO; n]);
                    let lengths = scratch_len::newton(n, ne);
                    let mut vectors = vec![Vec3::ZERO; lengths.vectors];
                    let mut blocks = vec![Mat3::ZERO; lengths.blocks];
                    let mut hessians = vec![TetHessian::default(); lengths.hessians];
                    let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
                    let mut reports = String::new();
                    for _ in 0..steps {
                        let report = newton_step(
                            model,
                            masses,
                            &[],
                            &scene,
                            &settings,
                            &mut x,
                            &mut v,
                            &mut scratch,
                        )
                        .unwrap();
                        reports += &format!("{report:?}\n");
                    }
                    (bits(&x), bits(&v), reports)
                }

                /// Whole relaxation and Newton runs of the dropped box (landing included),
                /// sequential against `ParallelTetElastic` on 1, 2, 3 and 8 threads: every
                /// position, velocity and report bit, with the ground's friction applied after
                /// the solve and in the objective (`SUGGESTED_STICKING_SPEED`); Newton with
                /// block Jacobi and (feature `alloc`) with the multilevel preconditioner, whose
                /// hierarchy then carries the ground's active set and friction's blocks.
                #[test]
                fn relaxation_and_newton_runs_on_1_2_3_8_threads_give_the_sequential_bits() {
                    for sticking_speed in [0.0, sf::step::SUGGESTED_STICKING_SPEED] {
                        runs_on_1_2_3_8_threads_give_the_sequential_bits(sticking_speed);
                    }
                }

                /// One sticking speed of the test above.
                fn runs_on_1_2_3_8_threads_give_the_sequential_bits(sticking_speed: Real) {
                    let (start, tets) = lifted_box(4);
                    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &start, &tets, 1000.0);
                    let ne = mesh.element_count();
                    let material = StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap();
                    let body = TetElastic::new(mesh, material);
                    let relaxed = relax_run(&body, &masses, &start, (6, sticking_speed));
                    let preconditioners = [
                        Preconditioner::BlockJacobi,
                        #[cfg(feature = "alloc")]
                        Preconditioner::Multilevel,
                    ];
                    let newton: Vec<RunBits> = preconditioners
                        .iter()
                        .map(|&p| newton_run(&body, &masses, &start, (4, sticking_speed, p)))
                        .collect();
                    // Landed: some vertex is on the ground (y = 0) at the end.
                    // The multilevel runs built their hierarchy (no fallback to block Jacobi).
                    #[cfg(feature = "alloc")]
                    assert!(newton[1].2.contains("multilevel_builds: 1"), "{}", newton[1].2);
                    for (x, _, _) in newton.iter().chain([&relaxed]) {
                        assert!(x.iter().any(|p| p[1] == 0.0f64.to_bits()), "not landed");
                    }
                    for threads in THREADS {
                        let (mut offsets, mut incident) = (Vec::new(), Vec::new());
                        let p = partition(mesh, 2 * threads + 1, &mut offsets, &mut incident);
                        let (mut element_forces, mut energies) =
                            (vec![[Vec3::ZERO; 4]; ne], vec![0.0; ne]);
                        let pool = pool(threads);
                        let parallel_body =
                            ParallelTetElastic::new(body, p, &mut element_forces, &mut energies)
                                .unwrap()
                                .with_pool(&pool);
                        let got = relax_run(&parallel_body, &masses, &start, (6, sticking_speed));
                        assert!(got == relaxed, "{threads} threads: relaxation run differs");
                        for (&preconditioner, newton) in preconditioners.iter().zip(&newton) {
                            let got = newton_run(&parallel_body, &masses, &start, (4, sticking_speed, preconditioner));
                            assert!(got == *newton, "{threads} threads: Newton run with {preconditioner:?} differs");
                        }
                    }
                }

                /// 100 explicit steps of a box dropped onto the ground, sequential against the
                /// parallel body on 1, 2, 3 and 8 threads: every position and velocity bit.
                #[test]
                fn explicit_box_drop_on_1_2_3_8_threads_gives_the_sequential_bits() {
                    let (rest, tets) = box_mesh(6);
                    let lifted: Vec<Vec3> = rest.iter().map(|p| *p + Vec3::Y * 0.002).collect();
                    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &lifted, &tets, 1000.0);
                    let (nv, ne) = (mesh.vertex_count(), mesh.element_count());
                    let material = StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap();
                    let body = TetElastic::new(mesh, material);
                    let mut stiffness = vec![0.0; nv];
                    let dt = 0.5 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                    let scene = Scene::new(dt)
                        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                        .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
                    let settings = ExplicitSettings::new().with_damping(2.0);
                    let run = |model: &dyn Fn(
                        &mut [Vec3],
                        &mut [Vec3],
                        &mut ExplicitScratch<'_, Vec3>,
                    )| {
                        let (mut x, mut v) = (lifted.clone(), vec![Vec3::ZERO; nv]);
                        let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(nv)];
                        let mut scratch = ExplicitScratch::new(&mut buffer);
                        for _ in 0..100 {
                            model(&mut x, &mut v, &mut scratch);
                        }
                        (bits(&x), bits(&v))
                    };
                    let expected = run(&|x, v, scratch| {
                        explicit_step(&body, &masses, &[], &scene, &settings, x, v, scratch).unwrap();
                    });
                    // The box has landed: the run exercised contacts, not only free fall.
                    let (mut x, mut v) = (lifted.clone(), vec![Vec3::ZERO; nv]);
                    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(nv)];
                    let mut scratch = ExplicitScratch::new(&mut buffer);
                    let mut contacts = 0;
                    for _ in 0..100 {
                        let report = explicit_step(
                            &body,
                            &masses,
                            &[],
                            &scene,
                            &settings,
                            &mut x,
                            &mut v,
                            &mut scratch,
                        )
                        .unwrap();
                        contacts += report.ground_contacts;
                    }
                    assert!(contacts > 0, "no contact in 100 steps");
                    for threads in THREADS {
                        let mut offsets = vec![0; partition_offsets_len(nv)];
                        let mut incident = vec![0; partition_incident_len(ne)];
                        let partition =
                            TetPartition::new(mesh, 3 * threads, &mut offsets, &mut incident)
                                .unwrap();
                        let mut element_forces = vec![[Vec3::ZERO; 4]; ne];
                        let mut energies = vec![0.0; ne];
                        let pool = pool(threads);
                        let parallel_body = ParallelTetElastic::new(
                            body,
                            partition,
                            &mut element_forces,
                            &mut energies,
                        )
                        .unwrap()
                        .with_pool(&pool);
                        let got = run(&|x, v, scratch| {
                            explicit_step(&parallel_body, &masses, &[], &scene, &settings, x, v, scratch)
                                .unwrap();
                        });
                        assert!(got == expected, "{threads} threads: explicit run differs");
                    }
                }

                /// Explicit steps of a free box of more vertices than one block of the vertex
                /// passes, with pinned vertices and external loads in every block, against the
                /// symplectic Euler update written out here vertex by vertex (forces from the
                /// sequential kernel): every block updates its own vertices with their own
                /// masses, flags and loads, bit for bit, sequential and on 2 and 3 threads.
                #[test]
                fn split_explicit_update_matches_the_update_written_out_vertex_by_vertex() {
                    let (start, tets) = box_mesh(13); // 2744 vertices: three blocks
                    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &start, &tets, 1000.0);
                    let nv = mesh.vertex_count();
                    let material = StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap();
                    let body = TetElastic::new(mesh, material);
                    let pinned: Vec<bool> = (0..nv).map(|i| i % 97 == 5).collect();
                    let loads: Vec<Vec3> = (0..nv)
                        .map(|i| Vec3::new(0.01, -0.02, 0.005) * (i % 13) as Real)
                        .collect();
                    let (gravity, damping, substeps) = (Vec3::new(0.0, -9.81, 0.0), 3.0, 2);
                    let mut stiffness = vec![0.0; nv];
                    let dt = 0.5 * stable_time_step(&body, &masses, &pinned, &mut stiffness).unwrap();
                    let scene = Scene::new(dt).with_gravity(gravity).with_external_forces(&loads);
                    let settings = ExplicitSettings::new()
                        .with_damping(damping)
                        .with_substeps(substeps);
                    // The update of `explicit_step`'s docs, one vertex at a time.
                    let (mut x, mut v) = (deformed(&start), vec![Vec3::ZERO; nv]);
                    let h = dt / substeps as Real;
                    let drag = 1.0 / (1.0 + damping * h);
                    for _ in 0..6 * substeps {
                        let mut f = vec![Vec3::ZERO; nv];
                        mesh.add_elastic_forces(&material, &x, &mut f).unwrap();
                        for i in (0..nv).filter(|&i| !pinned[i]) {
                            let mut acceleration = f[i] * (1.0 / masses[i]) + gravity;
                            acceleration += loads[i] * (1.0 / masses[i]);
                            v[i] = (v[i] + acceleration * h) * drag;
                            x[i] += v[i] * h;
                        }
                    }
                    let expected = (bits(&x), bits(&v));
                    let run = |model: &dyn Fn(
                        &mut [Vec3],
                        &mut [Vec3],
                        &mut ExplicitScratch<'_, Vec3>,
                    )| {
                        let (mut x, mut v) = (deformed(&start), vec![Vec3::ZERO; nv]);
                        let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(nv)];
                        let mut scratch = ExplicitScratch::new(&mut buffer);
                        for _ in 0..6 {
                            model(&mut x, &mut v, &mut scratch);
                        }
                        (bits(&x), bits(&v))
                    };
                    let sequential = run(&|x, v, scratch| {
                        explicit_step(&body, &masses, &pinned, &scene, &settings, x, v, scratch).unwrap();
                    });
                    assert!(sequential == expected, "sequential: the update differs");
                    for threads in [2, 3] {
                        let got = on_parallel_body(body, threads, threads, |parallel_body| {
                            run(&|x, v, scratch| {
                                explicit_step(parallel_body, &masses, &pinned, &scene, &settings, x, v, scratch)
                                    .unwrap();
                            })
                        });
                        assert!(got == expected, "{threads} threads: the update differs");
                    }
                }

                /// A box resting on the ground with more vertices than one block of the
                /// steppers' vertex passes (`VERTEX_BLOCK`, so that the passes split and their
                /// sums go over the block tree): explicit, relaxation and Newton runs, sequential
                /// against `ParallelTetElastic` on 1, 2, 3 and 8 threads, every position,
                /// velocity and report bit; and the explicit report's kinetic energy against a
                /// recomputation in f64.
                #[test]
                fn runs_with_vertex_passes_split_in_blocks_on_1_2_3_8_threads_give_the_sequential_bits()
                {
                    let (start, tets) = box_mesh(13); // 2744 vertices: three blocks
                    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &start, &tets, 1000.0);
                    let nv = mesh.vertex_count();
                    assert!(nv > 2 * sf::step::vertex_pass::VERTEX_BLOCK && nv < 3 * sf::step::vertex_pass::VERTEX_BLOCK);
                    let material = StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap();
                    let body = TetElastic::new(mesh, material);
                    let mut stiffness = vec![0.0; nv];
                    let dt = 0.5 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                    let explicit_scene = Scene::new(dt)
                        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                        .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
                    let explicit_settings = ExplicitSettings::new().with_damping(2.0).with_substeps(2);
                    let relax_scene = Scene::new(1.0 / 60.0)
                        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                        .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
                    let relax_settings = RelaxSettings::new().with_tolerance(0.0, 12);
                    let explicit = |model: &dyn Fn(
                        &mut [Vec3],
                        &mut [Vec3],
                        &mut ExplicitScratch<'_, Vec3>,
                    ) -> sf::step::ExplicitReport| {
                        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; nv]);
                        let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(nv)];
                        let mut scratch = ExplicitScratch::new(&mut buffer);
                        let mut reports = String::new();
                        for _ in 0..8 {
                            let report = model(&mut x, &mut v, &mut scratch);
                            reports += &format!("{report:?} {}\n", report.kinetic_energy.to_bits());
                            // The report's kinetic energy is the state's, to the rounding of
                            // a sum of 2744 positive terms (relative 2744 eps bounds it).
                            let exact: f64 = v
                                .iter()
                                .zip(&masses)
                                .map(|(v, &m)| 0.5 * m as f64 * (v.dot(*v) as f64))
                                .sum();
                            let tolerance = 2744.0 * Real::EPSILON as f64 * exact;
                            assert!(
                                (report.kinetic_energy as f64 - exact).abs() <= tolerance,
                                "kinetic energy {} against {exact}",
                                report.kinetic_energy
                            );
                        }
                        (bits(&x), bits(&v), reports)
                    };
                    let expected_explicit = explicit(&|x, v, scratch| {
                        explicit_step(&body, &masses, &[], &explicit_scene, &explicit_settings, x, v, scratch)
                            .unwrap()
                    });
                    assert!(
                        !expected_explicit.2.contains("ground_contacts: 0 }"),
                        "the box must touch the ground"
                    );
                    let relax = |model: &dyn Fn(
                        &mut [Vec3],
                        &mut [Vec3],
                        &mut RelaxScratch<'_, Vec3>,
                    ) -> String| {
                        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; nv]);
                        let mut vectors = vec![Vec3::ZERO; scratch_len::relax(nv)];
                        let mut scalars = vec![0.0; nv];
                        let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                        let reports: String =
                            (0..2).map(|_| model(&mut x, &mut v, &mut scratch)).collect();
                        (bits(&x), bits(&v), reports)
                    };
                    let expected_relax = relax(&|x, v, scratch| {
                        let report =
                            relax_step(&body, &masses, &[], &relax_scene, &relax_settings, x, v, scratch)
                                .unwrap();
                        format!("{report:?}\n")
                    });
                    // Newton with its linear solves cut short, so that the run stays short
                    // but every CG pass (the product's vertex terms, the updates with their
                    // dot products, the preconditioner) runs many times over the three blocks.
                    let newton_scene = Scene::new(1.0 / 60.0)
                        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                        .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
                    let newton_settings = NewtonSettings::new().with_tolerance(0.0, 3).with_cg_iterations(40);
                    let ne = mesh.element_count();
                    let newton = |model: &dyn Fn(
                        &mut [Vec3],
                        &mut [Vec3],
                        &mut NewtonScratch<'_>,
                    ) -> sf::step::NewtonReport| {
                        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; nv]);
                        let lengths = scratch_len::newton(nv, ne);
                        let mut vectors = vec![Vec3::ZERO; lengths.vectors];
                        let mut blocks = vec![Mat3::ZERO; lengths.blocks];
                        let mut hessians = vec![TetHessian::default(); lengths.hessians];
                        let mut scratch =
                            NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
                        let mut reports = String::new();
                        for _ in 0..2 {
                            let report = model(&mut x, &mut v, &mut scratch);
                            // The whole budget of Newton iterations, each with CG passes
                            // over the three blocks (73 to 117 CG iterations a step measured).
                            assert!(
                                report.iterations == 3 && report.details.cg_iterations >= 3 * 10,
                                "{report:?}"
                            );
                            reports += &format!("{report:?}\n");
                        }
                        (bits(&x), bits(&v), reports)
                    };
                    let expected_newton = newton(&|x, v, scratch| {
                        newton_step(&body, &masses, &[], &newton_scene, &newton_settings, x, v, scratch).unwrap()
                    });
                    for threads in THREADS {
                        on_parallel_body(body, 2 * threads, threads, |parallel_body| {
                            let got = newton(&|x, v, scratch| {
                                newton_step(
                                    parallel_body,
                                    &masses,
                                    &[],
                                    &newton_scene,
                                    &newton_settings,
                                    x,
                                    v,
                                    scratch,
                                )
                                .unwrap()
                            });
                            assert!(got == expected_newton, "{threads} threads: Newton differs");
                            let got = explicit(&|x, v, scratch| {
                                explicit_step(
                                    parallel_body,
                                    &masses,
                                    &[],
                                    &explicit_scene,
                                    &explicit_settings,
                                    x,
                                    v,
                                    scratch,
                                )
                                .unwrap()
                            });
                            assert!(got == expected_explicit, "{threads} threads: explicit differs");
                            let got = relax(&|x, v, scratch| {
                                let report = relax_step(
                                    parallel_body,
                                    &masses,
                                    &[],
                                    &relax_scene,
                                    &relax_settings,
                                    x,
                                    v,
                                    scratch,
                                )
                                .unwrap();
                                format!("{report:?}\n")
                            });
                            assert!(got == expected_relax, "{threads} threads: relaxation differs");
                        });
                    }
                }
            }
        }
    };
}

precision_tests!(single, softfem, f32);
precision_tests!(double, softfem::f64, f64);
