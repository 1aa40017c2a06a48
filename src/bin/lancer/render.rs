//! `lancer render`: a scene to an image (with its variance, figures and
//! trace), or, with `--film-out`, samples A..B of it to a film file.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};

use lancer::io::image_file;
use lancer::io::run_files::RunFiles;
use lancer::render::adaptive::{render_adaptive, Goal};
use lancer::render::budget::{render_with_budget, Budget};
use lancer::scene;

use crate::args::{
    json_bytes, load_scene, new_renderer, no_validation_errors, open_device, DeviceArgs,
    KernelArgs, Overrides, SizeArgs,
};
use crate::progress;

#[derive(clap::Args)]
#[command(group = clap::ArgGroup::new("budget").args(["time_limit", "target_error"]))]
pub struct RenderArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output image: .png or .exr; `-` writes a PNG to standard output
    /// (the table then goes to standard error).
    #[arg(long, short, default_value = "out.png")]
    out: PathBuf,
    /// Samples per pixel (overrides the scene).
    #[arg(long)]
    spp: Option<u32>,
    #[command(flatten)]
    size: SizeArgs,
    /// Longest path in segments (overrides the scene).
    #[arg(long)]
    max_depth: Option<u32>,
    /// Random seed (overrides the scene).
    #[arg(long)]
    seed: Option<u32>,
    #[command(flatten)]
    kernels: KernelArgs,
    /// Render until this many seconds of rendering are spent, stopping at a
    /// whole number of samples per pixel (at most --max-spp, default: the
    /// scene's spp).
    #[arg(long, value_name = "SECONDS", conflicts_with = "target_error")]
    time_limit: Option<f64>,
    /// Render until the relMSE that the film's variance predicts is at most
    /// this (e.g. 0.01), at a whole number of samples per pixel (at most
    /// --max-spp, default 65536; a warning says when that cap stops the
    /// render first, and --stats-json records target_met).
    #[arg(long, value_name = "RELMSE")]
    target_error: Option<f64>,
    /// Upper bound on samples per pixel for --time-limit (default: the
    /// scene's spp) and --target-error (default 65536); with --adaptive, on
    /// each pixel's samples.
    #[arg(long, value_name = "N", requires = "budget")]
    max_spp: Option<u32>,
    /// Spend the samples where the error is: every pixel gets 16 samples,
    /// then each the share its own noise needs for --target-error, or for
    /// the least error in --time-limit (docs/accuracy.md, "Adaptive
    /// sampling"). Not with --samples: split renders are not adaptive.
    #[arg(long)]
    adaptive: bool,
    /// Also write the samples of each pixel: an EXR holds the counts, a
    /// PNG shows them as a heat map (black: none, pale yellow: the most).
    #[arg(long, value_name = "FILE.exr|FILE.png", conflicts_with = "film_out")]
    spp_out: Option<PathBuf>,
    /// Also write the per-pixel variance of the mean as a linear EXR, for
    /// `lancer compare --var`.
    #[arg(long, value_name = "FILE.exr")]
    var_out: Option<PathBuf>,
    /// Write the per-pass figures as JSON.
    #[arg(long)]
    stats_json: Option<PathBuf>,
    /// Write every timed dispatch as a Chrome trace (open it in Perfetto
    /// or chrome://tracing).
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Render only samples A to B-1 of every pixel (0 <= A < B <= spp), for
    /// a render split across machines; needs --film-out.
    #[arg(long, value_name = "A..B", value_parser = lancer::io::film::parse_range, requires = "film_out")]
    samples: Option<(u32, u32)>,
    /// Write the raw film (sums for the mean and variance, docs/split-render.md)
    /// instead of an image, for `lancer merge` (--stats-json and --trace
    /// are written as in every render).
    #[arg(long, value_name = "FILE.film", conflicts_with_all = ["out", "var_out", "time_limit", "target_error"])]
    film_out: Option<PathBuf>,
    /// Do not print the per-pass table.
    #[arg(long, short)]
    quiet: bool,
    #[command(flatten)]
    device: DeviceArgs,
}

