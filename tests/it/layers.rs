//! The crate's layers, checked from its own `use` lines: every module under
//! `src/` imports only from layers below its own, and no files import each
//! other in a circle (outside `src/vk/`, whose wrappers share one device).
//!
//! Run it alone with `cargo test --release --test it layers::`. It reads the
//! source as text: references are the `crate::`, `super::` and `self::`
//! paths in code (comments, doc comments and `#[cfg(test)]` modules are
//! left out, because tests and doc links may point anywhere).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers, bottom first: a module may use any module of a lower rank,
/// and none of its own rank but itself. `lib.rs` (the crate root, which
/// declares and re-exports) is above them all.
const LAYERS: &[(&str, u32)] = &[
    ("util", 0),
    ("interface", 0),
    ("vk", 1),
    ("scene", 1),
    ("accel", 2),
    ("gpu", 3),
    ("render", 4),
    ("io", 5),
    ("analysis", 6),
];

/// The folder whose files may import each other in a circle.
const CIRCLES_ALLOWED_IN: &str = "vk";

/// One source file: its module path (`["render", "record"]`) and the code
/// that counts (no comments, no test modules).
struct Source {
    module: Vec<String>,
    code: String,
}

/// Every `.rs` file under `src/` but the command line (`src/bin/`, a crate
/// of its own on top), keyed by path relative to `src/`.
fn sources(src: &Path) -> BTreeMap<String, Source> {
    let mut out = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let rel = path
                .strip_prefix(src)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            if path.is_dir() {
                if rel != "bin" {
                    stack.push(path);
                }
            } else if rel.ends_with(".rs") && !rel.ends_with("/tests.rs") {
                let text = std::fs::read_to_string(&path).unwrap();
                out.insert(
                    rel.clone(),
                    Source {
                        module: module_of(&rel),
                        code: code_of(&text),
                    },
                );
            }
        }
    }
    out
}

/// The module path of a file: `render/mod.rs` is `render`, `io/film.rs` is
/// `io::film`, `lib.rs` the root.
fn module_of(rel: &str) -> Vec<String> {
    let stem = rel.trim_end_matches(".rs");
    let mut parts: Vec<String> = stem.split('/').map(str::to_string).collect();
    if parts.last().is_some_and(|p| p == "mod" || p == "lib") {
        parts.pop();
    }
    parts
}

/// The code of a file without comments and without what follows a
/// top-level `#[cfg(test)]` (the test module closes every file here).
fn code_of(text: &str) -> String {
    let mut code = String::new();
    for line in text.lines() {
        if line.trim_start() == "#[cfg(test)]" && !line.starts_with(' ') {
            break;
        }
        let line = line.split("//").next().unwrap();
        code.push_str(line);
        code.push('\n');
    }
    code
}

/// The module paths `code` (in module `module`) refers to: every
/// `crate::a::b`, `super::x` and `self::x`, with `use` groups expanded.
fn references(module: &[String], code: &str) -> BTreeSet<Vec<String>> {
    let mut out = BTreeSet::new();
    let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    for (start, root) in ["crate::", "super::", "self::"]
        .iter()
        .flat_map(|k| code.match_indices(k))
    {
        if code[..start].chars().next_back().is_some_and(ident) {
            continue;
        }
        let mut base: Vec<String> = match root {
            "crate::" => Vec::new(),
            "super::" => module[..module.len().saturating_sub(1)].to_vec(),
            _ => module.to_vec(),
        };
        let rest = &code[start + root.len()..];
        // `super::super::x`
        let mut rest = rest;
        while let Some(r) = rest.strip_prefix("super::") {
            base.pop();
            rest = r;
        }
        let path: String = rest.chars().take_while(|&c| ident(c) || c == ':').collect();
        let path = path.trim_end_matches(':');
        let tail = &rest[path.len()..];
        let mut prefix = base.clone();
        prefix.extend(
            path.split("::")
                .filter(|s| !s.is_empty())
                .map(str::to_string),
        );
        if let Some(group) = tail.strip_prefix("::{").or_else(|| tail.strip_prefix('{')) {
            let group = &group[..group.find('}').unwrap_or(group.len())];
            for item in group.split(',') {
                let item = item.trim();
                if item.is_empty() || item == "self" {
                    out.insert(prefix.clone());
                    continue;
                }
                let mut p = prefix.clone();
                p.extend(
                    item.split_whitespace()
                        .next()
                        .unwrap()
                        .split("::")
                        .map(str::to_string),
                );
                out.insert(p);
            }
        } else {
            out.insert(prefix);
        }
    }
    out
}

/// The file a module path resolves to: its longest prefix that is a file's
/// module (the rest names items inside it).
fn resolve<'a>(by_module: &'a BTreeMap<Vec<String>, String>, path: &[String]) -> Option<&'a str> {
    (1..=path.len())
        .rev()
        .find_map(|n| by_module.get(&path[..n]).map(String::as_str))
}

/// The layer that the crate root and the items it declares (re-exports
/// such as `crate::Scene`) count as: above every module.
const ROOT: (&str, u32) = ("the crate root", u32::MAX);

/// The rank of the layer a module path belongs to; `None` for the root
/// itself (`lib.rs`), [`ROOT`] for an item of the root.
fn rank(module: &[String], modules: &BTreeMap<Vec<String>, String>) -> Option<(&'static str, u32)> {
    let top = module.first()?;
    if !modules.keys().any(|m| m.first() == Some(top)) {
        return Some(ROOT);
    }
    let layer = LAYERS.iter().find(|(name, _)| name == top);
    Some(*layer.unwrap_or_else(|| panic!("src/{top} is in no layer: add it to LAYERS")))
}

