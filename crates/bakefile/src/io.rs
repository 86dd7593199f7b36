//! Reading and atomically writing bake files.

use std::io::Write;
use std::path::Path;

use crate::error::BakeFileError;
use crate::model::{Bake, ScalarType};

/// Writes `bake` to `path` as [`crate::encode`] would encode it (the same bytes, streamed: the
/// payloads are converted and checksummed a chunk at a time, a reflectance field's values
/// written straight from the field), atomically: the bytes go to a temporary file in the
/// same directory, which is flushed to disk (`fsync`) and then renamed over `path`; the
/// directory is synced afterwards where the platform allows it. On any error, no file at
/// `path` is created or changed and no temporary file is left behind.
///
/// # Errors
/// Everything [`crate::encode`] refuses, and I/O errors; every error names `path`.
pub fn write_bake(path: &Path, bake: &Bake, scalar: ScalarType) -> Result<(), BakeFileError> {
    write_inner(path, bake, scalar).map_err(|e| e.in_file(path))
}

fn write_inner(path: &Path, bake: &Bake, scalar: ScalarType) -> Result<(), BakeFileError> {
    // Laid out (and validated) first; the payloads are streamed into the file, so a
    // reflectance field is written from its own bytes, not from a second copy.
    let plan = crate::encode::Plan::new(bake, scalar)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    // Dropping `tmp` on any early return deletes the temporary file.
    let mut builder = tempfile::Builder::new();
    builder.prefix(".prtbake-").suffix(".tmp");
    #[cfg(unix)]
    {
        // A temporary file is private (0600) by default; the bake is an ordinary output file,
        // readable like any other the user creates (0644 less the umask).
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    {
        let mut w = std::io::BufWriter::with_capacity(1 << 16, tmp.as_file_mut());
        plan.write_to(&mut w)?;
        w.flush()?;
    }
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| BakeFileError::Io(e.error))?;
    #[cfg(unix)]
    {
        // Make the rename itself durable. A failure here leaves a complete file behind, so it
        // is not reported as an error.
        if let Ok(d) = std::fs::File::open(dir) {
            let _ = d.sync_all();
        }
    }
    Ok(())
}

/// Reads and decodes the bake file at `path` (see [`crate::decode`]); a reflectance field's
/// values are the file's own buffer, in the file's precision (see [`crate::decode_owned`]).
///
/// # Errors
/// I/O errors and everything [`crate::decode`] refuses; every error names `path`.
pub fn read_bake(path: &Path) -> Result<Bake, BakeFileError> {
    let bytes = std::fs::read(path).map_err(|e| BakeFileError::from(e).in_file(path))?;
    // The file's buffer becomes a reflectance field's values ([`crate::decode_owned`]): reading
    // a field costs the file's size, not the file plus a decoded copy.
    crate::decode_owned(bytes).map_err(|e| e.in_file(path))
}
