//! The workspace keeps the layout its README and ARCHITECTURE.md promise.

mod common;

use std::path::Path;

#[test]
fn top_level_holds_only_the_documented_entries() {
    let allowed = [
        "Cargo.toml",
        "Cargo.lock",
        "crates",
        "scenes",
        "tests",
        "tools",
        "docs",
        "fuzz",
        "README.md",
        "ARCHITECTURE.md",
        "LICENSE-MIT",
        "LICENSE-APACHE",
        ".ci",
        // The x86-64-v3 build flags (README, "Run the main job").
        ".cargo",
        ".git",
        ".gitignore",
        "target",
        "out",
    ];
    let root = common::workspace_root();
    for entry in std::fs::read_dir(&root).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(
            allowed.contains(&name.as_str()),
            "unexpected top-level entry {name:?} in {}",
            root.display()
        );
    }
}

#[test]
fn every_crate_is_a_prt_package_with_docs() {
    let crates = common::workspace_root().join("crates");
    for entry in std::fs::read_dir(&crates).unwrap() {
        let dir = entry.unwrap().path();
        let manifest = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
        assert!(
            manifest.contains("name = \"prt-"),
            "{} lacks the prt- prefix",
            dir.display()
        );
        let lib = dir.join("src/lib.rs");
        if lib.exists() {
            let text = std::fs::read_to_string(&lib).unwrap();
            assert!(
                text.starts_with("//!"),
                "{} must open with //! docs",
                lib.display()
            );
        }
    }
}

/// Each crate's allowed `prt-*` dependencies (issue 31): data flows one way, from the leaves
/// (SH, wavelets, comparison, the file format) up through the scene, shading, tracer and the
/// baker to the presentation and the binary. Relighting a scene from a bake
/// (`prt-scene-relight`), its glTF export (`prt-gltf`) and reflectance fields (`prt-fields`)
/// never depend on the baker; the
/// report runs experiments over every stage; only the CLI sees everything. A new edge must
/// be added here on purpose (and to ARCHITECTURE.md's graph).
const ALLOWED: &[(&str, &[&str])] = &[
    ("sh", &[]),
    ("wavelet", &[]),
    ("image", &[]),
    ("compare", &["image"]),
    ("bakefile", &[]),
    ("atlas", &[]),
    ("scene", &["bakefile"]),
    ("shading", &["scene", "sh", "bakefile"]),
    ("tracer", &["scene", "shading", "image"]),
    ("relight", &["sh", "image"]),
    (
        "bake",
        &["sh", "scene", "shading", "tracer", "bakefile", "atlas"],
    ),
    (
        "scene-relight",
        &[
            "sh", "scene", "shading", "tracer", "bakefile", "relight", "compare", "image",
        ],
    ),
    (
        "gltf",
        &["scene", "tracer", "bakefile", "scene-relight", "image"],
    ),
    (
        "fields",
        &[
            "sh",
            "scene",
            "shading",
            "tracer",
            "bakefile",
            "scene-relight",
            "wavelet",
        ],
    ),
    (
        "report",
        &[
            "sh",
            "scene",
            "tracer",
            "bake",
            "bakefile",
            "relight",
            "scene-relight",
            "fields",
            "compare",
            "wavelet",
            "gltf",
            "image",
        ],
    ),
    (
        "cli",
        &[
            "sh",
            "scene",
            "tracer",
            "compare",
            "bake",
            "bakefile",
            "relight",
            "report",
            "scene-relight",
            "gltf",
            "fields",
            "wavelet",
            "image",
        ],
    ),
];

/// The `prt-*` names in the `[dependencies]` table of a crate's manifest.
fn prt_dependencies(manifest: &str) -> Vec<String> {
    manifest
        .lines()
        .skip_while(|l| l.trim() != "[dependencies]")
        .skip(1)
        .take_while(|l| !l.trim_start().starts_with('['))
        .filter_map(|l| l.trim().strip_prefix("prt-"))
        .map(|l| l.split(['.', ' ', '=']).next().unwrap().to_owned())
        .collect()
}

