//! Scene inputs that could render a silently wrong image render right, or
//! are refused before rendering with the real figure.

mod common;

use common::{context, lancer, load_inline, options, render, scene_header, stderr};

/// A lit sphere in front of a camera at the origin looking down -z, with
/// `look_at` and `up` as given.
fn camera_scene(look_at: &str, up: &str) -> lancer::scene::Scene {
    let camera = format!("eye = [0, 0, 0]\nlook_at = {look_at}\nup = {up}\nvfov = 50");
    let text = scene_header((16, 12), 4, 3, &camera, "[0.2, 0.3, 0.4]")
        + "[materials.white]\ntype = \"lambert\"\nalbedo = [0.7, 0.7, 0.7]\n\
         [materials.lamp]\ntype = \"lambert\"\nalbedo = [0, 0, 0]\nemission = [4, 3, 2]\n\
         [[objects]]\ntype = \"sphere\"\ncenter = [0.4, 0, -3]\nradius = 0.8\nmaterial = \"white\"\n\
         [[objects]]\ntype = \"sphere\"\ncenter = [-0.8, 0.5, -2.5]\nradius = 0.3\nmaterial = \"lamp\"\n";
    load_inline(&text).unwrap_or_else(|e| panic!("{e}"))
}

/// `look_at` 1e-30 from `eye` and an `up` of length 1e-30 built a NaN
/// camera basis in f32 (a black image). Built in f64, they give the same
/// image, bit for bit, as the same camera with unit vectors.
#[test]
fn camera_vectors_of_length_1e30_render_like_unit_ones() {
    let ctx = context();
    let unit = render(
        &ctx,
        &camera_scene("[0, 0, -1]", "[1, 0, 0]"),
        &options(1 << 12),
    );
    let tiny = render(
        &ctx,
        &camera_scene("[0, 0, -1e-30]", "[1e-30, 0, 0]"),
        &options(1 << 12),
    );
    let mean: f64 = unit.mean.iter().map(|&x| x as f64).sum::<f64>() / unit.mean.len() as f64;
    assert!(mean > 0.1, "the reference image is dark: mean {mean}");
    assert_eq!(unit.mean, tiny.mean);
}

/// 65536 x 65536 wraps a u32 pixel count to 0: refused when the scene is
/// read, and when --width / --height set it after reading.
#[test]
fn image_size_overflow_is_refused_with_the_real_figure() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let o = lancer(
        &[
            "render",
            "tests/bad_scenes/huge_image.toml",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("huge_image.toml:3: render.width: 65536 x 65536 = 4294967296 pixels"),
        "{e}"
    );
    let o = lancer(
        &[
            "render",
            "tests/scenes/furnace.toml",
            "--width",
            "100000",
            "--height",
            "100000",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains(
            "render.width: 100000 x 100000 = 10000000000 pixels; lancer renders at most \
             2147483648 pixels (2^31: the kernels index pixels in 32-bit integers); lower \
             the width or height (in the scene, or --width / --height)"
        ),
        "{e}"
    );
    assert!(!e.contains("panicked"), "{e}");
    assert!(!out.exists());
}