/// `lancer render`.
pub fn render(args: RenderArgs) -> Result<()> {
    let overrides = Overrides {
        spp: args.spp,
        size: args.size.clone(),
        max_depth: args.max_depth,
        seed: args.seed,
    };
    // Every option alone, then together, then every file: all before the
    // device opens
    let budget = match (args.time_limit, args.target_error) {
        (Some(s), _) => Some(Budget::Time(s)),
        (None, Some(e)) => Some(Budget::Error(e)),
        (None, None) => None,
    };
    if let Some(b) = &budget {
        b.validate()?;
    }
    anyhow::ensure!(args.max_spp != Some(0), "--max-spp must be at least 1");
    refuse_combinations(&args)?;
    let mut scene = load_scene(&args.scene, &overrides)?;
    check_files(&args, &scene)?;
    if let Some(path) = &args.film_out {
        return render_part(&args, &scene, path);
    }
    // A budget renders up to its cap; size the waves for that
    let cap = budget.map(|b| max_spp(&args, b, scene.render.spp));
    if let Some(cap) = cap {
        scene.render.spp = cap;
    }
    let ctx = open_device(&args.device)?;
    let mut options = args.kernels.options();
    options.progressive = budget.is_some();
    options.adaptive = args.adaptive;
    let mut renderer = new_renderer(&ctx, &scene, &options)?;
    let bars = progress::Waves::new();
    let result = match budget {
        Some(b) if args.adaptive => {
            let goal = match b {
                Budget::Time(s) => Goal::Time(s),
                Budget::Error(e) => Goal::Error(e),
            };
            render_adaptive(&mut renderer, goal, scene.render.spp, bars.observer())?
        }
        Some(b) => render_with_budget(&mut renderer, b, scene.render.spp, bars.observer())?,
        None => renderer.render(bars.observer())?,
    };
    let predicted = budget
        .map(|_| lancer::util::metrics::predicted_rel_mse(&result.error_estimate, &result.mean));
    // Whether --target-error was met, and a warning when its cap stopped it
    let target_met = match (args.target_error, predicted, cap) {
        (Some(target), Some(reached), Some(cap)) => {
            let met = reached <= target;
            if !met {
                crate::args::warn(&format!(
                    "--target-error {target:e} not met: stopped at the cap of {cap} spp ({}) \
                     with predicted relMSE {reached:.3e}; raise --max-spp to render further",
                    if args.max_spp.is_some() {
                        "--max-spp"
                    } else {
                        "the default cap of --target-error"
                    }
                ));
            }
            Some(met)
        }
        _ => None,
    };
    // Write every output together, or none of them
    no_validation_errors(&ctx)?;
    let meta = image_file::Metadata::of_stats(&result.stats);
    let mut outputs = image_file::Outputs::default();
    let (w, h) = (result.width, result.height);
    let to_stdout = args.out == Path::new(STDOUT);
    let image = if to_stdout {
        Some(image_file::encode_image_with(
            Path::new("-.png"),
            w,
            h,
            &result.mean,
            &meta,
        )?)
    } else {
        outputs.add_image(&args.out, w, h, &result.mean, &meta)?;
        None
    };
    if let Some(path) = &args.var_out {
        outputs.add_image(path, w, h, &result.var_of_mean, &meta)?;
    }
    if let Some(path) = &args.spp_out {
        let counts = result
            .pixel_spp
            .clone()
            .unwrap_or_else(|| vec![result.spp; w as usize * h as usize]);
        let bytes = lancer::analysis::metrics::sample_count_image(path, w, h, &counts)?;
        outputs.add(path, bytes);
    }
    let mut stats = result.stats.to_json();
    if let (Some(cap), Some(reached)) = (cap, predicted) {
        stats["max_spp"] = cap.into();
        stats["predicted_rel_mse"] = reached.into();
    }
    if let (Some(target), Some(met)) = (args.target_error, target_met) {
        stats["target_error"] = target.into();
        stats["target_met"] = met.into();
    }
    add_reports(&mut outputs, &args, &result.stats, &stats)?;
    outputs.commit()?;
    if let Some(png) = image {
        let mut stdout = std::io::stdout().lock();
        stdout
            .write_all(&png)
            .and_then(|()| stdout.flush())
            .context("cannot write the image to standard output")?;
    }
    if !args.quiet {
        // With the image on standard output, the report goes to standard error
        let mut report = result.stats.table();
        if let Some(reached) = predicted {
            let spp = if result.stats.adaptive {
                format!(
                    "a mean of {:.1} spp (at most {} in a pixel)",
                    result.stats.mean_spp(),
                    result.spp
                )
            } else {
                format!("{} spp", result.spp)
            };
            report += &format!(
                "\nstopped at {spp} after {:.3} s of rendering; predicted relMSE {reached:.3e}",
                result.stats.wall_seconds,
            );
        }
        if to_stdout {
            eprintln!("{report}");
        } else {
            println!("{report}\nwrote {}", args.out.display());
        }
    }
    Ok(())
}

/// The `--out` that writes the image to standard output.
const STDOUT: &str = "-";

/// The most samples per pixel `--target-error` renders when no `--max-spp`
/// is given: a render that cannot reach its target stops here, with a
/// warning, instead of running on without end.
pub const TARGET_ERROR_MAX_SPP: u32 = 65_536;

/// The samples per pixel a budget renders at most: `--max-spp`, else
/// [`TARGET_ERROR_MAX_SPP`] for `--target-error` and the scene's spp
/// (`--spp`) for `--time-limit`.
fn max_spp(args: &RenderArgs, budget: Budget, scene_spp: u32) -> u32 {
    match (args.max_spp, budget) {
        (Some(n), _) => n,
        (None, Budget::Error(_)) => TARGET_ERROR_MAX_SPP,
        (None, Budget::Time(_)) => scene_spp,
    }
}

