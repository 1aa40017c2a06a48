//! The two schedules run the same path code: the megakernel gives the
//! wavefront's image bit for bit on a CPU device (lavapipe), and to
//! rounding on a GPU (`common::kernels_disagree`), on every example and
//! test scene, with the
//! scene's features and with every feature on, with either film encoding
//! and with waves that split the image. `lancer info` names the schedule's
//! kernels.

use crate::common;

use common::*;
use lancer::render::kernels::Integrator;
use lancer::render::kernels::Pass;
use lancer::render::kernels::Schedule;
use lancer::render::{RenderOptions, RenderOutput};

/// Renders `scene` under `options` with `schedule`, and checks that the
/// dispatches were that schedule's kernels.
fn render_with(
    ctx: &lancer::Context,
    scene: &lancer::scene::Scene,
    options: &RenderOptions,
    schedule: Schedule,
) -> RenderOutput {
    let out = render(
        ctx,
        scene,
        &RenderOptions {
            schedule,
            ..options.clone()
        },
    );
    let megakernel = out
        .stats
        .records
        .iter()
        .filter(|r| r.pass == Pass::Megakernel)
        .count();
    match schedule {
        Schedule::Wavefront => assert_eq!(megakernel, 0, "the wavefront ran the megakernel"),
        Schedule::Megakernel => assert_eq!(
            megakernel,
            out.stats.records.len(),
            "the megakernel schedule ran other kernels"
        ),
    }
    out
}

/// Pixels (RGB values) whose bits differ between `a` and `b`, and the first one.
fn bit_differences(a: &[f32], b: &[f32]) -> (usize, Option<(usize, f32, f32)>) {
    assert_eq!(a.len(), b.len());
    let differ: Vec<usize> = (0..a.len())
        .filter(|&i| a[i].to_bits() != b[i].to_bits())
        .collect();
    (differ.len(), differ.first().map(|&i| (i, a[i], b[i])))
}

/// Asserts that both schedules render `file` to the same mean and variance,
/// bit for bit on a CPU device (to rounding on a GPU), and that the image
/// is not black.
fn assert_same_image(ctx: &lancer::Context, file: &str, label: &str, options: &RenderOptions) {
    let mut scene = load(file);
    scene.render.width = 24;
    scene.render.height = 24;
    scene.render.spp = 4;
    assert_same_render(ctx, &scene, file, label, options);
}

/// Asserts that both schedules render `scene` (read from `file`) to the
/// same mean and variance, bit for bit on a CPU device (to rounding on a
/// GPU, see `common::kernels_disagree`), and that the image is not black.
fn assert_same_render(
    ctx: &lancer::Context,
    scene: &lancer::scene::Scene,
    file: &str,
    label: &str,
    options: &RenderOptions,
) {
    let wave = render_with(ctx, scene, options, Schedule::Wavefront);
    let mega = render_with(ctx, scene, options, Schedule::Megakernel);
    let total: f64 = wave.mean.iter().map(|&v| f64::from(v)).sum();
    assert!(
        total > 0.0,
        "{file} ({label}): black image, nothing compared"
    );
    for (what, a, b) in [
        ("mean", &wave.mean, &mega.mean),
        ("variance", &wave.var_of_mean, &mega.var_of_mean),
        ("error estimate", &wave.error_estimate, &mega.error_estimate),
    ] {
        if let Some(how) = kernels_disagree(ctx, a, b) {
            panic!("{file} ({label}): the schedules' {what} values disagree: {how}");
        }
    }
    let (same, _) = bit_differences(&wave.mean, &mega.mean);
    println!(
        "{file} ({label}): {}, image sum {total:.6}",
        if same == 0 {
            "identical".to_string()
        } else {
            format!("{same} mean values differ by rounding")
        }
    );
}

#[test]
fn megakernel_gives_the_wavefront_image_bit_for_bit() {
    let ctx = context();
    let files = example_and_test_scenes();
    for file in &files {
        for (label, all_features) in [("scene features", false), ("all features", true)] {
            let options = RenderOptions {
                all_features,
                ..options(1 << 14)
            };
            assert_same_image(&ctx, file, label, &options);
        }
    }
}

#[test]
fn megakernel_matches_with_the_f32_film_bsdf_sampling_and_split_waves() {
    let ctx = context();
    for file in [
        "scenes/cornell.toml",
        "scenes/glass.toml",
        "scenes/dof.toml",
        "scenes/textured.toml",
    ] {
        let f32_film = RenderOptions {
            f32_film: true,
            ..options(1 << 14)
        };
        assert_same_image(&ctx, file, "f32 film", &f32_film);
        let bsdf = RenderOptions {
            integrator: Integrator::Bsdf,
            ..options(1 << 14)
        };
        assert_same_image(&ctx, file, "bsdf", &bsdf);
        // 300 paths a wave: waves start mid-image and a pixel's samples
        // span several waves
        assert_same_image(&ctx, file, "300-path waves", &options(300));
    }
}