#[test]
fn crate_dependencies_flow_one_way() {
    let crates = common::workspace_root().join("crates");
    let mut seen = Vec::new();
    for entry in std::fs::read_dir(&crates).unwrap() {
        let dir = entry.unwrap().path();
        let manifest = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
        let name = manifest
            .lines()
            .find_map(|l| l.strip_prefix("name = \"prt-"))
            .and_then(|l| l.strip_suffix('"'))
            .unwrap()
            .to_owned();
        let allowed = ALLOWED
            .iter()
            .find(|(c, _)| *c == name)
            .unwrap_or_else(|| panic!("prt-{name} is not in tests/layout.rs's ALLOWED table"))
            .1;
        for dep in prt_dependencies(&manifest) {
            assert!(
                allowed.contains(&dep.as_str()),
                "prt-{name} depends on prt-{dep}, which its row of ALLOWED does not list"
            );
        }
        seen.push(name);
    }
    assert_eq!(
        seen.len(),
        ALLOWED.len(),
        "ALLOWED lists a crate that is gone"
    );
    // The table itself is acyclic: each crate's allowed dependencies come before it.
    for (i, (name, deps)) in ALLOWED.iter().enumerate() {
        for d in *deps {
            let j = ALLOWED.iter().position(|(c, _)| c == d);
            assert!(
                j.is_some_and(|j| j < i),
                "{name} may depend on {d}, which is not listed before it"
            );
        }
    }
}

#[test]
fn manifest_dependencies_are_parsed() {
    let m = "[package]\nname = \"prt-x\"\n[dependencies]\nprt-sh.workspace = true\nprt-scene-relight = { path = \"a\" }\nglam.workspace = true\n\n[dev-dependencies]\nprt-bake.workspace = true\n";
    assert_eq!(prt_dependencies(m), ["sh", "scene-relight"]);
}

