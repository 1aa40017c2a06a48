//! `lancer bench`: the fixed suite of scenes with every schedule (or, with
//! `--scale`, the million-triangle figures), printed, written as JSON and
//! compared with a baseline as asked.

use std::path::PathBuf;

use anyhow::Result;

use lancer::analysis::bench::{self, scale, scenes, BenchReport, SceneSource, SUITE, VARIANTS};
use lancer::io::run_files::RunFiles;

use crate::args::{no_validation_errors, open_device, DeviceArgs};
use crate::progress;

#[derive(clap::Args)]
pub struct BenchArgs {
    /// Write every figure as JSON (for a later --baseline).
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// An earlier `lancer bench --json` file: print the change against it.
    #[arg(long, value_name = "FILE")]
    baseline: Option<PathBuf>,
    /// Instead of the suite, measure how lancer scales to a million
    /// triangles: OBJ load, BVH build and SAH cost, device memory, time per
    /// sample against a thousand triangles, 4x the pixels, more waves.
    #[arg(long, conflicts_with = "baseline")]
    scale: bool,
    /// Folder for the generated scenes (default: $LANCER_SCENE_CACHE_DIR,
    /// else ~/.cache/lancer/scenes).
    #[arg(long, value_name = "DIR")]
    scene_dir: Option<PathBuf>,
    /// Write the suite's scenes (the million-triangle one included) and
    /// print each case's name and scene file, without rendering.
    #[arg(long, conflicts_with_all = ["json", "baseline", "scale"])]
    write_scenes: bool,
    #[command(flatten)]
    device: DeviceArgs,
}

/// `lancer bench`.
pub fn bench(args: BenchArgs) -> Result<()> {
    // Check the baseline and the outputs (the scenes generated in the
    // scene folder among them) before opening the device
    let dir = match &args.scene_dir {
        Some(d) => d.clone(),
        None => scenes::default_scene_dir()?,
    };
    let mut files = RunFiles::default();
    if let Some(path) = &args.baseline {
        files.input(path, "--baseline");
    }
    if let Some(path) = &args.json {
        files.output(path, "--json");
    }
    let sources: Vec<SceneSource> = if args.scale {
        scale::SOURCES.to_vec()
    } else {
        SUITE.iter().map(|case| case.source).collect()
    };
    // Cornell and glass share their folder of files: each file once
    let generated: std::collections::BTreeSet<PathBuf> = sources
        .into_iter()
        .flat_map(|source| bench::scene_files(source, &dir))
        .collect();
    for path in &generated {
        files.cache_output(path, "a scene generated in the scene folder");
    }
    files.check()?;
    let baseline = args
        .baseline
        .as_deref()
        .map(BenchReport::read)
        .transpose()?;
    let ctx = open_device(&args.device)?;
    if args.write_scenes {
        for case in SUITE {
            println!(
                "{} {}",
                case.name,
                bench::scene_file(case.source, &dir)?.display()
            );
        }
    } else if args.scale {
        let report = scale::run(&ctx, &dir, &|step| eprintln!("{step}"))?;
        println!("{}", report.table());
        if let Some(path) = &args.json {
            report.write_json(path)?;
        }
    } else {
        let bar = progress::Suite::new();
        let report = bench::run_suite(&ctx, SUITE, VARIANTS, &dir, bar.observer())?;
        println!("{}", report.table());
        if let Some(before) = &baseline {
            println!("{}", bench::change_table(&report, before));
        }
        if let Some(path) = &args.json {
            report.write_json(path)?;
        }
    }
    no_validation_errors(&ctx)
}
