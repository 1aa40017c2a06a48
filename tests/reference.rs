//! Statistical comparison against images made by an independent renderer
//! (Mitsuba 3; see tools/mitsuba_reference.py), with a per-pixel z-test on
//! lancer's own per-pixel variance, at alpha = 0.01 with Šidák correction
//! over the pixels, as in Mitsuba 3's render tests.

mod common;

use common::*;
use lancer::compare::{z_test, ZTest};
use lancer::render::RenderOutput;
use lancer::scene::Scene;

/// Share of pixels that must pass the z-test.
const MIN_PASS_FRACTION: f64 = 0.995;
/// Largest relative difference of the image means.
const MAX_MEAN_REL_DIFF: f64 = 0.01;

/// Reads a stored reference: the mean and the variance of the mean.
fn reference(name: &str) -> (u32, u32, Vec<f32>, Vec<f32>) {
    let (w, h, mean) = lancer::output::read_exr(&repo(&format!("tests/reference/{name}.exr")))
        .expect("reference mean");
    let (_, _, var) = lancer::output::read_exr(&repo(&format!("tests/reference/{name}.var.exr")))
        .expect("reference variance");
    (w, h, mean, var)
}

/// Compares a render with a reference image.
fn compare(out: &RenderOutput, mean: &[f32], ref_mean: &[f32], ref_var: &[f32]) -> ZTest {
    z_test(mean, &out.var_of_mean, ref_mean, ref_var, 0.01)
}

/// Tells whether a comparison passes both criteria.
fn passes(z: &ZTest) -> bool {
    z.pass_fraction >= MIN_PASS_FRACTION && z.mean_rel_diff.abs() <= MAX_MEAN_REL_DIFF
}

/// Renders the Cornell box at the reference's size.
fn cornell(scene: &Scene, w: u32, h: u32) -> RenderOutput {
    let mut scene = scene.clone();
    scene.render.width = w;
    scene.render.height = h;
    scene.render.spp = 1024;
    let ctx = context();
    render(&ctx, &scene, &options(1 << 18))
}

#[test]
fn cornell_box_matches_mitsuba_and_wrong_images_fail() {
    let (w, h, ref_mean, ref_var) = reference("cornell");
    let scene = load("scenes/cornell.toml");
    let out = cornell(&scene, w, h);

    let z = compare(&out, &out.mean, &ref_mean, &ref_var);
    println!("lancer vs Mitsuba 3: {z}");
    assert!(
        passes(&z),
        "Cornell box differs from the Mitsuba reference: {z}"
    );

    // A mirrored image must fail: the red wall is on the wrong side.
    let mut mirrored = out.mean.clone();
    for row in mirrored.chunks_mut(3 * w as usize) {
        let pixels: Vec<[f32; 3]> = row.chunks(3).rev().map(|p| [p[0], p[1], p[2]]).collect();
        row.copy_from_slice(pixels.concat().as_slice());
    }
    let z_mirrored = compare(&out, &mirrored, &ref_mean, &ref_var);
    println!("mirrored: {z_mirrored}");
    assert!(
        !passes(&z_mirrored),
        "a mirrored image passed: {z_mirrored}"
    );

    // A light 5% brighter must fail.
    let mut brighter = scene.clone();
    for m in &mut brighter.materials {
        m.emission *= 1.05;
    }
    let out_bright = cornell(&brighter, w, h);
    let z_bright = compare(&out_bright, &out_bright.mean, &ref_mean, &ref_var);
    println!("5% brighter light: {z_bright}");
    assert!(!passes(&z_bright), "a 5% brighter light passed: {z_bright}");
}

/// Renders a stored test scene at its reference's size and z-tests it.
fn check_against_reference(name: &str, spp: u32) {
    let (w, h, ref_mean, ref_var) = reference(name);
    let mut scene = load(&format!("tests/scenes/{name}.toml"));
    scene.render.width = w;
    scene.render.height = h;
    scene.render.spp = spp;
    let ctx = context();
    let out = render(&ctx, &scene, &options(1 << 18));
    let z = compare(&out, &out.mean, &ref_mean, &ref_var);
    println!("{name}: lancer vs Mitsuba 3: {z}");
    assert!(passes(&z), "{name} differs from the Mitsuba reference: {z}");
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
