//! The `prt` command: a thin layer that parses options and calls the library crates.
//!
//! Each subcommand lives in its own module with a clap `Args` struct and a `run` function.

mod compare_cmd;
mod sh_cmd;

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
    /// Spherical-harmonic tools: project environment maps, evaluate the basis.
    #[command(subcommand)]
    Sh(sh_cmd::ShCommand),
    /// Compare an image with a reference: PSNR (LDR, HDR), RMSE, relative L2, noise.
    Compare(compare_cmd::CompareArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Sh(cmd) => sh_cmd::run(cmd),
        Command::Compare(args) => compare_cmd::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
