//! Accuracy against time: the convergence study, the error the film
//! predicts, renders that stop at a time or an error budget, and the
//! `converge` and `compare` commands as a user meets them.

use crate::common;

use std::path::{Path, PathBuf};

use common::*;
use lancer::analysis::metrics::Metrics;
use lancer::internal::converge::loglog_slope;
use lancer::internal::study::{self, Length, Reference};
use lancer::render::budget::{render_with_budget, Budget};
use lancer::render::kernels::Pass;
use lancer::render::kernels::{Integrator, Sampler};
use lancer::render::{RenderOptions, RenderOutput, Renderer};
use lancer::scene::Scene;
use lancer::util::metrics::rel_mse;
use lancer::Context;

/// `path` shrunk to `side` x `side` pixels.
fn small(path: &str, side: u32) -> Scene {
    let mut scene = load(path);
    scene.render.width = side;
    scene.render.height = side;
    scene
}

/// Options of a progressive render (unstratified jitter).
fn progressive() -> RenderOptions {
    RenderOptions {
        progressive: true,
        ..RenderOptions::default()
    }
}

/// A lancer reference of `scene` at `spp`, cached across tests and runs
/// in cargo's scratch space (the file name holds spp, seed and a hash of
/// the scene and options). It is drawn by the independent sampler, whose
/// variance EXR (sample variance / spp), which the predicted relMSE adds
/// for the reference, is exact.
fn lancer_reference(scene: &Scene, spp: u32) -> Reference {
    let ctx = context();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("accuracy-references");
    std::fs::create_dir_all(&dir).unwrap();
    let options = RenderOptions {
        sampler: Sampler::Independent,
        ..RenderOptions::default()
    };
    study::rendered_reference(&ctx, scene, &options, spp, &dir, None).expect("reference")
}

/// A converge study of the scene with `options`, one seed, up to `spp`.
fn converge_with(
    ctx: &Context,
    scene: &Scene,
    reference: &Reference,
    spp: u32,
    options: &RenderOptions,
) -> study::Study {
    let variants = study::variants(&[]).unwrap();
    study::run(
        ctx,
        scene,
        options,
        &variants,
        1,
        Length::Spp(spp),
        reference,
        |_| {},
    )
    .expect("converge")
}

/// The Cornell box against Mitsuba's 65,536-spp reference: relMSE falls as
/// 1/spp under independent samples, the slope of a log-log fit over 1 to
/// 256 spp -1 within 0.15, as Monte Carlo theory has it. Under the Sobol
/// sampler it falls at least that fast (slope at most -0.85) and at most
/// as fast as scrambled nets can on integrands with edges (N^-1.5): it
/// measured -1.17, as the stratified pixel positions and light samples
/// pay off more with each sample. A biased render would flatten out.
#[test]
fn cornell_relmse_falls_as_one_over_spp() {
    let ctx = context();
    let scene = small("scenes/cornell.toml", 64);
    let reference = study::read_reference(&repo("tests/reference/cornell.exr"), 64, 64)
        .expect("stored reference");
    assert!(
        reference.var.is_some(),
        "the stored variance is found beside it"
    );
    for (sampler, slopes) in [
        (Sampler::Independent, -1.15..=-0.85),
        (Sampler::Sobol, -1.5..=-0.85),
    ] {
        let options = RenderOptions {
            sampler,
            ..RenderOptions::default()
        };
        let run = converge_with(&ctx, &scene, &reference, 256, &options);
        let spp: Vec<f64> = run.steps.iter().map(|s| s.spp as f64).collect();
        let err: Vec<f64> = run.steps.iter().map(|s| s.metrics.rel_mse).collect();
        assert_eq!(spp, [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0]);
        let slope = loglog_slope(&spp, &err);
        println!("{sampler}: relMSE {err:?}, slope {slope:.3}");
        assert!(
            slopes.contains(&slope),
            "{sampler}: log-log slope {slope}, outside {slopes:?}"
        );
        // Render time grows with spp; measuring is never counted in it.
        assert!(run
            .steps
            .windows(2)
            .all(|w| w[1].render_seconds > w[0].render_seconds));
    }
    assert_eq!(ctx.validation_errors(), 0);
}