/// A module's source without its test module (written last, by convention) and comments.
fn code_of(source: &str) -> String {
    let end = source.find("#[cfg(test)]").unwrap_or(source.len());
    source[..end]
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The identifiers that follow `prefix` in `code` (`crate::x` gives `x`; `crate::{a, b::c}`
/// gives `a` and `b`).
fn names_after(code: &str, prefix: &str) -> Vec<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = Vec::new();
    for (at, _) in code.match_indices(prefix) {
        let rest = &code[at + prefix.len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let group = &group[..group.find('}').unwrap_or(group.len())];
            out.extend(group.split(',').map(|p| ident(p.trim())));
        } else {
            out.push(ident(rest));
        }
    }
    out.retain(|n| !n.is_empty());
    out
}

/// The module graph of one crate's `src/`: module → the modules its code names, through
/// `crate::module`, items defined in the crate root, or items the root re-exports.
fn module_graph(
    src: &Path,
) -> std::collections::BTreeMap<String, std::collections::BTreeSet<String>> {
    let files: std::collections::BTreeMap<String, String> = std::fs::read_dir(src)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .map(|p| {
            let name = p.file_stem().unwrap().to_string_lossy().into_owned();
            (name, code_of(&std::fs::read_to_string(&p).unwrap()))
        })
        .collect();
    let root = if files.contains_key("lib") {
        "lib"
    } else {
        "main"
    };
    let root_code = files.get(root).cloned().unwrap_or_default();
    let modules: Vec<&String> = files.keys().filter(|m| *m != root).collect();
    let mut defined_in_root = std::collections::BTreeSet::new();
    let mut reexported_from = std::collections::BTreeMap::new();
    for line in root_code.lines().map(str::trim) {
        let bare = line
            .trim_start_matches("pub(crate) ")
            .trim_start_matches("pub ");
        for kw in [
            "fn ", "struct ", "enum ", "const ", "static ", "type ", "trait ",
        ] {
            if let Some(rest) = bare.strip_prefix(kw) {
                defined_in_root.insert(names_after(&format!(" {rest}"), " ")[0].clone());
            }
        }
        if let Some(rest) = line.strip_prefix("pub use ") {
            let rest = rest.trim_start_matches("crate::");
            let module: String = rest.split("::").next().unwrap().to_owned();
            for name in names_after(rest, "::") {
                reexported_from.insert(name, module.clone());
            }
        }
    }
    let mut graph = std::collections::BTreeMap::new();
    for (name, code) in &files {
        let mut refs = names_after(code, "crate::");
        if name == root {
            // The root's own code (not its `mod` and `pub use` lines) naming a module.
            let body: String = code
                .lines()
                .filter(|l| {
                    let t = l.trim_start();
                    !(t.starts_with("mod ")
                        || t.starts_with("pub mod ")
                        || t.starts_with("pub use "))
                })
                .collect::<Vec<_>>()
                .join("\n");
            for m in &modules {
                if body.contains(&format!("{m}::")) {
                    refs.push((*m).clone());
                }
            }
        }
        let targets: std::collections::BTreeSet<String> = refs
            .into_iter()
            .filter_map(|r| {
                if modules.contains(&&r) {
                    Some(r)
                } else if defined_in_root.contains(&r) {
                    Some(root.to_owned())
                } else {
                    reexported_from.get(&r).cloned()
                }
            })
            .filter(|t| t != name)
            .collect();
        graph.insert(name.clone(), targets);
    }
    graph
}

/// A cycle of `graph`, if it has one (depth-first search).
fn find_cycle(
    graph: &std::collections::BTreeMap<String, std::collections::BTreeSet<String>>,
) -> Option<Vec<String>> {
    fn visit(
        g: &std::collections::BTreeMap<String, std::collections::BTreeSet<String>>,
        v: &str,
        path: &mut Vec<String>,
        done: &mut std::collections::BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == v) {
            let mut cycle = path[at..].to_vec();
            cycle.push(v.to_owned());
            return Some(cycle);
        }
        if done.contains(v) {
            return None;
        }
        path.push(v.to_owned());
        for w in g.get(v).into_iter().flatten() {
            if let Some(c) = visit(g, w, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(v.to_owned());
        None
    }
    let mut done = std::collections::BTreeSet::new();
    graph
        .keys()
        .find_map(|v| visit(graph, v, &mut Vec::new(), &mut done))
}

/// Issue 31: no import circle between the files of a crate (`relit` ↔ `imaging` and the
/// like), so each file can be read, and moved, after the ones it uses.
#[test]
fn no_crate_has_an_import_circle_between_its_files() {
    let crates = common::workspace_root().join("crates");
    for entry in std::fs::read_dir(&crates).unwrap() {
        let src = entry.unwrap().path().join("src");
        if !src.is_dir() {
            continue;
        }
        let graph = module_graph(&src);
        assert!(!graph.is_empty(), "{}: no sources", src.display());
        if let Some(cycle) = find_cycle(&graph) {
            panic!("{}: import circle {}", src.display(), cycle.join(" → "));
        }
    }
}

#[test]
fn the_import_analysis_sees_the_three_ways_a_file_names_another() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    write(
        "lib.rs",
        "mod a;\nmod b;\nmod c;\npub use c::Thing;\npub struct Root;\n",
    );
    write(
        "a.rs",
        "use crate::b::f;\n// crate::c is only named in a comment\n",
    );
    write(
        "b.rs",
        "use crate::{Thing, Root};\n#[cfg(test)]\nmod tests { use crate::a; }\n",
    );
    write("c.rs", "pub struct Thing;\nfn g() { crate::a::h() }\n");
    let graph = module_graph(dir);
    let names = |m: &str| graph[m].iter().cloned().collect::<Vec<_>>();
    assert_eq!(names("a"), ["b"]);
    assert_eq!(names("b"), ["c", "lib"]);
    assert_eq!(names("c"), ["a"]);
    assert_eq!(find_cycle(&graph).unwrap(), ["a", "b", "c", "a"]);
    std::fs::write(dir.join("c.rs"), "pub struct Thing;\n").unwrap();
    assert!(find_cycle(&module_graph(dir)).is_none());
}

/// The longest a function may be without a reason written beside it (issue 31: functions a
/// reader can hold in their head).
const LONGEST_FUNCTION: usize = 200;

/// The word that, in the comment lines just above a function, says why it is longer.
const LONG_REASON: &str = "Long function:";

/// Every `fn` in `source` with its name, first line (1-based) and length in lines, from its
/// signature to the closing brace written at the signature's indentation (rustfmt's layout).
/// Declarations without a body (trait items ending in `;`) are skipped.
fn function_lengths(source: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = source.lines().collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = line.len() - trimmed.len();
        let mut rest = trimmed;
        for qualifier in [
            "pub(crate) ",
            "pub(super) ",
            "pub ",
            "const ",
            "async ",
            "unsafe ",
        ] {
            rest = rest.strip_prefix(qualifier).unwrap_or(rest);
        }
        let Some(after) = rest.strip_prefix("fn ") else {
            continue;
        };
        let name: String = after
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let Some(open) = (i..lines.len()).find(|&j| {
            let l = lines[j].trim_end();
            l.ends_with('{') || l.ends_with(';')
        }) else {
            continue;
        };
        if lines[open].trim_end().ends_with(';') {
            continue;
        }
        let close = (open + 1..lines.len()).find(|&j| {
            let l = lines[j];
            l.len() > indent && l[..indent].trim().is_empty() && l[indent..].starts_with('}')
        });
        if let Some(close) = close {
            out.push((name, i + 1, close - i + 1));
        }
    }
    out
}