/// Refuses the options that cannot go together and that clap's own rules
/// let through, naming both.
fn refuse_combinations(args: &RenderArgs) -> Result<()> {
    let budget = match (args.time_limit, args.target_error) {
        (Some(_), _) => Some("--time-limit"),
        (None, Some(_)) => Some("--target-error"),
        (None, None) => None,
    };
    if args.adaptive {
        let split = match (args.samples, &args.film_out) {
            (Some(_), _) => Some("--samples"),
            (None, Some(_)) => Some("--film-out"),
            (None, None) => None,
        };
        if let Some(split) = split {
            anyhow::bail!(
                "--adaptive gives each pixel its own number of samples and {split} writes the \
                 same samples of every pixel for `lancer merge`: split renders are not \
                 adaptive; drop one of them"
            );
        }
        anyhow::ensure!(
            budget.is_some(),
            "--adaptive spends samples where the error is and stops at a goal: give \
             --target-error E (e.g. 1e-3) or --time-limit SECONDS"
        );
    }
    if let (Some(_), Some(budget)) = (args.samples, budget) {
        anyhow::bail!(
            "--samples renders a fixed range of samples and {budget} stops at a budget: give \
             one or the other"
        );
    }
    // clap's `requires` lets `--samples --out X` through; say it here.
    anyhow::ensure!(
        args.samples.is_none() || args.film_out.is_some(),
        "--samples renders part of an image: give --film-out FILE.film (and merge the parts with `lancer merge`)"
    );
    anyhow::ensure!(
        args.spp.is_none() || args.target_error.is_none(),
        "--spp fixes the samples per pixel and --target-error chooses them: drop --spp, and \
         give --max-spp N to cap --target-error (default {TARGET_ERROR_MAX_SPP})"
    );
    Ok(())
}

/// Checks every file of the run before anything is rendered (see
/// [`RunFiles`]): the outputs of the mode asked for can be
/// written, images have a supported extension, the variance is an EXR,
/// and no output names another output, the scene or a file it reads.
fn check_files(args: &RenderArgs, scene: &scene::Scene) -> Result<()> {
    let mut files = RunFiles::default();
    files.scene(scene);
    match &args.film_out {
        Some(path) => {
            files.output(path, "--film-out");
        }
        None => {
            if args.out != Path::new(STDOUT) {
                files.image_output(&args.out, "--out");
            }
            if let Some(path) = &args.var_out {
                files.exr_output(path, "--var-out");
            }
            if let Some(path) = &args.spp_out {
                files.image_output(path, "--spp-out");
            }
        }
    }
    if let Some(path) = &args.stats_json {
        files.output(path, "--stats-json");
    }
    if let Some(path) = &args.trace {
        files.output(path, "--trace");
    }
    files.check()
}

/// Adds `--stats-json` (the figures `json`) and `--trace` (the dispatches
/// of `stats`) to `outputs`, as asked, in every mode of `render`.
fn add_reports(
    outputs: &mut image_file::Outputs,
    args: &RenderArgs,
    stats: &lancer::RenderStats,
    json: &serde_json::Value,
) -> Result<()> {
    if let Some(path) = &args.stats_json {
        outputs.add(path, json_bytes(json)?);
    }
    if let Some(path) = &args.trace {
        outputs.add(path, serde_json::to_vec(&stats.to_trace())?);
    }
    Ok(())
}

/// `lancer render --film-out`: samples A..B (default: all) into a film
/// file, with `--stats-json` and `--trace` as in every render.
fn render_part(args: &RenderArgs, scene: &scene::Scene, path: &Path) -> Result<()> {
    let (first, end) = args.samples.unwrap_or((0, scene.render.spp));
    anyhow::ensure!(
        end <= scene.render.spp,
        "--samples {first}..{end}: the scene has {} spp (set by the scene or --spp); B must be at most that",
        scene.render.spp
    );
    let options = args.kernels.options();
    let scene_hash = lancer::io::film::scene_hash(scene, options.integrator, options.sampler)?;
    let ctx = open_device(&args.device)?;
    let mut renderer = new_renderer(&ctx, scene, &options)?;
    let bars = progress::Waves::new();
    renderer.render_samples(first, end, bars.observer())?;
    let (sums, nonfinite) = renderer.film_sums()?;
    let stats = renderer.stats()?;
    no_validation_errors(&ctx)?;
    let part = lancer::io::film::FilmPart {
        scene_hash,
        sampler: options.sampler,
        first,
        end,
        spp: scene.render.spp,
        width: scene.render.width,
        height: scene.render.height,
        nonfinite,
        sum: sums.sum,
        sum_sq: sums.sum_sq,
        sum_odd: sums.sum_odd,
    };
    let mut outputs = image_file::Outputs::default();
    outputs.add(path, part.to_bytes());
    add_reports(&mut outputs, args, &stats, &stats.to_json())?;
    outputs.commit()?;
    if !args.quiet {
        println!("{}", stats.table());
        println!(
            "wrote samples {first}..{end} of {} to {}",
            scene.render.spp,
            path.display()
        );
    }
    Ok(())
}
