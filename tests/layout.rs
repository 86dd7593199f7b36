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
