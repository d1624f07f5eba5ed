//! The library's layers import only downward, and no two modules of a layer import each other
//! round a cycle: read from the `crate::` and `super::` paths of every file under `src/`
//! (the command line, `src/cli` and `main.rs`, sits on top and is not read). Within a layer
//! it follows paths into the layer's own modules (`crate::planning::gait`, `super::gait`
//! from a file of the layer's folder); a name the layer's `mod.rs` re-exports, and
//! `super::` inside a nested folder, are not followed.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The layers, bottom first: the utilities, then the stages in the order the data flows
/// (DESIGN.md), the parameter set that gathers them, the recordings, the regression runner.
const LAYERS: &[&[&str]] = &[
    &["cancel", "stats", "geom2d", "geom3d", "cloud", "plot_font"],
    &["scenario"],
    &["scene"],
    &["robot"],
    &["sensor"],
    &["perception"],
    &["planning"],
    &["estimate"],
    &["control"],
    &["climb"],
    &["sim"],
    &["params"],
    &["record"],
    &["regress"],
];

fn layer_of(top: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&top))
}

/// A source file's module: its layer (the top-level module) and, inside a folder, the
/// submodule it belongs to (`None` for the folder's own `mod.rs`).
fn module_of(rel: &Path) -> (String, Option<String>) {
    let parts: Vec<String> =
        rel.iter().map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string()).collect();
    let top = parts[0].clone();
    let sub = parts.get(1).filter(|s| s.as_str() != "mod").cloned();
    (top, sub)
}

/// The code of a file without its unit-test modules (`#[cfg(test)] mod tests { .. }` imports
/// `super::*`, its own file) and without line comments.
fn code_of(text: &str) -> String {
    let mut code = String::new();
    let mut rest = text;
    while let Some(i) = rest.find("#[cfg(test)]") {
        code.push_str(&rest[..i]);
        let after = &rest[i + "#[cfg(test)]".len()..];
        let item = after.trim_start();
        if !item.starts_with("mod ") {
            rest = after;
            continue;
        }
        // Skip the module, up to its matching brace.
        let open = item.find('{').unwrap_or(item.len());
        let mut depth = 0usize;
        let mut end = item.len();
        for (k, c) in item[open..].char_indices() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = open + k + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        rest = &item[end..];
    }
    code.push_str(rest);
    code.lines().filter(|l| !l.trim_start().starts_with("//")).collect::<Vec<_>>().join("\n")
}

/// Every path after `prefix` in `code`, as its first two segments; a group
/// (`crate::{a::b, c}`) gives each of its paths.
fn paths_after(code: &str, prefix: &str) -> Vec<(String, Option<String>)> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(i) = rest.find(prefix) {
        let before = rest[..i].chars().last();
        rest = &rest[i + prefix.len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        match rest.strip_prefix('{') {
            Some(group) => out.extend(group_items(group).iter().filter_map(|item| first_two(item))),
            None => out.extend(first_two(rest)),
        }
    }
    out
}

/// A path's first two segments (the second `None` where it ends or opens a group).
fn first_two(path: &str) -> Option<(String, Option<String>)> {
    let ident = |s: &str| s.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect::<String>();
    let path = path.trim_start();
    let first = ident(path);
    let second = path[first.len()..].strip_prefix("::").map(ident).filter(|s| !s.is_empty());
    (!first.is_empty()).then_some((first, second))
}

