//! `lancer bench --scale`: how lancer scales to a million triangles.
//!
//! The bumpy sphere at about a thousand and about a million triangles
//! ([`super::scenes`]) renders at the same settings; for each it reports
//! the OBJ's size and load time, the BVH's build time, SAH cost, nodes and
//! depth, device memory and samples per second, then the per-sample cost of
//! the million against the thousand. For the million it also renders at 4x
//! the pixels (render time ratio) and at 4x the samples (4x the waves),
//! reading the device memory lancer's live buffers hold after each render:
//! it should grow with the film only, by exactly the film's bytes.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context as _, Result};
use serde::Serialize;

use super::{scenes, SceneSource};
use crate::gpu::GpuFilmPixel;
use crate::render::{RenderOptions, Renderer};
use crate::scene;
use crate::vk::Context;

/// Image side of the per-sample comparison and of the larger image.
const SIDE: u32 = 256;

/// Samples per pixel of every measured render.
const SPP: u32 = 16;

/// Repetitions of each render in the image-size comparison (medians).
const REPEATS: usize = 3;

/// Figures of one mesh size.
#[derive(Serialize, Debug, Clone)]
pub struct MeshFigures {
    /// Triangles in the scene (the sphere and the box's 12).
    pub triangles: u64,
    /// Bytes of the OBJ file.
    pub obj_bytes: u64,
    /// Seconds to write the OBJ and scene; `None` when they were cached.
    pub generate_seconds: Option<f64>,
    /// Seconds to load the scene (tobj, checks, transforms).
    pub load_seconds: f64,
    /// Seconds of the BVH build.
    pub bvh_seconds: f64,
    /// SAH cost of the BVH.
    pub bvh_sah_cost: f64,
    /// BVH nodes.
    pub bvh_nodes: usize,
    /// BVH depth.
    pub bvh_depth: u32,
    /// Seconds to build the renderer (BVH, packing, upload, kernels).
    pub setup_seconds: f64,
    /// Device memory of the renderer's buffers, in bytes.
    pub device_bytes: u64,
    /// Samples per second at `SIDE`² and `SPP` samples per pixel.
    pub samples_per_second: f64,
    /// Mrays/s of the intersect pass.
    pub intersect_mrays_per_s: f64,
    /// Mrays/s of the shadow pass.
    pub shadow_mrays_per_s: f64,
}

/// Device memory after one render of the million-triangle scene.
#[derive(Serialize, Debug, Clone)]
pub struct MemoryFigure {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Waves rendered.
    pub waves: u32,
    /// Paths per wave.
    pub wave_size: u32,
    /// Bytes held by live buffers after the render.
    pub bytes_in_use: u64,
}

/// Everything `lancer bench --scale` measured.
#[derive(Serialize, Debug, Clone)]
pub struct ScaleReport {
    /// Vulkan device name.
    pub device: String,
    /// Driver name and version.
    pub driver: String,
    /// The thousand-triangle sphere.
    pub thousand: MeshFigures,
    /// The million-triangle sphere.
    pub million: MeshFigures,
    /// Time per sample of the million over the thousand.
    pub per_sample_cost_ratio: f64,
    /// Median render seconds of the million at `SIDE/2`² and `SIDE`².
    pub pixel_seconds: [f64; 2],
    /// Render time at 4x the pixels over the time at 1x.
    pub pixel_time_ratio: f64,
    /// Device memory at (small image, 1 wave), (small image, 4 waves),
    /// (4x the pixels, 4 waves).
    pub memory: Vec<MemoryFigure>,
    /// Bytes the film of the 4x image adds: two sums per pixel.
    pub film_bytes_added: u64,
}

/// A loaded bumpy sphere and what loading it took.
struct Loaded {
    scene: scene::Scene,
    obj_bytes: u64,
    generate_seconds: Option<f64>,
    load_seconds: f64,
}

/// Writes (or finds) and loads the bumpy sphere of `n` quads per face edge.
fn load(dir: &Path, n: u32) -> Result<Loaded> {
    let [obj, _] = scenes::bumpy_sphere_files(dir, n);
    let cached = obj.exists();
    let started = Instant::now();
    let path = scenes::bumpy_sphere_scene(dir, n)?;
    let generate_seconds = (!cached).then(|| started.elapsed().as_secs_f64());
    let obj_bytes = std::fs::metadata(&obj)
        .with_context(|| format!("{}: the generated OBJ is missing", obj.display()))?
        .len();
    let started = Instant::now();
    let scene = scene::load(&path)?;
    Ok(Loaded {
        scene,
        obj_bytes,
        generate_seconds,
        load_seconds: started.elapsed().as_secs_f64(),
    })
}

