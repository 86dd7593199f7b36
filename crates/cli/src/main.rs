//! The `prt` command: a thin layer that parses options and calls the library crates.
//!
//! Each subcommand lives in its own module with a clap `Args` struct and a `run` function.

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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Sh(cmd) => sh_cmd::run(cmd),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
