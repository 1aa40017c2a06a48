//! Statistical comparison against images made by an independent renderer
//! (Mitsuba 3; see tools/mitsuba_reference.py): a z-test with Šidák
//! correction at alpha = 0.01, as in Mitsuba 3's render tests, on 2x2 pixel
//! blocks rather than single pixels, with a variance estimate for lancer that
//! is robust to heavy-tailed samples (see [`compare`]).
//!
//! When a comparison fails, the test writes a per-pixel z-map PNG and lancer's
//! mean and variance EXRs into `CARGO_TARGET_TMPDIR` and prints their paths.
//!
//! The Cornell box and the stored test scenes are checked under every
//! sampler. lancer's variance of the mean (sample variance / spp) overstates
//! the error of the Sobol sampler's stratified samples, which makes the
//! z-test more lenient there; the mean criterion, and the wrong images that
//! must fail, keep it honest.

mod common;

use common::*;
use lancer::analysis::ztest::{z_test, ZTest};
use lancer::render::kernels::Sampler;
use lancer::render::{RenderOptions, RenderOutput};
use lancer::scene::Scene;

/// Share of blocks that must pass the z-test.
const MIN_PASS_FRACTION: f64 = 0.995;
/// Largest relative difference of the image means.
const MAX_MEAN_REL_DIFF: f64 = 0.01;
/// Side, in pixels, of the square blocks the z-test compares.
const BLOCK: usize = 2;

/// A mean image and the variance of each value of it, interleaved RGB.
#[derive(Clone)]
struct Estimate {
    width: usize,
    height: usize,
    mean: Vec<f32>,
    var: Vec<f32>,
}

impl Estimate {
    /// Averages `k` x `k` pixel blocks: the block mean is the mean of its
    /// pixels, and its variance is the sum of theirs over n² (the pixels'
    /// estimates are independent). Blocks cut by the right or bottom edge
    /// average the pixels they have.
    fn blocks(&self, k: usize) -> Estimate {
        let (width, height, mean, var) =
            block_average(self.width, self.height, &self.mean, &self.var, k);
        Estimate {
            width,
            height,
            mean,
            var,
        }
    }

    /// Raises each variance to the median of its 3 x 3 neighbourhood (the
    /// neighbours inside the image, itself included), per channel.
    fn variance_floored_by_neighbours(&self) -> Estimate {
        let (w, h) = (self.width as isize, self.height as isize);
        let mut var = self.var.clone();
        let mut around = Vec::with_capacity(9);
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    around.clear();
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let (nx, ny) = (x + dx, y + dy);
                            if (0..w).contains(&nx) && (0..h).contains(&ny) {
                                around.push(self.var[3 * (ny * w + nx) as usize + c]);
                            }
                        }
                    }
                    around.sort_by(f32::total_cmp);
                    let i = 3 * (y * w + x) as usize + c;
                    var[i] = var[i].max(around[around.len() / 2]);
                }
            }
        }
        Estimate {
            var,
            ..self.clone()
        }
    }

    /// The image mirrored left to right.
    fn mirrored(&self) -> Estimate {
        let flip = |img: &[f32]| -> Vec<f32> {
            img.chunks(3 * self.width)
                .flat_map(|row| row.chunks(3).rev().flatten().copied().collect::<Vec<_>>())
                .collect()
        };
        Estimate {
            mean: flip(&self.mean),
            var: flip(&self.var),
            ..self.clone()
        }
    }

    /// The image of a scene whose every emitter is `s` times brighter:
    /// radiance is linear in emission (light selection goes by relative
    /// power), so with the same seed every sample scales by `s`.
    fn scaled(&self, s: f32) -> Estimate {
        Estimate {
            mean: self.mean.iter().map(|v| v * s).collect(),
            var: self.var.iter().map(|v| v * s * s).collect(),
            ..self.clone()
        }
    }
}

/// Lancer's output as an [`Estimate`].
fn estimate(out: &RenderOutput) -> Estimate {
    Estimate {
        width: out.width as usize,
        height: out.height as usize,
        mean: out.mean.clone(),
        var: out.var_of_mean.clone(),
    }
}

