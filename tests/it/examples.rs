//! Every example scene in `scenes/` loads and renders: each `scenes/*.toml`
//! (the folder is listed when the test runs, so a new scene is covered
//! without editing this file) is rendered at 32 x 32, 4 spp, and must give a
//! finite image that is not black. `render` also asserts no NaN or Inf, no
//! dropped sample and no validation error. The gallery scenes the README
//! shows must all be there, so that a deleted one is noticed.

use crate::common;
use common::*;

/// The scenes the README's gallery shows.
const GALLERY: [&str; 8] = [
    "cornell.toml",
    "glass.toml",
    "mirror.toml",
    "glossy.toml",
    "phong.toml",
    "dof.toml",
    "textured.toml",
    "soft_shadows.toml",
];

/// The file names of `scenes/*.toml`, sorted.
fn example_scenes() -> Vec<String> {
    scene_files(&["scenes"])
        .into_iter()
        .map(|f| f.trim_start_matches("scenes/").to_string())
        .collect()
}

#[test]
fn gallery_scenes_are_all_there() {
    let names = example_scenes();
    for scene in GALLERY {
        assert!(
            names.iter().any(|n| n == scene),
            "scenes/{scene} is missing (the README's gallery shows it); found {names:?}"
        );
    }
}

#[test]
fn every_example_scene_renders() {
    let names = example_scenes();
    assert!(names.len() >= GALLERY.len(), "too few scenes: {names:?}");
    let ctx = context();
    for name in &names {
        let path = format!("scenes/{name}");
        let mut scene = load(&path);
        scene.render.width = 32;
        scene.render.height = 32;
        scene.render.spp = 4;
        let out = render(&ctx, &scene, &options(1 << 14));
        assert_eq!(out.mean.len(), 32 * 32 * 3, "{path}");
        let mean = out.mean.iter().map(|&v| f64::from(v)).sum::<f64>() / out.mean.len() as f64;
        assert!(
            mean.is_finite() && mean > 0.0,
            "{path}: image mean {mean} (must be finite and > 0)"
        );
    }
}
