//! `lancer merge`: the film files of a render split into sample ranges,
//! merged into one image (and its variance).

use std::path::PathBuf;

use anyhow::Result;

use lancer::io::image_file;
use lancer::io::run_files::RunFiles;

#[derive(clap::Args)]
pub struct MergeArgs {
    /// The parts' film files, in any order.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output image: .png or .exr.
    #[arg(long, short)]
    out: PathBuf,
    /// Also write the per-pixel variance of the mean as a linear EXR.
    #[arg(long, value_name = "FILE.exr")]
    var_out: Option<PathBuf>,
}

/// `lancer merge`.
pub fn merge(args: MergeArgs) -> Result<()> {
    // Every file before any is read: the outputs name neither each other
    // nor a part
    let mut files = RunFiles::default();
    for part in &args.parts {
        files.input(part, "a film part");
    }
    files.image_output(&args.out, "--out");
    if let Some(path) = &args.var_out {
        files.exr_output(path, "--var-out");
    }
    files.check()?;
    let parts = (args.parts.iter())
        .map(|p| Ok((p.clone(), lancer::io::film::FilmPart::read(p)?)))
        .collect::<Result<Vec<_>>>()?;
    let merged = lancer::io::film::merge(&parts)?;
    // The parts carry their scene's hash and sampler, not its settings:
    // record what the merge knows
    let meta = image_file::Metadata {
        spp: Some(merged.spp),
        sampler: Some(merged.sampler.name().to_string()),
        version: Some(lancer::VERSION.to_string()),
        ..Default::default()
    };
    let mut outputs = image_file::Outputs::default();
    outputs.add_image(
        &args.out,
        merged.width,
        merged.height,
        &merged.image.mean,
        &meta,
    )?;
    if let Some(path) = &args.var_out {
        outputs.add_image(
            path,
            merged.width,
            merged.height,
            &merged.image.var_of_mean,
            &meta,
        )?;
    }
    outputs.commit()?;
    println!(
        "merged {} parts, {} spp, {}x{}{}; wrote {}",
        parts.len(),
        merged.spp,
        merged.width,
        merged.height,
        if merged.nonfinite > 0 {
            format!(" ({} non-finite samples dropped)", merged.nonfinite)
        } else {
            String::new()
        },
        args.out.display()
    );
    Ok(())
}
