//! The README's "Using it" leads with the owning body (explicit and implicit, with colliders, in
//! about ten lines), and the crate docs' front page (`src/lib.rs`, "Stepping a body") opens
//! with the same example, character for character. Every copy runs as a doc test (the README's
//! through `ReadmeDoctests` in `src/lib.rs`); this test keeps them from drifting apart. It also
//! keeps the user guide honest: every chapter under `docs/guide/` is listed in the guide's table
//! of contents and in the README, and runs as a doc test through its own item in `src/lib.rs`.

/// The crate-level documentation of `src/lib.rs` as markdown (its `//!` lines, prefix removed).
fn crate_docs() -> String {
    include_str!("../../src/lib.rs")
        .lines()
        .filter_map(|line| line.strip_prefix("//!"))
        .map(|line| line.strip_prefix(' ').unwrap_or(line))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The first fenced code block after the heading `heading` in `markdown`, without its fences.
fn first_block_after(markdown: &str, heading: &str) -> String {
    let section = markdown
        .split_once(&format!("\n{heading}\n"))
        .unwrap_or_else(|| panic!("no heading {heading:?}"))
        .1;
    let mut lines = section.lines().skip_while(|line| !line.starts_with("```"));
    let fence = lines
        .next()
        .unwrap_or_else(|| panic!("no code after {heading:?}"));
    assert!(
        fence == "```" || fence == "```rust",
        "the first block after {heading:?} is not Rust: {fence}"
    );
    lines
        .take_while(|line| !line.starts_with("```"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The README leads with the owning body, stepped explicitly and by an implicit solver, with
/// colliders, in about ten lines (it runs as a doc test through `ReadmeDoctests`).
#[test]
fn the_readme_leads_with_a_body_stepped_explicitly_and_implicitly() {
    let readme = first_block_after(include_str!("../../README.md"), "## Using it");
    for needle in [
        "Body::<FixedStorage",
        "Solver::explicit()",
        "Solver::newton()",
        "step_with_colliders(",
        "Collider::",
    ] {
        assert!(readme.contains(needle), "no {needle:?} in:\n{readme}");
    }
    let code = readme
        .lines()
        .filter(|line| !line.trim_start().starts_with("//") && !line.starts_with('#'))
        .filter(|line| !line.trim().is_empty() && line.trim() != "}")
        .count();
    assert!(code <= 14, "{code} lines of code:\n{readme}");
}

#[test]
fn the_readme_and_the_crate_docs_open_with_the_same_body_example() {
    let front_page = first_block_after(&crate_docs(), "## Stepping a body");
    let readme = first_block_after(include_str!("../../README.md"), "## Using it");
    assert!(
        front_page.contains("Body::<FixedStorage"),
        "the crate docs' first example does not step a body:\n{front_page}"
    );
    assert_eq!(
        readme, front_page,
        "README.md's first example under \"## Using it\" differs from src/lib.rs's under \
         \"## Stepping a body\"; copy one onto the other"
    );
}

/// The chapters of the user guide: the markdown files of `docs/guide/` but its table of
/// contents, in file-name order (their numbers give the reading order).
fn guide_chapters() -> Vec<String> {
    let folder = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/guide");
    let mut chapters: Vec<String> = std::fs::read_dir(&folder)
        .unwrap_or_else(|error| panic!("{}: {error}", folder.display()))
        .map(|entry| {
            entry
                .expect("a readable entry")
                .file_name()
                .into_string()
                .expect("UTF-8")
        })
        .filter(|name| name.ends_with(".md") && name != "README.md")
        .collect();
    chapters.sort();
    chapters
}

#[test]
fn every_guide_chapter_is_listed_and_runs_its_examples_as_doc_tests() {
    let chapters = guide_chapters();
    assert!(
        chapters.len() >= 10,
        "only {} chapters: {chapters:?}",
        chapters.len()
    );
    let lib = include_str!("../../src/lib.rs");
    let contents = include_str!("../../docs/guide/README.md");
    let readme = include_str!("../../README.md");
    for chapter in &chapters {
        let item = format!("#[doc = include_str!(\"../docs/guide/{chapter}\")]");
        let at = lib
            .find(&item)
            .unwrap_or_else(|| panic!("src/lib.rs has no doc-test item for {chapter}"));
        assert!(
            lib[..at].trim_end().ends_with("#[cfg(doctest)]"),
            "{chapter}'s item in src/lib.rs is not #[cfg(doctest)]"
        );
        assert!(
            contents.contains(&format!("({chapter})")),
            "docs/guide/README.md does not list {chapter}"
        );
        assert!(
            readme.contains(&format!("(docs/guide/{chapter})")),
            "README.md does not link {chapter}"
        );
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("docs/guide")
                .join(chapter),
        )
        .expect("the chapter reads");
        assert!(text.contains("\n```rust"), "{chapter} has no Rust example");
        assert!(
            text.contains("assert"),
            "{chapter}'s examples assert nothing"
        );
    }
}

#[test]
fn the_readme_is_a_front_page() {
    let readme = include_str!("../../README.md");
    let lines = readme.lines().count();
    assert!(
        lines <= 300,
        "README.md has {lines} lines; the issue allows 300"
    );
    // The commands `.ci/run` calls "the README's": the test command and the main example.
    for command in [
        "cargo test --workspace --all-features",
        "cargo run --release -p softfem-examples --bin bouncy",
    ] {
        assert!(readme.contains(command), "README.md lost {command:?}");
    }
}
