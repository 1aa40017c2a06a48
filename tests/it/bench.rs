//! `lancer bench` and the scale promises, on small scenes: the suite
//! reports what it rendered and its JSON round-trips, a bad baseline is
//! refused by name before anything renders, the generated bumpy sphere is
//! the scene it claims, and device memory grows with the film only, never
//! with the number of waves. Speed itself is measured by `lancer bench`,
//! never asserted here.

use crate::common;

use common::*;
use lancer::analysis::bench::{self, BenchReport, Case, SceneSource, VARIANTS};
use lancer::internal::gpu::GpuFilmPixel;
use lancer::render::Renderer;

/// Quads per face edge of the small bumpy sphere the tests render.
const SMALL_SPHERE: u32 = 3;

#[test]
fn generated_sphere_scene_is_the_cornell_box_around_12_n_squared_triangles() {
    let dir = scratch("sphere");
    let path = bench::scenes::bumpy_sphere_scene(&dir, SMALL_SPHERE).unwrap();
    let scene = lancer::scene::load(&path).unwrap();
    let cornell = load("scenes/cornell.toml");
    // The box's five walls and light are two triangles each
    assert_eq!(scene.triangles.len(), 12 + 12 * 9);
    assert_eq!(scene.camera, cornell.camera);
    let emitters = scene
        .materials
        .iter()
        .filter(|m| m.emission.max_element() > 0.0)
        .count();
    assert_eq!(emitters, 1);
    // Written once: a second call finds the same files and leaves them alone
    let obj = dir.join(format!("bumpy_sphere_{SMALL_SPHERE}.obj"));
    let modified = std::fs::metadata(&obj).unwrap().modified().unwrap();
    let bytes = std::fs::read(&obj).unwrap();
    assert_eq!(
        bench::scenes::bumpy_sphere_scene(&dir, SMALL_SPHERE).unwrap(),
        path
    );
    assert_eq!(
        std::fs::metadata(&obj).unwrap().modified().unwrap(),
        modified
    );
    // A damaged (stale) file is written again, to the same bytes
    std::fs::write(&obj, "# something else\n").unwrap();
    bench::scenes::bumpy_sphere_scene(&dir, SMALL_SPHERE).unwrap();
    assert_eq!(std::fs::read(&obj).unwrap(), bytes);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn suite_reports_what_it_rendered_and_its_json_round_trips() {
    let dir = scratch("suite");
    let ctx = context();
    let cases = [
        Case {
            name: "cornell",
            source: SceneSource::Cornell,
            width: 16,
            height: 12,
            spp: 2,
        },
        Case {
            name: "sphere",
            source: SceneSource::BumpySphere(SMALL_SPHERE),
            width: 8,
            height: 8,
            spp: 3,
        },
    ];
    let report = bench::run_suite(&ctx, &cases, VARIANTS, &dir, None).unwrap();
    assert_eq!(ctx.validation_errors(), 0);
    assert_eq!(report.results.len(), cases.len() * VARIANTS.len());
    for (r, (case, variant)) in report.results.iter().zip(
        cases
            .iter()
            .flat_map(|c| VARIANTS.iter().map(move |v| (c, v))),
    ) {
        assert_eq!(
            (r.case.as_str(), r.variant.as_str()),
            (case.name, variant.name)
        );
        assert_eq!(
            (r.width, r.height, r.spp),
            (case.width, case.height, case.spp)
        );
        let samples = u64::from(case.width * case.height * case.spp);
        assert!(r.render_seconds > 0.0);
        let sps = samples as f64 / r.render_seconds;
        assert!((r.samples_per_second - sps).abs() <= 1e-9 * sps, "{r:?}");
        assert_eq!(
            r.first_dispatch_seconds,
            r.load_seconds + r.setup_seconds,
            "{r:?}"
        );
        assert!(
            r.bvh_seconds <= r.setup_seconds && r.bvh_sah_cost >= 1.0,
            "{r:?}"
        );
        if variant.name == "megakernel" {
            // One kernel runs every path of every sample
            let mega = r.pass("megakernel").expect("megakernel ran");
            assert_eq!(mega.rays, samples, "{r:?}");
            assert!(r.pass("generate").is_none(), "{r:?}");
        } else {
            // Every camera ray is generated and intersected once, at bounce 0
            let generate = r.pass("generate").expect("generate ran");
            let intersect = r.pass("intersect").expect("intersect ran");
            assert_eq!(generate.rays, samples);
            assert!(intersect.rays >= samples, "{r:?}");
        }
        for p in &r.passes {
            assert!(p.ms > 0.0 && p.mrays_per_s > 0.0, "{p:?}");
            let mrays = p.rays as f64 / (p.ms * 1e-3) / 1e6;
            assert!((p.mrays_per_s - mrays).abs() <= 1e-9 * mrays, "{p:?}");
        }
    }
    let triangles: Vec<u64> = report.results.iter().map(|r| r.triangles).collect();
    let expected: Vec<u64> = [36, 12 + 12 * 9]
        .into_iter()
        .flat_map(|t| VARIANTS.iter().map(move |_| t))
        .collect();
    assert_eq!(triangles, expected);
    // The device memory is what a renderer of that scene holds
    let scene = lancer::scene::load(&dir.join("examples/cornell.toml")).unwrap();
    let mut small = scene.clone();
    (small.render.width, small.render.height, small.render.spp) = (16, 12, 2);
    let renderer = Renderer::new(&ctx, &small, &lancer::render::RenderOptions::default()).unwrap();
    assert_eq!(
        report.results[0].device_bytes,
        renderer.scene_info.device_bytes
    );
    drop(renderer);

    let text = report.to_json().unwrap();
    let back = BenchReport::from_json(&text, &dir.join("r.json")).unwrap();
    assert_eq!(back, report);
    // The table names every case and pass
    let table = report.table();
    for name in ["cornell", "sphere", "intersect Mrays/s", "shadow Mrays/s"] {
        assert!(table.contains(name), "{table}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_baseline_is_refused_before_anything_renders() {
    let dir = scratch("baseline");
    let bad = dir.join("bad.json");
    std::fs::write(&bad, "{\"format\": 1, \"results\": 3}").unwrap();
    let bad = bad.to_str().unwrap();
    let scenes = dir.join("scenes");
    let scenes = scenes.to_str().unwrap();
    let out = lancer(&["bench", "--baseline", bad, "--scene-dir", scenes], &[]);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(
        err.contains(&format!("{bad}: not a `lancer bench --json` file")),
        "{err}"
    );
    // Nothing was generated, so nothing was rendered
    assert!(!dir.join("scenes").exists());
    let missing = dir.join("missing.json");
    let missing = missing.to_str().unwrap();
    let out = lancer(
        &["bench", "--baseline", missing, "--scene-dir", scenes],
        &[],
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains(&format!("{missing}: cannot read the baseline")),
        "{}",
        stderr(&out)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn device_memory_grows_with_the_film_only_never_with_the_waves() {
    let ctx = context();
    let scene = load("scenes/cornell.toml");
    let wave = 1024;
    let held = |width: u32, height: u32, spp: u32| {
        let mut s = scene.clone();
        (s.render.width, s.render.height, s.render.spp) = (width, height, spp);
        let before = ctx.memory_in_use();
        let mut r = Renderer::new(&ctx, &s, &options(wave)).unwrap();
        let declared = r.scene_info.device_bytes;
        let out = r.render(None).unwrap();
        check_finite(&out);
        let bytes = ctx.memory_in_use() - before;
        assert_eq!(bytes, declared, "lancer info's figure is what is held");
        (bytes, out.stats.waves)
    };
    let (one, waves_one) = held(32, 32, 1);
    let (many, waves_many) = held(32, 32, 16);
    let (large, _) = held(64, 64, 1);
    assert_eq!((waves_one, waves_many), (1, 16));
    assert_eq!(many, one, "more waves must not hold more memory");
    let film = 3 * (64 * 64 - 32 * 32) * std::mem::size_of::<GpuFilmPixel>() as u64;
    assert_eq!(
        large - one,
        film,
        "4x the pixels adds the film's three sums"
    );
    assert_eq!(ctx.validation_errors(), 0);
}
