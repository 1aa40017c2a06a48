//! `lancer info`: what a scene calls for and what would run for it: the
//! features, the passes and their specialisation constants, the sizes of
//! what goes on the device, and the device's memory budgets.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;

use lancer::internal::interface::SPEC_MATERIAL_MASK;
use lancer::render::kernels::{Features, Pass};

use crate::args::{load_scene, new_renderer, open_device, DeviceArgs, KernelArgs, Overrides};

#[derive(clap::Args)]
pub struct InfoArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    #[command(flatten)]
    kernels: KernelArgs,
    #[command(flatten)]
    device: DeviceArgs,
}

/// `lancer info`.
pub fn info(args: InfoArgs) -> Result<()> {
    let started = Instant::now();
    let scene = load_scene(&args.scene, &Overrides::default())?;
    let load_seconds = started.elapsed().as_secs_f64();
    let ctx = open_device(&args.device)?;
    let started = Instant::now();
    let renderer = new_renderer(&ctx, &scene, &args.kernels.options())?;
    let setup_seconds = started.elapsed().as_secs_f64();
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
        ("environment map", f.envmap),
        ("textures", f.textures),
        ("depth of field", f.depth_of_field),
        ("pixel filter", f.pixel_filter),
        ("clip planes", f.clip),
        ("filter cut at the image's edge", f.film_edge),
        ("crop window or principal point", f.camera_shift),
        ("texture to_uv, wrap, checkerboard", f.texture_mapping),
        ("orthographic camera", f.orthographic),
        ("mask (opacity)", f.mask),
        ("normal or bump map", f.normal_map),
        ("mesh attributes", f.mesh_attributes),
        ("point, spot, directional lights", f.delta_lights),
        ("hide_emitters or bsdf_samples = 0", f.path_flags),
        ("Mitsuba's material sides", f.shading_sides),
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
    println!(
        "load: scene and meshes read in {load_seconds:.3} s; packed (BVH included), \
         uploaded and kernels built in {setup_seconds:.3} s"
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
