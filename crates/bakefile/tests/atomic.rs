//! `write_bake` is atomic: the file appears whole or not at all, and no temporary file is
//! left behind on failure.

mod common;

use std::path::Path;

use common::*;
use prt_bakefile::*;

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn test01_write_then_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.prtbake");
    let bake = sample_bake();
    write_bake(&path, &bake, ScalarType::F32).unwrap();
    assert_eq!(entries(dir.path()), ["scene.prtbake"]);
    assert_eq!(read_bake(&path).unwrap(), bake);
    // Overwriting replaces the file whole.
    let mut smaller = bake.clone();
    smaller.objects.truncate(1);
    smaller.meta.ray_stats.truncate(1);
    write_bake(&path, &smaller, ScalarType::F16).unwrap();
    assert_eq!(entries(dir.path()), ["scene.prtbake"]);
    assert_eq!(read_bake(&path).unwrap().objects.len(), 1);
    // An output file, not a private temporary one: others may read it (the umask allowing;
    // test runners use 022 or 002, which both keep the read bits).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode & 0o444, 0o444, "mode {mode:o}");
        assert_eq!(mode & 0o111, 0, "mode {mode:o}");
    }
}

#[test]
fn test02_encoding_failure_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.prtbake");
    let mut bake = sample_bake();
    bake.objects[0].blocks[0].data[0] = f32::NAN;
    let e = write_bake(&path, &bake, ScalarType::F32).unwrap_err();
    assert!(e.to_string().contains("bad.prtbake"), "{e}");
    assert!(matches!(e.root(), BakeFileError::NonFinite { .. }));
    assert!(entries(dir.path()).is_empty());
    // An existing file is left untouched by a failed write.
    let good = sample_bake();
    write_bake(&path, &good, ScalarType::F32).unwrap();
    let before = std::fs::read(&path).unwrap();
    bake.objects[0].blocks[0].data[0] = 1e9;
    assert!(write_bake(&path, &bake, ScalarType::F16).is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(entries(dir.path()), ["bad.prtbake"]);
}

#[test]
fn test03_rename_failure_leaves_no_temporary_file() {
    // The target is a non-empty directory: the temporary file is written and synced, then
    // the rename fails; the temporary must be removed.
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("occupied");
    std::fs::create_dir(&target).unwrap();
    std::fs::write(target.join("keep"), b"x").unwrap();
    let e = write_bake(&target, &sample_bake(), ScalarType::F32).unwrap_err();
    assert!(matches!(e.root(), BakeFileError::Io(_)), "{e}");
    assert!(e.to_string().contains("occupied"), "{e}");
    assert_eq!(entries(dir.path()), ["occupied"]);
    assert_eq!(entries(&target), ["keep"]);
}

#[test]
fn test04_missing_or_unwritable_directory() {
    let dir = tempfile::tempdir().unwrap();
    let e = write_bake(
        &dir.path().join("no/such/dir/x.prtbake"),
        &sample_bake(),
        ScalarType::F32,
    )
    .unwrap_err();
    assert!(matches!(e.root(), BakeFileError::Io(_)));
    assert!(entries(dir.path()).is_empty());

    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let ro = dir.path().join("readonly");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        // Root ignores directory permissions; the check is only meaningful for other users.
        let probe = ro.join("probe");
        let enforced = std::fs::write(&probe, b"").is_err();
        let _ = std::fs::remove_file(&probe);
        if enforced {
            let e = write_bake(&ro.join("x.prtbake"), &sample_bake(), ScalarType::F32).unwrap_err();
            assert!(matches!(e.root(), BakeFileError::Io(_)));
            assert!(entries(&ro).is_empty());
        } else {
            eprintln!("running as root: directory permissions not enforced, part skipped");
        }
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}
