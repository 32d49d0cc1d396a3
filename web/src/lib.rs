//! The softfem playground in a web browser (issue #43): the scene of `examples/playground`
//! ([`scene`]) and a pile of balls in contact in one `World` ([`pile`]), the page's two scenes
//! ([`stage`]), stepped by softfem's `no_std` API (f32, growable storage), and their plain
//! `extern "C"` face for the page ([`exports`]), compiled to `wasm32-unknown-unknown` as a
//! cdylib that `web/main.js` instantiates without wasm-bindgen. The native program
//! `web-timing` steps the same scenes for the page's wasm/native ratio.
//!
//! Build the module, serve the repository root and open <http://127.0.0.1:8000/web/> (the page
//! loads `../target/wasm32-unknown-unknown/release/softfem_web.wasm`, or the URL in its `wasm`
//! query parameter):
//!
//! ```text
//! cargo rustc --release -p softfem-web --lib --target wasm32-unknown-unknown --crate-type cdylib
//! python3 -m http.server -b 127.0.0.1 8000
//! ```
// No panic path in what the page calls; the tests may index and unwrap.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

pub mod exports;
pub mod pile;
pub mod scene;
pub mod stage;