/// A deep wave is split into runs of pixels, one command buffer each, with
/// at most as many path segments as one wavefront command buffer: the image
/// stays the wavefront's (bit for bit on a CPU device), and the megakernel runs more than
/// one dispatch per wave.
#[test]
fn deep_megakernel_waves_are_split_into_bounded_runs_with_the_same_image() {
    let ctx = context();
    for file in ["scenes/mirror.toml", "scenes/glass.toml"] {
        let mut scene = load(file);
        scene.render.max_depth = 200;
        scene.render.width = 24;
        scene.render.height = 24;
        scene.render.spp = 4;
        // 64 paths a wave, 1 sample each: runs of 64 * 16 / 200 = 5 pixels
        let deep = options(64);
        assert_same_render(&ctx, &scene, file, "depth 200, 64-path waves", &deep);
        let mega = render_with(
            &ctx,
            &scene,
            &RenderOptions {
                schedule: Schedule::Megakernel,
                ..deep.clone()
            },
            Schedule::Megakernel,
        );
        let waves = mega.stats.waves as usize;
        assert_eq!(waves, 24 * 24 * 4 / 64);
        assert_eq!(mega.stats.records.len(), waves * 64usize.div_ceil(5));
    }
}

/// `lancer info --schedule megakernel` lists the one kernel and its
/// specialisation constants; the default is the wavefront's passes.
#[test]
fn info_lists_the_schedules_kernels() {
    let info = |args: &[&str]| {
        let out = lancer(&[&["info", "scenes/cornell.toml"], args].concat(), &[]);
        assert!(out.status.success(), "{}", stderr(&out));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let mega = info(&["--schedule", "megakernel"]);
    assert!(mega.contains("\nschedule: megakernel\n"), "{mega}");
    assert!(mega.contains("\npasses: megakernel\n"), "{mega}");
    assert!(mega.contains("\n  megakernel  HAS_SPHERES="), "{mega}");
    let default = info(&[]);
    assert!(default.contains("\nschedule: wavefront\n"), "{default}");
    assert!(
        default.contains("\npasses: generate -> intersect -> shade -> shadow -> accumulate\n"),
        "{default}"
    );
    let bad = lancer(&["info", "scenes/cornell.toml", "--schedule", "fused"], &[]);
    assert!(!bad.status.success());
    assert!(stderr(&bad).contains("megakernel"), "{}", stderr(&bad));
}

/// The megakernel keeps path state in registers: its device memory does
/// not grow with the wave, the wavefront's grows by the path state and
/// queues of every path in flight.
#[test]
fn megakernel_memory_does_not_grow_with_the_wave() {
    let ctx = context();
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 64;
    scene.render.height = 64;
    scene.render.spp = 64;
    let bytes = |schedule, wave_size| {
        let options = RenderOptions {
            schedule,
            ..options(wave_size)
        };
        lancer::Renderer::new(&ctx, &scene, &options)
            .expect("renderer")
            .scene_info
            .device_bytes
    };
    let (mega_small, mega_big) = (
        bytes(Schedule::Megakernel, 1 << 12),
        bytes(Schedule::Megakernel, 1 << 18),
    );
    let (wave_small, wave_big) = (
        bytes(Schedule::Wavefront, 1 << 12),
        bytes(Schedule::Wavefront, 1 << 18),
    );
    println!("device bytes, waves of 4096 and 262144 paths: megakernel {mega_small} {mega_big}, wavefront {wave_small} {wave_big}");
    assert_eq!(mega_small, mega_big);
    assert!(wave_big > wave_small && mega_big < wave_small);
    // Per path in flight the wavefront holds seven vec4s of path and shadow
    // ray state, a 16-byte hit, two ray queue entries and a shadow queue entry
    assert_eq!(
        wave_big - wave_small,
        ((1 << 18) - (1 << 12)) * (7 * 16 + 16 + 3 * 4)
    );
}

/// The lights and integrators of Mitsuba's XML scenes (delta lights,
/// `direct` with and without BSDF samples, `hide_emitters`, an environment
/// map): both schedules
/// give the same image, with the scene's features and with all of them.
#[test]
fn megakernel_gives_the_wavefront_image_with_lights_and_integrators() {
    let ctx = context();
    for name in [
        "point",
        "spot",
        "spot_texture",
        "projector",
        "directional",
        "direct",
        "direct_emitter_only",
        "hide_emitters",
        "envmap",
    ] {
        let file = format!("tests/scenes/mitsuba/{name}.xml");
        for (label, all_features) in [("scene features", false), ("all features", true)] {
            let options = RenderOptions {
                all_features,
                ..options(1 << 14)
            };
            assert_same_image(&ctx, &file, label, &options);
        }
    }
}

/// Rough dielectrics (refraction, and next-event estimation through the
/// surface), smooth plastics (a delta and a diffuse lobe) and rough
/// plastics (a glossy and a diffuse lobe, the coating's table), thin
/// dielectrics (a delta reflection and a pass straight through), masks
/// (a pass straight through where the surface is not met) and normal maps
/// (tilted shading frames), mesh attributes (values interpolated at the
/// hit) and principled weights from textures (lobe probabilities computed
/// at the hit): both schedules give the same image, with the scene's
/// features and with all of them.
#[test]
fn megakernel_gives_the_wavefront_image_with_rough_dielectrics_and_plastics() {
    let ctx = context();
    for file in [
        "tests/scenes/mitsuba/roughdielectric.xml",
        "tests/scenes/mitsuba/plastic.xml",
        "tests/scenes/mitsuba/roughplastic.xml",
        "tests/scenes/mitsuba/thindielectric.xml",
        "tests/scenes/mitsuba/mask.xml",
        "tests/scenes/mitsuba/normalmap.xml",
        "tests/scenes/mitsuba/bumpmap.xml",
        "tests/scenes/mitsuba/mesh_attribute.xml",
        "tests/scenes/mitsuba/principled_textured.xml",
    ] {
        for (label, all_features) in [("scene features", false), ("all features", true)] {
            let options = RenderOptions {
                all_features,
                ..options(1 << 14)
            };
            assert_same_image(&ctx, file, label, &options);
        }
    }
}
