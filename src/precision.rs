//! The list of softfem's numeric modules, written once for both precisions.
//!
//! `src/f32/mod.rs` and `src/f64/mod.rs` each declare their precision's aliases (`types`), math
//! shim (`math`), AVX intrinsics (`wide_ops`) and lane representation (`lane_repr`), then invoke
//! `numeric_modules!()`, which declares the modules below: the same source files, compiled once
//! per precision against those items (they reach them through `super::`). The `#[path]`s are
//! relative to the invoking file's folder, `src/f32/` or `src/f64/`, both one level below
//! `src/`, so one list serves both.

/// Declares the numeric modules of one precision (see the module docs).
macro_rules! numeric_modules {
    () => {
        #[path = "../lanes/mod.rs"]
        pub mod lanes;

        #[path = "../svd.rs"]
        pub mod svd;

        #[path = "../polar.rs"]
        pub mod polar;

        #[path = "../material/mod.rs"]
        pub mod material;

        #[path = "../generate.rs"]
        pub mod generate;

        #[path = "../element/mod.rs"]
        pub mod element;

        #[path = "../mesh/mod.rs"]
        pub mod mesh;

        #[path = "../step/mod.rs"]
        pub mod step;

        #[path = "../body/mod.rs"]
        pub mod body;

        #[path = "../world/mod.rs"]
        pub mod world;

        #[cfg(feature = "rayon")]
        #[cfg_attr(docsrs, doc(cfg(feature = "rayon")))]
        #[path = "../parallel.rs"]
        pub mod parallel;

        #[path = "../asset/mod.rs"]
        pub mod asset;
    };
}

pub(crate) use numeric_modules;
