//! `lancer compare`: an image against a reference, printed with each check
//! and the verdict; exit code 1 when a tolerance is exceeded.

use std::path::PathBuf;

use anyhow::Result;

use lancer::analysis::compare::{compare_files, CompareOptions};

#[derive(clap::Args)]
pub struct CompareArgs {
    /// The image under test (.exr or .png).
    image: PathBuf,
    /// The reference image (.exr or .png), of the same size.
    reference: PathBuf,
    /// Per-pixel variance of IMAGE's mean (an EXR, as `render --var-out`
    /// writes): runs the per-pixel z-test. The reference's variance is read
    /// from REFERENCE's `NAME.var.exr` when that file exists, else taken as 0.
    #[arg(long, value_name = "VAR.exr")]
    var: Option<PathBuf>,
    /// Write the FLIP error map as a PNG heat map.
    #[arg(long, value_name = "OUT.png")]
    heatmap: Option<PathBuf>,
    /// Fail (exit code 1) when relMSE is above this.
    #[arg(long, value_name = "X")]
    max_relmse: Option<f64>,
    /// Fail (exit code 1) when the mean FLIP error is above this.
    #[arg(long, value_name = "X")]
    max_flip: Option<f64>,
    /// Write every figure as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

/// The compared image is worse than the tolerance asked for: exit code 1,
/// with the report already printed.
#[derive(Debug, thiserror::Error)]
#[error("the image is worse than the tolerance")]
pub struct Worse;

/// `lancer compare`.
pub fn compare(args: CompareArgs) -> Result<()> {
    let mut opts = CompareOptions::new(&args.image, &args.reference);
    opts.var = args.var;
    opts.heatmap = args.heatmap;
    opts.max_relmse = args.max_relmse;
    opts.max_flip = args.max_flip;
    opts.json = args.json;
    let report = compare_files(&opts)?;
    println!("{}", report.verdict(opts.max_relmse, opts.max_flip));
    if report.passes(opts.max_relmse, opts.max_flip) {
        Ok(())
    } else {
        Err(Worse.into())
    }
}
