//! Assets in and out: voxel meshing, embedding a render surface, surface buffers, the OBJ, Gmsh
//! and TetGen readers, and the README's and crate docs' front-page examples kept in step. One
//! test binary (one link) for what were separate files; each module is one of them, its docs say
//! what it proves. `cargo test --test assets voxel::` runs one of them.

#[path = "../common/mod.rs"]
mod common;

mod embed;
mod front_page;
mod gmsh;
mod obj;
mod reliability;
mod surface;
mod tetgen;
mod voxel;
