//! The `prt` command: a thin layer that parses options and calls the library crates.
//!
//! Each subcommand lives in its own module with a clap `Args` struct and a `run` function.

/// `println!` that returns the write error instead of panicking (a closed pipe, e.g.
/// `prt inspect F | head`, ends the command quietly; see `main`).
macro_rules! outln {
    () => {
        std::io::Write::write_all(&mut std::io::stdout(), b"\n")?
    };
    ($($arg:tt)*) => {{
        let line = format!($($arg)*);
        let mut out = std::io::stdout().lock();
        std::io::Write::write_all(&mut out, line.as_bytes())?;
        std::io::Write::write_all(&mut out, b"\n")?;
    }};
}

mod bake_cmd;
mod bench_cmd;
mod common;
mod compare_cmd;
mod compress_cmd;
mod fit_cmd;
mod reflectance_cmd;
mod relight_cmd;
mod render_cmd;
mod report_cmd;
mod sh_cmd;
mod view_cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Offline path-traced references, PRT bakes, SH relighting and comparisons.
#[derive(Parser)]
#[command(name = "prt", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Path-trace a reference image of a scene (EXR, optional PNG view).
    Render(render_cmd::RenderArgs),
    /// Spherical-harmonic tools: project environment maps, evaluate the basis.
    #[command(subcommand)]
    Sh(sh_cmd::ShCommand),
    /// Bake precomputed radiance transfer of a scene into a .prtb file.
    Bake(bake_cmd::BakeArgs),
    /// Print the header and per-object summary of a bake file.
    Inspect(bake_cmd::InspectArgs),
    /// Merge the shard files of a sharded bake into one file.
    Merge(bake_cmd::MergeArgs),
    /// Compress every transfer block of a bake by clustered PCA (Sloan et al. 2003), to a PSNR
    /// target on the relit image when the scene is given.
    Compress(compress_cmd::CompressArgs),
    /// Write a per-vertex or per-texel bake as binary glTF 2.0: the meshes with their own
    /// materials, the transfer as vertex attributes (or lightmap textures) and the
    /// view-dependent terms prt relight shades with (SPEC §10).
    Export(bake_cmd::ExportArgs),
    /// Relight a bake under the (rotated) environment: full-order or locally adaptive SH, or a
    /// reflectance field (from `prt reflectance`) reconstructed on a fine grid.
    Relight(relight_cmd::RelightArgs),
    /// Sample a scene's reflectance field: per pixel, its response to a distant light from each
    /// direction of a lat-long grid (Masselus et al. 2004), for all-frequency relighting.
    Reflectance(reflectance_cmd::ReflectanceArgs),
    /// Speed-against-error report: reference, bake, full and adaptive relighting per order.
    Report(report_cmd::ReportArgs),
    /// Compare an image with a reference: PSNR (LDR, HDR), RMSE, relative L2, noise.
    Compare(compare_cmd::CompareArgs),
    /// Write a self-contained page that relights an export (`prt export`) live with WebGL2
    /// from the file alone: turn the environment, change the exposure, switch to stills.
    View(view_cmd::ViewArgs),
    /// Fit the environment's SH lighting to an image of a baked scene (inverse lighting:
    /// the image is linear in the lighting), with the conditioning of each band.
    FitLighting(fit_cmd::FitLightingArgs),
    /// Timings: `prt bench relight` times `prt relight`'s shading (median of warm frames).
    #[command(subcommand)]
    Bench(bench_cmd::BenchCommand),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render_cmd::run(&args),
        Command::Sh(cmd) => sh_cmd::run(cmd),
        Command::Bake(args) => bake_cmd::run_bake(&args),
        Command::Inspect(args) => bake_cmd::run_inspect(&args),
        Command::Merge(args) => bake_cmd::run_merge(&args),
        Command::Compress(args) => compress_cmd::run(&args),
        Command::Export(args) => bake_cmd::run_export(&args),
        Command::Relight(args) => relight_cmd::run(&args),
        Command::Reflectance(args) => reflectance_cmd::run(&args),
        Command::Report(args) => report_cmd::run(&args),
        Command::Compare(args) => compare_cmd::run(args),
        Command::Bench(cmd) => bench_cmd::run(&cmd),
        Command::View(args) => view_cmd::run(&args),
        Command::FitLighting(args) => fit_cmd::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The reader of our standard output went away (`prt inspect F | head`): nothing is
        // wrong with the command, and nobody is left to read a message.
        Err(err)
            if err
                .downcast_ref::<std::io::Error>()
                .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            ExitCode::SUCCESS
        }
        Err(err) => {
            eprintln!("error: {}", error_message(&err));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line, each cause only once: several library errors already
/// include their source in their own message (e.g. "FILE: reason"), and printing the whole
/// chain would repeat it.
fn error_message(err: &anyhow::Error) -> String {
    let mut msg = err.to_string();
    for cause in err.chain().skip(1) {
        let c = cause.to_string();
        if !msg.contains(&c) {
            msg.push_str(": ");
            msg.push_str(&c);
        }
    }
    msg
}
