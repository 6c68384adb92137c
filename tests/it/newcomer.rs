//! Integration tests: what a newcomer reads is true of the tree. README.md and every page
//! of `src/docs/` name repository paths (`src/…`, `tests/…`, `data/…`, `benches/…`,
//! `schemas/…`) and Rust paths (`engine::imz`, `markers::MotionField::step`); each must
//! exist in the tree as it is. Only code spans, fenced code and link targets are read, so
//! prose is never taken for a path.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};
use std::rc::Rc;

/// The prefixes of the repository paths a page may name.
const REPO_PREFIXES: [&str; 5] = ["src/", "tests/", "data/", "benches/", "schemas/"];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// README.md and the `src/docs/*.md` pages: (path relative to the root, text).
fn pages(root: &Path) -> Vec<(PathBuf, String)> {
    let mut files = vec![PathBuf::from("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("src/docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .map(|p| p.strip_prefix(root).unwrap().to_path_buf())
        .collect();
    docs.sort();
    files.extend(docs);
    files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(root.join(&f)).unwrap();
            (f, text)
        })
        .collect()
}

/// A page's text split into what lies inside fenced code blocks and what lies outside.
fn split_fences(md: &str) -> (Vec<String>, Vec<String>) {
    let (mut fenced, mut prose) = (Vec::new(), Vec::new());
    let mut in_fence = false;
    for line in md.lines() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if in_fence {
            fenced.push(line.to_string());
        } else {
            prose.push(line.to_string());
        }
    }
    (fenced, prose)
}

/// The inline code spans of prose lines: a run of n backticks up to the next run of
/// exactly n, within a paragraph (a span may wrap onto the next line).
fn code_spans(prose: &[String]) -> Vec<String> {
    let mut spans = Vec::new();
    for paragraph in prose.split(|l| l.trim().is_empty()) {
        let text: Vec<char> = paragraph.join(" ").chars().collect();
        let run = |i: usize| text[i..].iter().take_while(|&&c| c == '`').count();
        let mut i = 0;
        while i < text.len() {
            if text[i] != '`' {
                i += 1;
                continue;
            }
            let n = run(i);
            let start = i + n;
            let mut j = start;
            let mut end = None;
            while j < text.len() {
                if text[j] == '`' {
                    let m = run(j);
                    if m == n {
                        end = Some(j);
                        break;
                    }
                    j += m;
                } else {
                    j += 1;
                }
            }
            match end {
                Some(e) => {
                    spans.push(text[start..e].iter().collect::<String>().trim().to_string());
                    i = e + n;
                }
                None => i = start,
            }
        }
    }
    spans
}

/// The targets of Markdown links and images, `[..](target)`, outside code spans.
fn link_targets(prose: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    for line in prose {
        // Drop code spans so that `a](b)` inside one is not a link.
        let mut plain = String::new();
        for (k, piece) in line.split('`').enumerate() {
            if k % 2 == 0 {
                plain.push_str(piece);
            }
        }
        let mut rest = plain.as_str();
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let end = after.find([')', ' ']).unwrap_or(after.len());
            out.push(after[..end].to_string());
            rest = &after[end..];
        }
    }
    out
}

/// `a/{x,y}/b` → `a/x/b`, `a/y/b` (one level of braces).
fn expand_braces(s: &str) -> Vec<String> {
    if let (Some(i), Some(j)) = (s.find('{'), s.find('}')) {
        if i < j {
            return s[i + 1..j]
                .split(',')
                .flat_map(|alt| expand_braces(&format!("{}{}{}", &s[..i], alt.trim(), &s[j + 1..])))
                .collect();
        }
    }
    vec![s.to_string()]
}

