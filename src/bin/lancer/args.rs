//! What several commands share: the device, kernel and image-size options,
//! loading a scene with the command line's overrides, opening the device,
//! building a renderer, and printing the library's warnings.

use std::path::Path;

use anyhow::Result;

use lancer::internal::vk;
use lancer::render::kernels::{Integrator, Sampler, Schedule};
use lancer::render::{RenderOptions, Renderer};
use lancer::scene;

use crate::flags;

/// Options shared by every command that opens a device.
#[derive(clap::Args, Clone)]
pub struct DeviceArgs {
    /// Device to use: its index in `lancer devices`, or part of its name.
    #[arg(long)]
    device: Option<String>,
    /// Run under the Khronos validation layer (also LANCER_VALIDATION=1).
    #[arg(long)]
    validation: bool,
}

/// Options that choose which kernels run and how, shared by `render` and `info`.
#[derive(clap::Args, Clone)]
pub struct KernelArgs {
    /// Paths in flight per wave [default: 262144 on a CPU device such as
    /// lavapipe; on a GPU up to 4194304, as a quarter of its memory allows].
    /// The image is the same.
    #[arg(long, value_name = "N")]
    wave_size: Option<u32>,
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
    /// Random numbers of every path dimension: Owen-scrambled Sobol points
    /// (lower error at equal time), or independent (hashed).
    #[arg(long, value_enum, default_value_t = Sampler::Sobol)]
    sampler: Sampler,
    /// Most image rows whose film the device holds at once (default: as
    /// many as one storage binding holds); the image is the same, bit for
    /// bit, and device memory lower.
    #[arg(long, value_name = "ROWS", value_parser = clap::value_parser!(u32).range(1..))]
    tile_rows: Option<u32>,
}

impl KernelArgs {
    /// The renderer options these flags ask for.
    pub fn options(&self) -> RenderOptions {
        RenderOptions {
            wave_size: self.wave_size,
            integrator: self.integrator,
            all_features: self.all_features,
            schedule: self.schedule,
            sampler: self.sampler,
            tile_rows: self.tile_rows,
            ..RenderOptions::default()
        }
    }
}

/// Image size overrides, shared by `render` and `converge`.
#[derive(clap::Args, Clone, Default)]
pub struct SizeArgs {
    /// Image width (overrides the scene).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (overrides the scene).
    #[arg(long)]
    height: Option<u32>,
}

/// What the command line changes in a scene's `[render]` table.
#[derive(Default)]
pub struct Overrides {
    /// `--spp`.
    pub spp: Option<u32>,
    /// `--width`, `--height`.
    pub size: SizeArgs,
    /// `--max-depth`.
    pub max_depth: Option<u32>,
    /// `--seed`.
    pub seed: Option<u32>,
}

/// Loads a scene with the command line's overrides, which the library
/// applies before it checks the settings (its messages name the settings,
/// e.g. `render.width`; they are shown as this command line's flags).
pub fn load_scene(path: &Path, overrides: &Overrides) -> Result<scene::Scene> {
    let overrides = scene::RenderOverrides {
        width: overrides.size.width,
        height: overrides.size.height,
        spp: overrides.spp,
        max_depth: overrides.max_depth,
        seed: overrides.seed,
    };
    let scene = scene::load_with(path, &overrides)
        .map_err(|e| anyhow::anyhow!(flags::named(&e.to_string())))?;
    for warning in &scene.warnings {
        warn(warning);
    }
    Ok(scene)
}

/// Opens the device the user asked for.
pub fn open_device(args: &DeviceArgs) -> Result<vk::Context> {
    let options = vk::ContextOptions {
        device: args.device.clone(),
        validation: args.validation,
    };
    Ok(vk::Context::new(&options)?)
}

/// Packs `scene` for the device and prints what packing changed (textures
/// shrunk to fit the device).
pub fn new_renderer<'c>(
    ctx: &'c vk::Context,
    scene: &scene::Scene,
    options: &RenderOptions,
) -> Result<Renderer<'c>> {
    let renderer = Renderer::new(ctx, scene, options)?;
    for warning in renderer.warnings() {
        warn(warning);
    }
    Ok(renderer)
}

/// Prints a warning of the library on standard error, with the settings it
/// names as this command line's flags.
pub fn warn(warning: &str) {
    eprintln!("warning: {}", flags::named(warning));
}

/// Fails when the validation layer (if on) reported errors.
pub fn no_validation_errors(ctx: &vk::Context) -> Result<()> {
    anyhow::ensure!(
        ctx.validation_errors() == 0,
        "the Vulkan validation layer reported {} errors",
        ctx.validation_errors()
    );
    Ok(())
}

/// Pretty-printed JSON with a final newline.
pub fn json_bytes(value: &serde_json::Value) -> Result<Vec<u8>> {
    let mut bytes = serde_json::to_vec_pretty(value)?;
    bytes.push(b'\n');
    Ok(bytes)
}
