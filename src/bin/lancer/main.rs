//! The `lancer` command line: render, list devices, describe a scene.
#![deny(unsafe_code)]

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context as _, Result};
use clap::{Parser, Subcommand};

use lancer::analysis::compare::{run_compare, CompareOptions};
use lancer::internal::interface::SPEC_MATERIAL_MASK;
use lancer::internal::study::{self, Vary};
use lancer::internal::{converge, vk};
use lancer::io::image_file;
use lancer::render::budget::{render_with_budget, Budget};
use lancer::render::kernels::Pass;
use lancer::render::kernels::Schedule;
use lancer::render::kernels::{Features, Integrator};
use lancer::render::{RenderOptions, Renderer, DEFAULT_WAVE_SIZE};
use lancer::scene;
use lancer::util::interrupt;

/// A wavefront path tracer on Vulkan compute.
#[derive(Parser)]
#[command(name = "lancer", version = lancer::VERSION, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to a PNG (sRGB) or EXR (linear) file.
    Render(RenderArgs),
    /// List the Vulkan devices lancer can use.
    Devices,
    /// Print the features a scene calls for, the passes and kernels that
    /// will run, and the sizes of what goes on the device.
    Info(InfoArgs),
    /// Measure error against render time and samples per pixel, for one or
    /// more settings, against a reference: CSV, JSON, plots and a table.
    Converge(ConvergeArgs),
    /// Compare an image with a reference: RMSE, relMSE, bias, FLIP, the
    /// per-pixel z-test; exit code 1 when a tolerance is exceeded.
    Compare(CompareArgs),
    /// Merge the film files of a render split into sample ranges
    /// (`render --samples A..B --film-out`) into one image.
    Merge(MergeArgs),
    /// Write a scene (e.g. Mitsuba 3 XML) as a lancer TOML scene, with its
    /// triangles in OBJ files beside it.
    Convert(ConvertArgs),
    /// Run a fixed suite of scenes (Cornell, glass, a million triangles)
    /// with every schedule: samples/s, Mrays/s per pass, time to first
    /// dispatch, device memory; compare with an earlier run.
    Bench(BenchArgs),
}

