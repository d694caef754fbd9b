//! `slscan info FILE`: a summary of a point cloud or a calibration file.

use std::path::PathBuf;

/// Arguments of `slscan info`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A PLY point cloud, or a calibration file (.json, .yml, .yaml, .xml).
    pub file: PathBuf,
}

/// Runs `slscan info`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    anyhow::bail!("{}: `slscan info` is not wired yet", args.file.display())
}