/// Reads a stored reference: the mean and the variance of the mean.
fn reference(name: &str) -> Estimate {
    let (w, h, mean) =
        lancer::io::image_file::read_exr(&repo(&format!("tests/reference/{name}.exr")))
            .expect("reference mean");
    let (_, _, var) =
        lancer::io::image_file::read_exr(&repo(&format!("tests/reference/{name}.var.exr")))
            .expect("reference variance");
    Estimate {
        width: w as usize,
        height: h as usize,
        mean,
        var,
    }
}

/// Compares a render with a reference.
///
/// The verdict is a z-test on 2x2 blocks, in which lancer's variance of each
/// block mean is at least the median of those of the 3x3 blocks around it.
/// Why not the plain per-pixel test: lancer's per-pixel variance is the
/// sample variance of its 512 to 1024 samples. Where the samples are heavy
/// tailed (caustics that only BSDF sampling finds, Russian roulette's 1/q
/// weights, pixels that a blurred edge reaches with a few samples in a
/// thousand), that estimate is unbiased on average but small exactly in the
/// pixels that drew none of the rare large samples, and those pixels also
/// have a low mean: they fail with large negative z although lancer agrees
/// with Mitsuba at high spp (dielectric at 16384 spp, dof at 8192 spp: every
/// pixel passes). Blocks quadruple the samples per tested value; the
/// neighbourhood median gives each block a variance that does not depend on
/// its own luck, and, being a median, does not leak the large variance of an
/// edge (a light's outline) into the blocks beside it. Raising the variance
/// can only make blocks pass, so each test also checks that a mirrored image
/// and a 5% brighter light fail.
///
/// The per-pixel test on lancer's raw variance is returned too, for
/// information.
fn compare(test: &Estimate, reference: &Estimate) -> (ZTest, ZTest) {
    let a = test.blocks(BLOCK).variance_floored_by_neighbours();
    let b = reference.blocks(BLOCK);
    let blocks = z_test(&a.mean, &a.var, &b.mean, &b.var, 0.01);
    let pixels = z_test(&test.mean, &test.var, &reference.mean, &reference.var, 0.01);
    (blocks, pixels)
}

/// Tells whether a comparison passes both criteria.
fn passes(z: &ZTest) -> bool {
    z.pass_fraction >= MIN_PASS_FRACTION && z.mean_rel_diff.abs() <= MAX_MEAN_REL_DIFF
}

/// Signed z-score of the channel with the largest |z| in each pixel:
/// (test - reference) / sqrt(var_test + var_ref).
fn z_scores(test: &Estimate, reference: &Estimate) -> Vec<f64> {
    test.mean
        .chunks(3)
        .zip(test.var.chunks(3))
        .zip(reference.mean.chunks(3).zip(reference.var.chunks(3)))
        .map(|((a, va), (b, vb))| {
            (0..3)
                .map(|c| {
                    let v = f64::from(va[c]).max(0.0) + f64::from(vb[c]).max(0.0);
                    let d = f64::from(a[c]) - f64::from(b[c]);
                    if v > 0.0 {
                        d / v.sqrt()
                    } else if d == 0.0 {
                        0.0
                    } else {
                        d.signum() * f64::INFINITY
                    }
                })
                .fold(0.0f64, |z, zc| {
                    if zc.abs() > z.abs() || zc.is_nan() {
                        zc
                    } else {
                        z
                    }
                })
        })
        .collect()
}

