//! `prt sh ...`: spherical-harmonic utilities.

use clap::Subcommand;

/// Spherical-harmonic subcommands.
#[derive(Subcommand)]
pub enum ShCommand {}

/// Runs an `sh` subcommand.
pub fn run(cmd: ShCommand) -> anyhow::Result<()> {
    match cmd {}
}
