//! `lancer bench`: the fixed suite of scenes with every schedule (or, with
//! `--scale`, the million-triangle figures).

use anyhow::Result;

use crate::args::{no_validation_errors, open_device, DeviceArgs};

#[derive(clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    bench: lancer::analysis::bench::BenchOptions,
    #[command(flatten)]
    device: DeviceArgs,
}

/// `lancer bench`.
pub fn bench(args: BenchArgs) -> Result<()> {
    let ctx = open_device(&args.device)?;
    lancer::analysis::bench::run(&ctx, &args.bench)?;
    no_validation_errors(&ctx)
}
