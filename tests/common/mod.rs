//! Helpers shared by the integration tests (declared once, `mod common;`, in each test binary's
//! `main.rs`): a deterministic random stream, the two precisions of the SVD-based routines behind
//! one interface, the per-precision scaffolding of the material and mesh identity tests, the lock
//! on the process-wide SIMD width, closed surfaces ([`shapes`]), vibration modes ([`modes`]) and
//! the scene set-ups the suites repeat ([`scenes`]).

// Every test binary compiles its own copy of this module and uses only part of it (tests/assets/
// none of the material macros, tests/steppers/ none of the SVD helpers), so the items, macros
// and macro re-exports one binary leaves unused would otherwise warn there.
#![allow(dead_code, unused_macros, unused_imports)]

pub mod modes;
pub mod scenes;
pub mod shapes;

use std::sync::{Mutex, MutexGuard};

use softfem::glam::{DMat3, DQuat, DVec3};

/// The SIMD width cap (`softfem::simd::set_max_width`) is process-wide: the tests that set it
/// (tests/kernels/simd.rs, tests/kernels/hessian.rs, one binary, one process) take turns.
static WIDTH_LOCK: Mutex<()> = Mutex::new(());

/// Holds the SIMD width cap for the caller until the guard drops.
pub fn lock_width() -> MutexGuard<'static, ()> {
    WIDTH_LOCK
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

// ---------------------------------------------------------------------------------------------
// Deterministic random numbers.
// ---------------------------------------------------------------------------------------------

/// xorshift64* (Vigna 2016): deterministic and dependency-free, so every run sees the same
/// samples.
///
/// `Rng(state)` starts from `state` as given (it must be non-zero); [`Rng::new`] mixes a seed
/// first. The two are kept apart because the tests' expected streams were recorded both ways.
pub struct Rng(pub u64);

impl Rng {
    /// A stream from `seed`, mixed so that nearby seeds give unrelated streams (any non-zero
    /// state works; the `| 1` keeps it non-zero).
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in `[0, 1)`, from the top 53 bits (exact in f64).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform in `[-1, 1)`. Bit for bit `uniform(-1.0, 1.0)`: `2 unit` is exact and IEEE
    /// addition is commutative, so `2 unit - 1 = -1 + 2 unit` exactly.
    pub fn signed(&mut self) -> f64 {
        2.0 * self.unit() - 1.0
    }

    /// Uniform in `0..n`.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// `+1` or `-1` with equal probability.
    pub fn sign(&mut self) -> f64 {
        if self.next_u64() >> 63 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// Log-uniform in `[lo, hi]`.
    pub fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo * (hi / lo).powf(self.unit())
    }

    /// `k / 2^bits` for a uniform integer `|k| <= 2^bits`: products of two such numbers with
    /// `bits <= 12`, and sums of two products with `bits <= 11`, are exact in f32.
    pub fn short(&mut self, bits: u32) -> f64 {
        let k = self.below((2 << bits) + 1) as f64 - (1u64 << bits) as f64;
        k / (1u64 << bits) as f64
    }

    /// A matrix of entries uniform in `[-1, 1)`.
    pub fn entries(&mut self) -> DMat3 {
        DMat3::from_cols_array(&core::array::from_fn(|_| self.signed()))
    }

    /// A vector of entries uniform in `[-1, 1)`.
    pub fn vector(&mut self) -> DVec3 {
        DVec3::new(self.signed(), self.signed(), self.signed())
    }

    /// A uniformly distributed proper rotation (normalised point of the unit 4-ball).
    pub fn rotation(&mut self) -> DMat3 {
        loop {
            let q = DQuat::from_xyzw(self.signed(), self.signed(), self.signed(), self.signed());
            let norm = q.length();
            if norm > 0.1 && norm <= 1.0 {
                return DMat3::from_quat(q / norm);
            }
        }
    }

    /// `r1 diag(s) r2^T` with independent random rotations.
    pub fn rotated(&mut self, s: DVec3) -> DMat3 {
        self.rotation() * DMat3::from_diagonal(s) * self.rotation().transpose()
    }
}

// ---------------------------------------------------------------------------------------------
// The SVD-based routines in both precisions (tests/kernels/svd.rs, tests/kernels/polar.rs).
// ---------------------------------------------------------------------------------------------