/// A renderer of `scene` at `side`² and `spp`, with its setup time.
fn renderer<'c>(
    ctx: &'c Context,
    scene: &scene::Scene,
    side: u32,
    spp: u32,
) -> Result<(Renderer<'c>, f64)> {
    let mut scene = scene.clone();
    scene.render.width = side;
    scene.render.height = side;
    scene.render.spp = spp;
    let started = Instant::now();
    let mut r = Renderer::new(ctx, &scene, &RenderOptions::default())?;
    let setup = started.elapsed().as_secs_f64();
    // One warm-up sample: some drivers compile a kernel at its first dispatch
    r.restart()?;
    r.render_to(1, None)?;
    Ok((r, setup))
}

/// Measures one mesh size.
fn mesh_figures(ctx: &Context, loaded: &Loaded) -> Result<MeshFigures> {
    let (mut r, setup_seconds) = renderer(ctx, &loaded.scene, SIDE, SPP)?;
    let out = r.render(None)?;
    let rows = out.stats.pass_rows();
    let mrays = |name: &str| {
        rows.iter()
            .find(|row| row.pass.name() == name)
            .map_or(0.0, |row| row.mrays_per_s)
    };
    let info = &r.scene_info;
    Ok(MeshFigures {
        triangles: info.triangles as u64,
        obj_bytes: loaded.obj_bytes,
        generate_seconds: loaded.generate_seconds,
        load_seconds: loaded.load_seconds,
        bvh_seconds: info.bvh_seconds,
        bvh_sah_cost: info.bvh_sah_cost,
        bvh_nodes: info.bvh_nodes,
        bvh_depth: info.bvh_depth,
        setup_seconds,
        device_bytes: info.device_bytes,
        samples_per_second: out.stats.samples_per_second().unwrap_or(0.0),
        intersect_mrays_per_s: mrays("intersect"),
        shadow_mrays_per_s: mrays("shadow"),
    })
}

/// Median of a few values.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Device memory after rendering `spp` samples of `scene` at `side`².
fn memory_after_render(
    ctx: &Context,
    scene: &scene::Scene,
    side: u32,
    spp: u32,
) -> Result<MemoryFigure> {
    let before = ctx.memory_in_use();
    let (mut r, _) = renderer(ctx, scene, side, spp)?;
    let out = r.render(None)?;
    Ok(MemoryFigure {
        width: side,
        height: side,
        spp,
        waves: out.stats.waves,
        wave_size: out.stats.wave_size,
        bytes_in_use: ctx.memory_in_use() - before,
    })
}

/// The scenes `lancer bench --scale` generates: the thousand- and the
/// million-triangle spheres.
pub const SOURCES: [SceneSource; 2] = [
    SceneSource::BumpySphere(scenes::THOUSAND_SUBDIVISIONS),
    SceneSource::BumpySphere(scenes::MILLION_SUBDIVISIONS),
];

/// Runs every measurement of `lancer bench --scale`, with the generated
/// scenes in `dir`; `say` is told what each step measures as it starts.
pub fn run(ctx: &Context, dir: &Path, say: &dyn Fn(&str)) -> Result<ScaleReport> {
    say("the thousand-triangle sphere");
    let small = load(dir, scenes::THOUSAND_SUBDIVISIONS)?;
    let thousand = mesh_figures(ctx, &small)?;
    drop(small);
    say("the million-triangle sphere (written on first use)");
    let big = load(dir, scenes::MILLION_SUBDIVISIONS)?;
    let million = mesh_figures(ctx, &big)?;

    say("4x the pixels");
    let (mut small_image, _) = renderer(ctx, &big.scene, SIDE / 2, SPP)?;
    let (mut large_image, _) = renderer(ctx, &big.scene, SIDE, SPP)?;
    let (mut t_small, mut t_large) = (Vec::new(), Vec::new());
    // Alternate, so a machine that slows down slows both alike
    for _ in 0..REPEATS {
        t_small.push(small_image.render(None)?.stats.wall_seconds);
        t_large.push(large_image.render(None)?.stats.wall_seconds);
    }
    drop((small_image, large_image));
    let pixel_seconds = [median(t_small), median(t_large)];

    say("device memory after more waves and more pixels");
    let memory = vec![
        memory_after_render(ctx, &big.scene, SIDE / 2, SPP)?,
        memory_after_render(ctx, &big.scene, SIDE / 2, 4 * SPP)?,
        memory_after_render(ctx, &big.scene, SIDE, SPP)?,
    ];
    let added_pixels = u64::from(SIDE * SIDE - (SIDE / 2) * (SIDE / 2));
    let film_bytes_added = 2 * added_pixels * std::mem::size_of::<GpuFilmPixel>() as u64;

    let info = ctx.info();
    Ok(ScaleReport {
        device: info.name.clone(),
        driver: info.driver_name.clone(),
        per_sample_cost_ratio: thousand.samples_per_second / million.samples_per_second,
        thousand,
        million,
        pixel_time_ratio: pixel_seconds[1] / pixel_seconds[0],
        pixel_seconds,
        memory,
        film_bytes_added,
    })
}

