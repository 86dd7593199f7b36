//! `prt compare A B`: errors of an image against a reference (B), with the reference's noise.

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use prt_compare::{
    check_same_kind, compare_with, noise_from_pair, noise_from_variance, read_image, report_json,
    report_table, write_error_png, CompareOptions, ErrorChannel, ErrorImageOptions, ErrorMeasure,
    LoadedImage, Mask,
};
use std::path::PathBuf;

/// Per-pixel error shown in the error image.
#[derive(Clone, Copy, ValueEnum)]
pub enum ErrorMeasureArg {
    /// |a − b|.
    Abs,
    /// |a − b| / max(|b|, 1e-3).
    Rel,
}

/// Quantity whose error the error image shows.
#[derive(Clone, Copy, ValueEnum)]
pub enum ErrorChannelArg {
    /// Rec.709 luminance.
    Luminance,
    /// Largest channel difference.
    Max,
}

/// Options of `prt compare`.
#[derive(Args)]
pub struct CompareArgs {
    /// The image to measure (EXR or PNG).
    pub test: PathBuf,
    /// The reference (EXR or PNG), e.g. a path-traced render.
    pub reference: PathBuf,
    /// Mask PNG: nonzero pixels are the object; adds masked_* metrics.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Print exactly one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Write a false-colour error image with a scale bar (PNG).
    #[arg(long, value_name = "E.png")]
    pub error_png: Option<PathBuf>,
    /// Error image: absolute or relative error.
    #[arg(long, value_enum, default_value = "abs")]
    pub error_measure: ErrorMeasureArg,
    /// Error image: luminance or largest channel.
    #[arg(long, value_enum, default_value = "luminance")]
    pub error_channel: ErrorChannelArg,
    /// Error image: error at the top of the colour map (default: the largest error).
    #[arg(long)]
    pub error_max: Option<f64>,
    /// Exposure of the 8-bit view used by psnr_ldr, in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f64,
    /// A second, independent render of the reference (same spp): estimates its noise.
    #[arg(long, value_name = "C", conflicts_with = "variance")]
    pub noise_pair: Option<PathBuf>,
    /// The reference's variance-of-the-mean image (EXR AOV): estimates its noise.
    #[arg(long, value_name = "V")]
    pub variance: Option<PathBuf>,
}

fn load(path: &PathBuf, role: &str) -> Result<LoadedImage> {
    let loaded = read_image(path).with_context(|| format!("reading the {role}"))?;
    if loaded.alpha_ignored {
        eprintln!(
            "note: {}: alpha channel ignored (only R, G, B are compared)",
            path.display()
        );
    }
    Ok(loaded)
}

/// Runs `prt compare`.
pub fn run(args: CompareArgs) -> Result<()> {
    let options = CompareOptions {
        exposure_ev: args.exposure,
    };
    let test = load(&args.test, "test image")?;
    let reference = load(&args.reference, "reference")?;
    check_same_kind(&test, &reference)?;
    let mask = args
        .mask
        .as_ref()
        .map(|p| Mask::from_file(p).context("reading the mask"))
        .transpose()?;
    let metrics = compare_with(&test.image, &reference.image, mask.as_ref(), &options)?;

    let noise = if let Some(path) = &args.noise_pair {
        let second = load(path, "second render of the reference")?;
        check_same_kind(&second, &reference)?;
        Some(noise_from_pair(
            &reference.image,
            &second.image,
            mask.as_ref(),
            &options,
        )?)
    } else if let Some(path) = &args.variance {
        let var = load(path, "variance image")?;
        Some(noise_from_variance(
            &var.image,
            &reference.image,
            mask.as_ref(),
            &options,
        )?)
    } else {
        None
    };

    if let Some(path) = &args.error_png {
        let error_options = ErrorImageOptions {
            measure: match args.error_measure {
                ErrorMeasureArg::Abs => ErrorMeasure::Absolute,
                ErrorMeasureArg::Rel => ErrorMeasure::Relative,
            },
            channel: match args.error_channel {
                ErrorChannelArg::Luminance => ErrorChannel::Luminance,
                ErrorChannelArg::Max => ErrorChannel::MaxChannel,
            },
            scale_max: args.error_max,
            ..ErrorImageOptions::default()
        };
        let picture = write_error_png(
            path,
            &test.image,
            &reference.image,
            mask.as_ref(),
            &error_options,
        )
        .context("writing the error image")?;
        if !args.json {
            outln!(
                "error image: {} (viridis, 0 … {})",
                path.display(),
                prt_compare::format_number(picture.scale_max)
            );
        }
    }

    if args.json {
        outln!("{}", report_json(&metrics, noise.as_ref()));
    } else {
        outln!(
            "{} against reference {}",
            args.test.display(),
            args.reference.display()
        );
        print!("{}", report_table(&metrics, noise.as_ref()));
    }
    Ok(())
}