/// `a/b/../c` → `a/c`.
fn normalise(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

/// A token that names a repository path, as the root-relative path it names (None: not a
/// repository path). Quotes, brackets and trailing punctuation around it are not part of it.
fn repo_path(token: &str) -> Option<String> {
    let t = token
        .trim_start_matches(['"', '\'', '(', '['])
        .trim_end_matches(['"', '\'', ')', ']', ',', ';', ':', '.']);
    let t = t.strip_prefix("./").unwrap_or(t);
    REPO_PREFIXES
        .iter()
        .any(|p| t.starts_with(p))
        .then(|| t.to_string())
}

/// Whether a named repository path exists. A placeholder (`schemas/<table>.json`,
/// `tests/figures/*.png`) is checked up to the folder before it.
fn repo_path_exists(root: &Path, path: &str) -> bool {
    expand_braces(path).iter().all(|p| {
        let p = match p.find(['<', '*', '…']).or_else(|| p.find("...")) {
            Some(k) => match p[..k].rfind('/') {
                Some(slash) => &p[..=slash],
                None => return true,
            },
            None => p.as_str(),
        };
        root.join(p).exists()
    })
}

/// Every repository path a page names (its code spans, fenced code and relative link
/// targets), with what named it.
fn named_repo_paths(page: &Path, md: &str) -> Vec<(String, String)> {
    let (fenced, prose) = split_fences(md);
    let mut named: Vec<(String, String)> = Vec::new();
    let tokens = |s: &str| -> Vec<String> {
        s.split(|c: char| c.is_whitespace() || c == '=')
            .filter_map(repo_path)
            .collect()
    };
    for span in code_spans(&prose) {
        for p in tokens(&span) {
            named.push((p, format!("`{span}`")));
        }
    }
    for line in &fenced {
        for p in tokens(line) {
            named.push((p, format!("code block line `{}`", line.trim())));
        }
    }
    let dir = page.parent().unwrap_or(Path::new(""));
    for target in link_targets(&prose) {
        let target = target.split('#').next().unwrap_or("");
        if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        let resolved = normalise(&dir.join(target));
        let rel = resolved.to_string_lossy().to_string();
        if rel.is_empty() {
            continue;
        }
        named.push((rel, format!("link ({target})")));
    }
    named
}

/// Every repository path a page names that does not exist, with what named it.
fn missing_repo_paths(root: &Path, page: &Path, md: &str) -> Vec<String> {
    named_repo_paths(page, md)
        .into_iter()
        .filter(|(p, _)| !repo_path_exists(root, p))
        .map(|(p, by)| format!("{}: {p} (named by {by})", page.display()))
        .collect()
}

fn is_ident(s: &str) -> bool {
    let mut c = s.chars();
    c.next().is_some_and(|f| f.is_alphabetic() || f == '_')
        && c.all(|ch| ch.is_alphanumeric() || ch == '_')
}

/// A code span that is a Rust path (`engine::imz`, `crate::docs::physics`,
/// `engine::{air_gap, rilling}`), as its expanded paths' segments. None: not a path.
fn rust_paths(span: &str) -> Option<Vec<Vec<String>>> {
    if !span.contains("::") {
        return None;
    }
    let expanded = match (span.find('{'), span.ends_with('}')) {
        (Some(i), true) => {
            let head = span[..i].strip_suffix("::")?;
            span[i + 1..span.len() - 1]
                .split(',')
                .map(|alt| format!("{head}::{}", alt.trim()))
                .collect()
        }
        (None, _) => vec![span.to_string()],
        _ => return None,
    };
    let mut out = Vec::new();
    for p in expanded {
        let segs: Vec<String> = p.split("::").map(str::to_string).collect();
        if segs.len() < 2 || !segs.iter().all(|s| is_ident(s)) {
            return None;
        }
        let segs = match segs[0].as_str() {
            "crate" | "caveflow" => segs[1..].to_vec(),
            _ => segs,
        };
        if segs.is_empty() {
            return None;
        }
        out.push(segs);
    }
    Some(out)
}

thread_local! {
    /// The `.rs` files listed so far, by folder.
    static LISTINGS: RefCell<HashMap<PathBuf, Vec<PathBuf>>> = RefCell::new(HashMap::new());
}

/// The `.rs` files under `dir`, recursively, sorted (listed once per thread).
fn rs_files(dir: &Path) -> Vec<PathBuf> {
    if let Some(l) = LISTINGS.with(|c| c.borrow().get(dir).cloned()) {
        return l;
    }
    let l = list_rs_files(dir);
    LISTINGS.with(|c| c.borrow_mut().insert(dir.to_path_buf(), l.clone()));
    l
}

fn list_rs_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.extend(list_rs_files(&p));
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Where a module lives: its file, and the folder of its submodules where it has one.
#[derive(Debug, Clone)]
struct Module {
    file: PathBuf,
    folder: Option<PathBuf>,
}

impl Module {
    /// The module `name` in folder `dir`: `dir/name.rs` or `dir/name/mod.rs`.
    fn at(dir: &Path, name: &str) -> Option<Module> {
        let flat = dir.join(format!("{name}.rs"));
        let folder = dir.join(name);
        if flat.is_file() {
            Some(Module {
                file: flat,
                folder: folder.is_dir().then_some(folder),
            })
        } else if folder.join("mod.rs").is_file() {
            Some(Module {
                file: folder.join("mod.rs"),
                folder: Some(folder),
            })
        } else {
            None
        }
    }

    /// The files an item of this module may be defined in: its file and its folder's.
    fn files(&self) -> Vec<PathBuf> {
        let mut f = vec![self.file.clone()];
        if let Some(dir) = &self.folder {
            f.extend(rs_files(dir).into_iter().filter(|p| *p != self.file));
        }
        f
    }
}

/// The identifier tokens of a line.
fn idents(line: &str) -> Vec<&str> {
    line.split(|c: char| !(c.is_alphanumeric() || c == '_'))
        .filter(|t| !t.is_empty())
        .collect()
}

/// Whether `text` defines `name` as an item: `fn`, `struct`, `enum`, `const`, `static`,
/// `trait`, `type`, `union`, `mod` or `macro_rules!` followed by the name.
fn defines_item(text: &str, name: &str) -> bool {
    const KEYWORDS: [&str; 10] = [
        "fn",
        "struct",
        "enum",
        "const",
        "static",
        "trait",
        "type",
        "union",
        "mod",
        "macro_rules",
    ];
    text.contains(name)
        && text.lines().any(|line| {
            line.contains(name)
                && idents(line)
                    .windows(2)
                    .any(|w| w[1] == name && KEYWORDS.contains(&w[0]))
        })
}

/// Whether `text` defines `name` as an item or as a member of one: a field (`name: T`) or
/// a variant (`Name,`, `Name(..)`, `Name { .. }`).
fn defines_member(text: &str, name: &str) -> bool {
    text.contains(name) && defines_item(text, name)
        || text.contains(name)
            && text.lines().any(|line| {
                let mut l = line.trim_start();
                if let Some(r) = l.strip_prefix("pub") {
                    l = r.trim_start();
                    if l.starts_with('(') {
                        l = l.split_once(')').map_or("", |(_, r)| r).trim_start();
                    }
                }
                l.strip_prefix(name).is_some_and(|rest| {
                    let rest = rest.trim_start();
                    (rest.starts_with(':') && !rest.starts_with("::"))
                        || rest.starts_with([',', '(', '{'])
                })
            })
}

thread_local! {
    /// The source files read so far: every path resolved reads the same files again.
    static SOURCES: RefCell<HashMap<PathBuf, Rc<str>>> = RefCell::new(HashMap::new());
}

/// A source file's text, read once per thread ("" where it cannot be read).
fn source(p: &Path) -> Rc<str> {
    SOURCES.with(|c| {
        c.borrow_mut()
            .entry(p.to_path_buf())
            .or_insert_with(|| std::fs::read_to_string(p).unwrap_or_default().into())
            .clone()
    })
}

fn any_file(files: &[PathBuf], f: impl Fn(&str) -> bool) -> bool {
    files.iter().any(|p| f(&source(p)))
}

/// Resolves the segments after a module: submodules while there are such files, then an
/// item defined in the module's file or folder, then members defined there too.
fn resolve_from(module: Module, rest: &[String]) -> bool {
    let Some((first, tail)) = rest.split_first() else {
        return true;
    };
    if let Some(dir) = &module.folder {
        if let Some(sub) = Module::at(dir, first) {
            return resolve_from(sub, tail);
        }
    }
    let files = module.files();
    any_file(&files, |t| defines_item(t, first))
        && tail
            .iter()
            .all(|m| any_file(&files, |t| defines_member(t, m)))
}

/// The modules a path's first segment may name: a module of the crate's root, a module of
/// that name anywhere under `src/` (the pages shorten `engine::markers::Bins` to
/// `markers::Bins`), a module of the integration tests (`tests/it/<name>.rs`), or a file
/// that declares an inline `mod name`.
fn first_segment_modules(root: &Path, name: &str) -> Vec<Module> {
    thread_local! {
        static FOUND: RefCell<HashMap<(PathBuf, String), Vec<Module>>> =
            RefCell::new(HashMap::new());
    }
    let key = (root.to_path_buf(), name.to_string());
    if let Some(m) = FOUND.with(|c| c.borrow().get(&key).cloned()) {
        return m;
    }
    let found = find_first_segment_modules(root, name);
    FOUND.with(|c| c.borrow_mut().insert(key, found.clone()));
    found
}

fn find_first_segment_modules(root: &Path, name: &str) -> Vec<Module> {
    let src = root.join("src");
    let mut out: Vec<Module> = Vec::new();
    let mut dirs = vec![src.clone()];
    while let Some(d) = dirs.pop() {
        out.extend(Module::at(&d, name));
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            }
        }
    }
    out.extend(Module::at(&root.join("tests/it"), name));
    for file in rs_files(&src) {
        let text = source(&file);
        if text.contains(name)
            && text.lines().any(|l| {
                let ids = idents(l);
                ids.windows(2).any(|w| w[0] == "mod" && w[1] == name) && l.contains('{')
            })
        {
            out.push(Module { file, folder: None });
        }
    }
    out
}

