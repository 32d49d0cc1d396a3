//! The repository's paths for the programs that write charts into `docs/` (`tradeoffs`,
//! `tuning_map`), included by each with `#[path]`.

use std::path::{Component, Path, PathBuf};

/// The repository's root: the folder above this program's package, `examples/`.
pub fn repository_root() -> &'static Path {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR"));
    examples.parent().unwrap_or(examples)
}

/// The repository's `docs/` directory, which holds the committed charts.
pub fn docs_dir() -> PathBuf {
    repository_root().join("docs")
}

/// `path` made absolute (against `cwd`) with `.` and `..` resolved by name, so that
/// `docs/../docs/charts` and `./docs/charts` compare equal to `docs/charts`.
pub fn absolute(path: &Path, cwd: &Path) -> PathBuf {
    let mut resolved = PathBuf::new();
    for component in cwd.join(path).components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => {
                resolved.pop();
            }
            other => resolved.push(other),
        }
    }
    resolved
}