/// `||m||_F`.
pub fn frobenius(m: DMat3) -> f64 {
    m.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// One precision of softfem, seen from f64: inputs are generated in f64 and rounded to the
/// precision, outputs widened back exactly, and errors measured in f64.
pub trait Precision {
    const NAME: &'static str;
    /// `||q^T q - I||_F` and `|det q - 1|` for the rotations of the SVD (and of the polar
    /// decomposition built on it). About 80 eps in f32 and 450 in f64: a product of a dozen
    /// exact plane rotations drifts from orthogonality by a few eps; the margin keeps the bound
    /// robust to reordering of the arithmetic by the ongoing optimisation work.
    const ORTH_TOL: f64;
    /// `||u diag(sigma) v^T - a||_F / ||a||_F`. 2e-6 is 17 eps in f32, 1e-13 is 450 eps in f64:
    /// the SVD is backward stable (orthogonal transformations only, exact power-of-two
    /// scaling), so the error is a small multiple of eps whatever the conditioning.
    const RECON_TOL: f64;

    /// `a` rounded to this precision: the input the routine actually sees.
    fn round(a: DMat3) -> DMat3;
    /// `a` as a Rust expression of this precision, for failure messages.
    fn show(a: DMat3) -> String;
}

/// The `f32` API at the crate root.
pub struct F32;
/// The `f64` API under `softfem::f64`.
pub struct F64;

impl Precision for F32 {
    const NAME: &'static str = "f32";
    const ORTH_TOL: f64 = 1e-5;
    const RECON_TOL: f64 = 2e-6;

    fn round(a: DMat3) -> DMat3 {
        a.as_mat3().as_dmat3()
    }

    fn show(a: DMat3) -> String {
        format!("Mat3::from_cols_array(&{:?})", a.as_mat3().to_cols_array())
    }
}

impl Precision for F64 {
    const NAME: &'static str = "f64";
    const ORTH_TOL: f64 = 1e-13;
    const RECON_TOL: f64 = 1e-13;

    fn round(a: DMat3) -> DMat3 {
        a
    }

    fn show(a: DMat3) -> String {
        format!("DMat3::from_cols_array(&{:?})", a.to_cols_array())
    }
}

// ---------------------------------------------------------------------------------------------
// Per-precision scaffolding of the material and mesh identity tests (tests/kernels/material.rs,
// tests/kernels/identities.rs). These are macros because each suite is itself a macro instantiated
// once per precision: the names below (`Real`, `Mat3`, `Lame`, the models, `Rng`) resolve to the
// items in scope where they expand.
// ---------------------------------------------------------------------------------------------

/// `EPS`, the parameter sets, the modulus, the Frobenius norm and a uniform sample in `Real`.
macro_rules! material_helpers {
    () => {
        const EPS: Real = Real::EPSILON;

        /// Parameter sets (Pa): soft rubber, nearly incompressible rubber (`lambda/mu = 9`,
        /// which amplifies rounding), and an auxetic material with negative `lambda`, so that
        /// sign mistakes in `lambda` show.
        fn parameter_sets() -> [Lame; 3] {
            [
                Lame::from_young_poisson(1.0e5, 0.3).unwrap(),
                Lame::from_young_poisson(1.0e6, 0.45).unwrap(),
                Lame::from_young_poisson(2.0e3, -0.3).unwrap(),
            ]
        }

        /// The P-wave modulus `lambda + 2 mu` (Pa): the scale of every stress at strains of
        /// order one, used to turn relative tolerances into absolute ones.
        fn modulus(lame: Lame) -> Real {
            lame.lambda() + 2.0 * lame.mu()
        }

        fn norm(m: Mat3) -> Real {
            (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared())
                .sqrt()
        }

        /// Uniform in `[lo, hi)`, drawn in f64 and rounded to `Real`.
        fn uniform(rng: &mut Rng, lo: Real, hi: Real) -> Real {
            rng.uniform(lo as f64, hi as f64) as Real
        }
    };
}
pub(crate) use material_helpers;

/// Runs the generic check `$check(lame, model)` for the three models and every parameter set.
macro_rules! for_each_model {
    ($check:ident) => {
        for lame in parameter_sets() {
            $check(lame, StVK::new(lame));
            $check(lame, NeoHookean::new(lame));
            $check(lame, StableNeoHookean::new(lame));
        }
    };
}
pub(crate) use for_each_model;