/// On every example scene (glass and mirror caustics included), under
/// every sampler, at 64, 256 and 1024 spp, the relMSE that the film's two
/// half films predict is within a factor of 2 of the relMSE measured
/// against an independent reference (8192 spp, another seed, the
/// independent sampler). docs/accuracy.md lists the table this prints.
#[test]
fn predicted_relmse_tracks_the_measured_one_on_every_example_scene() {
    let ctx = context();
    let mut failures = Vec::new();
    let mut ratios = Vec::new();
    println!("| scene | sampler | spp | measured | predicted | ratio |");
    println!("|---|---|---:|---:|---:|---:|");
    for path in scene_files(&["scenes"]) {
        let scene = small(&path, 32);
        let reference = lancer_reference(&scene, 8192);
        for sampler in Sampler::ALL {
            let options = RenderOptions {
                sampler,
                ..RenderOptions::default()
            };
            let run = converge_with(&ctx, &scene, &reference, 1024, &options);
            for s in run
                .steps
                .iter()
                .filter(|s| [64, 256, 1024].contains(&s.spp))
            {
                let ratio = s.predicted_rel_mse / s.metrics.rel_mse;
                let name = Path::new(&path).file_stem().unwrap().to_string_lossy();
                println!(
                    "| {name} | {sampler} | {} | {:.3e} | {:.3e} | {ratio:.2} |",
                    s.spp, s.metrics.rel_mse, s.predicted_rel_mse
                );
                ratios.push(ratio);
                if !(0.5..=2.0).contains(&ratio) {
                    failures.push(format!(
                        "{path}, {sampler}, {} spp: ratio {ratio:.2}",
                        s.spp
                    ));
                }
            }
        }
    }
    let (lo, hi) = ratios
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &r| (lo.min(r), hi.max(r)));
    println!(
        "predicted / measured: {lo:.2} to {hi:.2} over {} runs",
        ratios.len()
    );
    assert!(failures.is_empty(), "{failures:#?}");
    assert_eq!(ctx.validation_errors(), 0);
}

/// `--target-error E` stops when the predicted relMSE reaches E; the
/// relMSE measured against a reference is then between 0.4 E and 1.5 E,
/// under every sampler: the Sobol sampler's error estimate does not
/// overstate its error, so it does not render on past the target.
#[test]
fn target_error_is_met_on_two_scenes() {
    let ctx = context();
    for (path, target) in [("scenes/cornell.toml", 2e-3), ("scenes/glass.toml", 2e-3)] {
        let mut scene = small(path, 32);
        scene.render.spp = 4096;
        let reference = lancer_reference(&small(path, 32), 8192);
        for sampler in Sampler::ALL {
            let options = RenderOptions {
                sampler,
                ..progressive()
            };
            let mut renderer = Renderer::new(&ctx, &scene, &options).unwrap();
            let out = render_with_budget(&mut renderer, Budget::Error(target), 4096, None).unwrap();
            check_finite(&out);
            let measured = rel_mse(&out.mean, &reference.mean);
            println!(
                "{path}, {sampler}: {} spp, measured relMSE {measured:.3e} for target {target:.1e} \
                 ({:.2} of it)",
                out.spp,
                measured / target
            );
            assert!(
                out.spp < 4096,
                "{path}, {sampler}: the target was not reached before --max-spp"
            );
            assert!(
                (0.4 * target..=1.5 * target).contains(&measured),
                "{path}, {sampler}: measured {measured} is not within 0.4 to 1.5 x {target}"
            );
        }
    }
    assert_eq!(ctx.validation_errors(), 0);
}

