//! The core's modules form layers (`src/lib.rs`): a module may use only modules of lower layers.
//! This test reads the sources and checks every `crate::…` path outside comments and test
//! modules, so a dependency cycle (such as the former classifier → features → monitor →
//! classifier) cannot come back unnoticed.

use std::collections::BTreeMap;
use std::path::Path;

/// Layer of each top-level module of `src/` (see the crate docs).
const LAYERS: &[(&str, u32)] = &[
    ("fixed", 0),
    ("units", 1),
    ("fault", 1),
    ("metrics", 1),
    ("mechanism", 1),
    ("params", 2),
    ("sensor", 2),
    ("twin", 3),
    ("plausibility", 3),
    ("report", 3),
    ("estimator", 4),
    ("reservoir", 4),
    ("can", 4),
    ("monitor", 5),
    ("features", 5),
    ("classifier", 6),
    ("pipeline", 7),
];

/// Code of a source file without comments and without its `#[cfg(test)]` module.
fn code(text: &str) -> String {
    let text = text.find("#[cfg(test)]\nmod ").map_or(text, |i| &text[..i]);
    text.lines().map(|l| l.find("//").map_or(l, |i| &l[..i])).collect::<Vec<_>>().join("\n")
}

/// Identifiers following `crate::` (and those inside `crate::{…}` groups).
fn crate_paths(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (i, _) in code.match_indices("crate::") {
        let rest = &code[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let group = &group[..group.find('}').unwrap_or(group.len())];
            out.extend(group.split(',').filter_map(|p| p.trim().split("::").next()).map(str::to_owned));
        } else {
            out.push(rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect());
        }
    }
    out.retain(|s| !s.is_empty());
    out
}

/// The crate root's re-exports (`pub use module::{A, B};`): name → module.
fn reexports(lib: &str) -> BTreeMap<String, String> {
    let mut map = BTreeMap::new();
    for line in code(lib).lines() {
        let Some(rest) = line.trim().strip_prefix("pub use ") else { continue };
        let (module, names) = rest.trim_end_matches(';').split_once("::").expect("pub use module::…");
        for name in names.trim_matches(|c| c == '{' || c == '}').split(',') {
            map.insert(name.trim().to_owned(), module.to_owned());
        }
    }
    map
}

fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn every_module_uses_only_lower_layers() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let layers: BTreeMap<&str, u32> = LAYERS.iter().copied().collect();
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
    let reexported = reexports(&lib);
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut violations = Vec::new();
    for file in files {
        let rel = file.strip_prefix(&src).unwrap();
        let module = rel.iter().next().unwrap().to_string_lossy().trim_end_matches(".rs").to_owned();
        if module == "lib" {
            continue;
        }
        let own = *layers.get(module.as_str()).unwrap_or_else(|| panic!("module `{module}` has no layer"));
        for path in crate_paths(&code(&std::fs::read_to_string(&file).unwrap())) {
            let used = reexported.get(&path).cloned().unwrap_or(path);
            if used == module {
                continue;
            }
            let layer =
                *layers.get(used.as_str()).unwrap_or_else(|| panic!("{}: `crate::{used}` has no layer", rel.display()));
            if layer >= own {
                violations.push(format!("{} (layer {own}) uses crate::{used} (layer {layer})", rel.display()));
            }
        }
    }
    assert!(violations.is_empty(), "dependencies against the layers:\n{}", violations.join("\n"));
}

#[test]
fn the_check_sees_a_violation() {
    let paths = crate_paths(&code("use crate::monitor::MonitorStep;\n// crate::pipeline\nuse crate::{a, b::C};"));
    assert_eq!(paths, ["monitor", "a", "b"]);
    assert!(code("x\n#[cfg(test)]\nmod tests {\n use crate::pipeline;\n}").find("pipeline").is_none());
}