#[derive(clap::Args)]
struct MergeArgs {
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

#[derive(clap::Args)]
struct ConvertArgs {
    /// Scene file (TOML, or Mitsuba 3 XML by the extension .xml).
    scene: PathBuf,
    /// The TOML file to write; OBJ files go to the folder STEM_meshes beside it.
    #[arg(long, short)]
    out: PathBuf,
}

#[derive(clap::Args)]
struct BenchArgs {
    #[command(flatten)]
    bench: lancer::analysis::bench::BenchOptions,
    #[command(flatten)]
    device: DeviceArgs,
}

#[derive(clap::Args)]
struct CompareArgs {
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

/// Options shared by every command that opens a device.
#[derive(clap::Args, Clone)]
struct DeviceArgs {
    /// Device to use: its index in `lancer devices`, or part of its name.
    #[arg(long)]
    device: Option<String>,
    /// Run under the Khronos validation layer (also LANCER_VALIDATION=1).
    #[arg(long)]
    validation: bool,
}

/// Options that choose which kernels run and how, shared by `render` and `info`.
#[derive(clap::Args, Clone)]
struct KernelArgs {
    /// Paths in flight per wave.
    #[arg(long, default_value_t = DEFAULT_WAVE_SIZE)]
    wave_size: u32,
    /// Estimator: next-event estimation with MIS, or BSDF sampling only.
    #[arg(long, value_enum, default_value_t = Integrator::Nee)]
    integrator: Integrator,
    /// Turn every feature on, whatever the scene calls for.
    #[arg(long)]
    all_features: bool,
    /// How the kernels of a wave run: one kernel per pass (wavefront) or
    /// the whole path in one kernel (megakernel); the image is the same.
    #[arg(long, value_enum, default_value_t = Schedule::Wavefront)]
    schedule: Schedule,
    /// Most image rows whose film the device holds at once (default: as
    /// many as one storage binding holds); the image is the same, bit for
    /// bit, and device memory lower.
    #[arg(long, value_name = "ROWS", value_parser = clap::value_parser!(u32).range(1..))]
    tile_rows: Option<u32>,
}

impl KernelArgs {
    /// The renderer options these flags ask for.
    fn options(&self) -> RenderOptions {
        RenderOptions {
            wave_size: self.wave_size,
            integrator: self.integrator,
            all_features: self.all_features,
            schedule: self.schedule,
            tile_rows: self.tile_rows,
            ..RenderOptions::default()
        }
    }
}

/// Image size overrides, shared by `render` and `converge`.
#[derive(clap::Args, Clone, Default)]
struct SizeArgs {
    /// Image width (overrides the scene).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (overrides the scene).
    #[arg(long)]
    height: Option<u32>,
}

#[derive(clap::Args)]
#[command(group = clap::ArgGroup::new("budget").args(["time_limit", "target_error"]))]
struct RenderArgs {
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

#[derive(clap::Args)]
struct InfoArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    #[command(flatten)]
    kernels: KernelArgs,
    #[command(flatten)]
    device: DeviceArgs,
}

#[derive(clap::Args)]
#[command(group = clap::ArgGroup::new("length").args(["max_spp", "time_limit"]))]
#[command(group = clap::ArgGroup::new("reference_source").args(["reference", "reference_spp"]))]
struct ConvergeArgs {
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
    /// max_depth, features (scene,all), wave_size. May be given again for
    /// another key; every combination runs.
    #[arg(long, value_name = "KEY=V1,V2,...")]
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Ctrl-C stops a render between waves; a second one stops at once
    let _ = ctrlc::set_handler(|| {
        if interrupt::request() {
            std::process::exit(EXIT_INTERRUPTED.into());
        }
    });
    // `compare` keeps exit code 1 for "worse than the tolerance" and fails
    // with 2, so that a CI job can tell a bad image from a broken check
    let (result, failure) = match cli.command {
        Command::Render(args) => (render(args), 1),
        Command::Devices => (devices(), 1),
        Command::Info(args) => (info(args), 1),
        Command::Converge(args) => (converge(args), 1),
        Command::Compare(args) => (compare(args), 2),
        Command::Convert(args) => (convert(args), 1),
        Command::Merge(args) => (merge(args), 1),
        Command::Bench(args) => (bench(args), 1),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if err.is::<Worse>() => ExitCode::from(1),
        Err(err) if err.is::<interrupt::Interrupted>() => {
            eprintln!("{err}");
            ExitCode::from(EXIT_INTERRUPTED)
        }
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::from(failure)
        }
    }
}

/// Exit code after Ctrl-C, as a shell reports a process ended by SIGINT.
const EXIT_INTERRUPTED: u8 = 130;

/// The compared image is worse than the tolerance asked for: exit code 1,
/// with the report already printed.
#[derive(Debug, thiserror::Error)]
#[error("the image is worse than the tolerance")]
struct Worse;

/// `lancer bench`.
fn bench(args: BenchArgs) -> Result<()> {
    let ctx = open_device(&args.device)?;
    lancer::analysis::bench::run(&ctx, &args.bench)?;
    no_validation_errors(&ctx)
}

/// `lancer compare`.
fn compare(args: CompareArgs) -> Result<()> {
    let mut opts = CompareOptions::new(&args.image, &args.reference);
    opts.var = args.var;
    opts.heatmap = args.heatmap;
    opts.max_relmse = args.max_relmse;
    opts.max_flip = args.max_flip;
    opts.json = args.json;
    if run_compare(&opts)? {
        Ok(())
    } else {
        Err(Worse.into())
    }
}

/// `lancer convert`: every file written together, or none.
fn convert(args: ConvertArgs) -> Result<()> {
    let scene = load_scene(&args.scene, &Overrides::default())?;
    let mut outputs = image_file::Outputs::default();
    let files = scene::to_toml(&scene, &args.out);
    for (path, bytes) in files {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
        }
        outputs.add(&path, bytes);
    }
    outputs.commit()?;
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Opens the device the user asked for.
fn open_device(args: &DeviceArgs) -> Result<vk::Context> {
    let options = vk::ContextOptions {
        device: args.device.clone(),
        validation: args.validation,
    };
    Ok(vk::Context::new(&options)?)
}

/// Packs `scene` for the device and prints what packing changed (textures
/// shrunk to fit the device).
fn new_renderer<'c>(
    ctx: &'c vk::Context,
    scene: &scene::Scene,
    options: &lancer::render::RenderOptions,
) -> Result<Renderer<'c>> {
    let renderer = Renderer::new(ctx, scene, options)?;
    for warning in renderer.warnings() {
        eprintln!("warning: {warning}");
    }
    Ok(renderer)
}