impl ScaleReport {
    /// Writes the figures as pretty JSON to `path`, atomically.
    pub fn write_json(&self, path: &Path) -> Result<()> {
        crate::io::image_file::write_atomically(path, |w| {
            serde_json::to_writer_pretty(&mut *w, self)?;
            Ok(std::io::Write::write_all(w, b"\n")?)
        })
    }

    /// The figures for a terminal.
    pub fn table(&self) -> String {
        let mib = |b: u64| format!("{:.1}", super::mib(b));
        let header = [
            "mesh",
            "triangles",
            "OBJ MiB",
            "generate s",
            "load s",
            "BVH s",
            "SAH cost",
            "nodes",
            "depth",
            "setup s",
            "device MiB",
            "samples/s",
            "intersect Mrays/s",
            "shadow Mrays/s",
        ];
        let rows: Vec<Vec<String>> = [("1k", &self.thousand), ("1M", &self.million)]
            .iter()
            .map(|(name, m)| {
                vec![
                    name.to_string(),
                    m.triangles.to_string(),
                    mib(m.obj_bytes),
                    m.generate_seconds
                        .map_or("cached".into(), |s| format!("{s:.2}")),
                    format!("{:.3}", m.load_seconds),
                    format!("{:.3}", m.bvh_seconds),
                    format!("{:.2}", m.bvh_sah_cost),
                    m.bvh_nodes.to_string(),
                    m.bvh_depth.to_string(),
                    format!("{:.3}", m.setup_seconds),
                    mib(m.device_bytes),
                    format!("{:.0}", m.samples_per_second),
                    format!("{:.2}", m.intersect_mrays_per_s),
                    format!("{:.2}", m.shadow_mrays_per_s),
                ]
            })
            .collect();
        let mut out = format!(
            "device: {} (driver {}); renders at {SIDE}x{SIDE}, {SPP} spp, after one warm-up sample\n",
            self.device, self.driver
        );
        out.push_str(&crate::render::stats::render_table(&header, &rows, 1));
        out.push_str(&format!(
            "time per sample, 1M / 1k triangles: {:.2}x\n",
            self.per_sample_cost_ratio
        ));
        let half = SIDE / 2;
        out.push_str(&format!(
            "1M, {half}x{half} -> {SIDE}x{SIDE} (4x the pixels), {SPP} spp: {:.3} s -> {:.3} s, {:.2}x the time (median of {REPEATS})\n",
            self.pixel_seconds[0], self.pixel_seconds[1], self.pixel_time_ratio
        ));
        let header = ["image", "spp", "waves", "wave size", "device bytes"];
        let rows: Vec<Vec<String>> = self
            .memory
            .iter()
            .map(|m| {
                vec![
                    format!("{}x{}", m.width, m.height),
                    m.spp.to_string(),
                    m.waves.to_string(),
                    m.wave_size.to_string(),
                    m.bytes_in_use.to_string(),
                ]
            })
            .collect();
        out.push_str("1M, device memory held after the render:\n");
        out.push_str(&crate::render::stats::render_table(&header, &rows, 1));
        if let [one, more_waves, more_pixels] = &self.memory[..] {
            out.push_str(&format!(
                "4x the waves: {:+} bytes; 4x the pixels: {:+} bytes (the film's two sums: {} bytes)",
                more_waves.bytes_in_use as i64 - one.bytes_in_use as i64,
                more_pixels.bytes_in_use as i64 - one.bytes_in_use as i64,
                self.film_bytes_added
            ));
        }
        out
    }
}