/// Whether the comment block just above line `first` (1-based) gives a reason for length.
fn has_long_reason(source: &str, first: usize) -> bool {
    source
        .lines()
        .take(first - 1)
        .collect::<Vec<_>>()
        .iter()
        .rev()
        .take_while(|l| {
            let t = l.trim_start();
            t.starts_with("//") || t.starts_with("#[")
        })
        .any(|l| l.contains(LONG_REASON))
}

#[test]
fn no_function_is_longer_than_a_reader_can_hold_without_a_reason() {
    // Library and binary code: each crate's `src/` (test files, whose long tables of rows
    // are data, are not held to it).
    let crates = common::workspace_root().join("crates");
    let mut long = Vec::new();
    let mut stack: Vec<_> = std::fs::read_dir(&crates)
        .unwrap()
        .map(|e| e.unwrap().path().join("src"))
        .filter(|p| p.is_dir())
        .collect();
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let source = std::fs::read_to_string(&path).unwrap();
                for (name, first, len) in function_lengths(&source) {
                    if len > LONGEST_FUNCTION && !has_long_reason(&source, first) {
                        long.push(format!("{}:{first} {name} ({len} lines)", path.display()));
                    }
                }
            }
        }
    }
    assert!(
        long.is_empty(),
        "functions over {LONGEST_FUNCTION} lines with no `{LONG_REASON}` comment above them:\n{}",
        long.join("\n")
    );
}

#[test]
fn function_lengths_are_measured_from_signature_to_closing_brace() {
    let source = "\
pub fn short() {
    let x = 1;
}

trait T {
    fn declared(&self);
    fn defaulted(&self) {
        if true {
        }
    }
}

// Long function: a reason.
#[inline]
pub(crate) fn explained(
    a: u32,
) -> u32 {
    a
}
";
    let found = function_lengths(source);
    let names: Vec<_> = found.iter().map(|(n, f, l)| (n.as_str(), *f, *l)).collect();
    assert_eq!(
        names,
        [("short", 1, 3), ("defaulted", 7, 4), ("explained", 15, 5)]
    );
    assert!(!has_long_reason(source, 1));
    assert!(!has_long_reason(source, 7));
    assert!(has_long_reason(source, 15));
}
