//! `lancer render`: a scene to an image (with its variance, figures and
//! trace), or, with `--film-out`, samples A..B of it to a film file.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};

use lancer::io::image_file;
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
    /// --max-spp, default: the scene's spp).
    #[arg(long, value_name = "RELMSE")]
    target_error: Option<f64>,
    /// Upper bound on samples per pixel for --time-limit and --target-error.
    #[arg(long, value_name = "N", requires = "budget")]
    max_spp: Option<u32>,
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
    /// instead of an image, for `lancer merge`.
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
    // clap's `requires` lets `--samples --out X` through; say it here.
    anyhow::ensure!(
        args.samples.is_none() || args.film_out.is_some(),
        "--samples renders part of an image: give --film-out FILE.film (and merge the parts with `lancer merge`)"
    );
    let mut scene = load_scene(&args.scene, &overrides)?;
    if let Some(path) = &args.film_out {
        return render_part(&args, &scene, path);
    }
    let budget = match (args.time_limit, args.target_error) {
        (Some(s), _) => Some(Budget::Time(s)),
        (None, Some(e)) => Some(Budget::Error(e)),
        (None, None) => None,
    };
    if let Some(b) = &budget {
        b.validate()?;
    }
    check_outputs(&args)?;
    // A budget renders up to --max-spp; size the waves for that
    if budget.is_some() {
        scene.render.spp = args.max_spp.unwrap_or(scene.render.spp);
        anyhow::ensure!(scene.render.spp >= 1, "--max-spp must be at least 1");
    }
    let ctx = open_device(&args.device)?;
    let mut options = args.kernels.options();
    options.progressive = budget.is_some();
    let mut renderer = new_renderer(&ctx, &scene, &options)?;
    let bars = progress::Waves::new();
    let result = match budget {
        Some(b) => render_with_budget(&mut renderer, b, scene.render.spp, bars.observer())?,
        None => renderer.render(bars.observer())?,
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
    if let Some(path) = &args.stats_json {
        outputs.add(path, json_bytes(&result.stats.to_json())?);
    }
    if let Some(path) = &args.trace {
        outputs.add(path, serde_json::to_vec(&result.stats.to_trace())?);
    }
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
        if budget.is_some() {
            report += &format!(
                "\nstopped at {} spp after {:.3} s of rendering; predicted relMSE {:.3e}",
                result.spp,
                result.stats.wall_seconds,
                lancer::util::metrics::predicted_rel_mse(&result.error_estimate, &result.mean)
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

/// `lancer render --film-out`: samples A..B (default: all) into a film file.
fn render_part(args: &RenderArgs, scene: &scene::Scene, path: &Path) -> Result<()> {
    image_file::check_destination(path, false)?;
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
    outputs.commit()?;
    if !args.quiet {
        println!("{}", renderer.output()?.stats.table());
        println!(
            "wrote samples {first}..{end} of {} to {}",
            scene.render.spp,
            path.display()
        );
    }
    Ok(())
}

/// Checks every output path of `render` before anything is rendered: each
/// can be written, images have a supported extension, the variance is an
/// EXR, and no two outputs share a path.
fn check_outputs(args: &RenderArgs) -> Result<()> {
    let mut paths = Vec::new();
    if args.out != Path::new(STDOUT) {
        paths.push((&args.out, true));
    }
    paths.extend(args.var_out.iter().map(|p| (p, true)));
    paths.extend(args.stats_json.iter().map(|p| (p, false)));
    paths.extend(args.trace.iter().map(|p| (p, false)));
    for (i, &(path, image)) in paths.iter().enumerate() {
        image_file::check_destination(path, image)?;
        anyhow::ensure!(
            !paths[..i].iter().any(|(p, _)| *p == path),
            "{}: given for two outputs; give each output its own file",
            path.display()
        );
    }
    if let Some(path) = &args.var_out {
        anyhow::ensure!(
            path.extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("exr")),
            "{}: --var-out writes linear variances and must end in .exr",
            path.display()
        );
    }
    Ok(())
}
