//! Published Mitsuba 3 scenes, unedited (`../shared/realscenes/`, read where
//! they are: its README gives their sources, licences and the sizes to test
//! at), rendered by lancer and compared with Mitsuba's own render of the same
//! file by the block z-test of tests/it/common/reference.rs.
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
//!
//! The comparison covers the whole image, border pixels included: none of
//! these films states `sample_border`, so it is Mitsuba's default, false
//! (no sample lands outside the image, so a border pixel's filter is cut
//! and renormalised), and lancer samples the filter cut at the edge in the
//! same way (docs/mitsuba.md, "Image borders"). A frame can still be left
//! out (`border`), for a scene that samples past its edge.

use crate::common;

use common::reference::*;
use common::*;
use lancer::scene::{load_with, RenderOverrides};

/// Where the shared scenes are, from the crate root.
const REALSCENES: &str = "../shared/realscenes";

/// How a published scene is checked.
struct Case {
    /// Name of the reference, `tests/reference/real/{name}`.
    name: &'static str,
    /// The scene file under [`REALSCENES`].
    file: &'static str,
    /// Image size the README of the scenes gives.
    size: (u32, u32),
    /// lancer's samples per pixel.
    spp: u32,
    /// Pixels left out on every side: how far the scene's filter reaches
    /// past a pixel (0 for the box).
    border: usize,
    /// The scene is mirror-symmetric left to right, so a mirrored image
    /// is no wrong image; only the 5% brighter one must fail.
    symmetric: bool,
    /// Pixels left out on every side for the wrong-image checks (at least
    /// `border`): a scene whose object fills only the middle of a black
    /// image is judged where it is, or the black pixels, which pass
    /// whatever the light, would hide a wrong one.
    wrong_border: usize,
}

/// Renders the case's scene, checks every value is finite, and z-tests it
/// against the stored reference, with wrong images that must fail.
fn check(case: Case) {
    let Case {
        name,
        file,
        size: (width, height),
        spp,
        border,
        symmetric,
        wrong_border,
    } = case;
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
    assert_matches(name, &test.cropped(border), &reference.cropped(border));
    let wrong_border = wrong_border.max(border);
    let (test, reference) = (test.cropped(wrong_border), reference.cropped(wrong_border));
    if symmetric {
        let (z, _) = compare(&test.scaled(1.05), &reference);
        println!("{name}: 5% brighter light: {z}");
        assert!(!passes(&z), "{name}: a 5% brighter light passed: {z}");
    } else {
        assert_wrong_images_fail(name, &test, &reference);
    }
}

#[test]
fn tutorial_cornell_box() {
    check(Case {
        name: "tut_cbox",
        file: "tut_cbox/cbox.xml",
        size: (256, 256),
        spp: 1024,
        border: 0,
        symmetric: false,
        wrong_border: 0,
    });
}

#[test]
fn tutorial_teapot_under_point_lights() {
    check(Case {
        name: "tut_simple",
        file: "tut_simple/simple.xml",
        size: (256, 256),
        spp: 128,
        border: 0,
        symmetric: false,
        wrong_border: 0,
    });
}

#[test]
fn bitterli_cornell_box() {
    check(Case {
        name: "bitterli_cornell",
        file: "bitterli_cornell/scene_v3.xml",
        size: (256, 256),
        spp: 512,
        border: 0,
        symmetric: false,
        wrong_border: 0,
    });
}

#[test]
fn mitsuba_hello_teapot() {
    check(Case {
        name: "mi_hello",
        file: "mi_hello/scenes/hello.xml",
        size: (256, 192),
        spp: 128,
        border: 0,
        symmetric: false,
        wrong_border: 0,
    });
}

#[test]
fn lit_sphere() {
    check(Case {
        name: "diff_sphere",
        file: "diff_sphere/diff_sphere.xml",
        size: (16, 16),
        spp: 1024,
        border: 0,
        symmetric: true,
        wrong_border: 0,
    });
}

#[test]
fn anisotropic_rough_conductor() {
    check(Case {
        name: "rough_aniso",
        file: "rough_aniso/rough_anisotropic_optimization.xml",
        size: (256, 256),
        spp: 1024,
        border: 0,
        symmetric: true,
        wrong_border: 0,
    });
}

#[test]
fn cow_under_an_environment_map() {
    check(Case {
        name: "spot_cow",
        file: "spot_cow/spot.xml",
        size: (256, 256),
        spp: 1024,
        border: 0,
        symmetric: false,
        // The cow spans rows 34 to 202 and columns 61 to 206 of the black
        // image (hide_emitters): judge wrong images on the middle 144 x 144
        wrong_border: 56,
    });
}
