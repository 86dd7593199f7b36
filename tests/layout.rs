//! The workspace keeps the layout its README and ARCHITECTURE.md promise.

mod common;

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
    ("compare", &[]),
    ("bakefile", &[]),
    ("scene", &["bakefile"]),
    ("shading", &["scene", "sh", "bakefile"]),
    ("tracer", &["scene", "shading"]),
    ("relight", &["sh"]),
    ("bake", &["sh", "scene", "shading", "tracer", "bakefile"]),
    (
        "scene-relight",
        &[
            "sh", "scene", "shading", "tracer", "bakefile", "relight", "compare",
        ],
    ),
    ("gltf", &["scene", "tracer", "bakefile", "scene-relight"]),
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
