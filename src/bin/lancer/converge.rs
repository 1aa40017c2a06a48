//! `lancer converge`: error against render time and samples per pixel, for
//! one or more settings, against a reference: CSV, JSON, plots and a table.

use std::path::PathBuf;

use anyhow::{Context as _, Result};

use lancer::internal::converge;
use lancer::internal::study::{self, Vary};
use lancer::io::run_files::RunFiles;
use lancer::render::budget::Budget;

use crate::args::{
    load_scene, no_validation_errors, open_device, DeviceArgs, KernelArgs, Overrides, SizeArgs,
};
use crate::progress;

#[derive(clap::Args)]
#[command(group = clap::ArgGroup::new("length").args(["max_spp", "time_limit"]))]
#[command(group = clap::ArgGroup::new("reference_source").args(["reference", "reference_spp"]))]
pub struct ConvergeArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Reference image (linear EXR of the scene's size). A `NAME.var.exr`
    /// beside it, if present, is taken as its variance of the mean; its spp
    /// and seed are read from the file when lancer wrote it.
    #[arg(long, value_name = "REF.exr")]
    reference: Option<PathBuf>,
    /// Render the reference with lancer at this spp, with a seed that no
    /// measured run uses, and cache it in the output folder.
    #[arg(long, value_name = "N")]
    reference_spp: Option<u32>,
    /// Measure up to this many samples per pixel (default 256).
    #[arg(long, value_name = "N")]
    max_spp: Option<u32>,
    /// Measure until this many seconds of rendering are spent, per run.
    #[arg(long, value_name = "SECONDS")]
    time_limit: Option<f64>,
    /// Repeat every run with K seeds and report mean and spread.
    #[arg(long, value_name = "K", default_value_t = 1)]
    seeds: u32,
    /// Compare settings: KEY=V1,V2,... with KEY one of integrator (nee,bsdf),
    /// max_depth, features (scene,all), wave_size, sampler
    /// (independent,sobol). May be given again for another key; every
    /// combination runs.
    #[arg(long, value_name = "KEY=V1,V2,...", value_parser = parse_vary)]
    vary: Vec<Vary>,
    /// Output folder for converge.csv, converge.json, the plots and the
    /// cached reference.
    #[arg(long, default_value = "converge")]
    out: PathBuf,
    #[command(flatten)]
    size: SizeArgs,
    /// Do not print a line per step.
    #[arg(long, short)]
    quiet: bool,
    #[command(flatten)]
    kernels: KernelArgs,
    #[command(flatten)]
    device: DeviceArgs,
}

/// The errors `lancer converge` reports the time to reach.
const REPORTED_ERRORS: [f64; 2] = [1e-2, 1e-3];

/// Default `--max-spp` of `lancer converge`.
const CONVERGE_DEFAULT_SPP: u32 = 256;
/// Default `--reference-spp` of `lancer converge`.
const CONVERGE_DEFAULT_REFERENCE_SPP: u32 = 4096;

