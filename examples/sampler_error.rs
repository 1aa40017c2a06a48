//! Error at equal samples of each sampler: relMSE against a high-spp
//! reference, the mean over several seeds, at 64 x 64 pixels.
//!
//! ```text
//! cargo run --release --example sampler_error -- [SPP] [SEEDS] [REFERENCE_SPP]
//! ```
//!
//! Defaults: 256 spp, 4 seeds (0..4), references of 65,536 spp. The Cornell
//! box is measured against Mitsuba 3's 65,536-spp image
//! (`tests/reference/cornell.exr`, the reference of the sampler comparison
//! in the issue that asked for the Sobol sampler); `scenes/dof.toml` against
//! lancer's own render of REFERENCE_SPP samples with the independent
//! sampler and seed 1000 (no seed of the measured renders), kept in the
//! system's temporary folder for the next run. Only samples matter here;
//! the render seconds are printed for information, as the machine may be
//! busy.
use anyhow::{Context as _, Result};
use lancer::render::kernels::Sampler;
use lancer::util::metrics::rel_mse;
use lancer::{Context, ContextOptions, RenderOptions, Renderer, Scene};

/// Image side in pixels.
const SIZE: u32 = 64;

/// Renders `scene` at SIZE x SIZE with `spp`, `seed` and `sampler`: the
/// mean and the render seconds.
fn render(
    ctx: &Context,
    scene: &Scene,
    spp: u32,
    seed: u32,
    sampler: Sampler,
) -> Result<(Vec<f32>, f64)> {
    let mut scene = scene.clone();
    scene.render.width = SIZE;
    scene.render.height = SIZE;
    scene.render.spp = spp;
    scene.render.seed = seed;
    let options = RenderOptions {
        sampler,
        ..RenderOptions::default()
    };
    let out = Renderer::new(ctx, &scene, &options)?.render(None)?;
    Ok((out.mean, out.stats.wall_seconds))
}

/// lancer's own reference of `scene`, rendered once and kept in `path`.
fn own_reference(
    ctx: &Context,
    scene: &Scene,
    spp: u32,
    path: &std::path::Path,
) -> Result<Vec<f32>> {
    if let Ok((w, h, mean)) = lancer::io::image_file::read_exr(path) {
        if (w, h) == (SIZE, SIZE) {
            eprintln!("reference: {}", path.display());
            return Ok(mean);
        }
    }
    eprintln!(
        "rendering the reference, {spp} spp, into {}",
        path.display()
    );
    let (mean, _) = render(ctx, scene, spp, 1000, Sampler::Independent)?;
    lancer::io::image_file::write_image(path, SIZE, SIZE, &mean)?;
    Ok(mean)
}

fn main() -> Result<()> {
    let arg = |i: usize, default: u32| -> Result<u32> {
        std::env::args()
            .nth(i)
            .map_or(Ok(default), |a| a.parse().context("a whole number"))
    };
    let (spp, seeds, reference_spp) = (arg(1, 256)?, arg(2, 4)?, arg(3, 65536)?);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let ctx = Context::new(&ContextOptions::default())?;
    let cornell = lancer::scene::load(&root.join("scenes/cornell.toml"))?;
    let (_, _, cornell_ref) =
        lancer::io::image_file::read_exr(&root.join("tests/reference/cornell.exr"))?;
    let dof = lancer::scene::load(&root.join("scenes/dof.toml"))?;
    let dof_path =
        std::env::temp_dir().join(format!("lancer-dof-{SIZE}-{reference_spp}spp-seed1000.exr"));
    let dof_ref = own_reference(&ctx, &dof, reference_spp, &dof_path)?;
    println!("relMSE at {spp} spp, {SIZE}x{SIZE}, mean over seeds 0..{seeds}");
    println!("| scene | independent | sobol | independent / sobol | seconds independent | seconds sobol |");
    println!("|---|---:|---:|---:|---:|---:|");
    for (name, scene, reference) in [("cornell", &cornell, &cornell_ref), ("dof", &dof, &dof_ref)] {
        let (mut mean, mut seconds) = ([0.0f64; 2], [0.0f64; 2]);
        for (i, sampler) in Sampler::ALL.into_iter().enumerate() {
            for seed in 0..seeds {
                let (image, s) = render(&ctx, scene, spp, seed, sampler)?;
                let e = rel_mse(&image, reference);
                eprintln!("{name} {sampler} seed {seed}: {e:.3e} in {s:.2} s");
                mean[i] += e / f64::from(seeds);
                seconds[i] += s;
            }
        }
        println!(
            "| {name} | {:.3e} | {:.3e} | {:.2} | {:.1} | {:.1} |",
            mean[0],
            mean[1],
            mean[0] / mean[1],
            seconds[0],
            seconds[1]
        );
    }
    Ok(())
}
