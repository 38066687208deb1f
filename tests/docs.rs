//! The documentation's links: every relative Markdown link in README.md, CHANGELOG.md,
//! docs/*.md, docs/guide/*.md and docs/performance-log/*.md names a file that exists, and every
//! `#anchor` into a Markdown file names one of its headings (GitHub's anchor rule: the heading's
//! text lowercased, spaces to '-', punctuation other than '-' and '_' dropped, a repeated
//! heading's anchor followed by -1, -2, …). Links to other sites (`https:`, `mailto:`) are not
//! followed. Code blocks and code spans are not links.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Component, Path, PathBuf};

/// The Markdown files whose links are checked, relative to the repository root.
fn documents(root: &Path) -> Vec<PathBuf> {
    let mut files = vec![root.join("README.md"), root.join("CHANGELOG.md")];
    for dir in ["docs", "docs/guide", "docs/performance-log"] {
        let Ok(entries) = fs::read_dir(root.join(dir)) else {
            continue;
        };
        let mut found: Vec<PathBuf> = entries
            .map(|e| e.expect("a readable docs folder").path())
            .filter(|p| p.extension().is_some_and(|e| e == "md"))
            .collect();
        found.sort();
        files.extend(found);
    }
    files.retain(|p| p.is_file());
    files
}

/// The lines of a Markdown file outside fenced code blocks, with their 1-based numbers.
fn prose_lines(text: &str) -> Vec<(usize, &str)> {
    let mut fence: Option<&str> = None;
    let mut lines = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        let marker = ["```", "~~~"].into_iter().find(|m| trimmed.starts_with(m));
        match (fence, marker) {
            (None, Some(m)) => fence = Some(m),
            (Some(open), Some(m)) if open == m => fence = None,
            (None, None) => lines.push((i + 1, line)),
            _ => {}
        }
    }
    lines
}

