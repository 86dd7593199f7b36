//! `prt view`: the live WebGL2 page of an export (`prt_gltf::viewer`).

use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;

/// Options of `prt view`.
#[derive(Args)]
pub struct ViewArgs {
    /// The export (`prt export … --out ASSET.glb`; any `--target`).
    pub glb: PathBuf,
    /// The page to write (self-contained HTML: the file, the script, the stills; no network).
    #[arg(long)]
    pub out: PathBuf,
    /// A path-traced still the page can switch to (`prt render --png`), as `LABEL=FILE.png`
    /// or `FILE.png`; repeat for several.
    #[arg(long, value_name = "[LABEL=]FILE.png")]
    pub still: Vec<String>,
}

/// Runs `prt view`.
pub fn run(args: &ViewArgs) -> Result<()> {
    let mut stills = Vec::new();
    for s in &args.still {
        let (label, file) = match s.split_once('=') {
            Some((l, f)) => (l.to_owned(), PathBuf::from(f)),
            None => (format!("path traced: {s}"), PathBuf::from(s)),
        };
        let png = std::fs::read(&file)
            .with_context(|| format!("{}: cannot read the still", file.display()))?;
        if !png.starts_with(&[0x89, b'P', b'N', b'G']) {
            anyhow::bail!(
                "{}: a still must be a PNG (prt render --png)",
                file.display()
            );
        }
        stills.push(prt_gltf::viewer::Still { label, png });
    }
    prt_gltf::viewer::write_page(&args.glb, &stills, &args.out)
        .with_context(|| format!("{}: cannot write its page", args.glb.display()))?;
    outln!("wrote {}", args.out.display());
    Ok(())
}
