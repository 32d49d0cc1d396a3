//! The README's "Using it" leads with the owning body (explicit and implicit, with colliders, in
//! about ten lines); its second example and the crate docs' front page (`src/lib.rs`) are the
//! same low-level example, stepping a body, character for character. Every copy runs as a doc
//! test (the README's through `ReadmeDoctests` in `src/lib.rs`); this test keeps them from
//! drifting apart.

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

/// The second fenced code block after the heading `heading` in `markdown`.
fn second_block_after(markdown: &str, heading: &str) -> String {
    let section = markdown
        .split_once(&format!("\n{heading}\n"))
        .unwrap_or_else(|| panic!("no heading {heading:?}"))
        .1;
    // Past the first block's closing fence.
    let mut fences = section.match_indices("\n```");
    let (_, _) = (fences.next(), fences.next());
    let rest = &section[fences.next().expect("no second block").0..];
    first_block_after(&format!("\n{heading}\n{rest}"), heading)
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
fn the_readme_leads_with_the_front_page_example_of_stepping_a_body() {
    let front_page = first_block_after(&crate_docs(), "## Stepping a body");
    let readme = second_block_after(include_str!("../../README.md"), "## Using it");
    assert!(
        front_page.contains("explicit_step(&body"),
        "the front page's first example does not step a body:\n{front_page}"
    );
    assert_eq!(
        readme, front_page,
        "README.md's second example under \"## Using it\" differs from src/lib.rs's under \
         \"## Stepping a body\"; copy one onto the other"
    );
}
