//! The README's "Using it" and the crate docs' front page (`src/lib.rs`) lead with the same
//! example, stepping a body, character for character. Both copies run as doc tests (the README's
//! through `ReadmeDoctests` in `src/lib.rs`); this test keeps them from drifting apart.

/// The crate-level documentation of `src/lib.rs` as markdown (its `//!` lines, prefix removed).
fn crate_docs() -> String {
    include_str!("../src/lib.rs")
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

#[test]
fn the_readme_leads_with_the_front_page_example_of_stepping_a_body() {
    let front_page = first_block_after(&crate_docs(), "## Stepping a body");
    let readme = first_block_after(include_str!("../README.md"), "## Using it");
    assert!(
        front_page.contains("step_explicit(&body"),
        "the front page's first example does not step a body:\n{front_page}"
    );
    assert_eq!(
        readme, front_page,
        "README.md's first example under \"## Using it\" differs from src/lib.rs's under \
         \"## Stepping a body\"; copy one onto the other"
    );
}
