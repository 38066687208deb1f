//! The modules of `src/` form layers, at the top level and within every folder: no module
//! reaches, directly or through others, back into one that uses it. A module uses another when any of its files names
//! `crate::other` (in code or in a doc link, which ties the two as much as an import does).

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::Path;

type Graph = BTreeMap<String, BTreeSet<String>>;

/// Top-level modules named after `crate::` in `text`, including each name in a `crate::{a, b::c}` group.
fn named_modules(text: &str) -> Vec<String> {
    named_after(text, "crate::")
}

/// Names that follow `prefix` (a path such as `crate::` or `super::super::`, not itself the tail
/// of a longer path) in `text`, including each name in a `prefix{a, b::c}` group.
fn named_after(text: &str, prefix: &str) -> Vec<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut names = Vec::new();
    for (at, _) in text.match_indices(prefix) {
        let before = text[..at].chars().next_back();
        if before.is_some_and(|c| c == ':' || c.is_ascii_alphanumeric() || c == '_') {
            continue;
        }
        let rest = &text[at + prefix.len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 0;
            let mut start = true;
            for (k, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => start = true,
                    c if start && !c.is_whitespace() => {
                        names.push(ident(&group[k..]));
                        start = false;
                    }
                    _ => {}
                }
            }
        } else {
            names.push(ident(rest));
        }
    }
    names
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in fs::read_dir(dir).expect("src/ is readable") {
        let path = entry.expect("src/ entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Which top-level module of `src/` uses which.
fn module_graph(src: &Path) -> Graph {
    let top_name = |p: &Path| -> String {
        let first = p.strip_prefix(src).expect("under src").components().next();
        let name = first
            .expect("a path under src")
            .as_os_str()
            .to_string_lossy();
        name.trim_end_matches(".rs").to_string()
    };
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let tops: BTreeSet<String> = files
        .iter()
        .map(|f| top_name(f))
        .filter(|t| t != "lib" && t != "main")
        .collect();
    let mut graph: Graph = tops.iter().map(|t| (t.clone(), BTreeSet::new())).collect();
    for file in &files {
        let from = top_name(file);
        let Some(uses) = graph.get_mut(&from) else {
            continue;
        };
        let text = fs::read_to_string(file).expect("source is UTF-8");
        for to in named_modules(&text) {
            if to != from && tops.contains(&to) {
                uses.insert(to);
            }
        }
    }
    graph
}

/// One cycle of `graph` as the path `a -> b -> … -> a`, if there is one.
fn find_cycle(graph: &Graph) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &Graph,
        done: &mut BTreeSet<String>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        if let Some(k) = path.iter().position(|p| p == node) {
            let mut cycle = path[k..].to_vec();
            cycle.push(node.to_string());
            return Some(cycle);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(cycle) = visit(next, graph, done, path) {
                return Some(cycle);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|n| visit(n, graph, &mut done, &mut Vec::new()))
}

/// For the module folder `dir` (module path `path`, e.g. `engines::optix`), which of its
/// child modules (files and folders) uses which: a file of child `a` names child `b` as
/// `crate::path::b` or through `super::` paths from where it lies.
fn folder_graph(dir: &Path, path: &str) -> Graph {
    let mut children: BTreeMap<String, Vec<std::path::PathBuf>> = BTreeMap::new();
    for entry in fs::read_dir(dir).expect("a module folder is readable") {
        let p = entry.expect("a folder entry").path();
        let stem = p.file_stem().unwrap().to_string_lossy().to_string();
        if p.is_dir() {
            let mut files = Vec::new();
            rust_files(&p, &mut files);
            children.insert(stem, files);
        } else if p.extension().is_some_and(|e| e == "rs")
            && !["mod", "lib", "main"].contains(&stem.as_str())
        {
            children.insert(stem, vec![p]);
        }
    }
    let mut graph: Graph = children
        .keys()
        .map(|c| (c.clone(), BTreeSet::new()))
        .collect();
    for (from, files) in &children {
        for file in files {
            let text = fs::read_to_string(file).expect("source is UTF-8");
            // How many `super::` reach this folder's module from the file's module.
            let parts = file.strip_prefix(dir).unwrap().components().count();
            let is_mod = file.file_name().is_some_and(|n| n == "mod.rs");
            let ups = parts - is_mod as usize;
            let mut named = named_after(&text, &"super::".repeat(ups));
            if !path.is_empty() {
                named.extend(named_after(&text, &format!("crate::{path}::")));
            }
            for to in named {
                if &to != from && children.contains_key(&to) {
                    graph.get_mut(from).unwrap().insert(to);
                }
            }
        }
    }
    graph
}

/// Every module folder under `dir` with its module path (`dir` itself with `path`).
fn module_folders(dir: &Path, path: &str, out: &mut Vec<(std::path::PathBuf, String)>) {
    out.push((dir.to_path_buf(), path.to_string()));
    for entry in fs::read_dir(dir).expect("a module folder is readable") {
        let p = entry.expect("a folder entry").path();
        if p.is_dir() {
            let name = p.file_name().unwrap().to_string_lossy().to_string();
            let sub = if path.is_empty() {
                name
            } else {
                format!("{path}::{name}")
            };
            module_folders(&p, &sub, out);
        }
    }
}

/// The source folders of the library and of the tool (cli/), each a crate's root.
const CRATE_SOURCES: [&str; 2] = ["src", "cli/src"];

#[test]
fn the_modules_of_every_folder_form_no_cycle() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut cycles = Vec::new();
    for crate_src in CRATE_SOURCES {
        let src = root.join(crate_src);
        let mut folders = Vec::new();
        module_folders(&src, "", &mut folders);
        assert!(folders.len() > 2, "read the folders: {folders:?}");
        cycles.extend(folders.iter().filter_map(|(dir, path)| {
            let cycle = find_cycle(&folder_graph(dir, path))?;
            let folder = dir.strip_prefix(root).unwrap().display();
            Some(format!("{folder}: {}", cycle.join(" -> ")))
        }));
    }
    let wgpu = folder_graph(&root.join("src/engines/wgpu"), "engines::wgpu");
    assert!(
        wgpu["step"].contains("granular"),
        "read the wgpu engines' uses: {wgpu:?}"
    );
    assert!(
        cycles.is_empty(),
        "modules use each other:\n{}",
        cycles.join("\n")
    );
}

#[test]
fn top_level_modules_form_no_cycle() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for crate_src in CRATE_SOURCES {
        let graph = module_graph(&root.join(crate_src));
        assert!(graph.len() > 1, "read the module tree: {graph:?}");
        if let Some(cycle) = find_cycle(&graph) {
            panic!(
                "top-level modules of {crate_src} import each other: {}",
                cycle.join(" -> ")
            );
        }
    }
}

#[test]
fn the_check_sees_direct_grouped_and_long_cycles() {
    let graph = |edges: &[(&str, &str)]| {
        let mut g = Graph::new();
        for (a, b) in edges {
            g.entry(a.to_string()).or_default().insert(b.to_string());
            g.entry(b.to_string()).or_default();
        }
        g
    };
    assert_eq!(
        find_cycle(&graph(&[("a", "b"), ("b", "c"), ("a", "c")])),
        None
    );
    let cycle = find_cycle(&graph(&[("a", "b"), ("b", "c"), ("c", "a")])).expect("a cycle");
    assert_eq!(cycle.len(), 4);
    assert_eq!(cycle.first(), cycle.last());
    assert!(find_cycle(&graph(&[("x", "y"), ("y", "x")])).is_some());
    assert_eq!(
        named_modules("use crate::{error::{Error, Result}, io};\n/// [`crate::proxy::keep`]"),
        ["error", "io", "proxy"]
    );
    assert_eq!(
        named_after("use super::{a, b::c};\nuse super::super::d;", "super::"),
        ["a", "b", "super"]
    );
    assert_eq!(named_after("use super::super::d;", "super::super::"), ["d"]);
}