/// The items of a group whose `{` was just read, up to its `}`: split at its own commas.
fn group_items(group: &str) -> Vec<&str> {
    let (mut depth, mut start, mut items) = (0usize, 0usize, Vec::new());
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => {
                items.push(&group[start..i]);
                return items;
            }
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&group[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items
}

/// The layering's violations among `files` (paths relative to `src/`, with their text): an
/// import of a layer above, and cycles among the submodules of one layer.
fn violations(files: &[(String, String)]) -> Vec<String> {
    let subs: BTreeSet<(String, String)> = files
        .iter()
        .filter_map(|(p, _)| module_of(Path::new(p)).1.map(|s| (module_of(Path::new(p)).0, s)))
        .collect();
    let mut bad = Vec::new();
    let mut edges: BTreeMap<(String, String), BTreeSet<String>> = BTreeMap::new();
    for (path, text) in files {
        let (top, sub) = module_of(Path::new(path));
        let Some(here) = layer_of(&top) else {
            bad.push(format!("{path}: module `{top}` is in no layer of tests/layers.rs"));
            continue;
        };
        let code = code_of(text);
        for (to, to_sub) in paths_after(&code, "crate::") {
            if to == top {
                if let (Some(s), Some(t)) = (&sub, &to_sub) {
                    if subs.contains(&(top.clone(), t.clone())) && s != t {
                        edges.entry((top.clone(), s.clone())).or_default().insert(t.clone());
                    }
                }
                continue;
            }
            match layer_of(&to) {
                Some(there) if there > here => {
                    bad.push(format!("{path}: `{top}` imports `crate::{to}`, a layer above it"))
                }
                _ => {}
            }
        }
        if let (Some(s), true) = (&sub, super_is_the_layers_root(path)) {
            for (to, _) in paths_after(&code, "super::") {
                if subs.contains(&(top.clone(), to.clone())) && &to != s {
                    edges.entry((top.clone(), s.clone())).or_default().insert(to);
                }
            }
        }
    }
    // Cycles among a layer's submodules: a depth-first search for a back edge.
    for ((top, from), _) in edges.iter() {
        let mut stack = vec![(from.clone(), vec![from.clone()])];
        let mut seen = BTreeSet::new();
        while let Some((at, trail)) = stack.pop() {
            for next in edges.get(&(top.clone(), at.clone())).into_iter().flatten() {
                if next == from {
                    let cycle = format!("{top}: {} -> {from}", trail.join(" -> "));
                    if !bad
                        .iter()
                        .any(|b: &String| b.starts_with(&format!("{top}: ")) && same_cycle(b, &cycle))
                    {
                        bad.push(cycle);
                    }
                } else if seen.insert(next.clone()) {
                    let mut t = trail.clone();
                    t.push(next.clone());
                    stack.push((next.clone(), t));
                }
            }
        }
    }
    bad
}

/// Whether `super::` in the file at `path` is its layer's root module: a file right in the
/// layer's folder, or a subfolder's `mod.rs`.
fn super_is_the_layers_root(path: &str) -> bool {
    let parts: Vec<&str> = path.split('/').collect();
    parts.len() == 2 || (parts.len() == 3 && parts[2] == "mod.rs")
}

/// Whether two cycle messages name the same modules (a cycle is found from each of them).
fn same_cycle(a: &str, b: &str) -> bool {
    fn words(s: &str) -> BTreeSet<&str> {
        s.split(&[' ', ':', '-', '>'][..]).filter(|w| !w.is_empty()).collect()
    }
    words(a) == words(b)
}

fn sources() -> Vec<(String, String)> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = Vec::new();
    let mut dirs = vec![src.clone()];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).expect("src/ is readable") {
            let p = e.expect("a directory entry").path();
            let rel = p.strip_prefix(&src).expect("under src/").to_string_lossy().to_string();
            if rel == "cli" || rel == "main.rs" || rel == "lib.rs" {
                continue;
            }
            if p.is_dir() {
                dirs.push(p);
            } else if rel.ends_with(".rs") {
                out.push((rel, std::fs::read_to_string(&p).expect("a source file")));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn the_library_imports_only_downward_and_no_layer_imports_itself_round_a_cycle() {
    let files = sources();
    assert!(files.len() > 50, "read {} files", files.len());
    let bad = violations(&files);
    assert!(bad.is_empty(), "layering broken:\n{}", bad.join("\n"));
}

#[test]
fn a_back_import_and_a_cycle_are_caught() {
    let file = |p: &str, t: &str| (p.to_string(), t.to_string());
    let back = vec![
        file("sim/execute.rs", "use crate::params::ClimbParams;\n"),
        file("params.rs", "use crate::sim::params::ServoParams;\n"),
        file(
            "scene/mod.rs",
            "use crate::{\n    scenario::Scenario,\n    perception::{PlaneSegment, Perception},\n};\n",
        ),
    ];
    let bad = violations(&back);
    assert_eq!(bad.len(), 2, "{bad:?}");
    assert!(bad[0].contains("`sim` imports `crate::params`"), "{bad:?}");
    assert!(bad[1].contains("`scene` imports `crate::perception`"), "{bad:?}");
    let cycle = vec![
        file("planning/gait.rs", "use super::footholds::{Foot, Stance};\n"),
        file("planning/footholds.rs", "use super::gait::Legs;\n#[cfg(test)]\nmod tests { use super::*; }\n"),
        file("planning/mod.rs", "pub use footholds::Foot;\n"),
    ];
    let bad = violations(&cycle);
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(bad[0].starts_with("planning: "), "{bad:?}");
    // Comments and a file's own unit tests are not imports; a downward import is fine.
    let fine = vec![
        file("planning/gait.rs", "// use super::footholds::Foot;\nuse crate::robot::Kinematics;\n"),
        file("planning/footholds.rs", "use super::gait::Legs;\n#[cfg(test)]\nmod tests { use super::*; }\n"),
        file("robot/mod.rs", "use crate::scene::mjcf;\n"),
    ];
    assert!(violations(&fine).is_empty(), "{:?}", violations(&fine));
}
