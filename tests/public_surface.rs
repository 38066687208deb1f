//! The library's public surface, as its sources declare it, against the list in
//! `docs/public-api.txt`: an item made public or private on purpose changes both in one commit.
//!
//! The surface read here: every `pub` item at the top level of a public module (functions,
//! types, traits, constants, statics, modules, re-exports), from `src/lib.rs` down through
//! `pub mod` (in its own file or inline); items behind a cargo feature carry its name. Methods
//! and fields follow their types and are not listed. `MOCHI_UPDATE_SURFACE=1 cargo test --test
//! public_surface` rewrites the list.

use std::fs;
use std::path::{Path, PathBuf};

/// The items declared in `text` (a module's source, its items indented by `indent`) as lines
/// `path::name  kind`, the modules they declare followed into `dir` (where a file module's
/// children live).
fn items(text: &str, indent: usize, path: &str, dir: &Path, out: &mut Vec<String>) {
    let lines: Vec<&str> = text.lines().collect();
    let pad = " ".repeat(indent);
    let mut feature: Option<String> = None;
    let mut k = 0;
    while k < lines.len() {
        let line = lines[k];
        k += 1;
        let Some(code) = line.strip_prefix(&pad) else {
            continue;
        };
        if code.starts_with(' ') || code.starts_with("//") || code.is_empty() {
            continue;
        }
        if let Some(rest) = code.strip_prefix("#[cfg(feature = \"") {
            feature = rest.split('"').next().map(str::to_owned);
            continue;
        }
        if code.starts_with("#[") {
            continue;
        }
        let tag = feature
            .take()
            .map(|f| format!("  [feature {f}]"))
            .unwrap_or_default();
        let Some(decl) = code.strip_prefix("pub ") else {
            continue;
        };
        if decl.starts_with("use ") {
            let mut statement = decl.to_owned();
            while !statement.trim_end().ends_with(';') && k < lines.len() {
                statement.push(' ');
                statement.push_str(lines[k].trim());
                k += 1;
            }
            let statement = statement.split_whitespace().collect::<Vec<_>>().join(" ");
            let statement = statement
                .replace("{ ", "{")
                .replace(", }", "}")
                .replace(" }", "}");
            out.push(format!("{path}  {statement}{tag}"));
            continue;
        }
        let decl = decl.strip_prefix("unsafe ").unwrap_or(decl);
        let Some((kind, rest)) = decl.split_once(' ') else {
            continue;
        };
        if !matches!(
            kind,
            "fn" | "struct" | "enum" | "trait" | "const" | "static" | "type" | "mod"
        ) {
            continue;
        }
        let name: String = rest
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let item = format!("{path}::{name}");
        out.push(format!("{item}  {kind}{tag}"));
        if kind != "mod" {
            continue;
        }
        if rest.trim_end().ends_with('{') {
            // An inline module: its lines up to the brace that closes it at this indent.
            let end = lines[k..]
                .iter()
                .position(|l| *l == format!("{pad}}}"))
                .map_or(lines.len(), |e| k + e);
            let body = lines[k..end].join("\n");
            items(&body, indent + 4, &item, &dir.join(&name), out);
            k = end;
        } else {
            let (file, child_dir) = module_file(dir, &name);
            let text = fs::read_to_string(&file).expect("a declared module's file");
            items(&text, 0, &item, &child_dir, out);
        }
    }
}

/// The file of module `name` declared by a module whose children live in `dir`, and where its
/// own children live.
fn module_file(dir: &Path, name: &str) -> (PathBuf, PathBuf) {
    let flat = dir.join(format!("{name}.rs"));
    match flat.exists() {
        true => (flat, dir.join(name)),
        false => (dir.join(name).join("mod.rs"), dir.join(name)),
    }
}

/// The library's public items, sorted.
fn surface() -> Vec<String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let lib = fs::read_to_string(src.join("lib.rs")).expect("src/lib.rs");
    let mut out = Vec::new();
    items(&lib, 0, "mochi", &src, &mut out);
    out.sort();
    out
}

#[test]
fn the_public_surface_is_the_listed_one() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let listed_at = root.join("docs/public-api.txt");
    let got = surface();
    assert!(got.len() > 100, "read the sources: {got:?}");
    assert!(got.contains(&"mochi::dem::model::StepParams  struct".to_owned()));
    assert!(got.contains(&"mochi::engines::optix  mod  [feature optix]".to_owned()));
    assert!(got.contains(&"mochi  use spheres::{MAX_MAGNITUDE, MAX_SPACING_PER_RADIUS, MAX_SPHERES, MIN_RADIUS, SphereSet, Spheres, check_count, coarse_coordinates};".to_owned()));
    let text = got.join("\n") + "\n";
    if std::env::var("MOCHI_UPDATE_SURFACE").is_ok_and(|v| v == "1") {
        fs::write(&listed_at, &text).expect("docs/public-api.txt written");
        return;
    }
    let listed = fs::read_to_string(&listed_at).unwrap_or_default();
    let listed: Vec<&str> = listed.lines().collect();
    let added: Vec<&String> = got
        .iter()
        .filter(|l| !listed.contains(&l.as_str()))
        .collect();
    let removed: Vec<&&str> = listed
        .iter()
        .filter(|l| !got.iter().any(|g| g == **l))
        .collect();
    assert!(
        added.is_empty() && removed.is_empty(),
        "the public surface differs from docs/public-api.txt (rewrite it with \
         MOCHI_UPDATE_SURFACE=1 cargo test --test public_surface if that is meant):\n\
         made public: {added:#?}\nno longer public: {removed:#?}"
    );
}

#[test]
fn the_reader_finds_items_modules_reexports_and_features() {
    let dir = tempfile::tempdir().unwrap();
    fs::write(
        dir.path().join("lib.rs"),
        "//! doc\npub mod a;\n#[cfg(feature = \"x\")]\npub mod b {\n    pub fn f() {}\n    \
         fn hidden() {}\n}\npub(crate) fn internal() {}\npub use a::{\n    One,\n    Two,\n};\n",
    )
    .unwrap();
    fs::create_dir(dir.path().join("a")).unwrap();
    fs::write(
        dir.path().join("a/mod.rs"),
        "pub struct One;\npub enum Two {}\nimpl One {\n    pub fn method() {}\n}\npub mod c;\n",
    )
    .unwrap();
    fs::write(dir.path().join("a/c.rs"), "pub const K: u32 = 1;\n").unwrap();
    let lib = fs::read_to_string(dir.path().join("lib.rs")).unwrap();
    let mut out = Vec::new();
    items(&lib, 0, "t", dir.path(), &mut out);
    assert_eq!(
        out,
        [
            "t::a  mod",
            "t::a::One  struct",
            "t::a::Two  enum",
            "t::a::c  mod",
            "t::a::c::K  const",
            "t::b  mod  [feature x]",
            "t::b::f  fn",
            "t  use a::{One, Two};",
        ]
    );
}
