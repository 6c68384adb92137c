//! Integration tests: the layers' one-way data flow (`schema` → `io` → `model` → `engine`
//! → `output` → `analysis` → `cli`, as `src/lib.rs` states it).

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
