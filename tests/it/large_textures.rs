//! Textures larger than the one device binding that holds every texel are
//! shrunk to fit, keeping their mean colour, with a warning that names
//! them; alone or together. The binding's limit is lowered with
//! `LANCER_MAX_TEXTURE_BYTES` so that small textures stand for large ones
//! (on lavapipe the real limit, 128 MiB, takes a 5800 x 5800 texture).

use crate::common;

use std::path::Path;

use common::{lancer, stderr};
use lancer::util::color::srgb_decode;

/// A `size` x `size` PNG of seeded noise, every channel 8 bits.
fn write_noise(path: &Path, size: u32, seed: u32) {
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (state >> 24) as u8
    };
    image::RgbaImage::from_fn(size, size, |_, _| {
        image::Rgba([next(), next(), next(), 255])
    })
    .save(path)
    .unwrap();
}

/// The mean of `pixels`' colour, each decoded by `linear`.
fn mean<P>(pixels: impl Iterator<Item = P>, linear: impl Fn(&P, usize) -> f64) -> [f64; 3] {
    let (mut m, mut n) = ([0.0; 3], 0.0);
    for p in pixels {
        for (c, m) in m.iter_mut().enumerate() {
            let v = linear(&p, c);
            assert!(v.is_finite(), "non-finite pixel");
            *m += v;
        }
        n += 1.0;
    }
    m.map(|v| v / n)
}

/// The texture's mean colour in linear light, as the kernels decode it.
fn linear_mean(path: &Path) -> [f64; 3] {
    let img = image::open(path).unwrap().into_rgba8();
    mean(img.pixels(), |p, c| {
        f64::from(srgb_decode(f32::from(p.0[c]) / 255.0))
    })
}

/// The mean colour of an EXR render.
fn image_mean(path: &Path) -> [f64; 3] {
    let img = image::open(path).unwrap().into_rgb32f();
    mean(img.pixels(), |p, c| f64::from(p.0[c]))
}