/// Seconds of the longest wave of a render, from its GPU timestamps.
fn longest_wave_seconds(out: &RenderOutput) -> f64 {
    let mut per_wave = std::collections::BTreeMap::<u32, u64>::new();
    for r in &out.stats.records {
        *per_wave.entry(r.wave).or_default() += r.gpu_ns;
    }
    per_wave.values().copied().max().unwrap_or(0) as f64 * 1e-9
}

/// `--time-limit` stops within the budget plus one wave, at a whole number
/// of samples per pixel, and the spp it reports is what the film holds.
#[test]
fn time_limit_stops_within_the_budget_plus_one_wave() {
    let ctx = context();
    let mut scene = small("scenes/cornell.toml", 32);
    scene.render.spp = 1 << 16;
    let options = RenderOptions {
        wave_size: Some(32 * 32 * 4),
        ..progressive()
    };
    let mut renderer = Renderer::new(&ctx, &scene, &options).unwrap();
    let limit = 1.0;
    let out = render_with_budget(&mut renderer, Budget::Time(limit), 1 << 16, None).unwrap();
    check_finite(&out);
    let spent = out.stats.wall_seconds;
    let wave = longest_wave_seconds(&out);
    println!(
        "{} spp in {spent:.3} s (limit {limit} s, longest wave {wave:.3} s)",
        out.spp
    );
    assert!(
        spent <= limit + wave + 0.05,
        "{spent} s for a {limit} s budget"
    );
    assert!(spent >= 0.5 * limit, "stopped far too early: {spent} s");
    assert_eq!(out.spp % 4, 0, "whole waves of 4 spp each");
    assert_eq!(out.stats.spp, out.spp);

    // The film holds exactly that many samples: the same image as a render
    // of that spp in one go
    let mut again = Renderer::new(&ctx, &scene, &options).unwrap();
    again.restart().unwrap();
    again.render_to(out.spp, None).unwrap();
    let direct = again.output().unwrap();
    let m = Metrics::compute(&out.mean, &direct.mean, 32, 32).unwrap();
    assert!(m.max_abs_diff <= 1e-5, "max difference {}", m.max_abs_diff);
    assert_eq!(ctx.validation_errors(), 0);
}

/// `lancer converge` on a 16 x 16 Cornell box.
const SMALL_CORNELL: [&str; 6] = [
    "converge",
    "scenes/cornell.toml",
    "--width",
    "16",
    "--height",
    "16",
];

/// The files `lancer converge` writes, for two settings and two seeds.
#[test]
fn converge_writes_every_file() {
    let dir = scratch("converge-files");
    let out = dir.join("study");
    let o = lancer(
        &[
            SMALL_CORNELL.as_slice(),
            &[
                "--max-spp",
                "16",
                "--reference-spp",
                "256",
                "--seeds",
                "2",
                "--vary",
                "integrator=nee,bsdf",
                "--out",
                out.to_str().unwrap(),
            ],
        ]
        .concat(),
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("converge.csv")).expect("converge.csv");
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    for column in [
        "variant",
        "seed",
        "spp",
        "render_seconds",
        "rmse",
        "rel_mse",
        "mean_bias",
        "flip",
        "predicted_rel_mse",
        "efficiency",
        "ms_intersect",
    ] {
        assert!(header.contains(&column), "no column {column} in {header:?}");
    }
    // 2 variants x 2 seeds x 5 steps (1, 2, 4, 8, 16 spp)
    assert_eq!(csv.lines().count(), 1 + 2 * 2 * 5, "{csv}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("converge.json")).unwrap())
            .expect("converge.json parses");
    assert!(json.is_object());
    for plot in ["relmse_time", "relmse_spp"] {
        let png = out.join(format!("{plot}.png"));
        let img = image::open(&png).unwrap_or_else(|e| panic!("{}: {e}", png.display()));
        assert!(img.width() >= 200 && img.height() >= 150);
        let svg = std::fs::read_to_string(out.join(format!("{plot}.svg"))).unwrap();
        assert!(
            svg.contains("<svg") && svg.trim_end().ends_with("</svg>"),
            "{plot}.svg"
        );
    }
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("integrator=bsdf"), "{stdout}");
}

