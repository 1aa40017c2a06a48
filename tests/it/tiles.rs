//! Large images: the film is rendered in bands of rows, one band on the
//! device at a time. A render in bands gives the single-binding image bit
//! for bit (both schedules, both film encodings, whole and progressive),
//! and an 8K render works with device memory bounded by the wave and one
//! band.

use crate::common;

use common::*;
use lancer::render::kernels::Schedule;
use lancer::render::{RenderOptions, RenderOutput, Renderer};

/// Renders `scene` progressively to `steps` samples per pixel, reading the
/// film after each step: the outputs and the raw sums of the last step.
fn render_steps(
    ctx: &lancer::Context,
    scene: &lancer::Scene,
    options: &RenderOptions,
    steps: &[u32],
) -> (Vec<RenderOutput>, (lancer::render::film::FilmSums, u64)) {
    let mut renderer = Renderer::new(ctx, scene, options).expect("renderer");
    renderer.restart().expect("restart");
    let outputs = steps
        .iter()
        .map(|&spp| {
            renderer.render_to(spp, None).expect("render");
            let out = renderer.output().expect("output");
            check_finite(&out);
            out
        })
        .collect();
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
    (outputs, renderer.film_sums().expect("film sums"))
}

/// 64 rows in bands of 24 rows (24, 24, 16), against one binding, with
/// each schedule, each film encoding, a wave that holds every sample of
/// the image and one that holds 1000 paths (waves that cross bands'
/// edges in the single binding), in one step and in three: every mean,
/// variance and raw sum is the same, bit for bit.
#[test]
fn bands_of_rows_give_the_single_binding_image_bit_for_bit() {
    let ctx = context();
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 64;
    scene.render.height = 64;
    scene.render.spp = 8;
    for schedule in Schedule::ALL {
        for f32_film in [false, true] {
            for wave_size in [1 << 18, 1000] {
                for steps in [&[8][..], &[1, 3, 8]] {
                    let label = format!(
                        "{schedule}, f32 film {f32_film}, wave {wave_size}, steps {steps:?}"
                    );
                    let whole = RenderOptions {
                        schedule,
                        f32_film,
                        ..options(wave_size)
                    };
                    let banded = RenderOptions {
                        tile_rows: Some(24),
                        ..whole.clone()
                    };
                    let (a, a_sums) = render_steps(&ctx, &scene, &whole, steps);
                    let (b, b_sums) = render_steps(&ctx, &scene, &banded, steps);
                    for (x, y) in a.iter().zip(&b) {
                        assert_eq!((x.stats.tiles, y.stats.tiles), (1, 3), "{label}");
                        assert_eq!(y.stats.tile_rows, 24, "{label}");
                        let total: f64 = x.mean.iter().map(|&v| f64::from(v)).sum();
                        assert!(total > 0.0, "{label}: black image, nothing compared");
                        assert_eq!(
                            differing_bits(&x.mean, &y.mean),
                            0,
                            "{label}: mean, {} spp",
                            x.spp
                        );
                        assert_eq!(
                            differing_bits(&x.var_of_mean, &y.var_of_mean),
                            0,
                            "{label}: variance, {} spp",
                            x.spp
                        );
                        assert_eq!(
                            differing_bits(&x.error_estimate, &y.error_estimate),
                            0,
                            "{label}: error estimate, {} spp",
                            x.spp
                        );
                    }
                    assert!(a_sums == b_sums, "{label}: the raw film sums differ");
                }
            }
        }
    }
}

/// `--tile-rows` reaches the renderer: the stats name the bands, and the
/// EXR's pixels are those of the render in one binding.
#[test]
fn tile_rows_flag_splits_the_film_and_keeps_the_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let (exr, json) = (
            dir.path().join(format!("{name}.exr")),
            dir.path().join(format!("{name}.json")),
        );
        let mut args = vec![
            "render",
            "scenes/cornell.toml",
            "--width",
            "64",
            "--height",
            "50",
            "--spp",
            "4",
            "-q",
            "--out",
            exr.to_str().unwrap(),
            "--stats-json",
            json.to_str().unwrap(),
        ];
        args.extend(extra);
        let out = lancer(&args, &[]);
        assert!(out.status.success(), "lancer {args:?}: {}", stderr(&out));
        let stats: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let pixels = lancer::io::image_file::read_exr(&exr).expect("read EXR").2;
        (stats["tiles"].as_u64(), stats["tile_rows"].as_u64(), pixels)
    };
    let (tiles, rows, whole) = run("whole", &[]);
    assert_eq!((tiles, rows), (Some(1), Some(50)));
    let (tiles, rows, banded) = run("banded", &["--tile-rows", "16"]);
    assert_eq!((tiles, rows), (Some(4), Some(16)));
    assert_eq!(differing_bits(&whole, &banded), 0);
    let bad = lancer(&["render", "scenes/cornell.toml", "--tile-rows", "0"], &[]);
    assert!(!bad.status.success());
    assert!(stderr(&bad).contains("--tile-rows"), "{}", stderr(&bad));
}