/// Whether a Rust path names something in the tree. A path that starts with a type
/// (`Engine::step`) needs the type defined under `src/` and its members in that file's
/// folder.
fn rust_path_resolves(root: &Path, segs: &[String]) -> bool {
    let first = &segs[0];
    if first.starts_with(|c: char| c.is_uppercase()) {
        return rs_files(&root.join("src")).iter().any(|file| {
            let text = source(file);
            let is_type = text.contains(first.as_str())
                && text.lines().any(|l| {
                    idents(l).windows(2).any(|w| {
                        w[1] == first.as_str()
                            && ["struct", "enum", "trait", "type", "union"].contains(&w[0])
                    })
                });
            is_type && {
                let files = rs_files(file.parent().unwrap());
                segs[1..]
                    .iter()
                    .all(|m| any_file(&files, |t| defines_member(t, m)))
            }
        });
    }
    first_segment_modules(root, first)
        .into_iter()
        .any(|m| resolve_from(m, &segs[1..]))
}

/// Every Rust path a page names in a code span, with the span.
fn named_rust_paths(md: &str) -> Vec<(Vec<String>, String)> {
    let (_, prose) = split_fences(md);
    code_spans(&prose)
        .into_iter()
        .flat_map(|span| {
            rust_paths(&span)
                .unwrap_or_default()
                .into_iter()
                .map(move |segs| (segs, span.clone()))
        })
        .collect()
}