/// Every file in `dir`, recursively.
fn files_in(dir: &Path) -> Vec<PathBuf> {
    match std::fs::read_dir(dir) {
        Err(_) => Vec::new(),
        Ok(entries) => entries
            .flat_map(|e| {
                let p = e.unwrap().path();
                if p.is_dir() {
                    files_in(&p)
                } else {
                    vec![p]
                }
            })
            .collect(),
    }
}

/// Bad input to `converge` is a clear error that writes nothing.
#[test]
fn converge_refuses_bad_input_before_writing() {
    let dir = scratch("converge-bad");
    let wrong_size = dir.join("wrong.exr");
    lancer::io::image_file::write_image(&wrong_size, 8, 8, &[0.5; 8 * 8 * 3]).unwrap();
    let out = dir.join("study");
    let out_s = out.to_str().unwrap();
    let base = SMALL_CORNELL;
    let cases: [(&[&str], &str); 5] = [
        (
            &["--reference", wrong_size.to_str().unwrap()],
            "the reference is 8x8 but the scene renders 16x16",
        ),
        (
            &["--reference", "no/such/ref.exr"],
            "reference image not found",
        ),
        (&["--vary", "colour=red,blue"], "unknown key \"colour\""),
        (
            &["--time-limit", "0"],
            "--time-limit must be a number of seconds above 0",
        ),
        (
            &["--time-limit=-2"],
            "--time-limit must be a number of seconds above 0",
        ),
    ];
    for (extra, message) in cases {
        let args: Vec<&str> = base
            .iter()
            .chain(extra)
            .chain(&["--out", out_s])
            .copied()
            .collect();
        let o = lancer(&args, &[]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} should fail");
        assert!(err.contains(message), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            files_in(&out).is_empty(),
            "{args:?} left {:?}",
            files_in(&out)
        );
    }
}