/// A 7680 x 4320 image of a sphere that emits radiance 1 under an
/// environment of radiance 0.5, 1 spp, max depth 1, on the default device:
/// every pixel is exactly 1 or exactly 0.5, 1 inside the sphere's disk and
/// 0.5 outside it (2 pixels clear of its edge), and none is NaN. The film
/// was rendered in bands of the rows one binding holds, and the device
/// never held more than the renderer of a single band's image holds: the
/// wave, the scene and one band's film. The image is written as EXR and
/// PNG and the EXR reads back.
#[test]
fn an_8k_render_is_exact_in_the_memory_of_one_band() {
    let ctx = context();
    let mut scene = load("tests/scenes/furnace.toml");
    let (width, height) = (7680u32, 4320u32);
    scene.render.width = width;
    scene.render.height = height;
    scene.render.spp = 1;
    scene.render.max_depth = 1;
    scene.environment = lancer::Vec3::splat(0.5);
    scene.materials[0].kind = materials::lambert(lancer::Vec3::ZERO);
    scene.materials[0].emission = lancer::Vec3::ONE;
    // The default (Sobol) sampler: 2 of its 33 million camera rays graze the
    // sphere's silhouette so closely that the rounded normal turns away
    // from them; they meet the sphere's outside all the same (the side is
    // where the ray starts), where their pixels were black
    let options = RenderOptions::default();
    let before = ctx.memory_in_use();
    let started = std::time::Instant::now();
    let mut renderer = Renderer::new(&ctx, &scene, &options).expect("renderer");
    let out = renderer.render(None).expect("render");
    let seconds = started.elapsed().as_secs_f64();
    check_finite(&out);
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
    assert_eq!(out.mean.len(), 3 * (width * height) as usize);

    // The sphere (radius 1, 4 from the eye, vfov 40) covers a disk of
    // radius tan(asin(1/4)) / tan(20 deg) half-heights about the centre
    let radius = (1.0 / 15f64.sqrt()) / 20f64.to_radians().tan() * f64::from(height) / 2.0;
    let mut wrong = Vec::new();
    for (i, rgb) in out.mean.chunks_exact(3).enumerate() {
        let (x, y) = (
            (i as u32 % width) as f64 + 0.5,
            (i as u32 / width) as f64 + 0.5,
        );
        let r = (x - f64::from(width) / 2.0).hypot(y - f64::from(height) / 2.0);
        let all = |v: f32| rgb.iter().all(|&c| c == v);
        let ok = (all(1.0) && r < radius + 2.0) || (all(0.5) && r > radius - 2.0);
        if !ok {
            wrong.push((i as u32 % width, i as u32 / width, rgb.to_vec()));
        }
    }
    assert!(
        wrong.is_empty(),
        "{} pixels are wrong; the first (column, row, value): {:?}",
        wrong.len(),
        wrong[0]
    );

    // The bands: as many rows as one binding of 32-byte film pixels holds
    let film_pixel = std::mem::size_of::<lancer::internal::gpu::GpuFilmPixel>() as u64;
    let rows =
        (ctx.max_storage_buffer_range() / film_pixel / u64::from(width)).min(height.into()) as u32;
    assert_eq!(renderer.tile_rows(), rows);
    assert_eq!(renderer.tile_count(), height.div_ceil(rows));
    assert_eq!(out.stats.tiles, height.div_ceil(rows));

    // Device memory: the peak is what the renderer allocated (and, on a
    // GPU whose film is not host visible, the one bounded staging buffer
    // that reads it back), and that is what a renderer of an image one band
    // tall allocates
    let held = renderer.scene_info.device_bytes;
    let peak = ctx.memory_peak() - before;
    drop(renderer);
    let mut one_band = scene.clone();
    one_band.render.height = rows;
    let band_bytes = Renderer::new(&ctx, &one_band, &options)
        .expect("renderer of one band")
        .scene_info
        .device_bytes;
    let whole_film = 2 * film_pixel * u64::from(width * height);
    println!(
        "8K: {seconds:.1} s, {} bands of {rows} rows, peak device bytes {peak} \
         (renderer {held}, one-band image {band_bytes}; the whole film alone would be {whole_film})",
        out.stats.tiles
    );
    assert_eq!(
        held, band_bytes,
        "the 8K renderer holds more than a one-band image's"
    );
    let staging = if ctx.info().kind == lancer::DeviceKind::Cpu {
        0
    } else {
        lancer::internal::vk::STAGING_CHUNK_BYTES
    };
    assert!(
        peak <= held + staging,
        "device memory peaked at {peak} bytes, above the {held} the renderer holds \
         (and {staging} of staging)"
    );

    // 33 million pixels written as EXR and PNG; the EXR reads back
    let dir = tempfile::tempdir().unwrap();
    for name in ["8k.exr", "8k.png"] {
        lancer::io::image_file::write_render(&dir.path().join(name), &out).expect("write");
    }
    let (w, h, pixels) =
        lancer::io::image_file::read_exr(&dir.path().join("8k.exr")).expect("read EXR");
    assert_eq!((w, h), (width, height));
    assert_eq!(
        differing_bits(&pixels, &out.mean),
        0,
        "the EXR holds other pixels"
    );
}