/// `lancer converge`.
pub fn converge(args: ConvergeArgs) -> Result<()> {
    // Check everything the user gave before rendering or writing anything:
    // the numbers, the scene, the settings, the reference, the files
    anyhow::ensure!(args.seeds >= 1, "--seeds must be at least 1");
    anyhow::ensure!(
        args.reference_spp != Some(0),
        "--reference-spp must be at least 1"
    );
    let overrides = Overrides {
        size: args.size.clone(),
        ..Overrides::default()
    };
    let scene = load_scene(&args.scene, &overrides)?;
    let length = match (args.time_limit, args.max_spp) {
        (Some(s), _) => {
            Budget::Time(s).validate()?;
            study::Length::Seconds(s)
        }
        (None, Some(n)) => {
            anyhow::ensure!(n >= 1, "--max-spp must be at least 1");
            study::Length::Spp(n)
        }
        (None, None) => study::Length::Spp(CONVERGE_DEFAULT_SPP),
    };
    let variants = study::variants(&args.vary)?;
    let (w, h) = (scene.render.width, scene.render.height);
    let given = match &args.reference {
        Some(path) => Some(study::read_reference(path, w, h)?),
        None => None,
    };
    if let (Some(r), study::Length::Spp(n)) = (&given, length) {
        match r.spp {
            Some(spp) if spp <= n => eprintln!(
                "warning: {}: the reference has {spp} spp, no more than the {n} spp measured; \
                 its own noise will dominate the error at the last steps",
                r.path.display()
            ),
            Some(spp) if !args.quiet => eprintln!("reference: {} spp", spp),
            _ => {}
        }
    }
    check_files(&args, &scene, given.as_ref())?;

    let ctx = open_device(&args.device)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the output folder", args.out.display()))?;
    let base = args.kernels.options();
    let reference = match given {
        Some(r) => r,
        None => {
            let spp = args.reference_spp.unwrap_or(CONVERGE_DEFAULT_REFERENCE_SPP);
            if !args.quiet {
                eprintln!(
                    "rendering the reference at {spp} spp (cached in {})",
                    args.out.display()
                );
            }
            let bars = progress::Waves::new();
            study::rendered_reference(&ctx, &scene, &base, spp, &args.out, bars.observer())?
        }
    };
    let quiet = args.quiet;
    let study = study::run(
        &ctx,
        &scene,
        &base,
        &variants,
        args.seeds,
        length,
        &reference,
        |s| {
            if !quiet {
                eprintln!(
                    "{} seed {}: {:>6} spp {:>9.3} s relMSE {:.3e} (predicted {:.3e})",
                    s.variant,
                    s.seed,
                    s.spp,
                    s.render_seconds,
                    s.metrics.rel_mse,
                    s.predicted_rel_mse
                );
            }
        },
    )?;
    let summary = converge::summarise(&study.steps);
    let meta = run_meta(&args, &scene, &ctx, &reference, &study, &summary);
    // Every file together, or none
    no_validation_errors(&ctx)?;
    converge::outputs(&args.out, &study.steps, &summary, &meta)?.commit()?;
    println!("{}", converge::table(&summary));
    for v in &summary.variants {
        let times: Vec<String> = REPORTED_ERRORS
            .iter()
            .map(|&e| match (v.time_to_reach(e), v.first_step_below(e)) {
                (Some(t), _) => format!("relMSE {e:.0e} in {t:.3} s"),
                (None, Some(first)) => format!(
                    "relMSE {e:.0e} already at the first step ({} spp, {:.3} s: relMSE {:.3e})",
                    first.spp, first.render_seconds.mean, first.rel_mse.mean
                ),
                (None, None) => format!("relMSE {e:.0e} not reached"),
            })
            .collect();
        println!("{}: {}", v.variant, times.join(", "));
    }
    println!(
        "reading films back and measuring took {:.3} s (not counted as render time)",
        study.measure_seconds
    );
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Checks the files of the run before anything is rendered: the output
/// folder is a folder (or does not exist yet), and none of the files
/// converge writes in it, the reference it caches there included, is an
/// input (the scene, a file it reads, the reference or its variance).
fn check_files(
    args: &ConvergeArgs,
    scene: &lancer::scene::Scene,
    reference: Option<&study::Reference>,
) -> Result<()> {
    let out = &args.out;
    anyhow::ensure!(
        !out.exists() || out.is_dir(),
        "{}: --out names a file; give the folder to write converge's files in",
        out.display()
    );
    let mut files = RunFiles::default();
    files.scene(scene);
    if let Some(r) = reference {
        files.input(&r.path, "--reference");
        let var = lancer::analysis::compare::variance_path(&r.path);
        if r.var.is_some() {
            files.input(&var, "the reference's variance");
        }
    }
    // A folder that does not exist yet holds no input
    if out.is_dir() {
        for name in converge::output_files() {
            files.output(&out.join(name), format!("{name} of --out"));
        }
    }
    // The reference rendered and cached in the folder, when none is given
    if reference.is_none() {
        let spp = args.reference_spp.unwrap_or(CONVERGE_DEFAULT_REFERENCE_SPP);
        let cached = study::reference_cache_path(scene, &args.kernels.options(), spp, out);
        let var = lancer::analysis::compare::variance_path(&cached);
        files
            .cache_output(&cached, "the reference cached in --out")
            .cache_output(&var, "the variance of the reference cached in --out");
    }
    files.check()
}

/// The `meta` object of `converge.json`: what was run, on what, against
/// which reference, and the render seconds each variant needed to reach
/// the errors of [`REPORTED_ERRORS`].
fn run_meta(
    args: &ConvergeArgs,
    scene: &lancer::scene::Scene,
    ctx: &lancer::internal::vk::Context,
    reference: &study::Reference,
    study: &study::Study,
    summary: &converge::Summary,
) -> serde_json::Value {
    let (w, h) = (scene.render.width, scene.render.height);
    // Time each variant needed to reach the errors users ask about
    let reach: serde_json::Map<String, serde_json::Value> = summary
        .variants
        .iter()
        .map(|v| {
            let times: serde_json::Map<String, serde_json::Value> = REPORTED_ERRORS
                .iter()
                .map(|&e| (format!("{e:.0e}"), serde_json::json!(v.time_to_reach(e))))
                .collect();
            (v.variant.clone(), times.into())
        })
        .collect();
    serde_json::json!({
        "scene": args.scene.display().to_string(),
        "width": w,
        "height": h,
        "device": ctx.info().name,
        "driver": ctx.info().driver_name,
        "seeds": args.seeds,
        "reference": {
            "path": reference.path.display().to_string(),
            "spp": reference.spp,
            "seed": reference.seed,
            "has_variance": reference.var.is_some(),
        },
        "measure_seconds": study.measure_seconds,
        "seconds_to_rel_mse": reach,
        "lancer": env!("CARGO_PKG_VERSION"),
    })
}

/// `--vary KEY=V1,V2,...`, with the library's message in the command
/// line's words.
fn parse_vary(text: &str) -> Result<Vary, String> {
    text.parse()
        .map_err(|e: anyhow::Error| crate::flags::named(&e.to_string()))
}
