//! Simulate only what the scene calls for: the features a scene turns on
//! change which code and passes run, never the image.

use crate::common;

use common::*;
use lancer::analysis::ztest::z_test;
use lancer::render::kernels::Integrator;
use lancer::render::kernels::Pass;
use lancer::render::{RenderOptions, RenderOutput};

/// Renders `scene` with `integrator` twice: with the kernels its features
/// call for, and with every feature forced on.
fn lean_and_full(
    ctx: &lancer::Context,
    scene: &lancer::Scene,
    integrator: Integrator,
) -> (RenderOutput, RenderOutput) {
    let base = RenderOptions {
        integrator,
        ..options(1 << 14)
    };
    let lean = render(ctx, scene, &base);
    let full = render(
        ctx,
        scene,
        &RenderOptions {
            all_features: true,
            ..base
        },
    );
    (lean, full)
}

/// With every feature forced on, each scene renders the same image, up to
/// float rounding: every pixel within 1e-4 relative, for the same seed.
#[test]
fn all_features_gives_the_same_image_for_every_scene() {
    let ctx = context();
    let files = example_and_test_scenes();
    for file in &files {
        let mut scene = load(file);
        scene.render.width = 24;
        scene.render.height = 24;
        scene.render.spp = 4;
        for integrator in [Integrator::Nee, Integrator::Bsdf] {
            let (lean, full) = lean_and_full(&ctx, &scene, integrator);
            let mut worst = 0.0f32;
            for (a, b) in lean.mean.iter().zip(&full.mean) {
                let scale = a.abs().max(b.abs());
                let rel = if scale > 0.0 {
                    (a - b).abs() / scale
                } else {
                    0.0
                };
                worst = worst.max(rel);
            }
            println!("{file} ({integrator:?}): worst relative pixel difference {worst:e}");
            assert!(
                worst <= 1e-4,
                "{file} ({integrator:?}): --all-features changes a pixel by {worst:e} relative"
            );
        }
    }
}

