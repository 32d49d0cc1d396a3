//! Readable names for the legacy-mangled symbols of the binaries the tests build and inspect
//! (`tests/no_std_probe.rs`, `tests/firmware.rs`).

/// `softfem::svd::svd3` for a legacy-mangled Rust symbol, with `<T as Trait>` spelled out; the
/// symbol itself otherwise.
pub fn demangle(symbol: &str) -> String {
    let Some(mut rest) = symbol.strip_prefix("_ZN").and_then(|s| s.strip_suffix('E')) else {
        return symbol.to_owned();
    };
    let mut path = Vec::new();
    while !rest.is_empty() {
        let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
        let Ok(len) = rest[..digits].parse::<usize>() else {
            return symbol.to_owned();
        };
        let Some(component) = rest.get(digits..digits + len) else {
            return symbol.to_owned();
        };
        path.push(component);
        rest = &rest[digits + len..];
    }
    if path
        .last()
        .is_some_and(|h| h.len() == 17 && h.starts_with('h'))
    {
        path.pop();
    }
    path.join("::")
        .replace("$LT$", "<")
        .replace("$GT$", ">")
        .replace("$u20$", " ")
        .replace("..", "::")
        .replace("_<", "<")
}