/// `lancer compare` as a CI golden-image check: zero error against itself,
/// finds a 5% brighter and a mirrored image, and its exit code follows
/// `--max-relmse`.
#[test]
fn compare_finds_wrong_images_and_sets_the_exit_code() {
    let ctx = context();
    let dir = scratch("compare-cli");
    let scene = small("scenes/cornell.toml", 32);
    let mut scene16 = scene.clone();
    scene16.render.spp = 64;
    let out = render(&ctx, &scene16, &RenderOptions::default());
    let (w, h) = (out.width as usize, out.height as usize);
    let image = dir.join("image.exr");
    let var = dir.join("image.var.exr");
    lancer::io::image_file::write_image(&image, 32, 32, &out.mean).unwrap();
    lancer::io::image_file::write_image(&var, 32, 32, &out.var_of_mean).unwrap();
    let brighter: Vec<f32> = out.mean.iter().map(|v| v * 1.05).collect();
    let mut mirrored = out.mean.clone();
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                mirrored[(y * w + x) * 3 + c] = out.mean[(y * w + (w - 1 - x)) * 3 + c];
            }
        }
    }
    let bright_path = dir.join("brighter.exr");
    let mirror_path = dir.join("mirrored.exr");
    lancer::io::image_file::write_image(&bright_path, 32, 32, &brighter).unwrap();
    lancer::io::image_file::write_image(&mirror_path, 32, 32, &mirrored).unwrap();

    let run = |a: &Path, extra: &[&str]| {
        let json = dir.join("c.json");
        let mut args = vec!["compare", a.to_str().unwrap(), image.to_str().unwrap()];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--json", json.to_str().unwrap()]);
        let o = lancer(&args, &[]);
        let v: serde_json::Value = std::fs::read_to_string(&json)
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or(serde_json::Value::Null);
        let _ = std::fs::remove_file(&json);
        (o, v)
    };
    let (o, v) = run(&image, &["--max-relmse", "0"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(v["metrics"]["rel_mse"], 0.0, "{v}");
    assert_eq!(v["metrics"]["rmse"], 0.0, "{v}");

    let (o, v) = run(&bright_path, &["--max-relmse", "1e-4"]);
    assert_eq!(o.status.code(), Some(1), "5% brighter must fail: {v}");
    let bias = v["metrics"]["mean_bias"].as_f64().unwrap();
    let mean: f64 = out.mean.iter().map(|&x| x as f64).sum::<f64>() / out.mean.len() as f64;
    assert!(
        (bias - 0.05 * mean).abs() <= 1e-6 * mean.max(1.0),
        "bias {bias}"
    );
    let (o, _) = run(&bright_path, &["--max-relmse", "1"]);
    assert_eq!(o.status.code(), Some(0), "a loose tolerance passes");

    let (o, v) = run(&mirror_path, &["--max-flip", "0.01"]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "the mirrored image must fail: {v}"
    );
    assert!(v["metrics"]["flip"].as_f64().unwrap() > 0.01, "{v}");
    assert_eq!(ctx.validation_errors(), 0);
}

/// Both budgets work with either integrator, every feature on, and a wave
/// that does not hold a whole number of samples per pixel: they stop at a
/// whole spp with a finite image.
#[test]
fn budgets_work_with_any_integrator_feature_set_and_wave_size() {
    let ctx = context();
    let mut scene = small("scenes/glass.toml", 32);
    scene.render.spp = 64;
    for integrator in [Integrator::Nee, Integrator::Bsdf] {
        for (all_features, wave_size) in [(false, 1000), (true, 32 * 32 * 3)] {
            let options = RenderOptions {
                integrator,
                all_features,
                wave_size: Some(wave_size),
                ..progressive()
            };
            for budget in [Budget::Time(0.3), Budget::Error(0.05)] {
                let mut renderer = Renderer::new(&ctx, &scene, &options).unwrap();
                let out = render_with_budget(&mut renderer, budget, 64, None).unwrap();
                check_finite(&out);
                let what = format!("{integrator:?} all={all_features} wave={wave_size} {budget:?}");
                assert!((1..=64).contains(&out.spp), "{what}: {} spp", out.spp);
                assert_eq!(out.stats.samples(), 32 * 32 * out.spp as u64, "{what}");
                let rays: u64 = out
                    .stats
                    .pass_rows()
                    .iter()
                    .filter(|r| r.pass == Pass::Generate)
                    .map(|r| r.rays)
                    .sum();
                assert_eq!(
                    rays,
                    32 * 32 * out.spp as u64,
                    "{what}: camera rays = samples"
                );
            }
        }
    }
    assert_eq!(ctx.validation_errors(), 0);
}

/// Issue 18 §5: a study whose error is exactly 0 (a white furnace against
/// its analytic image, 1 in every pixel) is a result: `converge` exits 0
/// and writes every file, its plots draw the zeros on the zero line
/// labelled 0, and it says that the errors were met at the first step.
/// A run that cannot write one of its files writes none of them.
#[test]
fn converge_plots_an_error_of_zero_and_writes_all_or_nothing() {
    let dir = scratch("converge-zero");
    let analytic = dir.join("analytic.exr");
    lancer::io::image_file::write_image(&analytic, 16, 16, &[1.0; 16 * 16 * 3]).unwrap();
    let out = dir.join("study");
    let args = |out: &Path| {
        [
            "converge",
            "tests/scenes/furnace.toml",
            "--width",
            "16",
            "--height",
            "16",
            "--max-spp",
            "4",
            "--reference",
            analytic.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]
        .map(String::from)
    };
    let o = lancer(&args(&out).each_ref().map(String::as_str), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("converge.json")).unwrap()).unwrap();
    let steps = json["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 3, "1, 2 and 4 spp");
    for s in steps {
        assert_eq!(s["metrics"]["rel_mse"].as_f64(), Some(0.0), "{s}");
    }
    for plot in ["relmse_time", "relmse_spp"] {
        let svg = std::fs::read_to_string(out.join(format!("{plot}.svg"))).unwrap();
        assert!(
            svg.contains("relMSE (0 is drawn on the bottom line)") && svg.contains(">\n0\n<"),
            "{plot}.svg has no zero line"
        );
        image::open(out.join(format!("{plot}.png"))).unwrap();
    }
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("relMSE 1e-3 already at the first step (1 spp"),
        "{stdout}"
    );

    // One file that cannot be written (a folder holds its name): the run is
    // refused before it renders, and no file appears
    let blocked = dir.join("blocked");
    std::fs::create_dir_all(blocked.join("relmse_spp.svg/inside")).unwrap();
    let o = lancer(&args(&blocked).each_ref().map(String::as_str), &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("is a folder"), "{}", stderr(&o));
    // Only the folder that blocks it: no CSV, JSON or plot
    assert!(files_in(&blocked).is_empty(), "{:?}", files_in(&blocked));
}

