//! The speed work must not change what lancer computes: the persistent
//! pipeline cache is reused when valid and ignored when damaged, with the
//! same image either way; scene data read through texel buffers gives the
//! same closest hits on scenes of every size.

use crate::common;

use std::path::{Path, PathBuf};

use common::*;
use lancer::internal::vk::PipelineCacheStats;
use lancer::render::Renderer;
use lancer::Context;

/// A context whose persistent pipeline cache lives under `dir`.
fn cached_context(dir: &Path) -> Context {
    let mut ctx = context();
    ctx.set_pipeline_cache_dir(Some(dir));
    ctx
}

/// Renders a small Cornell box on `ctx`; returns the mean image.
fn small_cornell(ctx: &Context) -> Vec<f32> {
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 16;
    scene.render.height = 16;
    scene.render.spp = 2;
    render(ctx, &scene, &options(1 << 12)).mean
}

/// The cache files of a context.
fn cache_files(ctx: &Context) -> Vec<PathBuf> {
    let dir = ctx.pipeline_cache_dir().expect("the cache is on");
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    files
}

/// 64-bit FNV-1a, as the cache file envelope uses.
fn fnv(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

#[test]
fn pipeline_cache_is_written_cold_reused_warm_and_damage_is_ignored() {
    let dir = scratch("pipeline-cache");
    let passes = 5; // generate, intersect, shade, shadow, accumulate

    // Cold: every kernel is built and its file written
    let cold = cached_context(&dir);
    let image = small_cornell(&cold);
    let stats = cold.pipeline_cache_stats();
    assert_eq!(
        stats,
        PipelineCacheStats {
            loaded: 0,
            rejected: 0,
            stored: passes
        }
    );
    let files = cache_files(&cold);
    assert_eq!(files.len(), passes as usize, "{files:?}");
    // The folder names the device and driver; each file names its kernel
    assert!(files.iter().any(|f| f
        .file_name()
        .unwrap()
        .to_string_lossy()
        .starts_with("intersect-")));
    drop(cold);

    // Warm: every kernel comes from its file, nothing is written
    let warm = cached_context(&dir);
    assert_eq!(small_cornell(&warm), image, "warm cache changed the image");
    assert_eq!(
        warm.pipeline_cache_stats(),
        PipelineCacheStats {
            loaded: passes,
            rejected: 0,
            stored: 0
        }
    );
    drop(warm);

    // Damaged: garbage, truncated, a flipped bit, an empty file, and a file
    // for another device (valid envelope, foreign Vulkan header)
    let good = std::fs::read(&files[0]).unwrap();
    assert!(good.len() >= 24 + 32, "envelope and Vulkan header");
    std::fs::write(&files[0], b"not a pipeline cache at all").unwrap();
    std::fs::write(&files[1], &good[..good.len() - 1]).unwrap();
    let mut flipped = std::fs::read(&files[2]).unwrap();
    let last = flipped.len() - 1;
    flipped[last] ^= 1;
    std::fs::write(&files[2], &flipped).unwrap();
    std::fs::write(&files[3], b"").unwrap();
    let mut foreign = std::fs::read(&files[4]).unwrap();
    foreign[24 + 16] ^= 0xff; // first byte of pipelineCacheUUID
    let hash = fnv(&foreign[24..]);
    foreign[16..24].copy_from_slice(&hash.to_le_bytes());
    std::fs::write(&files[4], &foreign).unwrap();

    let damaged = cached_context(&dir);
    assert_eq!(
        small_cornell(&damaged),
        image,
        "a damaged cache changed the image"
    );
    assert_eq!(
        damaged.pipeline_cache_stats(),
        PipelineCacheStats {
            loaded: 0,
            rejected: passes,
            stored: passes
        }
    );
    drop(damaged);

    // The damaged files were rewritten: warm again
    let again = cached_context(&dir);
    small_cornell(&again);
    assert_eq!(again.pipeline_cache_stats().loaded, passes);
    assert_eq!(again.pipeline_cache_stats().rejected, 0);
    drop(again);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn pipeline_cache_off_writes_nothing_and_gives_the_same_image() {
    let dir = scratch("pipeline-cache-off");
    let mut off = context();
    off.set_pipeline_cache_dir(None);
    assert!(off.pipeline_cache_dir().is_none());
    let image = small_cornell(&off);
    assert_eq!(off.pipeline_cache_stats(), PipelineCacheStats::default());
    let on = cached_context(&dir);
    assert_eq!(small_cornell(&on), image);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Scene data goes through texel buffers: on a mesh of 16,200 triangles
/// (64,800 primitive texels, a deep BVH) the device's closest hits are the
/// brute-force ones.
#[test]
fn texel_buffer_scene_data_gives_brute_force_hits_on_a_large_mesh() {
    use glam::Vec3;
    use lancer::render::KernelHit;
    let ctx = context();
    let mut scene = load("scenes/cornell.toml");
    // A bumpy 90x90 grid of quads, two triangles each, over the floor
    let n = 90;
    let p = |i: usize, j: usize| {
        Vec3::new(
            -1.0 + 2.0 * i as f32 / n as f32,
            0.05 + 0.01 * ((i * 7 + j * 13) % 5) as f32,
            -1.0 + 2.0 * j as f32 / n as f32,
        )
    };
    let template = scene.triangles[0];
    scene.triangles.clear();
    for i in 0..n {
        for j in 0..n {
            for corners in [
                [p(i, j), p(i + 1, j), p(i + 1, j + 1)],
                [p(i, j), p(i + 1, j + 1), p(i, j + 1)],
            ] {
                let mut t = template;
                t.p = corners;
                scene.triangles.push(t);
            }
        }
    }
    let mut rays = Vec::new();
    for k in 0..4000u32 {
        let u = (k as f32 * 0.618_034).fract();
        let v = (k as f32 * 0.414_213_5).fract();
        let o = Vec3::new(2.2 * u - 1.1, 1.5, 2.2 * v - 1.1);
        let d = Vec3::new(-0.4 * (u - 0.5), -1.0, -0.4 * (v - 0.5)).normalize();
        rays.push((o, d, f32::MAX));
    }
    let mut renderer = Renderer::new(&ctx, &scene, &options(rays.len() as u32)).expect("renderer");
    let gpu = renderer.intersect_rays(&rays).expect("intersect");
    assert_eq!(ctx.validation_errors(), 0);
    let mut hits = 0;
    for (&(o, d, tmax), g) in rays.iter().zip(&gpu) {
        let best = brute_force::closest_hit(&scene, (o, d, tmax));
        hits += best.is_some() as usize;
        match (best, g) {
            (None, None) => {}
            // Same triangle, or a tie at the same distance (shared edges)
            (Some(KernelHit { prim, t }), Some(g)) => {
                assert!(
                    (t - g.t).abs() <= 1e-4 * t.max(1.0),
                    "ray {o} {d}: t {t} vs {}",
                    g.t
                );
                assert!(
                    prim == g.prim || (t - g.t).abs() <= 1e-6 * t.max(1.0),
                    "ray {o} {d}: triangle {prim} vs {}",
                    g.prim
                );
            }
            (c, g) => panic!("ray {o} {d}: brute force {c:?}, device {g:?}"),
        }
    }
    assert!(
        hits > rays.len() * 3 / 4,
        "most rays should hit the grid: {hits}"
    );
}