/// Runs `lancer info` and returns the line listing the passes.
fn passes(args: &[&str]) -> String {
    let out = lancer(&[&["info"], args].concat(), &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    stdout
        .lines()
        .find(|l| l.starts_with("passes:"))
        .unwrap_or_else(|| panic!("no passes line:\n{stdout}"))
        .to_string()
}

/// A scene with emitters records a shadow pass; one without, or the plain
/// BSDF estimator, does not.
#[test]
fn info_lists_the_shadow_pass_only_where_it_runs() {
    let with_emitters = passes(&["scenes/cornell.toml"]);
    assert_eq!(
        with_emitters,
        "passes: generate -> intersect -> shade -> shadow -> accumulate"
    );
    let without_emitters = passes(&["tests/scenes/furnace.toml"]);
    assert_eq!(
        without_emitters,
        "passes: generate -> intersect -> shade -> accumulate"
    );
    let bsdf = passes(&["scenes/cornell.toml", "--integrator", "bsdf"]);
    assert_eq!(bsdf, "passes: generate -> intersect -> shade -> accumulate");
    let forced = passes(&["tests/scenes/furnace.toml", "--all-features"]);
    assert_eq!(
        forced,
        "passes: generate -> intersect -> shade -> shadow -> accumulate"
    );
}

/// The renderer records no shadow dispatch when the scene has no emitter.
#[test]
fn no_shadow_dispatch_without_emitters() {
    let ctx = context();
    let mut scene = load("tests/scenes/furnace.toml");
    scene.render.width = 16;
    scene.render.height = 16;
    let out = render(&ctx, &scene, &options(1 << 14));
    let passes: std::collections::BTreeSet<_> = out.stats.records.iter().map(|r| r.pass).collect();
    assert!(!passes.contains(&Pass::Shadow), "{passes:?}");
    assert!(passes.contains(&Pass::Shade) && passes.contains(&Pass::Intersect));
}

/// Renders `scene` with NEE at `nee_spp` and with BSDF sampling only at
/// `bsdf_spp`, asserts that the two agree by the z-test on 4x4 blocks, and
/// returns both renders.
///
/// Blocks, not pixels: in the darkest pixels BSDF sampling may find a small
/// light in none of its samples and report 0 with zero variance, a heavy
/// tail that a per-pixel variance cannot show. Blocks pool 16 times the
/// samples, and a block that still found no light is given the variance
/// that bounded samples of the other render's mean may have.
fn assert_estimators_agree(
    label: &str,
    mut scene: lancer::scene::Scene,
    nee_spp: u32,
    bsdf_spp: u32,
) -> (RenderOutput, RenderOutput) {
    let ctx = context();
    let side = scene.render.width as usize;
    assert_eq!(scene.render.height as usize, side, "square images only");
    scene.render.spp = nee_spp;
    let nee = render(&ctx, &scene, &options(1 << 18));
    scene.render.spp = bsdf_spp;
    let bsdf = render(
        &ctx,
        &scene,
        &RenderOptions {
            integrator: Integrator::Bsdf,
            ..options(1 << 18)
        },
    );
    const BLOCK: usize = 4;
    let (_, _, nee_mean, mut nee_var) =
        block_average(side, side, &nee.mean, &nee.var_of_mean, BLOCK);
    let (_, _, bsdf_mean, mut bsdf_var) =
        block_average(side, side, &bsdf.mean, &bsdf.var_of_mean, BLOCK);
    // A block whose every sample gave the same value (none found the light)
    // has a sample variance of 0, which is not its estimate's variance.
    // Samples in [0, M] with mean μ vary by at most μ (M - μ)
    // (Bhatia-Davis): bound such a block by the other render's mean, M the
    // brightest emission (every BSDF here reflects at most what it receives,
    // so a path's weight is at most 1)
    let brightest = scene.materials.iter().fold([0.0f64; 3], |m, mat| {
        let e = mat.emission.to_array();
        std::array::from_fn(|c| m[c].max(f64::from(e[c])))
    });
    let floor = |var: &mut [f32], other: &[f32], samples: u32| {
        for (i, v) in var.iter_mut().enumerate() {
            if *v == 0.0 {
                let mu = f64::from(other[i]).max(0.0);
                let m = brightest[i % 3];
                let n = (BLOCK * BLOCK) as f64 * f64::from(samples);
                *v = (mu * (m - mu).max(0.0) / n) as f32;
            }
        }
    };
    floor(&mut nee_var, &bsdf_mean, nee_spp);
    floor(&mut bsdf_var, &nee_mean, bsdf_spp);
    let z = z_test(&nee_mean, &nee_var, &bsdf_mean, &bsdf_var, 0.01);
    println!("{label}, nee ({nee_spp} spp) vs bsdf ({bsdf_spp} spp), {BLOCK}x{BLOCK} blocks: {z}");
    assert!(
        z.pass_fraction >= 0.995 && z.mean_rel_diff.abs() <= 0.01,
        "{label}: {z}"
    );
    (nee, bsdf)
}

/// Next-event estimation with MIS and plain BSDF sampling converge to the
/// same image on the Cornell box's small light, and NEE has the lower
/// variance.
#[test]
fn nee_and_bsdf_estimators_agree() {
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 32;
    scene.render.height = 32;
    scene.render.max_depth = 4;
    let (nee, bsdf) = assert_estimators_agree("Cornell box", scene, 256, 2048);
    // NEE must be the better estimator here: lower variance per sample.
    let per_sample =
        |o: &RenderOutput| o.var_of_mean.iter().map(|&x| x as f64).sum::<f64>() * o.spp as f64;
    let (v_nee, v_bsdf) = (per_sample(&nee), per_sample(&bsdf));
    println!("summed per-sample variance: nee {v_nee:.4}, bsdf {v_bsdf:.4}");
    assert!(
        v_nee < v_bsdf,
        "NEE should have lower variance per sample: {v_nee} vs {v_bsdf}"
    );
}

/// The same comparison with a small spherical light: cone sampling of the
/// sphere, its solid-angle pdf and the MIS weights of both strategies.
#[test]
fn nee_and_bsdf_agree_with_a_sphere_light() {
    let scene = load("tests/scenes/sphere_light.toml");
    assert_estimators_agree("sphere light", scene, 256, 4096);
}

/// Scenes with an environment map (`HAS_ENVMAP`), rough dielectrics,
/// smooth and rough plastics, thin dielectrics, mapped textures
/// (`HAS_TEX_MAPPING`), an orthographic camera (`HAS_ORTHO`), masks
/// (`HAS_MASK`) and normal and bump maps (`HAS_NORMAL_MAP`) render the same image,
/// bit for bit, with every feature forced on, under both estimators.
#[test]
fn all_features_keep_the_envmap_rough_dielectric_and_plastic_images_bit_for_bit() {
    let ctx = context();
    for file in [
        "envmap",
        "roughdielectric",
        "plastic",
        "roughplastic",
        "thindielectric",
        "texture_mapping",
        "orthographic",
        "mask",
        "normalmap",
        "bumpmap",
    ] {
        for integrator in [Integrator::Nee, Integrator::Bsdf] {
            let mut scene = load(&format!("tests/scenes/mitsuba/{file}.xml"));
            scene.render.width = 24;
            scene.render.height = 24;
            scene.render.spp = 4;
            let (lean, full) = lean_and_full(&ctx, &scene, integrator);
            let differ = differing_bits(&lean.mean, &full.mean);
            let total: f64 = lean.mean.iter().map(|&v| f64::from(v)).sum();
            println!("{file} ({integrator:?}): {differ} values differ, image sum {total:.6}");
            assert!(total > 0.0, "{file}: black image, nothing compared");
            assert_eq!(
                differ, 0,
                "{file} ({integrator:?}): --all-features changes {differ} values"
            );
        }
    }
}

/// The kernels specialised on the CPU before the driver sees them
/// (`lancer::render::specialise`) render every pixel exactly as the kernels
/// the driver specialises itself, under both schedules. Between them the
/// scenes turn on every feature the kernels have: spheres, textures, depth
/// of field, filters and clip planes, delta lights and hidden emitters,
/// environment maps, Mitsuba's material sides, crop windows, film edges,
/// texture mappings, orthographic cameras, masks, normal and bump maps,
/// and every material.
#[test]
fn kernels_specialised_on_the_cpu_render_the_same_pixels() {
    let scenes = [
        "scenes/cornell.toml",
        "scenes/glass.toml",
        "tests/scenes/dof.toml",
        "tests/scenes/filter_clip.toml",
        "tests/scenes/delta_lights.toml",
        "tests/scenes/textured.toml",
        "tests/scenes/mitsuba/envmap.xml",
        "tests/scenes/mitsuba/hide_emitters.xml",
        "tests/scenes/mitsuba/crop.xml",
        "tests/scenes/mitsuba/film_edge.xml",
        "tests/scenes/mitsuba/texture_mapping.xml",
        "tests/scenes/mitsuba/orthographic.xml",
        "tests/scenes/mitsuba/mask.xml",
        "tests/scenes/mitsuba/bumpmap.xml",
        "tests/scenes/mitsuba/roughplastic.xml",
        "tests/scenes/mitsuba/roughdielectric.xml",
        "tests/scenes/mitsuba/thindielectric.xml",
    ];
    let dir = scratch("specialised_kernels");
    for (i, scene) in scenes.iter().enumerate() {
        // The megakernel for every other scene
        let schedule = if i % 2 == 0 {
            "wavefront"
        } else {
            "megakernel"
        };
        let mut images = Vec::new();
        for setting in ["off", "on"] {
            let out = dir.join(format!("{i}_{setting}.exr"));
            let out_arg = out.to_str().unwrap();
            let run = lancer(
                &[
                    "render",
                    scene,
                    "--spp",
                    "2",
                    "--schedule",
                    schedule,
                    "--out",
                    out_arg,
                    "-q",
                ],
                &[(lancer::render::kernels::KERNEL_SPECIALISATION_ENV, setting)],
            );
            assert!(
                run.status.success(),
                "{scene}: {}",
                String::from_utf8_lossy(&run.stderr)
            );
            images.push(lancer::io::image_file::read_image(&out).unwrap());
        }
        let (a, b) = (&images[0], &images[1]);
        assert_eq!((a.0, a.1), (b.0, b.1));
        let same =
            a.2.iter()
                .zip(&b.2)
                .all(|(x, y)| x.to_bits() == y.to_bits());
        assert!(
            same,
            "{scene} ({schedule}): the specialised kernels changed pixels"
        );
    }
}