/// Issue 18 §8: `--target-error` without `--max-spp` renders up to its own
/// cap, 65,536 spp, not the scene's spp; when the cap stops it first, a
/// warning names the error reached and the cap, and `--stats-json` records
/// `target_met: false`. A target that is met records `target_met: true`
/// and warns of nothing.
#[test]
fn target_error_has_its_own_cap_and_says_when_it_stops_there() {
    let dir = scratch("target-error-cap");
    let stats = dir.join("s.json");
    let image = dir.join("x.exr");
    let run = |extra: &[&str]| {
        let args = [
            &[
                "render",
                "scenes/cornell.toml",
                "--width",
                "2",
                "--height",
                "2",
                "--max-depth",
                "3",
                "-q",
                "--out",
                image.to_str().unwrap(),
                "--stats-json",
                stats.to_str().unwrap(),
            ],
            extra,
        ]
        .concat();
        let o = lancer(&args, &[]);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
        (stderr(&o), json)
    };
    let brief = |j: &serde_json::Value| {
        let keys = [
            "spp",
            "max_spp",
            "target_error",
            "target_met",
            "predicted_rel_mse",
        ];
        keys.map(|k| format!("{k} {}", j[k])).join(", ")
    };
    // Unreachable: stops at the cap, says so
    let (e, json) = run(&["--target-error", "1e-12"]);
    assert_eq!(json["spp"].as_u64(), Some(65_536), "{}", brief(&json));
    assert_eq!(json["max_spp"].as_u64(), Some(65_536), "{}", brief(&json));
    assert_eq!(
        json["target_met"].as_bool(),
        Some(false),
        "{}",
        brief(&json)
    );
    assert_eq!(
        json["target_error"].as_f64(),
        Some(1e-12),
        "{}",
        brief(&json)
    );
    let reached = json["predicted_rel_mse"].as_f64().unwrap();
    assert!(reached > 1e-12, "{reached}");
    assert!(
        e.contains("warning: --target-error 1e-12 not met: stopped at the cap of 65536 spp")
            && e.contains(&format!("predicted relMSE {reached:.3e}")),
        "{e}"
    );
    // Reachable: met, no warning
    let (e, json) = run(&["--target-error", "0.5", "--max-spp", "4096"]);
    assert_eq!(json["target_met"].as_bool(), Some(true), "{}", brief(&json));
    assert!(json["spp"].as_u64().unwrap() < 4096, "{}", brief(&json));
    assert!(
        json["predicted_rel_mse"].as_f64().unwrap() <= 0.5,
        "{}",
        brief(&json)
    );
    assert!(!e.contains("warning"), "{e}");
}