/// A scene whose view a textured quad fills (Lambert under uniform
/// radiance 1: every pixel is the texture's linear colour at its uv), with
/// a second, Phong-textured quad behind the first, where no ray reaches
/// it, when `second` is given.
fn write_scene(dir: &Path, texture: &str, second: Option<&str>) -> std::path::PathBuf {
    let mut text = format!(
        r#"[render]
width = 64
height = 64
spp = 16
max_depth = 2
seed = 0

[camera]
eye = [0.0, 0.0, 1.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
vfov = 90.0

[environment]
radiance = [1.0, 1.0, 1.0]

[materials.noise]
type = "lambert"
albedo_texture = "{texture}"

[[objects]]
type = "quad"
origin = [-1.0, -1.0, 0.0]
edge_u = [2.0, 0.0, 0.0]
edge_v = [0.0, 2.0, 0.0]
material = "noise"
"#
    );
    if let Some(second) = second {
        text.push_str(&format!(
            r#"
[materials.small]
type = "phong"
diffuse_texture = "{second}"
specular = [0.1, 0.1, 0.1]
exponent = 10.0

[[objects]]
type = "quad"
origin = [-1.0, -1.0, -5.0]
edge_u = [0.0, 2.0, 0.0]
edge_v = [2.0, 0.0, 0.0]
material = "small"
"#
        ));
    }
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Renders `scene` to `out` (EXR) with extra environment variables and
/// returns stderr; the render must succeed.
fn render(scene: &Path, out: &Path, envs: &[(&str, &str)]) -> String {
    let o = lancer(
        &[
            "render",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ],
        envs,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    stderr(&o)
}

/// A 256 x 256 texture over a 16,400-byte binding (room for 64 x 64
/// texels and the header) is shrunk to 64 x 64 with the exact warning, and
/// the render's mean colour stays within 1% of the full-size render's and
/// of the texture's own linear mean (the shrinking filter averages in
/// linear light; averaging the sRGB codes of 4 x 4 blocks would darken
/// this noise by 29%).
#[test]
fn texture_over_the_binding_limit_is_shrunk_keeping_its_mean_colour() {
    let dir = tempfile::tempdir().unwrap();
    let texture = dir.path().join("noise.png");
    write_noise(&texture, 256, 7);
    let scene = write_scene(dir.path(), "noise.png", None);
    let full = dir.path().join("full.exr");
    let shrunk = dir.path().join("shrunk.exr");
    let quiet = render(&scene, &full, &[]);
    assert!(!quiet.contains("warning"), "{quiet}");
    let said = render(&scene, &shrunk, &[("LANCER_MAX_TEXTURE_BYTES", "16400")]);
    assert_eq!(
        said.trim_end(),
        format!(
            "warning: texture {} (material \"noise\", albedo_texture) downscaled from 256 x 256 \
             to 64 x 64 texels, keeping its mean colour: the scene's textures need 262160 bytes, \
             more than the 16400 bytes one device binding holds; give a smaller image to choose \
             the filtering yourself",
            texture.display()
        )
    );
    let (want, a, b) = (
        linear_mean(&texture),
        image_mean(&full),
        image_mean(&shrunk),
    );
    println!("texture {want:?}, full-size render {a:?}, shrunk {b:?}");
    for c in 0..3 {
        assert!(
            (b[c] - a[c]).abs() <= 0.01 * a[c],
            "channel {c}: {b:?} vs {a:?}"
        );
        assert!(
            (a[c] - want[c]).abs() <= 0.01 * want[c],
            "channel {c}: {a:?} vs {want:?}"
        );
    }
}

/// Textures each under the limit whose sum is over it: the largest is
/// shrunk until all fit, the small one keeps its size. Too many textures
/// for even one texel each, or a bad limit, are refused with a message.
#[test]
fn textures_that_together_exceed_the_binding_limit_are_shrunk() {
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.png");
    let small = dir.path().join("small.png");
    write_noise(&big, 64, 1);
    write_noise(&small, 32, 2);
    let scene = write_scene(dir.path(), "big.png", Some("small.png"));
    let out = dir.path().join("out.exr");
    // 64 x 64 + 32 x 32 = 5120 texels into 3000 (+ two 4-word headers):
    // the big one is capped at 1976 texels, 44 x 44
    let said = render(&scene, &out, &[("LANCER_MAX_TEXTURE_BYTES", "12032")]);
    assert_eq!(
        said.trim_end(),
        format!(
            "warning: texture {} (material \"noise\", albedo_texture) downscaled from 64 x 64 \
             to 44 x 44 texels, keeping its mean colour: the scene's textures need 20512 bytes, \
             more than the 12032 bytes one device binding holds; give a smaller image to choose \
             the filtering yourself",
            big.display()
        )
    );
    let m = image_mean(&out);
    let want = linear_mean(&big);
    for c in 0..3 {
        assert!(
            (m[c] - want[c]).abs() <= 0.02 * want[c],
            "{m:?} vs {want:?}"
        );
    }
    let scene_arg = scene.to_str().unwrap();
    for (limit, says) in [
        (
            "20",
            "the scene's 2 textures cannot fit in 20 bytes, the most one device binding holds, \
             even at one texel each: use fewer textures",
        ),
        (
            "lots",
            "LANCER_MAX_TEXTURE_BYTES=\"lots\" is not a number of bytes above 0",
        ),
        (
            "0",
            "LANCER_MAX_TEXTURE_BYTES=\"0\" is not a number of bytes above 0",
        ),
    ] {
        let o = lancer(&["info", scene_arg], &[("LANCER_MAX_TEXTURE_BYTES", limit)]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
    }
}

/// A scene of one sphere per texture file in `dir`, for `pack_textures`.
fn textured_scene(dir: &Path, files: &[&str]) -> lancer::scene::Scene {
    let mut text = String::from(
        "[render]\nwidth = 8\nheight = 8\nspp = 1\n\
         [camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40\n",
    );
    for (i, file) in files.iter().enumerate() {
        text += &format!(
            "[materials.m{i}]\ntype = \"lambert\"\nalbedo_texture = \"{file}\"\n\
             [[objects]]\ntype = \"sphere\"\ncenter = [{i}, 0, 0]\nradius = 0.5\nmaterial = \"m{i}\"\n"
        );
    }
    lancer::scene::load_str(&text, &dir.join("scene.toml")).unwrap_or_else(|e| panic!("{e}"))
}

fn pack_error(scene: &lancer::scene::Scene) -> String {
    match lancer::internal::gpu::pack_textures(scene, 1 << 27) {
        Ok(_) => String::from("packed"),
        Err(e) => format!("{e:#}"),
    }
}

/// Every texture's header is checked against the texel limit before any
/// texture is decoded, and the sizes are summed only then: the second
/// texture's header claims 10^10 texels, and the first, whose header is
/// fine but whose data is cut short, was decoded first and blamed.
#[test]
fn every_texture_header_is_checked_before_any_texture_is_decoded() {
    let dir = tempfile::tempdir().unwrap();
    let mut png = Vec::new();
    image::RgbaImage::from_pixel(64, 64, image::Rgba([200, 100, 50, 255]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    std::fs::write(dir.path().join("cut.png"), &png[..60]).unwrap();
    // The fuzzer's PNG header of 100000 x 100000 (after its extension byte).
    let huge = std::fs::read(common::repo(
        "fuzz/regressions/texture/png_header_1e10_texels",
    ));
    std::fs::write(dir.path().join("huge.png"), &huge.unwrap()[1..]).unwrap();
    let scene = textured_scene(dir.path(), &["cut.png", "huge.png"]);
    assert_eq!(
        pack_error(&scene),
        format!(
            "texture {} is 100000 x 100000 = 10000000000 texels; lancer reads textures of at \
             most 16777216 texels (4096 x 4096): downscale it",
            dir.path().join("huge.png").display()
        )
    );
}

/// An EXR's data window (the pixels it stores, which are decoded) is
/// checked against the texel limit as well as its display window (the
/// image's size): a 4 x 4 image storing 4097 x 4096 pixels was decoded
/// whole, 16.8 million pixels for 16 texels.
#[test]
fn exr_data_window_is_checked_against_the_texel_limit() {
    use exr::prelude::*;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("window.exr");
    let grey = f16::from_f32(0.5);
    let layer = Layer::new(
        Vec2(4097, 4096),
        LayerAttributes::named("rgb"),
        Encoding {
            compression: Compression::RLE,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        SpecificChannels::rgb(|_: Vec2<usize>| (grey, grey, grey)),
    );
    let mut image = Image::from_layer(layer);
    image.attributes.display_window = IntegerBounds::new(Vec2(0, 0), Vec2(4, 4));
    image.write().to_file(&path).unwrap();
    let scene = textured_scene(dir.path(), &["window.exr"]);
    assert_eq!(
        pack_error(&scene),
        format!(
            "texture {} stores a data window of 4097 x 4096 = 16781312 texels (its image is \
             4 x 4); lancer reads textures of at most 16777216 texels (4096 x 4096): crop it \
             to its display window, or downscale it",
            path.display()
        )
    );
}
