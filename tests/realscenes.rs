//! Published Mitsuba 3 scenes, unedited (`../shared/realscenes/`, read where
//! they are: its README gives their sources, licences and the sizes to test
//! at), rendered by lancer and compared with Mitsuba's own render of the same
//! file by the block z-test of tests/common/reference.rs.
//!
//! The references in `tests/reference/real/` were made by Mitsuba 3.9.1
//! loading each file itself, with the film size of the README:
//!
//! ```sh
//! python3 tools/mitsuba_xml_reference.py ../shared/realscenes/tut_cbox/cbox.xml \
//!     --out tests/reference/real/tut_cbox --spp-per-pass 256 --passes 16
//! ```
//!
//! (each reference's `.json` holds its exact command). lancer renders the
//! same file through `scene::load_with`, with the same size given as the
//! command line's `--width/--height` would.

mod common;

use common::reference::*;
use common::*;
use lancer::scene::{load_with, RenderOverrides};

/// Where the shared scenes are, from the crate root.
const REALSCENES: &str = "../shared/realscenes";

/// Renders `file` (under [`REALSCENES`]) at `width` x `height` and `spp`,
/// checks every value is finite, and z-tests it against the stored
/// reference `tests/reference/real/{name}`.
fn check(name: &str, file: &str, (width, height): (u32, u32), spp: u32) {
    let path = repo(REALSCENES).join(file);
    assert!(
        path.exists(),
        "{}: the shared published scenes are missing; they are expected at {REALSCENES} beside the repository",
        path.display()
    );
    let overrides = RenderOverrides {
        width: Some(width),
        height: Some(height),
        spp: Some(spp),
        ..RenderOverrides::default()
    };
    let scene = load_with(&path, &overrides).unwrap_or_else(|e| panic!("{name}: {e}"));
    let ctx = context();
    let out = render(&ctx, &scene, &options(1 << 18));
    check_finite(&out);
    let test = estimate(&out);
    let reference = reference(&format!("real/{name}"));
    assert_eq!(
        (test.width, test.height),
        (reference.width, reference.height),
        "{name}: size"
    );
    assert_matches(name, &test, &reference);
    assert_wrong_images_fail(name, &test, &reference);
}

#[test]
fn tutorial_cornell_box() {
    check("tut_cbox", "tut_cbox/cbox.xml", (256, 256), 128);
}

#[test]
fn tutorial_teapot_under_point_lights() {
    check("tut_simple", "tut_simple/simple.xml", (256, 256), 128);
}

#[test]
fn bitterli_cornell_box() {
    check(
        "bitterli_cornell",
        "bitterli_cornell/scene_v3.xml",
        (256, 256),
        128,
    );
}

#[test]
fn mitsuba_hello_teapot() {
    check("mi_hello", "mi_hello/scenes/hello.xml", (256, 192), 128);
}

#[test]
fn lit_sphere() {
    check("diff_sphere", "diff_sphere/diff_sphere.xml", (16, 16), 1024);
}

#[test]
fn anisotropic_rough_conductor() {
    check(
        "rough_aniso",
        "rough_aniso/rough_anisotropic_optimization.xml",
        (256, 256),
        128,
    );
}

#[test]
fn cow_under_an_environment_map() {
    check("spot_cow", "spot_cow/spot.xml", (256, 256), 128);
}