/// A line without its code spans (`…`, ``…``).
fn without_code_spans(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut rest = line;
    while let Some(start) = rest.find('`') {
        out.push_str(&rest[..start]);
        let ticks = rest[start..].chars().take_while(|&c| c == '`').count();
        let after = &rest[start + ticks..];
        match after.find(&"`".repeat(ticks)) {
            Some(end) => rest = &after[end + ticks..],
            None => {
                // An unmatched backtick is text.
                out.push_str(&rest[start..start + ticks]);
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// The targets of a line's inline links and images (`[text](target)`, `![alt](target "title")`)
/// and of a reference definition (`[label]: target`).
fn link_targets(line: &str) -> Vec<String> {
    let line = without_code_spans(line);
    let mut targets = Vec::new();
    let trimmed = line.trim_start();
    if trimmed.starts_with('[')
        && let Some(close) = trimmed.find("]:")
        && !trimmed[..close].contains('(')
    {
        if let Some(target) = trimmed[close + 2..].split_whitespace().next() {
            targets.push(target.to_string());
        }
        return targets;
    }
    let bytes = line.as_bytes();
    let mut i = 0;
    while let Some(pos) = line[i..].find("](") {
        let open = i + pos + 2;
        // The target runs to the matching ')' (a target may hold balanced parentheses).
        let mut depth = 1;
        let mut end = open;
        while end < bytes.len() {
            match bytes[end] {
                b'(' => depth += 1,
                b')' => {
                    depth -= 1;
                    if depth == 0 {
                        break;
                    }
                }
                _ => {}
            }
            end += 1;
        }
        let inner = line[open..end.min(bytes.len())].trim();
        let target = if let Some(stripped) = inner.strip_prefix('<') {
            stripped.split('>').next().unwrap_or("")
        } else {
            inner.split_whitespace().next().unwrap_or("")
        };
        targets.push(target.to_string());
        i = end.min(bytes.len());
    }
    targets
}

/// GitHub's anchor of a heading's text: lowercased, Markdown's emphasis and code marks and link
/// targets dropped, every character other than a letter, a digit, '-', '_' or a space dropped,
/// spaces turned into '-'.
fn anchor_of(heading: &str) -> String {
    // [text](target) shows as text.
    let mut text = String::new();
    let mut rest = heading;
    while let Some(pos) = rest.find("](") {
        text.push_str(&rest[..pos]);
        let after = &rest[pos + 2..];
        rest = after.find(')').map_or("", |end| &after[end + 1..]);
    }
    text.push_str(rest);
    text.trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            '-' | '_' => Some(c),
            c if c.is_alphanumeric() => Some(c),
            _ => None,
        })
        .collect()
}

/// Every anchor of a Markdown file's headings (ATX headings outside code blocks).
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut all = BTreeSet::new();
    for (_, line) in prose_lines(text) {
        let trimmed = line.trim_start();
        let hashes = trimmed.chars().take_while(|&c| c == '#').count();
        if hashes == 0 || hashes > 6 || !trimmed[hashes..].starts_with(' ') {
            continue;
        }
        let title = trimmed[hashes..].trim().trim_end_matches('#').trim();
        let base = anchor_of(title);
        let n = seen.entry(base.clone()).or_insert(0);
        all.insert(if *n == 0 { base } else { format!("{base}-{n}") });
        *n += 1;
    }
    all
}

/// `path` with `.` and `..` resolved lexically (the files need not exist).
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for part in path.components() {
        match part {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// Checks every link of the documents; returns how many were checked (files and anchors) and
/// the broken ones, each as "file:line: target: why".
fn check(root: &Path) -> (usize, usize, Vec<String>) {
    let mut links = 0;
    let mut anchored = 0;
    let mut broken = Vec::new();
    let mut anchor_cache: BTreeMap<PathBuf, BTreeSet<String>> = BTreeMap::new();
    for doc in documents(root) {
        let text = fs::read_to_string(&doc).expect("a readable Markdown file");
        let shown = doc.strip_prefix(root).unwrap_or(&doc).display().to_string();
        for (number, line) in prose_lines(&text) {
            for target in link_targets(line) {
                if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
                    continue;
                }
                links += 1;
                let (path, anchor) = match target.split_once('#') {
                    Some((p, a)) => (p, Some(a)),
                    None => (target.as_str(), None),
                };
                let file = if path.is_empty() {
                    doc.clone()
                } else {
                    normalize(&doc.parent().expect("a file in a folder").join(path))
                };
                if !file.exists() {
                    broken.push(format!("{shown}:{number}: {target}: no such file"));
                    continue;
                }
                let Some(anchor) = anchor else { continue };
                if file.extension().is_none_or(|e| e != "md") {
                    continue;
                }
                anchored += 1;
                let headings = anchor_cache.entry(file.clone()).or_insert_with(|| {
                    anchors(&fs::read_to_string(&file).expect("a readable Markdown file"))
                });
                if !headings.contains(anchor) {
                    broken.push(format!(
                        "{shown}:{number}: {target}: no heading with the anchor #{anchor}"
                    ));
                }
            }
        }
    }
    (links, anchored, broken)
}

#[test]
fn every_relative_link_and_anchor_of_the_docs_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (links, anchored, broken) = check(root);
    assert!(
        broken.is_empty(),
        "{} broken links:\n{}",
        broken.len(),
        broken.join("\n")
    );
    assert!(links > 0, "no relative links found: the check read nothing");
    assert!(anchored > 0, "no links with an anchor found");
    println!("{links} relative links checked, {anchored} of them with an anchor");
}

#[test]
fn anchors_follow_githubs_rule() {
    assert_eq!(anchor_of("Set up"), "set-up");
    assert_eq!(
        anchor_of("Walls that move, spheres that flow in and out"),
        "walls-that-move-spheres-that-flow-in-and-out"
    );
    assert_eq!(
        anchor_of("Issue 20: `mochi.detect` called again (1M: 130 → 2.6 ms)"),
        "issue-20-mochidetect-called-again-1m-130--26-ms"
    );
    assert_eq!(
        anchor_of("H100 — 2026-11-27, snake_case"),
        "h100--2026-11-27-snake_case"
    );
    assert_eq!(anchor_of("See [method](method.md) too"), "see-method-too");
    let text = "# A\n\n```\n# not a heading\n```\n## A\n### B.\n";
    let found = anchors(text);
    assert_eq!(
        found,
        ["a", "a-1", "b"].map(String::from).into_iter().collect()
    );
}

#[test]
fn links_are_read_from_prose_only() {
    assert_eq!(
        link_targets("see [a](a.md#x) and ![b](img/b.png \"t\") and `[c](c.md)`"),
        vec!["a.md#x", "img/b.png"]
    );
    assert_eq!(
        link_targets("[ref]: guide/files.md#frames"),
        vec!["guide/files.md#frames"]
    );
    assert_eq!(
        link_targets("`mochi simulate [SCENE.toml] [-n N]`"),
        Vec::<String>::new()
    );
    let text = "a [x](x.md)\n```sh\n[y](y.md)\n```\nb";
    let lines: Vec<usize> = prose_lines(text).into_iter().map(|(n, _)| n).collect();
    assert_eq!(lines, vec![1, 5]);
}
