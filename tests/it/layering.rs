//! Integration tests: the layers' one-way data flow (`schema` → `io` → `model` → `engine`
//! → `output` → `analysis` → `cli`, as `src/lib.rs` states it).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers, lowest first. A module may use its own layer and any layer before it.
const LAYERS: [&str; 7] = [
    "schema", "io", "model", "engine", "output", "analysis", "cli",
];

fn rank(layer: &str) -> Option<usize> {
    LAYERS.iter().position(|&l| l == layer)
}

/// The `.rs` files under `dir`, recursively.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The layers a line of code names as `crate::<layer>` (comments skipped: a doc link is
/// not a dependency).
fn named_layers(line: &str) -> Vec<&str> {
    let code = line.split("//").next().unwrap_or("");
    code.match_indices("crate::")
        .filter_map(|(i, _)| {
            let rest = &code[i + "crate::".len()..];
            let end = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            rank(&rest[..end]).map(|_| &rest[..end])
        })
        .collect()
}

/// No file of a layer names a higher layer (`crate::engine` from `src/model`, say), in a
/// `use` line or an inline path.
#[test]
fn no_layer_reaches_back_up() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut reaches = Vec::new();
    let mut checked = 0;
    for layer in LAYERS {
        let mut files = Vec::new();
        let dir = src.join(layer);
        if dir.is_dir() {
            sources(&dir, &mut files);
        }
        let file = src.join(format!("{layer}.rs"));
        if file.is_file() {
            files.push(file);
        }
        for f in files {
            checked += 1;
            let text = std::fs::read_to_string(&f).unwrap();
            for (n, line) in text.lines().enumerate() {
                for used in named_layers(line) {
                    if rank(used) > rank(layer) {
                        let at = f.strip_prefix(&src).unwrap().display();
                        reaches.push(format!("src/{at}:{}: {layer} uses {used}", n + 1));
                    }
                }
            }
        }
    }
    assert!(
        checked > 30,
        "only {checked} files read under {}",
        src.display()
    );
    assert!(
        reaches.is_empty(),
        "layers reach back up:\n{}",
        reaches.join("\n")
    );
}

/// The scan itself: it sees a reach in a `use` line and an inline path, and not in a
/// comment.
#[test]
fn the_layer_scan_sees_use_lines_and_paths_but_not_comments() {
    assert_eq!(named_layers("use crate::model::Periods;"), ["model"]);
    assert_eq!(
        named_layers("let x = crate::engine::imz::r_law(1.0); crate::io::read()"),
        ["engine", "io"]
    );
    assert!(named_layers("//! see [`load`](crate::model::load)").is_empty());
    assert!(named_layers("let y = 1; // crate::cli::main").is_empty());
    assert!(named_layers("use crate::docs;").is_empty());
}

/// The modules of `layer` that a line names: as `crate::<layer>::<m>`, or relative to a
/// file `depth` folders below the layer's (`super::<m>` from `src/<layer>/<own>.rs`,
/// `super::super::<m>` from `src/<layer>/<own>/<file>.rs`). Comments are skipped.
fn named_siblings<'a>(line: &'a str, layer: &str, depth: usize) -> Vec<&'a str> {
    let code = line.split("//").next().unwrap_or("");
    let absolute = format!("crate::{layer}::");
    let relative = "super::".repeat(depth);
    let mut out = Vec::new();
    for prefix in [absolute.as_str(), relative.as_str()] {
        for (i, _) in code.match_indices(prefix) {
            // `super::super::x` also contains `super::x`: only whole prefixes count.
            if prefix == relative && code[..i].ends_with("super::") {
                continue;
            }
            let rest = &code[i + prefix.len()..];
            let end = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            if end > 0 && !rest[..end].starts_with("super") {
                out.push(&rest[..end]);
            }
        }
    }
    out
}

/// Within a layer the modules use one another one way too: no circle (`output::run` uses
/// `output::stress`, which must not use `output::run` back). The layer's hub (`mod.rs`)
/// is not a module of its own here.
#[test]
fn no_circles_among_a_layers_modules() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut circles = Vec::new();
    let mut edges_seen = 0;
    for layer in LAYERS {
        let dir = src.join(layer);
        if !dir.is_dir() {
            continue;
        }
        // Module → the siblings it names.
        let mut uses: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let own = path.file_stem().unwrap().to_string_lossy().into_owned();
            let mut files = Vec::new();
            if path.is_dir() {
                sources(&path, &mut files);
            } else if path.extension().is_some_and(|e| e == "rs") && own != "mod" {
                files.push(path.clone());
            }
            for f in files {
                // How many `super::` lead from the file up to the layer: one per folder
                // below the layer's, less one for a folder's own `mod.rs`.
                let rel = f.strip_prefix(&dir).unwrap();
                let depth = rel.components().count() - usize::from(rel.ends_with("mod.rs"));
                let text = std::fs::read_to_string(&f).unwrap();
                for line in text.lines() {
                    for used in named_siblings(line, layer, depth) {
                        let sibling =
                            dir.join(format!("{used}.rs")).is_file() || dir.join(used).is_dir();
                        if used != own && sibling {
                            edges_seen += 1;
                            uses.entry(own.clone())
                                .or_default()
                                .insert(used.to_string());
                        }
                    }
                }
            }
        }
        // A circle: a module that reaches itself through the others.
        for start in uses.keys() {
            let mut stack = vec![(start.clone(), vec![start.clone()])];
            let mut seen = BTreeSet::new();
            while let Some((at, path)) = stack.pop() {
                for next in uses.get(&at).into_iter().flatten() {
                    if next == start {
                        circles.push(format!("{layer}: {} → {start}", path.join(" → ")));
                    } else if seen.insert(next.clone()) {
                        let mut p = path.clone();
                        p.push(next.clone());
                        stack.push((next.clone(), p));
                    }
                }
            }
        }
    }
    assert!(
        edges_seen > 20,
        "only {edges_seen} uses between modules seen"
    );
    circles.sort();
    circles.dedup();
    assert!(
        circles.is_empty(),
        "modules in a circle:\n{}",
        circles.join("\n")
    );
}

/// The sibling scan: absolute and relative paths, the right depth only, no comments.
#[test]
fn the_sibling_scan_sees_paths_at_the_right_depth() {
    assert_eq!(
        named_siblings("use super::columns::{f64s};", "output", 1),
        ["columns"]
    );
    assert_eq!(
        named_siblings(
            "use super::super::run::x; use crate::output::stress::y;",
            "output",
            2
        ),
        ["stress", "run"]
    );
    assert!(named_siblings("use super::render::x;", "output", 2).is_empty());
    assert!(named_siblings("// super::run", "output", 1).is_empty());
}