/// Every Rust path a page names in a code span that names nothing in the tree.
fn unresolved_rust_paths(root: &Path, page: &Path, md: &str) -> Vec<String> {
    named_rust_paths(md)
        .into_iter()
        .filter(|(segs, _)| !rust_path_resolves(root, segs))
        .map(|(segs, span)| format!("{}: `{}` (in `{span}`)", page.display(), segs.join("::")))
        .collect()
}

/// Every repository path that README.md and the `src/docs/` pages name exists.
#[test]
fn every_repository_path_the_docs_name_exists() {
    let root = root();
    let (mut missing, mut named) = (Vec::new(), 0);
    for (page, text) in pages(&root) {
        named += named_repo_paths(&page, &text).len();
        missing.extend(missing_repo_paths(&root, &page, &text));
    }
    // The pages name well over fifty of each: fewer means the reading broke, not that
    // the pages are right.
    assert!(
        named > 50,
        "only {named} repository paths found in the docs"
    );
    assert!(
        missing.is_empty(),
        "paths named in the docs that do not exist:\n{}",
        missing.join("\n")
    );
}

/// Every Rust path that README.md and the `src/docs/` pages name in a code span resolves to
/// a module file (`src/<a>/<b>.rs`, `src/<a>/<b>/mod.rs`) or an item defined in one.
#[test]
fn every_rust_path_the_docs_name_resolves() {
    let root = root();
    let (mut missing, mut named) = (Vec::new(), 0);
    for (page, text) in pages(&root) {
        named += named_rust_paths(&text).len();
        missing.extend(unresolved_rust_paths(&root, &page, &text));
    }
    assert!(named > 50, "only {named} Rust paths found in the docs");
    assert!(
        missing.is_empty(),
        "Rust paths named in the docs that resolve to nothing:\n{}",
        missing.join("\n")
    );
}

/// The checks find wrong paths, and let right ones and prose through.
#[test]
fn the_checks_find_wrong_paths() {
    let root = root();
    let page = Path::new("src/docs/example.md");
    let md = "Prose names src/nowhere.rs and engine::nowhere without backticks.\n\
        `src/engine/imz/mod.rs`, `src/engine/imz.rs`, `tests/figures/demo_section_p{10,99}.png`,\n\
        `schemas/<table>.json`, `caveflow run data/scenario.toml --out out`.\n\
        ![](../../tests/figures/stability.png) ![](../../tests/figures/none.png)\n\
        \n\
        ```sh\n\
        caveflow run data/no_scenario.toml\n\
        ```\n\
        `engine::imz`, `engine::imz::r_law`, `engine::imz::NoSuchItem`, `engine::nowhere`,\n\
        `engine::{air_gap, no_module}`, `markers::MotionField::step`, `Engine::step`,\n\
        `Engine::no_such_method`, `docs::physics`, `crate::docs::nowhere`.\n";
    let paths = missing_repo_paths(&root, page, md);
    let wrong: Vec<&str> = [
        "src/engine/imz.rs",
        "p{10,99}",
        "tests/figures/none.png",
        "data/no_scenario.toml",
    ]
    .to_vec();
    assert_eq!(paths.len(), wrong.len(), "{paths:#?}");
    for w in wrong {
        assert!(
            paths.iter().any(|p| p.contains(w)),
            "{w} not found in {paths:#?}"
        );
    }
    let rust = unresolved_rust_paths(&root, page, md);
    let wrong = [
        "`engine::imz::NoSuchItem`",
        "`engine::nowhere`",
        "`engine::no_module`",
        "`Engine::no_such_method`",
        "`docs::nowhere`",
    ];
    assert_eq!(rust.len(), wrong.len(), "{rust:#?}");
    for w in wrong {
        assert!(
            rust.iter().any(|p| p.contains(w)),
            "{w} not found in {rust:#?}"
        );
    }
}