/// Loads a scene and applies command-line overrides.
fn load_scene(path: &Path, overrides: &Overrides) -> Result<scene::Scene> {
    let mut scene = scene::load(path)?;
    for warning in &scene.warnings {
        eprintln!("warning: {warning}");
    }
    let r = &mut scene.render;
    for (name, flag, field) in [
        ("--spp", overrides.spp, &mut r.spp),
        ("--width", overrides.size.width, &mut r.width),
        ("--height", overrides.size.height, &mut r.height),
        ("--max-depth", overrides.max_depth, &mut r.max_depth),
    ] {
        if let Some(v) = flag {
            anyhow::ensure!(v >= 1, "{name} must be at least 1, got {v}");
            *field = v;
        }
    }
    if let Some(seed) = overrides.seed {
        r.seed = seed;
    }
    Ok(scene)
}

/// What the command line changes in a scene's `[render]` table.
#[derive(Default)]
struct Overrides {
    spp: Option<u32>,
    size: SizeArgs,
    max_depth: Option<u32>,
    seed: Option<u32>,
}

/// `lancer render`.
fn render(args: RenderArgs) -> Result<()> {
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
    let show_progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let result = match budget {
        Some(b) => render_with_budget(&mut renderer, b, scene.render.spp, show_progress)?,
        None => renderer.render(show_progress)?,
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
                lancer::util::metrics::predicted_rel_mse(&result.var_of_mean, &result.mean)
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
    let scene_hash = lancer::io::film::scene_hash(scene, options.integrator)?;
    let ctx = open_device(&args.device)?;
    let mut renderer = new_renderer(&ctx, scene, &options)?;
    let progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
    renderer.render_samples(first, end, progress)?;
    let (sum, sum_sq, nonfinite) = renderer.film_sums()?;
    no_validation_errors(&ctx)?;
    let part = lancer::io::film::FilmPart {
        scene_hash,
        first,
        end,
        spp: scene.render.spp,
        width: scene.render.width,
        height: scene.render.height,
        nonfinite,
        sum,
        sum_sq,
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

/// `lancer merge`.
fn merge(args: MergeArgs) -> Result<()> {
    image_file::check_destination(&args.out, true)?;
    if let Some(path) = &args.var_out {
        image_file::check_destination(path, true)?;
    }
    let parts = (args.parts.iter())
        .map(|p| Ok((p.clone(), lancer::io::film::FilmPart::read(p)?)))
        .collect::<Result<Vec<_>>>()?;
    let merged = lancer::io::film::merge(&parts)?;
    // The parts carry their scene's hash, not its settings: record what
    // the merge knows
    let meta = image_file::Metadata {
        spp: Some(merged.spp),
        version: Some(lancer::VERSION.to_string()),
        ..Default::default()
    };
    let mut outputs = image_file::Outputs::default();
    outputs.add_image(&args.out, merged.width, merged.height, &merged.mean, &meta)?;
    if let Some(path) = &args.var_out {
        outputs.add_image(
            path,
            merged.width,
            merged.height,
            &merged.var_of_mean,
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

/// Pretty-printed JSON with a final newline.
fn json_bytes(value: &serde_json::Value) -> Result<Vec<u8>> {
    let mut bytes = serde_json::to_vec_pretty(value)?;
    bytes.push(b'\n');
    Ok(bytes)
}

/// Fails when the validation layer (if on) reported errors.
fn no_validation_errors(ctx: &vk::Context) -> Result<()> {
    anyhow::ensure!(
        ctx.validation_errors() == 0,
        "the Vulkan validation layer reported {} errors",
        ctx.validation_errors()
    );
    Ok(())
}

/// `lancer devices`.
fn devices() -> Result<()> {
    let list = vk::list_devices()?;
    for d in &list {
        println!(
            "{}: {} ({:?}, Vulkan {}.{}.{}, driver {}, maxStorageBufferRange {} MiB, subgroup {})",
            d.index,
            d.name,
            d.kind,
            d.api_version.0,
            d.api_version.1,
            d.api_version.2,
            d.driver_name,
            d.max_storage_buffer_range >> 20,
            d.subgroup_size
        );
    }
    Ok(())
}

/// `lancer info`.
fn info(args: InfoArgs) -> Result<()> {
    let scene = load_scene(&args.scene, &Overrides::default())?;
    let ctx = open_device(&args.device)?;
    let renderer = new_renderer(&ctx, &scene, &args.kernels.options())?;
    let f = renderer.features();
    println!("scene: {}", args.scene.display());
    println!("device: {}", ctx.info().name);
    println!("features:");
    for (name, on) in [
        ("spheres", f.spheres),
        ("triangles", f.triangles),
        ("emitters (next-event estimation)", f.nee),
        ("emission", f.emission),
        ("environment", f.environment),
        ("textures", f.textures),
        ("depth of field", f.depth_of_field),
    ] {
        println!("  {:<34} {}", name, if on { "yes" } else { "no" });
    }
    println!("  {:<34} {}", "materials", f.material_names().join(", "));
    let schedule = renderer.schedule();
    let passes: Vec<&str> = f.passes(schedule).into_iter().map(Pass::name).collect();
    println!("schedule: {schedule}");
    println!("passes: {}", passes.join(" -> "));
    println!("kernels (specialisation constants):");
    for pass in f.passes(schedule) {
        let values: Vec<String> = f
            .spec_constants(pass)
            .iter()
            .map(|&(id, v)| match id {
                SPEC_MATERIAL_MASK => format!("{}={v:#07b}", Features::spec_constant_name(id)),
                _ => format!("{}={v}", Features::spec_constant_name(id)),
            })
            .collect();
        println!("  {:<11} {}", pass.name(), values.join(" "));
    }
    let s = &renderer.scene_info;
    println!(
        "primitives: {} spheres, {} triangles, {} emitters",
        s.spheres, s.triangles, s.emitters
    );
    println!(
        "bvh: {} nodes, depth {}, SAH cost {:.2}, built in {:.3} s",
        s.bvh_nodes, s.bvh_depth, s.bvh_sah_cost, s.bvh_seconds
    );
    println!("wave: {} paths in flight", renderer.wave_capacity());
    println!(
        "film: {}",
        if renderer.film_fp64() {
            "f64 sums"
        } else {
            "compensated f32 sums"
        }
    );
    println!(
        "device memory: {:.2} MiB",
        s.device_bytes as f64 / (1024.0 * 1024.0)
    );
    let heaps = &ctx.info().memory_heaps;
    for (b, heap) in ctx.memory_budgets().iter().zip(heaps) {
        println!(
            "memory budget: heap {} ({} bytes{}): {} bytes ({})",
            b.heap,
            heap.size,
            if heap.device_local {
                ", device local"
            } else {
                ""
            },
            b.bytes,
            b.source
        );
    }
    Ok(())
}

/// The errors `lancer converge` reports the time to reach.
const REPORTED_ERRORS: [f64; 2] = [1e-2, 1e-3];

/// Default `--max-spp` of `lancer converge`.
const CONVERGE_DEFAULT_SPP: u32 = 256;
/// Default `--reference-spp` of `lancer converge`.
const CONVERGE_DEFAULT_REFERENCE_SPP: u32 = 4096;

/// `lancer converge`.
fn converge(args: ConvergeArgs) -> Result<()> {
    // Check everything the user gave before rendering or writing anything
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
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the output folder", args.out.display()))?;

    let ctx = open_device(&args.device)?;
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
            study::rendered_reference(&ctx, &scene, &base, spp, &args.out)?
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
    let meta = serde_json::json!({
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
    });
    converge::write_csv(&args.out.join("converge.csv"), &study.steps)?;
    converge::write_json(
        &args.out.join("converge.json"),
        &study.steps,
        &summary,
        &meta,
    )?;
    converge::plot(&args.out, &study.steps, &summary)?;
    println!("{}", converge::table(&summary));
    for v in &summary.variants {
        let times: Vec<String> = REPORTED_ERRORS
            .iter()
            .map(|&e| match v.time_to_reach(e) {
                Some(t) => format!("relMSE {e:.0e} in {t:.3} s"),
                None => format!("relMSE {e:.0e} not reached"),
            })
            .collect();
        println!("{}: {}", v.variant, times.join(", "));
    }
    println!(
        "reading films back and measuring took {:.3} s (not counted as render time)",
        study.measure_seconds
    );
    println!("wrote {}", args.out.display());
    no_validation_errors(&ctx)
}