/// What breaks the rules: one line per upward or sideways import and per
/// circle of files.
fn violations(sources: &BTreeMap<String, Source>) -> Vec<String> {
    let by_module: BTreeMap<Vec<String>, String> = sources
        .iter()
        .map(|(rel, s)| (s.module.clone(), rel.clone()))
        .collect();
    let mut found = Vec::new();
    // File -> files it imports; a submodule may use its parent module's
    // items (`super::`), as a method uses its struct: that edge is no circle.
    let mut edges: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for (rel, source) in sources {
        let Some((layer, own)) = rank(&source.module, &by_module) else {
            continue;
        };
        for path in references(&source.module, &source.code) {
            let Some((target_layer, target)) = rank(&path, &by_module) else {
                continue;
            };
            if target_layer != layer && target >= own {
                let what = if (target_layer, target) == ROOT {
                    ROOT.0.to_string()
                } else {
                    format!("{target_layer}, layer {target}")
                };
                found.push(format!(
                    "src/{rel} ({layer}, layer {own}) uses {} ({what})",
                    path.join("::")
                ));
            }
            if let Some(file) = resolve(&by_module, &path) {
                let parent = &source.module[..source.module.len() - 1];
                let is_parent = sources[file].module == parent;
                if file != rel && !is_parent {
                    edges.entry(rel.as_str()).or_default().insert(file);
                }
            }
        }
    }
    for circle in circles(&edges) {
        if circle
            .iter()
            .all(|f| f.starts_with(&format!("{CIRCLES_ALLOWED_IN}/")))
        {
            continue;
        }
        found.push(format!("circle: {}", circle.join(" -> ")));
    }
    found
}

/// The strongly connected components of more than one file (Tarjan).
fn circles<'a>(edges: &BTreeMap<&'a str, BTreeSet<&'a str>>) -> Vec<Vec<&'a str>> {
    struct State<'a> {
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        out: Vec<Vec<&'a str>>,
    }
    fn visit<'a>(v: &'a str, edges: &BTreeMap<&'a str, BTreeSet<&'a str>>, s: &mut State<'a>) {
        let i = s.index.len();
        s.index.insert(v, i);
        s.low.insert(v, i);
        s.stack.push(v);
        s.on_stack.insert(v);
        for &w in edges.get(v).into_iter().flatten() {
            if !s.index.contains_key(w) {
                visit(w, edges, s);
                let l = s.low[v].min(s.low[w]);
                s.low.insert(v, l);
            } else if s.on_stack.contains(w) {
                let l = s.low[v].min(s.index[w]);
                s.low.insert(v, l);
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack.remove(w);
                component.push(w);
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                component.sort();
                s.out.push(component);
            }
        }
    }
    let mut s = State {
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for &v in edges.keys() {
        if !s.index.contains_key(v) {
            visit(v, edges, &mut s);
        }
    }
    s.out
}

#[test]
fn imports_point_down_and_no_files_import_each_other_in_a_circle() {
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src");
    let sources = sources(&src);
    assert!(sources.len() > 40, "read only {} files", sources.len());
    let found = violations(&sources);
    assert!(found.is_empty(), "{}", found.join("\n"));
}

/// Builds sources from `(path, text)` pairs, as [`sources`] would read them.
fn fake(files: &[(&str, &str)]) -> BTreeMap<String, Source> {
    files
        .iter()
        .map(|(rel, text)| {
            (
                rel.to_string(),
                Source {
                    module: module_of(rel),
                    code: code_of(text),
                },
            )
        })
        .collect()
}

#[test]
fn the_check_finds_an_upward_import_and_a_circle() {
    let upward = fake(&[
        ("scene/mod.rs", "use crate::render::Renderer;\n"),
        ("render/mod.rs", "use crate::scene::Scene;\n"),
    ]);
    assert_eq!(
        violations(&upward),
        [
            "src/scene/mod.rs (scene, layer 1) uses render::Renderer (render, layer 4)",
            "circle: render/mod.rs -> scene/mod.rs"
        ]
    );

    let circle = fake(&[
        ("render/a.rs", "use super::b::X;\npub struct Y;\n"),
        (
            "render/b.rs",
            "pub struct X;\nfn f() -> crate::render::a::Y { todo() }\n",
        ),
        ("render/mod.rs", "mod a;\nmod b;\n"),
    ]);
    assert_eq!(violations(&circle), ["circle: render/a.rs -> render/b.rs"]);

    // Grouped imports, sideways imports, a child using its parent, and
    // what comments and test modules say do not count
    let mixed = fake(&[
        ("vk/mod.rs", "use crate::{util::text::cut, scene};\n"),
        ("scene/mod.rs", "pub struct Scene;\n"),
        ("util/text.rs", "pub fn cut() {}\n"),
        ("analysis/mod.rs", "pub fn x() {}\n"),
        ("render/mod.rs", "mod a;\npub struct R;\nuse self::a::f;\n"),
        (
            "render/a.rs",
            "use super::R;\n/// [`crate::analysis::x`]\npub fn f() {}\n",
        ),
        (
            "io/mod.rs",
            "//! crate::analysis\n#[cfg(test)]\nmod tests { use crate::analysis::x; }\n",
        ),
    ]);
    assert_eq!(
        violations(&mixed),
        ["src/vk/mod.rs (vk, layer 1) uses scene (scene, layer 1)"]
    );
}
