//! The `lancer` command line: render, list devices, describe a scene.
#![deny(unsafe_code)]

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

use lancer::features::{Features, Integrator};
use lancer::pass::Pass;
use lancer::render::{RenderOptions, Renderer, DEFAULT_WAVE_SIZE};
use lancer::shader_interface::SPEC_MATERIAL_MASK;
use lancer::{output, scene, vk};

/// A wavefront path tracer on Vulkan compute.
#[derive(Parser)]
#[command(name = "lancer", version, about)]
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
}

impl KernelArgs {
    /// The renderer options these flags ask for.
    fn options(&self) -> RenderOptions {
        RenderOptions {
            wave_size: self.wave_size,
            integrator: self.integrator,
            all_features: self.all_features,
            ..RenderOptions::default()
        }
    }
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output image: .png or .exr.
    #[arg(long, short, default_value = "out.png")]
    out: PathBuf,
    /// Samples per pixel (overrides the scene).
    #[arg(long)]
    spp: Option<u32>,
    /// Image width (overrides the scene).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (overrides the scene).
    #[arg(long)]
    height: Option<u32>,
    /// Longest path in segments (overrides the scene).
    #[arg(long)]
    max_depth: Option<u32>,
    /// Random seed (overrides the scene).
    #[arg(long)]
    seed: Option<u32>,
    #[command(flatten)]
    kernels: KernelArgs,
    /// Write the per-pass figures as JSON.
    #[arg(long)]
    stats_json: Option<PathBuf>,
    /// Write every timed dispatch as a Chrome trace (open it in Perfetto
    /// or chrome://tracing).
    #[arg(long)]
    trace: Option<PathBuf>,
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Devices => devices(),
        Command::Info(args) => info(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

/// Opens the device the user asked for.
fn open_device(args: &DeviceArgs) -> Result<vk::Context> {
    let options = vk::ContextOptions {
        device: args.device.clone(),
        validation: args.validation,
    };
    Ok(vk::Context::new(&options)?)
}

/// Loads a scene and applies command-line overrides.
fn load_scene(path: &Path, args: Option<&RenderArgs>) -> Result<scene::Scene> {
    let mut scene = scene::load(path)?;
    for warning in &scene.warnings {
        eprintln!("warning: {warning}");
    }
    if let Some(a) = args {
        let r = &mut scene.render;
        for (name, flag, field) in [
            ("--spp", a.spp, &mut r.spp),
            ("--width", a.width, &mut r.width),
            ("--height", a.height, &mut r.height),
            ("--max-depth", a.max_depth, &mut r.max_depth),
        ] {
            if let Some(v) = flag {
                anyhow::ensure!(v >= 1, "{name} must be at least 1, got {v}");
                *field = v;
            }
        }
        if let Some(seed) = a.seed {
            r.seed = seed;
        }
    }
    Ok(scene)
}

/// `lancer render`.
fn render(args: RenderArgs) -> Result<()> {
    let scene = load_scene(&args.scene, Some(&args))?;
    let ctx = open_device(&args.device)?;
    let mut renderer = Renderer::new(&ctx, &scene, &args.kernels.options())?;
    let show_progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let result = renderer.render(show_progress)?;
    output::write_image(&args.out, result.width, result.height, &result.mean)?;
    if let Some(path) = &args.stats_json {
        result.stats.write_json(path)?;
    }
    if let Some(path) = &args.trace {
        result.stats.write_trace(path)?;
    }
    if !args.quiet {
        println!("{}", result.stats.table());
        println!("wrote {}", args.out.display());
    }
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
    let scene = load_scene(&args.scene, None)?;
    let ctx = open_device(&args.device)?;
    let renderer = Renderer::new(&ctx, &scene, &args.kernels.options())?;
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
    let passes: Vec<&str> = f.passes().into_iter().map(Pass::name).collect();
    println!("passes: {}", passes.join(" -> "));
    println!("kernels (specialisation constants):");
    for pass in f.passes() {
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
    println!("bvh: {} nodes, depth {}", s.bvh_nodes, s.bvh_depth);
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
    Ok(())
}