/// |z| of one channel at which a value fails the test `z` made: its p times
/// 3 (Bonferroni over the channels) falls below the per-value threshold.
fn z_threshold(z: &ZTest) -> f64 {
    let target = z.alpha_per_pixel / 3.0;
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if lancer::analysis::ztest::erfc(mid / std::f64::consts::SQRT_2) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Writes, for a failed comparison, the per-pixel z-map of lancer's raw
/// variance as a PNG (red: lancer brighter, blue: lancer darker, full at
/// |z| >= 8; a green tint marks the pixels beyond the per-pixel test's
/// threshold), and lancer's mean and variance of the mean as EXR, into the
/// test's temporary folder, and prints the paths.
fn dump_failure(name: &str, test: &Estimate, reference: &Estimate, per_pixel: &ZTest) {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let z_fail = z_threshold(per_pixel);
    let zmap: Vec<f32> = z_scores(test, reference)
        .iter()
        .flat_map(|&zv| {
            let m = (zv.abs() / 8.0).min(1.0) as f32;
            let g = if zv.abs() >= z_fail || zv.is_nan() {
                0.25
            } else {
                0.0
            };
            if zv > 0.0 {
                [m, g, 0.0]
            } else {
                [0.0, g, m]
            }
        })
        .collect();
    let (w, h) = (test.width as u32, test.height as u32);
    let files = [
        (dir.join(format!("{name}.zmap.png")), zmap),
        (dir.join(format!("{name}.lancer.exr")), test.mean.clone()),
        (dir.join(format!("{name}.lancer.var.exr")), test.var.clone()),
    ];
    for (path, img) in &files {
        match lancer::io::image_file::write_image(path, w, h, img) {
            Ok(()) => println!("{name}: wrote {}", path.display()),
            Err(e) => println!("{name}: could not write {}: {e:#}", path.display()),
        }
    }
    println!("{name}: per-pixel |z| threshold per channel {z_fail:.2}");
}

/// Compares lancer with the reference, prints both tests, dumps the images
/// when the verdict fails, and asserts that it passes.
fn assert_matches(name: &str, test: &Estimate, reference: &Estimate) {
    let (z, z_px) = compare(test, reference);
    println!("{name}: lancer vs Mitsuba 3, {BLOCK}x{BLOCK} blocks: {z}");
    println!("{name}: per pixel (information only): {z_px}");
    if !passes(&z) {
        dump_failure(name, test, reference, &z_px);
    }
    assert!(
        passes(&z),
        "{name} differs from the Mitsuba reference ({BLOCK}x{BLOCK} blocks): {z}"
    );
}

/// Asserts that a mirrored image fails, and that a 5% brighter light fails
/// the z-test on its own, without the image-mean criterion.
fn assert_wrong_images_fail(name: &str, test: &Estimate, reference: &Estimate) {
    let (z_mirrored, _) = compare(&test.mirrored(), reference);
    println!("{name}: mirrored: {z_mirrored}");
    assert!(
        !passes(&z_mirrored),
        "{name}: a mirrored image passed: {z_mirrored}"
    );
    let (z_bright, _) = compare(&test.scaled(1.05), reference);
    println!("{name}: 5% brighter light: {z_bright}");
    assert!(
        z_bright.pass_fraction < MIN_PASS_FRACTION,
        "{name}: a 5% brighter light passed the z-test: {z_bright}"
    );
}

/// Default options, with `sampler`.
fn sampling(sampler: Sampler) -> RenderOptions {
    RenderOptions {
        sampler,
        ..options(1 << 18)
    }
}

/// Renders the Cornell box at the reference's size with the default sampler.
fn cornell(scene: &Scene, w: usize, h: usize) -> RenderOutput {
    cornell_with(scene, w, h, Sampler::default())
}

/// Renders the Cornell box at the reference's size with `sampler`.
fn cornell_with(scene: &Scene, w: usize, h: usize, sampler: Sampler) -> RenderOutput {
    let mut scene = scene.clone();
    scene.render.width = w as u32;
    scene.render.height = h as u32;
    scene.render.spp = 1024;
    let ctx = context();
    render(&ctx, &scene, &sampling(sampler))
}

#[test]
fn cornell_box_matches_mitsuba_and_wrong_images_fail() {
    let reference = reference("cornell");
    let scene = load("scenes/cornell.toml");
    let (w, h) = (reference.width, reference.height);
    for sampler in Sampler::ALL {
        let name = format!("cornell.{sampler}");
        let out = estimate(&cornell_with(&scene, w, h, sampler));
        assert_matches(&name, &out, &reference);
        // The Cornell box also passes the plain per-pixel test, as Mitsuba 3's
        // render tests run it: no heavy-tailed pixels here.
        let (_, z_px) = compare(&out, &reference);
        assert!(passes(&z_px), "{name}, per-pixel z-test: {z_px}");

        // A mirrored image must fail: the red wall is on the wrong side.
        let (z_mirrored, _) = compare(&out.mirrored(), &reference);
        println!("{name}: mirrored: {z_mirrored}");
        assert!(
            !passes(&z_mirrored),
            "{name}: a mirrored image passed: {z_mirrored}"
        );

        // A light 5% brighter, rendered, must fail.
        let mut brighter = scene.clone();
        for m in &mut brighter.materials {
            m.emission *= 1.05;
        }
        let out_bright = estimate(&cornell_with(&brighter, w, h, sampler));
        let (z_bright, _) = compare(&out_bright, &reference);
        println!("{name}: 5% brighter light: {z_bright}");
        assert!(
            !passes(&z_bright),
            "{name}: a 5% brighter light passed: {z_bright}"
        );
    }
}

#[test]
fn cornell_xml_matches_mitsuba_and_the_toml_scene() {
    // scenes/cornell.xml is the Mitsuba 3 scene tools/mitsuba_reference.py
    // builds from scenes/cornell.toml, written by hand (rectangles, a cube
    // and an OBJ); lancer reads it through its own XML loader.
    let reference = reference("cornell");
    let (w, h) = (reference.width, reference.height);
    let out = estimate(&cornell(&load("scenes/cornell.xml"), w, h));
    assert_matches("cornell_xml", &out, &reference);
    // Against lancer's render of the TOML scene, with another seed so that
    // the two estimates are independent.
    let mut toml = load("scenes/cornell.toml");
    toml.render.seed = 1;
    let twin = estimate(&cornell(&toml, w, h));
    assert_matches("cornell_xml_vs_toml", &out, &twin);
}

/// Renders a stored test scene at its reference's size under every
/// sampler, z-tests it, and checks that a mirrored image and a 5% brighter
/// light fail.
fn check_against_reference(name: &str, spp: u32) {
    let reference = reference(name);
    let mut scene = load(&format!("tests/scenes/{name}.toml"));
    scene.render.width = reference.width as u32;
    scene.render.height = reference.height as u32;
    scene.render.spp = spp;
    let ctx = context();
    for sampler in Sampler::ALL {
        let label = format!("{name}.{sampler}");
        let out = estimate(&render(&ctx, &scene, &sampling(sampler)));
        assert_matches(&label, &out, &reference);
        assert_wrong_images_fail(&label, &out, &reference);
    }
}

/// Mirror: Mitsuba's `conductor` with material `none`.
#[test]
fn mirror_sphere_matches_mitsuba() {
    check_against_reference("mirror", 1024);
}

/// Glass: Mitsuba's `dielectric`.
#[test]
fn dielectric_sphere_matches_mitsuba() {
    check_against_reference("dielectric", 1024);
}

/// Textured Lambert on a quad and an OBJ with `vt`: Mitsuba's `bitmap`.
#[test]
fn textured_lambert_matches_mitsuba() {
    check_against_reference("textured", 256);
}

/// Depth of field: Mitsuba's `thinlens`.
#[test]
fn depth_of_field_matches_mitsuba() {
    check_against_reference("dof", 512);
}

/// The block statistic on synthetic data: an image with Bernoulli-like
/// heavy-tailed noise, whose per-pixel variance estimate fails the plain
/// per-pixel test, passes on blocks; a real bias still fails.
#[test]
fn block_statistic_on_synthetic_images() {
    let (w, h) = (32usize, 32usize);
    let flat = |v: f32| vec![v; w * h * 3];
    // Reference: exact 1.0 with a small variance.
    let reference = Estimate {
        width: w,
        height: h,
        mean: flat(1.0),
        var: flat(1e-4),
    };
    // A test image in which a few pixels drew no rare sample: low mean and
    // tiny variance, with neighbours that show the true variance.
    let mut test = Estimate {
        width: w,
        height: h,
        mean: flat(1.0),
        var: flat(1e-3),
    };
    for &(x, y) in &[(3usize, 4usize), (20, 9), (11, 27)] {
        for c in 0..3 {
            test.mean[3 * (y * w + x) + c] = 0.9;
            test.var[3 * (y * w + x) + c] = 1e-6;
        }
    }
    let (z, z_px) = compare(&test, &reference);
    assert_eq!(z_px.passed, w * h - 3, "{z_px}");
    assert_eq!(z.passed, z.pixels, "{z}");
    // Blocks are 2x2: 16x16 of them, each the mean of its 4 pixels.
    assert_eq!(z.pixels, (w / 2) * (h / 2));
    // A uniform 20% bias fails everywhere.
    let (z_biased, _) = compare(&test.scaled(1.2), &reference);
    assert_eq!(z_biased.passed, 0, "{z_biased}");
    // Odd sizes keep the partial blocks.
    let odd = Estimate {
        width: 3,
        height: 1,
        mean: vec![1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 4.0, 4.0, 4.0],
        var: vec![1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
    }
    .blocks(2);
    assert_eq!((odd.width, odd.height), (2, 1));
    assert_eq!(odd.mean, vec![1.5, 1.5, 1.5, 4.0, 4.0, 4.0]);
    assert_eq!(odd.var, vec![0.5, 0.5, 0.5, 2.0, 2.0, 2.0]);
}

/// Renders XML scene `tests/scenes/mitsuba/NAME.xml` (lights and
/// integrators as Mitsuba defines them) at `spp`, changed by `change`, and
/// returns lancer's estimate with Mitsuba's own render of the unedited file
/// (`tests/reference/mitsuba/NAME.*`, made by
/// `tools/mitsuba_xml_reference.py`).
fn xml_scene(name: &str, spp: u32, change: impl FnOnce(&mut Scene)) -> (Estimate, Estimate) {
    let reference = reference(&format!("mitsuba/{name}"));
    let mut scene = load(&format!("tests/scenes/mitsuba/{name}.xml"));
    scene.render.spp = spp;
    change(&mut scene);
    let out = estimate(&render(&context(), &scene, &options(1 << 18)));
    (out, reference)
}

/// z-tests the XML scene against Mitsuba; a mirrored image and a 5%
/// brighter light fail; so does the scene changed by `without`, which
/// removes the effect under test (when the effect shows, the test sees it).
fn check_xml_against_reference(name: &str, spp: u32, without: impl FnOnce(&mut Scene)) {
    let (out, reference) = xml_scene(name, spp, |_| {});
    assert_matches(name, &out, &reference);
    assert_wrong_images_fail(name, &out, &reference);
    let (other, _) = xml_scene(name, spp / 4, without);
    let (z, _) = compare(&other, &reference);
    println!("{name}: without the effect: {z}");
    assert!(
        !passes(&z),
        "{name}: the scene without the effect passed: {z}"
    );
}

/// Point lights by `position` and by `to_world`; without the second light
/// the image fails.
#[test]
fn point_lights_match_mitsuba() {
    check_xml_against_reference("point", 512, |s| {
        s.lights.pop();
    });
}

/// Spot lights, one stretched by a non-uniform scale; with the falloff
/// removed (beam width = cutoff angle) the image fails.
#[test]
fn spot_lights_match_mitsuba() {
    check_xml_against_reference("spot", 512, |s| {
        for light in &mut s.lights {
            if let lancer::scene::DeltaLight::Spot {
                cutoff_deg,
                beam_width_deg,
                ..
            } = light
            {
                *beam_width_deg = *cutoff_deg;
            }
        }
    });
}

/// Directional lights by `direction` and by `to_world`, with hard shadows;
/// with the shadow rays cut short (the lights turned into point lights 100
/// units away, no longer parallel) the image fails.
#[test]
fn directional_lights_match_mitsuba() {
    check_xml_against_reference("directional", 512, |s| {
        for light in &mut s.lights {
            if let lancer::scene::DeltaLight::Directional {
                direction,
                irradiance,
            } = *light
            {
                *light = lancer::scene::DeltaLight::Point {
                    position: -100.0 * direction,
                    intensity: irradiance * 1e4,
                };
            }
        }
    });
}

/// Mitsuba's `direct` integrator with an area light, a mirror and a point
/// light; as a full path tracer (max_depth 8) the image fails.
#[test]
fn direct_integrator_matches_mitsuba() {
    check_xml_against_reference("direct", 512, |s| s.render.max_depth = 8);
}

/// `direct` with `bsdf_samples` 0 and `emitter_samples` 2: emitter sampling
/// alone (the mirror shows no light), each point-light sample counted as
/// Mitsuba counts it; with plain MIS direct lighting the image fails.
#[test]
fn direct_emitter_sampling_only_matches_mitsuba() {
    check_xml_against_reference("direct_emitter_only", 512, |s| {
        s.render.emitter_sampling_only = false;
        s.render.delta_light_gain = 1;
    });
}

/// `hide_emitters`: camera rays pass through the area light and see no
/// environment; with the emitters shown the image fails.
#[test]
fn hide_emitters_matches_mitsuba() {
    check_xml_against_reference("hide_emitters", 512, |s| s.render.hide_emitters = false);
}