/// Issue 18 §8, a compact host film: a render in bands that visits each
/// band once ([`Renderer::render`]) resolves each band when its samples are
/// done and keeps no film on the host (an 8K image kept 3.2 GB, 96 bytes
/// a pixel); one that comes back to the bands keeps 24 bytes per pixel and
/// sum, the words of the device's 32 the kernels use. Either way the
/// image, and the raw sums of the one that keeps them, are those of one
/// binding bit for bit, with both film encodings; the film resolved and
/// not kept is not read again.
#[test]
fn the_host_keeps_no_film_for_one_visit_and_a_compact_one_for_more() {
    let ctx = context();
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 64;
    scene.render.height = 64;
    scene.render.spp = 4;
    for f32_film in [false, true] {
        let whole = RenderOptions {
            f32_film,
            ..options(1000)
        };
        let banded = RenderOptions {
            tile_rows: Some(24),
            ..whole.clone()
        };
        let mut one = Renderer::new(&ctx, &scene, &whole).expect("renderer");
        let reference = one.render(None).expect("render");
        let reference_sums = one.film_sums().expect("sums").0;
        let mut renderer = Renderer::new(&ctx, &scene, &banded).expect("renderer");
        assert_eq!(renderer.tile_count(), 3);
        let out = renderer.render(None).expect("render");
        assert_eq!(renderer.host_film_bytes(), 0, "f32 film {f32_film}");
        assert!(renderer.output().is_err() && renderer.film_sums().is_err());
        assert!(
            renderer.render_to(8, None).is_err(),
            "continued a film not kept"
        );
        // Progressive: the host keeps the bands
        renderer.restart().expect("restart");
        renderer.render_to(1, None).expect("render");
        renderer.render_to(4, None).expect("render");
        assert_eq!(renderer.host_film_bytes(), 3 * 24 * 64 * 64);
        let progressive = renderer.output().expect("output");
        for (label, x) in [("render", &out), ("progressive", &progressive)] {
            for (what, a, b) in [
                ("mean", &reference.mean, &x.mean),
                ("variance", &reference.var_of_mean, &x.var_of_mean),
                ("error", &reference.error_estimate, &x.error_estimate),
            ] {
                assert_eq!(
                    differing_bits(a, b),
                    0,
                    "f32 film {f32_film}, {label}: {what}"
                );
            }
        }
        assert!(reference.mean.iter().any(|&v| v > 0.0), "a black image");
        assert!(
            renderer.film_sums().expect("sums").0 == reference_sums,
            "f32 film {f32_film}: the raw sums differ"
        );
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}
